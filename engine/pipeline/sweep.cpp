#include "pipeline/sweep.h"

#include "capture/capture.h"
#include "core/error.h"
#include "core/file_util.h"
#include "core/format.h"
#include "core/log.h"
#include "core/timer.h"
#include "factorization/resolution.h"
#include "report/report_html.h"
#include "report/svg_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace specula {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

std::string samples_text(std::uint32_t n) {
    if (n == 0) return "all";
    if (n % 1000 == 0) return std::to_string(n / 1000) + "k";
    return std::to_string(n);
}

double number(const json& j, double fallback = std::numeric_limits<double>::quiet_NaN()) {
    return j.is_number() ? j.get<double>() : fallback;
}

json finite(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

// The inside of a double-quoted CSV field (RFC 4180: quotes doubled, no line breaks).
std::string csv_quote(const std::string& text) {
    std::string out;
    for (const char c : text) {
        if (c == '"') out += "\"\"";
        else if (c == '\n' || c == '\r') out += ' ';
        else out += c;
    }
    return out;
}

} // namespace

std::vector<std::size_t> pareto_front(std::span<const std::pair<double, double>> xy) {
    std::vector<std::size_t> front;
    for (std::size_t i = 0; i < xy.size(); ++i) {
        const auto [xi, yi] = xy[i];
        if (!std::isfinite(xi) || !std::isfinite(yi)) continue;
        bool dominated = false;
        for (std::size_t j = 0; j < xy.size() && !dominated; ++j) {
            if (j == i) continue;
            const auto [xj, yj] = xy[j];
            if (!std::isfinite(xj) || !std::isfinite(yj)) continue;
            // Exact ties: the earlier index stays, so equal points are not both on the front.
            const bool no_worse = xj <= xi && yj <= yi;
            const bool better = xj < xi || yj < yi;
            dominated = no_worse && (better || j < i);
        }
        if (!dominated) front.push_back(i);
    }
    std::sort(front.begin(), front.end(), [&](std::size_t a, std::size_t b) { return xy[a].first < xy[b].first; });
    return front;
}

