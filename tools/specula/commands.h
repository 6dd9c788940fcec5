#pragma once
// Each subcommand of `specula` registers itself here. A command's callback maps
// its options to an engine call; all logic lives in engine/.
#include "evaluate/indirect_light.h"
#include "export/bundle.h"

#include <CLI/CLI.hpp>

#include <cstdint>
#include <string>

namespace specula::cli {

/// The indirect-light options `evaluate` and `render` share (evaluate/indirect_light.h).
struct IndirectArgs {
    std::string mode = "auto";           ///< --indirect auto|on|off
    std::uint32_t bounces = 0;           ///< --indirect-bounces; 0: the bundle's, else 2
    std::uint32_t rays = 0;              ///< --indirect-rays; 0: the bundle's, else kTransferRays
    /// on, or auto and the bundle's albedo had that light removed.
    [[nodiscard]] bool wanted(const Bundle& bundle) const {
        return mode == "on" || (mode == "auto" && evaluate::indirect_removed_from_albedo(bundle));
    }
    [[nodiscard]] evaluate::BundleIndirectOptions options(const Bundle& bundle, unsigned threads) const {
        const evaluate::BundleTransfer transfer = evaluate::indirect_transfer_of(bundle);
        return {.bounces = bounces != 0 ? bounces : evaluate::indirect_bounces_of(bundle),
                .rays = rays != 0 ? rays : transfer.rays,
                .block = transfer.block,
                .threads = threads};
    }
};

/// Registers --indirect (its help: `what` is added to the common text), --indirect-bounces, --indirect-rays.
inline void add_indirect_options(CLI::App* cmd, IndirectArgs& a, const std::string& what) {
    cmd->add_option("--indirect", a.mode,
                    "Add the light that bounced off the object (on), or not (off); auto: when the bundle's albedo had it\n"
                    "removed (reconstruct's indirect stage ran). Built from the bundle alone: particles on its texture,\n"
                    "their visibility for the lights, a transfer of Embree rays. " + what)
        ->check(CLI::IsMember({"auto", "on", "off"}))
        ->capture_default_str();
    cmd->add_option("--indirect-bounces", a.bounces, "Bounces of the indirect light (default: the bundle's, else 2)")
        ->check(CLI::Range(1, 8));
    cmd->add_option("--indirect-rays", a.rays,
                    "Rays per row of the indirect transfer (default: the bundle's reconstruction's, else " +
                        std::to_string(kTransferRays) + "; its blocks are always the bundle's)")
        ->check(CLI::Range(1, 4096));
}

void add_validate_command(CLI::App& app); // cmd_validate.cpp
void add_synth_command(CLI::App& app);    // cmd_synth.cpp
void add_devices_command(CLI::App& app);  // cmd_devices.cpp
void add_reconstruct_command(CLI::App& app); // cmd_reconstruct.cpp
void add_bench_command(CLI::App& app);    // cmd_bench.cpp

void add_render_command(CLI::App& app);   // cmd_render.cpp
void add_evaluate_command(CLI::App& app); // cmd_evaluate.cpp
void add_import_command(CLI::App& app);   // cmd_import.cpp

} // namespace specula::cli
