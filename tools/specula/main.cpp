// specula: command-line front end. Parses arguments, calls the engine, returns
// an exit code: 0 success, 1 failure (bad input, numerical failure), 2 usage error.
#include "commands.h"
#include "core/error.h"
#include "core/log.h"
#include "specula/version.h"

#include <cstdio>
#include <exception>
#include <string>

int main(int argc, char** argv) {
    CLI::App app{"Specula: capture how a real object's surface looks (diffuse albedo + a specular lobe)\n"
                 "from calibrated photographs lit by known point lights."};
    app.set_version_flag("--version", std::string("specula ") + specula::kVersion);
    app.require_subcommand(1);
    bool quiet = false;
    bool verbose = false;
    app.add_flag("-q,--quiet", quiet, "Print only warnings and errors; no progress");
    app.add_flag("-v,--verbose", verbose, "Print debugging detail");
    app.parse_complete_callback([&] {
        specula::log::set_level(quiet ? specula::log::Level::Quiet
                                      : (verbose ? specula::log::Level::Verbose : specula::log::Level::Normal));
    });
    specula::cli::add_reconstruct_command(app);
    specula::cli::add_validate_command(app);
    specula::cli::add_synth_command(app);
    specula::cli::add_devices_command(app);
    specula::cli::add_bench_command(app);
    specula::cli::add_render_command(app);
    specula::cli::add_evaluate_command(app);
    try {
        app.parse(argc, argv);
        return 0;
    } catch (const CLI::ParseError& e) {
        // --help and --version exit 0; every other parse error is a usage error (2).
        return app.exit(e) == 0 ? 0 : 2;
    } catch (const specula::UsageError& e) {
        std::fprintf(stderr, "usage error: %s\n", e.what());
        return 2;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "error: %s\n", e.what());
        return 1;
    }
}