SweepResult run_sweep(const SweepOptions& o) {
    const SweepKnobs& k = o.knobs;
    if (k.texels_per_pixel.empty() || k.fit_samples.empty() || k.factorization_grid.empty() || k.backends.empty())
        throw UsageError("bench sweep: every knob needs at least one value");
    if (o.out_dir.empty()) throw UsageError("bench sweep: no output folder given");

    // The grid (full product), plus the default point when the grid lacks it.
    const ReconstructConfig defaults;
    std::vector<SweepPoint> points;
    for (const Backend b : k.backends)
        for (const double tpp : k.texels_per_pixel)
            for (const std::uint32_t fs_ : k.fit_samples)
                for (const std::uint32_t g : k.factorization_grid) {
                    SweepPoint p;
                    p.texels_per_pixel = tpp, p.fit_samples = fs_, p.factorization_grid = g, p.backend = b;
                    points.push_back(p);
                }
    const auto is_default = [&](const SweepPoint& p) {
        return p.texels_per_pixel == defaults.atlas.texels_per_pixel && p.fit_samples == defaults.max_fit_samples &&
               p.factorization_grid == 0 && p.backend == defaults.backend;
    };
    if (std::none_of(points.begin(), points.end(), is_default)) {
        SweepPoint p;
        p.texels_per_pixel = defaults.atlas.texels_per_pixel, p.fit_samples = defaults.max_fit_samples;
        p.factorization_grid = 0, p.backend = defaults.backend;
        points.push_back(p);
    }
    for (SweepPoint& p : points) {
        p.is_default = is_default(p);
        p.label = "tpp " + format_text("%g", p.texels_per_pixel) + ", fit " + samples_text(p.fit_samples) + ", grid " +
                  (p.factorization_grid == 0 ? std::string("auto") : std::to_string(p.factorization_grid)) + ", " +
                  to_string(p.backend);
    }

    SweepResult result;
    log::info("bench sweep: loading " + o.capture.string());
    const Capture capture = load_capture(o.capture, CaptureLoadOptions{.threads = static_cast<int>(o.base.threads)});
    result.load_seconds = capture.load_seconds;
    result.test_frames = capture.frame_count(Split::Test);
    if (result.test_frames == 0)
        throw UsageError("bench sweep: " + capture_json_path(o.capture).string() +
                         " has no test frames: the sweep measures the error on them");

    fs::create_directories(o.out_dir);
    log::info("bench sweep: " + std::to_string(points.size()) + " points");
    log::Progress progress("sweep", points.size());
    const log::Level level = log::level();
    for (std::size_t i = 0; i < points.size(); ++i) {
        SweepPoint& p = points[i];
        ReconstructConfig c = o.base;
        c.capture = o.capture;
        char name[32];
        std::snprintf(name, sizeof name, "%02zu", i);
        c.out_dir = o.out_dir / "points" / name;
        c.atlas.texels_per_pixel = p.texels_per_pixel;
        c.max_fit_samples = p.fit_samples;
        c.factorization_grid_h = p.factorization_grid;
        c.factorization_grid_d =
            p.factorization_grid == 0 ? 0 : std::min<std::uint32_t>(p.factorization_grid, factorization::kMaxGridProduct / p.factorization_grid);
        c.backend = p.backend;
        c.evaluate = true;
        c.evaluate_train = false;
        c.evaluate_factorized = true; // so the factorization grid shows in the error
        c.write_sheets = false;
        c.write_html = false;
        c.cost_probes = false;
        // The inner run's log lines would bury the sweep's: quiet while it runs.
        log::set_level(log::Level::Quiet);
        ReconstructResult r;
        try {
            r = reconstruct(c, &capture);
        } catch (const Error& e) {
            // One bad point (a grid too fine for the device, ...) must not lose the others.
            log::set_level(level);
            p.failure = e.what();
            p.seconds = p.error = p.test_q1 = p.test_psnr = p.test_full_rms_percent = std::numeric_limits<double>::quiet_NaN();
            log::warn("bench sweep: point " + std::to_string(i) + " (" + p.label + ") failed: " + p.failure);
            if (!o.keep_points) fs::remove_all(c.out_dir);
            progress.update(i + 1);
            continue;
        } catch (...) {
            log::set_level(level);
            throw;
        }
        log::set_level(level);
        for (const StageRecord& s : r.stages)
            if (s.name != "evaluation") p.seconds += s.seconds;
        const json& tm = r.report["evaluation"]["test"]["masked"];
        p.error = number(tm.value("rms_percent", json()));
        p.test_q1 = number(tm.value("q1", json()));
        p.test_psnr = number(tm.value("psnr", json()));
        p.test_full_rms_percent = number(r.report["evaluation"]["test"]["full"].value("rms_percent", json()));
        p.particles = r.report["particles"]["count"].get<std::size_t>();
        p.has_lobe = r.report["bundle"]["has_lobe"].get<bool>();
        const PlanDecision* grid = r.plan.find("factorization_grid");
        p.grid_used = grid != nullptr ? grid->value : "none";
        p.stages = r.report["stages"];
        if (!o.keep_points) fs::remove_all(c.out_dir);
        log::info("  [" + std::to_string(i + 1) + "/" + std::to_string(points.size()) + "] " + p.label + ": " +
                  format_text("%.2f", p.seconds) + " s, test masked RMS " + format_text("%.3f", p.error) + " %" +
                  (p.is_default ? "  (default)" : ""));
        progress.update(i + 1);
    }
    progress.finish();
    if (!o.keep_points) {
        std::error_code ec;
        fs::remove(o.out_dir / "points", ec); // empty by now
    }

    std::vector<std::pair<double, double>> xy;
    for (const SweepPoint& p : points) xy.emplace_back(p.seconds, p.error);
    result.front = pareto_front(xy);
    for (const std::size_t i : result.front) points[i].on_front = true;
    result.points = std::move(points);

    const std::string title = "Specula: test-frame error against run time (" + capture_json_path(o.capture).parent_path().filename().string() + ")";
    write_text_file(o.out_dir / "sweep.csv", to_csv(result));
    write_text_file(o.out_dir / "sweep.svg", to_svg(result, title));
    write_text_file(o.out_dir / "sweep.html", to_html(result, title));
    write_text_file(o.out_dir / "sweep.json", to_json(result).dump(2) + "\n");
    return result;
}

json to_json(const SweepResult& r) {
    json points = json::array();
    for (std::size_t i = 0; i < r.points.size(); ++i) {
        const SweepPoint& p = r.points[i];
        points.push_back({{"index", i},
                          {"label", p.label},
                          {"texels_per_pixel", p.texels_per_pixel},
                          {"fit_samples", p.fit_samples},
                          {"factorization_grid", p.factorization_grid == 0 ? json("auto") : json(p.factorization_grid)},
                          {"factorization_grid_used", p.grid_used},
                          {"backend", to_string(p.backend)},
                          {"seconds", finite(p.seconds)},
                          {"test_masked_rms_percent", finite(p.error)},
                          {"test_masked_q1", finite(p.test_q1)},
                          {"test_masked_psnr", finite(p.test_psnr)},
                          {"test_full_rms_percent", finite(p.test_full_rms_percent)},
                          {"particles", p.particles},
                          {"has_lobe", p.has_lobe},
                          {"is_default", p.is_default},
                          {"on_front", p.on_front},
                          {"stages", p.stages},
                          {"failure", p.failure.empty() ? json(nullptr) : json(p.failure)}});
    }
    json front = json::array();
    for (const std::size_t i : r.front) front.push_back(i);
    return {{"error", "test frames, masked RMS % (100 - Q1)"},
            {"time", "seconds of the run's stages without the capture load (shared) and the self-evaluation"},
            {"capture_load_seconds", r.load_seconds},
            {"test_frames", r.test_frames},
            {"points", points},
            {"pareto_front", front}};
}

