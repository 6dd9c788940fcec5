// specula: command-line front end. Parses arguments, calls the engine, returns
// an exit code: 0 success, 1 failure (bad input, numerical failure), 2 usage error.
#include "commands.h"
#include "core/error.h"
#include "core/log.h"
#include "core/memory.h"
#include "specula/version.h"

#include <cstdio>
#include <exception>
#include <new>
#include <string>

int main(int argc, char** argv) {
    specula::cap_malloc_arenas();
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
    specula::cli::add_import_command(app);
    try {
        app.parse(argc, argv);
        return 0;
    } catch (const CLI::ParseError& e) {
        // --help and --version exit 0; every other parse error is a usage error (2).
        return app.exit(e) == 0 ? 0 : 2;
    } catch (const specula::UsageError& e) {
        std::fprintf(stderr, "usage error: %s\n", e.what());
        return 2;
    } catch (const std::bad_alloc&) {
        // The last resort: the stages name their input when they run out of memory (e.g.
        // load_capture); an allocation none of them foresaw still never reaches the user as a
        // bare "std::bad_alloc". Name the command and what it was given.
        std::string command;
        for (int i = 1; i < argc; ++i) command += std::string(" ") + argv[i];
        if (command.size() > 400) command = command.substr(0, 400) + " ...";
        std::fprintf(stderr,
                     "error: out of memory (std::bad_alloc) in `specula%s`: the input needs more memory than this process "
                     "may use (%s available now: %s)\n",
                     command.c_str(), specula::format_bytes(specula::available_memory().bytes).c_str(),
                     specula::available_memory().limit.c_str());
        return 1;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "error: %s\n", e.what());
        return 1;
    }
}
