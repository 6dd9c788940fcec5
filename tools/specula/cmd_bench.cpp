// `specula bench fit`: runs the Lafortune fit's stiff-case suite
// (engine/specular/lafortune_fit_cases.h) and prints one line per case: truth, the robust
// fit's result, iterations, time, status, and the thesis's plain recipe on the same samples.
// `specula bench sweep CAPTURE`: the pipeline over a grid of accuracy/time knobs
// (engine/pipeline/sweep.h): a table (CSV, JSON) and a plot (SVG) of test-frame error
// against run time with the default and the Pareto front marked.
// `specula bench indirect CAPTURE...`: reconstruct with the indirect light off and on, the
// stage's cost and the whole run's ratio beside the test-frame error of both.
// `specula bench reconstruct CAPTURE`: the stage table of one default run beside the error it
// ends at, the run's time against the time `validate` takes to decode the capture, peak memory.
#include "commands.h"
#include "core/error.h"
#include "capture/capture.h"
#include "core/format.h"
#include "core/file_util.h"
#include "core/log.h"
#include "core/memory.h"
#include "core/timer.h"
#include "pipeline/reconstruct.h"
#include "pipeline/sweep.h"
#include "specular/lafortune_fit_cases.h"

#include <sys/resource.h>

#include <algorithm>
#include <cstdint>
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
            c.backend_auto = true; // reconstruct's default (--backend auto), not the config's plain Vulkan
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

struct BenchReconstructArgs {
    std::string capture;
    std::string out;
    std::string backend = "auto";
    unsigned threads = 2;
};

// Peak resident memory of this process so far (bytes).
std::uint64_t peak_rss_bytes() {
    rusage usage{};
    if (getrusage(RUSAGE_SELF, &usage) != 0) return 0;
    return static_cast<std::uint64_t>(usage.ru_maxrss) * 1024u; // kilobytes on Linux
}

void run_reconstruct_bench(const BenchReconstructArgs& a) {
    ReconstructConfig c;
    c.capture = a.capture;
    c.out_dir = a.out;
    c.force = true;
    c.threads = a.threads;
    c.backend = a.backend == "cpu" ? Backend::Cpu : Backend::Vulkan;
    c.backend_auto = a.backend == "auto";
    const Stopwatch run_clock;
    const ReconstructResult r = reconstruct(c);
    const double run_s = run_clock.seconds();
    const std::uint64_t peak_rss = peak_rss_bytes(); // the reconstruction's own (validate runs after it)

    // What `specula validate` does: the capture checked and every image decoded.
    const Stopwatch validate_clock;
    {
        const Capture capture = load_capture(a.capture, {.load_images = true, .threads = static_cast<int>(a.threads)});
    }
    const double validate_s = validate_clock.seconds();

    // Stages by name, without the "(joint round 2)"-like tags: how often and how long.
    struct Row {
        std::string name;
        int count = 0;
        double seconds = 0.0;
    };
    std::vector<Row> rows;
    for (const StageRecord& st : r.stages) {
        const std::string base = st.name.substr(0, st.name.find(" ("));
        auto it = std::find_if(rows.begin(), rows.end(), [&](const Row& row) { return row.name == base; });
        if (it == rows.end()) it = rows.insert(rows.end(), Row{base});
        ++it->count;
        it->seconds += st.seconds;
    }
    std::printf("%-28s %5s %9s %6s\n", "stage", "runs", "seconds", "share");
    for (const Row& row : rows)
        std::printf("%-28s %5d %9.2f %5.1f%%\n", row.name.c_str(), row.count, row.seconds, 100.0 * row.seconds / r.total_seconds);
    const nlohmann::json& e = r.report["evaluation"];
    const auto figure = [&](const char* split, const char* key) {
        return e.is_object() && e.contains(split) ? e[split]["masked"][key].get<double>() : 0.0;
    };
    std::printf("total %.2f s (reconstruct's own clock), %.2f s wall; validate %.2f s; ratio %.2f\n", r.total_seconds, run_s,
                validate_s, validate_s > 0.0 ? run_s / validate_s : 0.0);
    std::printf("peak RSS %s (reconstruct, before validate ran)\n", format_bytes(peak_rss).c_str());
    std::printf("masked PSNR (display): test %.3f dB, train %.3f dB (%s train frames); Q1 test %.3f\n", figure("test", "psnr_display"),
                figure("train", "psnr_display"),
                e.is_object() && e.contains("train") ? std::to_string(e["train"]["masked"].value("frames", 0)).c_str() : "no",
                figure("test", "q1_display"));
    const nlohmann::json& lobe = r.report["specular"]["lobe"];
    if (lobe.is_object()) std::printf("lobe: %s\n", lobe.dump().c_str());
    nlohmann::json j = {{"capture", a.capture},
                        {"total_seconds", r.total_seconds},
                        {"wall_seconds", run_s},
                        {"validate_seconds", validate_s},
                        {"ratio_to_validate", validate_s > 0.0 ? run_s / validate_s : 0.0},
                        {"peak_rss_bytes", peak_rss},
                        {"test_psnr_display", figure("test", "psnr_display")},
                        {"train_psnr_display", figure("train", "psnr_display")},
                        {"lobe", lobe}};
    nlohmann::json stages = nlohmann::json::array();
    for (const Row& row : rows) stages.push_back({{"stage", row.name}, {"runs", row.count}, {"seconds", row.seconds}});
    j["stages"] = std::move(stages);
    write_text_file(std::filesystem::path(a.out) / "bench.json", j.dump(2) + "\n");
    std::printf("wrote %s/bench.json\n", a.out.c_str());
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

    auto ra = std::make_shared<BenchReconstructArgs>();
    CLI::App* rec = bench->add_subcommand(
        "reconstruct",
        "Time `reconstruct` on CAPTURE with default settings (issue 18): the stage table (runs and seconds of each\n"
        "stage, joint and indirect rounds summed), the total beside the time `validate` takes to decode every\n"
        "image of the capture (and their ratio; validate runs after the reconstruction, whose peak resident memory\n"
        "is the one given), and the error the run ends at (masked test and train PSNR, display values; the lobe).\n"
        "The run's outputs and bench.json go to OUT.");
    rec->add_option("capture", ra->capture, "Capture folder (or its capture.json)")->required();
    rec->add_option("-o,--out", ra->out, "Output folder (replaced)")->required();
    rec->add_option("--backend", ra->backend, "As reconstruct's --backend")
        ->check(CLI::IsMember({"auto", "vulkan", "cpu"}))
        ->capture_default_str();
    rec->add_option("--threads", ra->threads, "CPU threads")->check(CLI::Range(1u, 256u))->capture_default_str();
    rec->callback([ra] { run_reconstruct_bench(*ra); });
}

} // namespace specula::cli
