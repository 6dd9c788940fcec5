// Means over frames, Q1 and Q2 (thesis eq. 5.7-5.10), and the JSON of the report.
#include "metrics/metrics_summary.h"

#include <algorithm>
#include <cmath>

namespace specula::metrics {

namespace {

nlohmann::json number(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }
nlohmann::json number_if(bool present, double v) { return present ? number(v) : nlohmann::json(nullptr); }

} // namespace

MetricsSummary summarize(std::span<const FrameMetrics> frames, const MetricsOptions& options) {
    MetricsSummary s;
    s.g = options.peak;
    s.psnr_cap_db = options.psnr_cap_db;
    s.has_ssim = true;
    s.has_hausdorff = true;
    for (const FrameMetrics& f : frames) {
        if (f.empty()) {
            ++s.frames_empty;
            continue;
        }
        ++s.frames;
        s.pixels += f.pixels;
        s.rms += f.rms;
        s.rms_percent += f.rms_percent;
        s.dde += f.dde;
        s.dde_percent += f.dde_percent;
        s.ncc += f.ncc;
        s.l1 += f.l1;
        s.l2 += f.l2;
        s.psnr += f.psnr;
        s.ssim += f.ssim;
        s.hausdorff += f.hausdorff;
        s.hausdorff_max = std::max(s.hausdorff_max, f.hausdorff);
        s.hausdorff_exact = s.hausdorff_exact && f.hausdorff_exact;
        s.has_ssim = s.has_ssim && f.has_ssim;
        s.has_hausdorff = s.has_hausdorff && f.has_hausdorff;
    }
    if (s.frames == 0) {
        s.has_ssim = s.has_hausdorff = false;
        return s;
    }
    const double m = static_cast<double>(s.frames);
    for (double* v : {&s.rms, &s.rms_percent, &s.dde, &s.dde_percent, &s.ncc, &s.l1, &s.l2, &s.psnr, &s.ssim,
                      &s.hausdorff})
        *v /= m;
    s.q1 = 100.0 - s.rms_percent; // eq. 5.7
    s.q2 = 100.0 - s.dde_percent; // eq. 5.9
    if (!s.has_ssim) s.ssim = 0.0;
    if (!s.has_hausdorff) s.hausdorff = s.hausdorff_max = 0.0;
    return s;
}

nlohmann::json to_json(const FrameMetrics& m) {
    const bool ok = !m.empty();
    return nlohmann::json{
        {"pixels", m.pixels},
        {"channels", m.channels},
        {"mse", number_if(ok, m.mse)},
        {"rms", number_if(ok, m.rms)},
        {"rms_percent", number_if(ok, m.rms_percent)},
        {"dde", number_if(ok, m.dde)},
        {"dde_percent", number_if(ok, m.dde_percent)},
        {"ncc", number_if(ok, m.ncc)},
        {"l1", number_if(ok, m.l1)},
        {"l2", number_if(ok, m.l2)},
        {"psnr", number_if(ok, m.psnr)},
        {"ssim", number_if(ok && m.has_ssim, m.ssim)},
        {"hausdorff", number_if(ok && m.has_hausdorff, m.hausdorff)},
        {"hausdorff_exact", ok && m.has_hausdorff ? nlohmann::json(m.hausdorff_exact) : nlohmann::json(nullptr)},
    };
}

nlohmann::json to_json(const MetricsSummary& s) {
    const bool ok = s.frames > 0;
    return nlohmann::json{
        {"frames", s.frames},
        {"frames_empty", s.frames_empty},
        {"pixels", s.pixels},
        {"q1", number_if(ok, s.q1)},
        {"q2", number_if(ok, s.q2)},
        {"rms", number_if(ok, s.rms)},
        {"rms_percent", number_if(ok, s.rms_percent)},
        {"dde", number_if(ok, s.dde)},
        {"dde_percent", number_if(ok, s.dde_percent)},
        {"ncc", number_if(ok, s.ncc)},
        {"l1", number_if(ok, s.l1)},
        {"l2", number_if(ok, s.l2)},
        {"psnr", number_if(ok, s.psnr)},
        {"ssim", number_if(ok && s.has_ssim, s.ssim)},
        {"hausdorff", number_if(ok && s.has_hausdorff, s.hausdorff)},
        {"hausdorff_max", number_if(ok && s.has_hausdorff, s.hausdorff_max)},
        {"hausdorff_exact", ok && s.has_hausdorff ? nlohmann::json(s.hausdorff_exact) : nlohmann::json(nullptr)},
        {"g", number(s.g)},
        {"psnr_cap_db", number(s.psnr_cap_db)},
    };
}

nlohmann::json to_json(const EvaluationMetrics& e) {
    return nlohmann::json{
        {"train", {{"masked", to_json(e.train_masked)}, {"full", to_json(e.train_full)}}},
        {"test", {{"masked", to_json(e.test_masked)}, {"full", to_json(e.test_full)}}},
    };
}

} // namespace specula::metrics
