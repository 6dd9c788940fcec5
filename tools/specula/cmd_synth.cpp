// Placeholder until the synth command lands.
#include "commands.h"
namespace specula::cli {
void add_synth_command(CLI::App& app) { (void)app; }
}
