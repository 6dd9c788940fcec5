// Summaries over frames: Q1 and Q2 (thesis eq. 5.7-5.10), means, empty frames, JSON shape.
#include "metrics/metrics_summary.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace specula::metrics {
namespace {

FrameMetrics frame(double rms, double dde, double psnr, double ssim, double hd) {
    FrameMetrics f;
    f.pixels = 100;
    f.channels = 3;
    f.rms = rms;
    f.rms_percent = 100.0 * rms;
    f.dde = dde;
    f.dde_percent = 100.0 * dde;
    f.mse = rms * rms;
    f.psnr = psnr;
    f.ssim = ssim;
    f.hausdorff = hd;
    f.has_ssim = f.has_hausdorff = true;
    return f;
}

// Two frames with RMS 0.10 and 0.06 (10 % and 6 % of G = 1): Q1 = 100 - (10 + 6)/2 = 92.
// DDE 0.05 and 0.03: Q2 = 100 - (5 + 3)/2 = 96. An empty frame is counted but left out.
TEST(MetricsSummary, Q1Q2AndMeans) {
    std::vector<FrameMetrics> frames{frame(0.10, 0.05, 20.0, 0.9, 0.2), frame(0.06, 0.03, 24.0, 0.8, 0.4),
                                     FrameMetrics{}};
    const MetricsSummary s = summarize(frames);
    EXPECT_EQ(s.frames, 2u);
    EXPECT_EQ(s.frames_empty, 1u);
    EXPECT_EQ(s.pixels, 200u);
    EXPECT_NEAR(s.q1, 92.0, 1e-12);
    EXPECT_NEAR(s.q2, 96.0, 1e-12);
    EXPECT_NEAR(s.rms_percent, 8.0, 1e-12);
    EXPECT_NEAR(s.psnr, 22.0, 1e-12);
    EXPECT_NEAR(s.ssim, 0.85, 1e-12);
    EXPECT_NEAR(s.hausdorff, 0.3, 1e-12);
    EXPECT_NEAR(s.hausdorff_max, 0.4, 1e-12);
}

TEST(MetricsSummary, JsonHasTheReportFields) {
    std::vector<FrameMetrics> frames{frame(0.10, 0.05, 20.0, 0.9, 0.2)};
    EvaluationMetrics e;
    e.train_masked = summarize(frames);
    e.train_full = summarize(frames);
    e.test_masked = summarize(frames);
    // test_full: no frames at all.
    const nlohmann::json j = to_json(e);
    for (const char* split : {"train", "test"})
        for (const char* set : {"masked", "full"}) {
            const auto& o = j.at(split).at(set);
            for (const char* key : {"q1", "q2", "rms_percent", "dde_percent", "psnr", "ssim", "frames"})
                EXPECT_TRUE(o.contains(key)) << split << "." << set << "." << key;
        }
    EXPECT_NEAR(j["train"]["masked"]["q1"].get<double>(), 90.0, 1e-12);
    EXPECT_EQ(j["train"]["masked"]["frames"], 1);
    EXPECT_EQ(j["test"]["full"]["frames"], 0);
    EXPECT_TRUE(j["test"]["full"]["q1"].is_null());
    EXPECT_TRUE(j["test"]["full"]["ssim"].is_null());
    // Never NaN or inf in the output.
    const std::string text = j.dump();
    EXPECT_EQ(text.find("NaN"), std::string::npos);
    EXPECT_EQ(text.find("nan"), std::string::npos);
    EXPECT_EQ(text.find("inf"), std::string::npos);
}

TEST(MetricsSummary, SkippedMeasuresAreNull) {
    FrameMetrics f = frame(0.1, 0.05, 20.0, 0.0, 0.0);
    f.has_ssim = false;
    f.has_hausdorff = false;
    const std::vector<FrameMetrics> frames{f};
    const nlohmann::json j = to_json(summarize(frames));
    EXPECT_TRUE(j["ssim"].is_null());
    EXPECT_TRUE(j["hausdorff"].is_null());
    EXPECT_FALSE(j["q1"].is_null());
    EXPECT_TRUE(to_json(f)["ssim"].is_null());
}

} // namespace
} // namespace specula::metrics
