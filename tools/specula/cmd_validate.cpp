// Placeholder until the validate command lands.
#include "commands.h"
namespace specula::cli {
void add_validate_command(CLI::App& app) { (void)app; }
}
