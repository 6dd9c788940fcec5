// `specula bench fit`: runs the Lafortune fit's stiff-case suite
// (engine/specular/lafortune_fit_cases.h) and prints one line per case: truth, the robust
// fit's result, iterations, time, status, and the thesis's plain recipe on the same samples.
// `specula bench sweep CAPTURE`: the pipeline over a grid of accuracy/time knobs
// (engine/pipeline/sweep.h): a table (CSV, JSON) and a plot (SVG) of test-frame error
// against run time with the default and the Pareto front marked.
// `specula bench indirect CAPTURE...`: reconstruct with the indirect light off and on, the
// stage's cost and the whole run's ratio beside the test-frame error of both.
#include "commands.h"
#include "core/error.h"
#include "core/log.h"
#include "pipeline/reconstruct.h"
#include "pipeline/sweep.h"
#include "specular/lafortune_fit_cases.h"

#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

namespace specula::cli {

namespace {
struct BenchFitOptions {
    std::string only;
    bool no_plain = false;
    bool no_long = false;
    bool reasons = false;
};

struct BenchSweepArgs {
    std::string capture;
    std::string out;
    std::vector<double> tpp{0.5, 1.0};
    std::vector<std::uint32_t> fit_samples{20000, 200000};
    std::vector<std::string> grids{"auto"};
    std::vector<std::string> backends{"vulkan", "cpu"};
    std::string device;
    std::string specular = "auto";
    unsigned threads = 2;
    bool keep = false;
};

void run_sweep_command(const BenchSweepArgs& a) {
    SweepOptions o;
    o.capture = a.capture;
    o.out_dir = a.out;
    o.keep_points = a.keep;
    o.base.device = a.device;
    o.base.threads = a.threads;
    o.base.specular = a.specular == "on" ? SpecularMode::On : a.specular == "off" ? SpecularMode::Off : SpecularMode::Auto;
    o.knobs.texels_per_pixel = a.tpp;
    o.knobs.fit_samples = a.fit_samples;
    o.knobs.factorization_grid.clear();
    for (const std::string& g : a.grids) {
        if (g == "auto") {
            o.knobs.factorization_grid.push_back(0);
            continue;
        }
        std::size_t used = 0;
        unsigned long v = 0;
        try {
            v = std::stoul(g, &used);
        } catch (const std::exception&) {
            used = 0;
        }
        if (used != g.size() || v < 4 || v > 128) throw UsageError("--grids: '" + g + "' is neither auto nor a resolution in [4, 128]");
        o.knobs.factorization_grid.push_back(static_cast<std::uint32_t>(v));
    }
    o.knobs.backends.clear();
    for (const std::string& b : a.backends) o.knobs.backends.push_back(b == "cpu" ? Backend::Cpu : Backend::Vulkan);
    const SweepResult r = run_sweep(o);
    std::printf("%-44s %10s %12s %9s %s\n", "point", "seconds", "test RMS %", "test Q1", "");
    for (const SweepPoint& p : r.points) {
        if (!p.failure.empty()) {
            std::printf("%-44s failed: %s\n", p.label.c_str(), p.failure.c_str());
            continue;
        }
        std::printf("%-44s %10.2f %12.3f %9.2f %s%s\n", p.label.c_str(), p.seconds, p.error, p.test_q1,
                    p.on_front ? "front " : "", p.is_default ? "default" : "");
    }
    std::printf("Pareto front (run time, test masked RMS %%):");
    for (const std::size_t i : r.front) std::printf(" [%s: %.2f s, %.3f %%]", r.points[i].label.c_str(), r.points[i].seconds, r.points[i].error);
    std::printf("\ncapture load %.2f s (shared, not in the run times); wrote %s/sweep.csv, sweep.json, sweep.svg, sweep.html\n", r.load_seconds,
                a.out.c_str());
}

struct BenchIndirectArgs {
    std::vector<std::string> captures;
    std::string out;
    unsigned threads = 2;
};

// The stage times of a run whose names start with `prefix`, summed.
double stage_seconds(const ReconstructResult& r, const std::string& prefix) {
    double s = 0.0;
    for (const StageRecord& st : r.stages)
        if (st.name.rfind(prefix, 0) == 0) s += st.seconds;
    return s;
}

void run_indirect_command(const BenchIndirectArgs& a) {
    std::printf("%-24s %10s %10s %10s %10s %10s %7s %12s %12s\n", "capture", "particles", "transfer s", "rounds s", "off s", "on s",
                "ratio", "test off dB", "test on dB");
    for (const std::string& capture : a.captures) {
        const std::string name = std::filesystem::path(capture).filename().string();
        ReconstructResult result[2];
        for (int on = 0; on < 2; ++on) {
            ReconstructConfig c;
            c.capture = capture;
            c.out_dir = std::filesystem::path(a.out) / (name + (on ? "-on" : "-off"));
            c.force = true;
            c.threads = a.threads;
            c.indirect = on ? Toggle::On : Toggle::Off;
            result[on] = reconstruct(c);
        }
        const auto test_psnr = [](const ReconstructResult& r) {
            const nlohmann::json& e = r.report["evaluation"];
            return e.is_object() && e.contains("test") ? e["test"]["masked"]["psnr_display"].get<double>() : 0.0;
        };
        const double off = result[0].total_seconds, on = result[1].total_seconds;
        std::printf("%-24s %10zu %10.2f %10.2f %10.2f %10.2f %7.3f %12.2f %12.2f\n", name.c_str(),
                    result[1].report["particles"]["count"].get<std::size_t>(), stage_seconds(result[1], "indirect transfer"),
                    stage_seconds(result[1], "indirect light") + stage_seconds(result[1], "diffuse solve (indirect round"), off, on,
                    on / off, test_psnr(result[0]), test_psnr(result[1]));
        std::fflush(stdout);
    }
}

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