std::string to_csv(const SweepResult& r) {
    std::string out = "index,texels_per_pixel,fit_samples,factorization_grid,factorization_grid_used,backend,seconds,"
                      "test_masked_rms_percent,test_masked_q1,test_masked_psnr,test_full_rms_percent,particles,has_lobe,"
                      "is_default,on_front,failure\n";
    const auto g = [](double v) { return std::isfinite(v) ? format_text("%.6g", v) : std::string(); };
    for (std::size_t i = 0; i < r.points.size(); ++i) {
        const SweepPoint& p = r.points[i];
        out += std::to_string(i) + "," + g(p.texels_per_pixel) + "," + std::to_string(p.fit_samples) + "," +
               (p.factorization_grid == 0 ? std::string("auto") : std::to_string(p.factorization_grid)) + ",\"" + p.grid_used +
               "\"," + to_string(p.backend) + "," + g(p.seconds) + "," + (std::isfinite(p.error) ? format_text("%.9g", p.error) : std::string()) + "," + g(p.test_q1) + "," +
               g(p.test_psnr) + "," + g(p.test_full_rms_percent) + "," + std::to_string(p.particles) + "," +
               (p.has_lobe ? "1" : "0") + "," + (p.is_default ? "1" : "0") + "," + (p.on_front ? "1" : "0") + ",\"" + csv_quote(p.failure) + "\"\n";
    }
    return out;
}

std::string to_svg(const SweepResult& r, const std::string& title) {
    std::vector<report::PlotPoint> pts;
    for (const SweepPoint& p : r.points) pts.push_back({p.seconds, p.error, p.label, p.is_default, p.on_front});
    return report::svg_pareto_plot(pts, title, "run time (s, without load and evaluation)", "test-frame error: masked RMS %");
}

} // namespace specula

namespace specula {

std::string to_html(const SweepResult& r, const std::string& title) {
    using report::html_escape;
    std::string out = "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>" + html_escape(title) +
                      "</title>\n<style>" + std::string(report::report_css()) + "</style>\n</head>\n<body>\n<h1>" +
                      html_escape(title) + "</h1>\n";
    out += "<p>Error: the test frames' masked RMS % (100 &minus; Q1), the lobe rendered through its factorization "
           "cube-maps. Run time: the reconstruction's stages without the capture load (" + format_text("%.2f", r.load_seconds) +
           " s, shared) and the self-evaluation. " + std::to_string(r.test_frames) + " test frames.</p>\n";
    out += to_svg(r, title);
    out += "<table>\n<tr><th>#</th><th>texels/pixel</th><th>fit samples</th><th>grid</th><th>grid used</th><th>backend</th>"
           "<th>seconds</th><th>test RMS %</th><th>test Q1</th><th>test PSNR</th><th></th></tr>\n";
    for (std::size_t i = 0; i < r.points.size(); ++i) {
        const SweepPoint& p = r.points[i];
        std::string mark = p.on_front ? "Pareto front" : "";
        if (p.is_default) mark += mark.empty() ? "default" : ", default";
        if (!p.failure.empty()) mark = "failed: " + html_escape(p.failure);
        out += "<tr><td>" + std::to_string(i) + "</td><td>" + format_text("%g", p.texels_per_pixel) + "</td><td>" +
               samples_text(p.fit_samples) + "</td><td>" +
               (p.factorization_grid == 0 ? std::string("auto") : std::to_string(p.factorization_grid)) + "</td><td>" +
               html_escape(p.grid_used) + "</td><td>" + to_string(p.backend) + "</td><td>" + format_text("%.2f", p.seconds) +
               "</td><td>" + format_text("%.3f", p.error) + "</td><td>" + format_text("%.2f", p.test_q1) + "</td><td>" +
               format_text("%.2f", p.test_psnr) + "</td><td>" + mark + "</td></tr>\n";
    }
    return out + "</table>\n</body>\n</html>\n";
}

} // namespace specula
