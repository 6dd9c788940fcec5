#pragma once
// Each subcommand of `specula` registers itself here. A command's callback maps
// its options to an engine call; all logic lives in engine/.
#include <CLI/CLI.hpp>

namespace specula::cli {

void add_validate_command(CLI::App& app); // cmd_validate.cpp
void add_synth_command(CLI::App& app);    // cmd_synth.cpp
void add_devices_command(CLI::App& app);  // cmd_devices.cpp
void add_reconstruct_command(CLI::App& app); // cmd_reconstruct.cpp
void add_bench_command(CLI::App& app);    // cmd_bench.cpp

void add_render_command(CLI::App& app);   // cmd_render.cpp
void add_evaluate_command(CLI::App& app); // cmd_evaluate.cpp
void add_import_command(CLI::App& app);   // cmd_import.cpp

} // namespace specula::cli
