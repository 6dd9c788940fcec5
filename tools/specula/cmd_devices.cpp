// Placeholder until the devices command lands.
#include "commands.h"
namespace specula::cli {
void add_devices_command(CLI::App& app) { (void)app; }
}
