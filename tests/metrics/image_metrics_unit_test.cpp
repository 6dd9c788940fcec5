// image_metrics against values computed by hand (the arithmetic is in the comments) on
// tiny images, on both backends (the Vulkan run skips without a device). Definitions:
// engine/metrics/image_metrics.h. G = peak = 1, delta = 1/16 unless a test says otherwise.
#include "metrics/image_metrics.h"
#include "metrics/metrics_summary.h"
#include "vulkan_env.h"

#include "core/error.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>
#include <vector>

namespace specula::metrics {
namespace {

enum class Backend { Cpu, Vulkan };

// Values from hand arithmetic are exact to ~1e-15 in double; the Vulkan path sums in
// float (relative error <= ~1e-6, see tests/kernels/image_metrics_test.cpp), so the
// hand values are checked to 1e-5 (relative for large values, absolute near 0).
constexpr double kTol = 1e-5;

Image gray(int w, int h, std::vector<float> v) {
    Image img(w, h, 1);
    img.pixels = std::move(v);
    return img;
}

Image rgb(int w, int h, std::vector<float> v) {
    Image img(w, h, 3);
    img.pixels = std::move(v);
    return img;
}

class ImageMetricsTest : public test::VulkanTest, public ::testing::WithParamInterface<Backend> {
protected:
    void SetUp() override {
        if (GetParam() == Backend::Vulkan) {
            test::VulkanTest::SetUp();
            if (!IsSkipped()) m_vk = std::make_unique<ImageMetricsVk>(ctx());
        }
    }
    void TearDown() override {
        m_vk.reset();
        if (GetParam() == Backend::Vulkan) test::VulkanTest::TearDown();
    }
    FrameMetrics run(const Image& a, const Image& b, std::span<const uint8_t> mask = {},
                     const MetricsOptions& o = {}) {
        const MetricsInputs in{a, b, mask};
        return GetParam() == Backend::Cpu ? image_metrics_cpu(in, o) : m_vk->run(in, o);
    }

private:
    std::unique_ptr<ImageMetricsVk> m_vk;
};

void expect_all_finite(const FrameMetrics& m) {
    for (double v : {m.mse, m.rms, m.rms_percent, m.dde, m.dde_percent, m.ncc, m.l1, m.l2, m.psnr, m.ssim, m.hausdorff})
        EXPECT_TRUE(std::isfinite(v));
}

// A (row-major, row 0 at the top)   B              A - B
//   0.2 0.4                         0.2 0.5         0   -0.1
//   0.6 0.8                         0.6 0.6         0    0.2
TEST_P(ImageMetricsTest, Gray2x2FullFrame) {
    const Image a = gray(2, 2, {0.2f, 0.4f, 0.6f, 0.8f});
    const Image b = gray(2, 2, {0.2f, 0.5f, 0.6f, 0.6f});
    const FrameMetrics m = run(a, b);
    EXPECT_EQ(m.pixels, 4u);
    EXPECT_EQ(m.channels, 1);
    // sum (A-B)^2 = 0.01 + 0.04 = 0.05; MSE = 0.05 / 4 = 0.0125
    EXPECT_NEAR(m.mse, 0.0125, kTol);
    EXPECT_NEAR(m.rms, std::sqrt(0.0125), kTol);               // 0.111803
    EXPECT_NEAR(m.rms_percent, 100.0 * std::sqrt(0.0125), 1e-3); // 11.1803 % of G = 1
    // sum |A-B| = 0.3; DDE = 0.3 / 4 = 0.075; one channel: L1 = L2 = DDE
    EXPECT_NEAR(m.dde, 0.075, kTol);
    EXPECT_NEAR(m.dde_percent, 7.5, 1e-3);
    EXPECT_NEAR(m.l1, 0.075, kTol);
    EXPECT_NEAR(m.l2, 0.075, kTol);
    // sum AB = 0.04 + 0.20 + 0.36 + 0.48 = 1.08; sum A^2 = 0.04 + 0.16 + 0.36 + 0.64 = 1.2;
    // sum B^2 = 0.04 + 0.25 + 0.36 + 0.36 = 1.01; CO = 1 - 1.08 / sqrt(1.212) = 0.0189918
    EXPECT_NEAR(m.ncc, 1.0 - 1.08 / std::sqrt(1.2 * 1.01), kTol);
    // PSNR = 10 log10(1 / 0.0125) = 10 log10(80) = 19.0309 dB
    EXPECT_NEAR(m.psnr, 10.0 * std::log10(80.0), 1e-4);
    // Hausdorff, d^2 = (dx^2 + dy^2)/256 + (A_p - B_q)^2:
    //  h(A,B): A(1,0)=0.4 -> B(1,0)=0.5: 0.01 (neighbours: 1/256 + 0.04 or more)
    //          A(1,1)=0.8 -> B(1,1)=0.6: 0.04 (B(0,1)=0.6 at 1 px: 1/256 + 0.04; B(1,0)=0.5: 1/256 + 0.09)
    //          the others match exactly: h(A,B)^2 = 0.04
    //  h(B,A): B(1,0)=0.5 -> 0.01; B(1,1)=0.6 -> A(0,1)=0.6 at 1 px: 1/256: h(B,A)^2 = 0.01
    //  HD = sqrt(max(0.04, 0.01)) = 0.2
    EXPECT_NEAR(m.hausdorff, 0.2, kTol);
    EXPECT_TRUE(m.hausdorff_exact);
    expect_all_finite(m);
}

// The same pair over the mask {(0,0), (1,1)} (the diagonal).
TEST_P(ImageMetricsTest, Gray2x2Masked) {
    const Image a = gray(2, 2, {0.2f, 0.4f, 0.6f, 0.8f});
    const Image b = gray(2, 2, {0.2f, 0.5f, 0.6f, 0.6f});
    const std::vector<uint8_t> mask{1, 0, 0, 255};
    const FrameMetrics m = run(a, b, mask);
    EXPECT_EQ(m.pixels, 2u);
    // diffs 0 and 0.2: MSE = 0.04 / 2 = 0.02, DDE = 0.2 / 2 = 0.1
    EXPECT_NEAR(m.mse, 0.02, kTol);
    EXPECT_NEAR(m.rms, std::sqrt(0.02), kTol);
    EXPECT_NEAR(m.dde, 0.1, kTol);
    EXPECT_NEAR(m.l1, 0.1, kTol);
    EXPECT_NEAR(m.l2, 0.1, kTol);
    // sum AB = 0.04 + 0.48 = 0.52; sum A^2 = 0.04 + 0.64 = 0.68; sum B^2 = 0.04 + 0.36 = 0.40
    EXPECT_NEAR(m.ncc, 1.0 - 0.52 / std::sqrt(0.68 * 0.40), kTol);
    EXPECT_NEAR(m.psnr, 10.0 * std::log10(1.0 / 0.02), 1e-4);
    // Only P's pixels are candidates: A(1,1)=0.8 -> B(1,1)=0.6 (0.04) or B(0,0)=0.2 at sqrt(2) px.
    EXPECT_NEAR(m.hausdorff, 0.2, kTol);
}

// One RGB pixel: A = (0.5, 0.5, 0.5), B = (0.2, 0.9, 0.5); A - B = (0.3, -0.4, 0).
TEST_P(ImageMetricsTest, RgbPixelMinkowskiAndLuminanceSsim) {
    const Image a = rgb(1, 1, {0.5f, 0.5f, 0.5f});
    const Image b = rgb(1, 1, {0.2f, 0.9f, 0.5f});
    const FrameMetrics m = run(a, b);
    EXPECT_EQ(m.channels, 3);
    EXPECT_NEAR(m.l1, 0.7, kTol);                       // 0.3 + 0.4 + 0        (eq. 5.1, r = 1)
    EXPECT_NEAR(m.l2, 0.5, kTol);                       // sqrt(0.09 + 0.16)    (eq. 5.1, r = 2)
    EXPECT_NEAR(m.rms, std::sqrt(0.25 / 3.0), kTol);    // per channel value: 0.288675
    EXPECT_NEAR(m.dde, 0.7 / 3.0, kTol);                // 0.233333 = L1 / C
    // sum AB = 0.10 + 0.45 + 0.25 = 0.8; sum A^2 = 0.75; sum B^2 = 0.04 + 0.81 + 0.25 = 1.1
    EXPECT_NEAR(m.ncc, 1.0 - 0.8 / std::sqrt(0.75 * 1.1), kTol); // 0.119222
    // A 1x1 window is constant: SSIM = (2 Ya Yb + C1) / (Ya^2 + Yb^2 + C1), C1 = 1e-4,
    // Ya = 0.5, Yb = 0.2126*0.2 + 0.7152*0.9 + 0.0722*0.5 = 0.7223
    const double ya = 0.5, yb = 0.2126 * 0.2 + 0.7152 * 0.9 + 0.0722 * 0.5;
    EXPECT_NEAR(m.ssim, (2 * ya * yb + 1e-4) / (ya * ya + yb * yb + 1e-4), kTol);
    EXPECT_NEAR(m.hausdorff, 0.5, kTol); // one point each: the colour distance
}

// Constant images a = 0.5, b = 0.25 (3x3): every window has zero variance and covariance,
// so SSIM = (2ab + C1)/(a^2 + b^2 + C1) * C2/C2 = 0.2501 / 0.3126 = 0.800064.
TEST_P(ImageMetricsTest, SsimOfConstantImages) {
    const FrameMetrics m = run(gray(3, 3, std::vector<float>(9, 0.5f)), gray(3, 3, std::vector<float>(9, 0.25f)));
    EXPECT_NEAR(m.ssim, 0.2501 / 0.3126, kTol);
    // Every pixel is 0.25 off and the best match is itself (neighbours are as far in value
    // and 1/16 away in space): HD = 0.25.
    EXPECT_NEAR(m.hausdorff, 0.25, kTol);
}

// 2x1 images A = [0 1], B = [1 0]. The window is 2 taps wide here (1 row): at x = 0 the
// taps are t0 = 1 (self) and t1 = exp(-1/(2*1.5^2)) = 0.800737, renormalised to
// w0 = 1/(1 + t1) = 0.555328 and w1 = t1/(1 + t1) = 0.444672 (the same at x = 1 mirrored).
//   x = 0: mu_a = w1, mu_b = w0, E[a^2] = w1, E[b^2] = w0, E[ab] = 0
//          var_a = w1 - w1^2 = w0 w1, var_b = w0 w1, cov = -w0 w1
//   SSIM = (2 w0 w1 + C1)(-2 w0 w1 + C2) / ((w0^2 + w1^2 + C1)(2 w0 w1 + C2))  = -0.9926...
// and by symmetry the same at x = 1.
TEST_P(ImageMetricsTest, SsimOfSwappedPair) {
    const FrameMetrics m = run(gray(2, 1, {0.0f, 1.0f}), gray(2, 1, {1.0f, 0.0f}));
    const double t1 = std::exp(-1.0 / 4.5);
    const double w0 = 1.0 / (1.0 + t1), w1 = t1 / (1.0 + t1);
    const double c1 = 1e-4, c2 = 9e-4;
    const double expected = (2 * w0 * w1 + c1) * (-2 * w0 * w1 + c2) / ((w0 * w0 + w1 * w1 + c1) * (2 * w0 * w1 + c2));
    EXPECT_NEAR(m.ssim, expected, 1e-4);
    // Swapped pixels: each finds its value one pixel away: HD = 1/16.
    EXPECT_NEAR(m.hausdorff, 1.0 / 16.0, kTol);
    EXPECT_NEAR(m.rms, 1.0, kTol);
    EXPECT_NEAR(m.ncc, 1.0, kTol); // sum AB = 0, both sums of squares 1
}

// 3x3 with one bright pixel: A at (1,1), B shifted one pixel right to (2,1).
// RMS = sqrt(2/9) = 0.4714 punishes the shift fully; Hausdorff finds every pixel's value
// one pixel away: d^2 = 1/256, HD = 1/16 = 0.0625.
TEST_P(ImageMetricsTest, HausdorffToleratesAShift) {
    Image a = gray(3, 3, std::vector<float>(9, 0.0f));
    Image b = a;
    a.at(1, 1) = 1.0f;
    b.at(2, 1) = 1.0f;
    const FrameMetrics m = run(a, b);
    EXPECT_NEAR(m.rms, std::sqrt(2.0 / 9.0), kTol);
    EXPECT_NEAR(m.hausdorff, 1.0 / 16.0, kTol);
    EXPECT_TRUE(m.hausdorff_exact);
    // A diagonal shift to (2,2): sqrt(2) pixels -> HD = sqrt(2)/16.
    b = gray(3, 3, std::vector<float>(9, 0.0f));
    b.at(2, 2) = 1.0f;
    EXPECT_NEAR(run(a, b).hausdorff, std::sqrt(2.0) / 16.0, kTol);
}

// With the ring cap at 0 nothing but q = p is searched: the bright pixel's distance is
// the colour distance 1, an upper bound (the true HD is 1/16) flagged as inexact.
TEST_P(ImageMetricsTest, HausdorffRingCapIsFlagged) {
    Image a = gray(3, 3, std::vector<float>(9, 0.0f));
    Image b = a;
    a.at(1, 1) = 1.0f;
    b.at(2, 1) = 1.0f;
    MetricsOptions o;
    o.hausdorff_max_radius = 0;
    const FrameMetrics m = run(a, b, {}, o);
    EXPECT_NEAR(m.hausdorff, 1.0, kTol);
    EXPECT_FALSE(m.hausdorff_exact);
}

// Identical images: RMS 0, DDE 0, CO 0, PSNR = the cap (100 dB), SSIM 1, HD 0; Q1 = Q2 = 100.
TEST_P(ImageMetricsTest, IdenticalImages) {
    const Image a = rgb(2, 2, {0.1f, 0.2f, 0.3f, 0.9f, 0.8f, 0.7f, 0.0f, 0.5f, 1.0f, 0.25f, 0.25f, 0.25f});
    const FrameMetrics m = run(a, a);
    EXPECT_EQ(m.rms, 0.0);
    EXPECT_EQ(m.dde, 0.0);
    EXPECT_EQ(m.l2, 0.0);
    EXPECT_NEAR(m.ncc, 0.0, 1e-12);
    EXPECT_EQ(m.psnr, 100.0);
    EXPECT_NEAR(m.ssim, 1.0, 1e-6);
    EXPECT_EQ(m.hausdorff, 0.0);
    const std::vector<FrameMetrics> frames{m, m};
    const MetricsSummary s = summarize(frames);
    EXPECT_EQ(s.q1, 100.0);
    EXPECT_EQ(s.q2, 100.0);
    EXPECT_EQ(s.psnr, 100.0);
}

// All black: CO's 0/0 is taken as 0 (identical images); SSIM = C1 C2 / (C1 C2) = 1.
// Black against non-black: CO = 1 (no correlation). Never NaN.
TEST_P(ImageMetricsTest, AllBlackConventions) {
    const Image black = rgb(2, 2, std::vector<float>(12, 0.0f));
    const FrameMetrics m = run(black, black);
    EXPECT_EQ(m.ncc, 0.0);
    EXPECT_EQ(m.rms, 0.0);
    EXPECT_EQ(m.psnr, 100.0);
    EXPECT_NEAR(m.ssim, 1.0, 1e-6);
    expect_all_finite(m);
    const Image grey = rgb(2, 2, std::vector<float>(12, 0.5f));
    const FrameMetrics n = run(black, grey);
    EXPECT_EQ(n.ncc, 1.0);
    EXPECT_NEAR(n.rms, 0.5, kTol);
    EXPECT_NEAR(n.psnr, 10.0 * std::log10(4.0), 1e-4); // MSE = 0.25
    // SSIM of constants 0 and 0.5: (0 + C1)/(0.25 + C1) = 1e-4 / 0.2501
    EXPECT_NEAR(n.ssim, 1e-4 / 0.2501, kTol);
    expect_all_finite(n);
}

// Masked vs full frame on a 3x3: the mask keeps the centre column; A - B is 0.1 there
// and 0.5 elsewhere. Full: MSE = (3 * 0.01 + 6 * 0.25) / 9 = 0.17; masked: 0.01.
TEST_P(ImageMetricsTest, MaskedVersusFullFrame) {
    const Image a = gray(3, 3, std::vector<float>(9, 0.6f));
    const Image b = gray(3, 3, {0.1f, 0.5f, 0.1f, 0.1f, 0.5f, 0.1f, 0.1f, 0.5f, 0.1f});
    const std::vector<uint8_t> mask{0, 1, 0, 0, 1, 0, 0, 1, 0};
    const FrameMetrics full = run(a, b);
    const FrameMetrics masked = run(a, b, mask);
    EXPECT_EQ(full.pixels, 9u);
    EXPECT_EQ(masked.pixels, 3u);
    EXPECT_NEAR(full.mse, 0.17, kTol);
    EXPECT_NEAR(masked.mse, 0.01, kTol);
    EXPECT_NEAR(full.dde, (3 * 0.1 + 6 * 0.5) / 9.0, kTol); // 0.366667
    EXPECT_NEAR(masked.dde, 0.1, kTol);
    EXPECT_NEAR(masked.psnr, 20.0, 1e-4);                   // 10 log10(1 / 0.01)
    // Masked CO: sum AB = 3 * 0.30 = 0.9, sum A^2 = 3 * 0.36 = 1.08, sum B^2 = 3 * 0.25 = 0.75
    EXPECT_NEAR(masked.ncc, 1.0 - 0.9 / std::sqrt(1.08 * 0.75), kTol);
    // Masked HD: A's 0.6 finds B's 0.5 in the column itself (0.1); nothing closer in P.
    EXPECT_NEAR(masked.hausdorff, 0.1, kTol);
    // Full frame: B's 0.1 pixels find A's 0.6 (0.5 off) at best, or B... h(B,A) = 0.5.
    EXPECT_NEAR(full.hausdorff, 0.5, kTol);
    // The masked SSIM averages the map over the column only: it lies between the map's
    // extremes and differs from the full-frame mean.
    EXPECT_NE(masked.ssim, full.ssim);
}

// An empty mask: no pixel, every measure 0 and null in the JSON; the summary skips it.
TEST_P(ImageMetricsTest, EmptyMask) {
    const Image a = gray(2, 2, {0.2f, 0.4f, 0.6f, 0.8f});
    const std::vector<uint8_t> mask(4, 0);
    const FrameMetrics m = run(a, a, mask);
    EXPECT_TRUE(m.empty());
    expect_all_finite(m);
    const auto j = to_json(m);
    EXPECT_TRUE(j["rms"].is_null());
    EXPECT_TRUE(j["ssim"].is_null());
    EXPECT_EQ(j["pixels"], 0);
}

// Alpha (a fourth channel) is ignored.
TEST_P(ImageMetricsTest, AlphaIsIgnored) {
    Image a(1, 1, 4), b(1, 1, 4);
    a.pixels = {0.5f, 0.5f, 0.5f, 1.0f};
    b.pixels = {0.2f, 0.9f, 0.5f, 0.0f};
    const FrameMetrics m = run(a, b);
    EXPECT_EQ(m.channels, 3);
    EXPECT_NEAR(m.l2, 0.5, kTol);
    EXPECT_NEAR(m.rms, std::sqrt(0.25 / 3.0), kTol);
}

TEST_P(ImageMetricsTest, RefusesBadInputs) {
    const Image a = gray(2, 2, {0.2f, 0.4f, 0.6f, 0.8f});
    const Image wrong = gray(2, 1, {0.2f, 0.4f});
    EXPECT_THROW((void)run(a, wrong), Error);
    Image nan = a;
    nan.at(1, 1) = std::numeric_limits<float>::quiet_NaN();
    EXPECT_THROW((void)run(a, nan), Error);
    Image inf = a;
    inf.at(0, 1) = std::numeric_limits<float>::infinity();
    EXPECT_THROW((void)run(inf, a), Error);
    const std::vector<uint8_t> short_mask(3, 1);
    EXPECT_THROW((void)run(a, a, short_mask), Error);
    Image two(2, 2, 2);
    EXPECT_THROW((void)run(two, two), Error);
}

INSTANTIATE_TEST_SUITE_P(Backends, ImageMetricsTest, ::testing::Values(Backend::Cpu, Backend::Vulkan),
                         [](const auto& info) { return info.param == Backend::Cpu ? "Cpu" : "Vulkan"; });

} // namespace
} // namespace specula::metrics