    auto sa = std::make_shared<BenchSweepArgs>();
    CLI::App* sweep = bench->add_subcommand(
        "sweep",
        "Run the pipeline over a grid of the knobs that trade accuracy for time and write OUT/sweep.csv,\n"
        "OUT/sweep.json, OUT/sweep.svg and OUT/sweep.html (plot and table): test-frame error (masked RMS %,\n"
        "= 100 - Q1) against run time (the stages without the capture load, which is shared, and without the\n"
        "self-evaluation), the default point and the Pareto front marked. The lobe is rendered through its\n"
        "factorization cube-maps. The grid is the product of the lists below; the default point is added when\n"
        "missing. A point that fails is listed with its reason.");
    sweep->add_option("capture", sa->capture, "Capture folder (or its capture.json); needs test frames")->required();
    sweep->add_option("-o,--out", sa->out, "Output folder (created if missing)")->required();
    sweep->add_option("--tpp", sa->tpp, "Atlas texels per pixel (the atlas size)")
        ->delimiter(',')
        ->check(CLI::Range(0.05, 8.0))
        ->capture_default_str();
    sweep->add_option("--fit-samples", sa->fit_samples, "Residual samples the Lafortune fit uses (sample reduction; 0: all)")
        ->delimiter(',')
        ->capture_default_str();
    sweep->add_option("--grids", sa->grids, "Factorization grid resolutions: auto (from the lobe's width) or N (h = d = N)")
        ->delimiter(',')
        ->capture_default_str();
    sweep->add_option("--backends", sa->backends, "Backends of the compute stages: vulkan, cpu")
        ->delimiter(',')
        ->check(CLI::IsMember({"vulkan", "cpu"}))
        ->capture_default_str();
    sweep->add_option("--specular", sa->specular,
                      "Specular stages at every point: auto (the planner's energy test), on, off. The fit-samples and\n"
                      "grids knobs only matter where a lobe is fitted")
        ->check(CLI::IsMember({"auto", "on", "off"}))
        ->capture_default_str();
    sweep->add_option("-d,--device", sa->device, "Vulkan device: index or name substring (see `specula devices`)");
    sweep->add_option("--threads", sa->threads, "CPU threads")->check(CLI::Range(1u, 256u))->capture_default_str();
    sweep->add_flag("--keep-points", sa->keep, "Keep every point's outputs in OUT/points/NN");
    sweep->callback([sa] { run_sweep_command(*sa); });

    auto ia = std::make_shared<BenchIndirectArgs>();
    CLI::App* indirect = bench->add_subcommand(
        "indirect",
        "The cost and the gain of the indirect light (issue 16) on each CAPTURE: `reconstruct` with --indirect off\n"
        "and on, and one line each: the particles, the transfer's and the rounds' seconds, the whole run's\n"
        "seconds and their ratio, and the masked test-frame PSNR (display values) of both. The outputs go to\n"
        "OUT/<capture>-off and OUT/<capture>-on.");
    indirect->add_option("capture", ia->captures, "Capture folders (or capture.json files); need test frames")->required();
    indirect->add_option("-o,--out", ia->out, "Output folder (created if missing)")->required();
    indirect->add_option("--threads", ia->threads, "CPU threads")->check(CLI::Range(1u, 256u))->capture_default_str();
    indirect->callback([ia] { run_indirect_command(*ia); });
}

} // namespace specula::cli
