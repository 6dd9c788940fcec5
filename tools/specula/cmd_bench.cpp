// `specula bench fit`: runs the Lafortune fit's stiff-case suite
// (engine/specular/lafortune_fit_cases.h) and prints one line per case: truth, the robust
// fit's result, iterations, time, status, and the thesis's plain recipe on the same samples.
#include "commands.h"
#include "core/error.h"
#include "specular/lafortune_fit_cases.h"

#include <cstdio>
#include <memory>
#include <string>

namespace specula::cli {

namespace {
struct BenchFitOptions {
    std::string only;
    bool no_plain = false;
    bool no_long = false;
    bool reasons = false;
};
} // namespace

void add_bench_command(CLI::App& app) {
    CLI::App* bench = app.add_subcommand("bench", "Measure engine stages on synthetic data");
    bench->require_subcommand(1);
    auto opts = std::make_shared<BenchFitOptions>();
    CLI::App* fit = bench->add_subcommand("fit", "Lafortune fit on the stiff-case suite, against the thesis's plain recipe");
    fit->add_option("--case", opts->only, "Run only the cases whose name contains this text");
    fit->add_flag("--no-plain", opts->no_plain, "Skip the thesis's plain recipe");
    fit->add_flag("--no-long", opts->no_long, "Skip the 10-million-sample case");
    fit->add_flag("--reasons", opts->reasons, "Print each fit's reason under its line");
    fit->callback([opts] {
        std::printf("%s\n", lafortune_case_table_header().c_str());
        int failed = 0;
        for (const LafortuneFitCase& c : lafortune_fit_cases()) {
            if (!opts->only.empty() && c.name.find(opts->only) == std::string::npos) continue;
            if (opts->no_long && c.long_running) continue;
            const LafortuneCaseResult r = run_lafortune_case(c, !opts->no_plain);
            std::printf("%s\n", lafortune_case_table_row(c, r).c_str());
            if (opts->reasons) {
                std::printf("    robust: %s\n", r.robust.reason.c_str());
                if (r.plain_run) std::printf("    plain:  %s\n", r.plain.reason.c_str());
            }
            std::fflush(stdout);
            failed += r.robust_pass ? 0 : 1;
        }
        if (failed > 0) throw NumericalError(std::to_string(failed) + " case(s) not recovered honestly by the robust fit");
    });
}

} // namespace specula::cli
