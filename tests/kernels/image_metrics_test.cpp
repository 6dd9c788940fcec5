// image_metrics: Vulkan (float, per-workgroup partial sums added in double on the host)
// against the CPU reference (double throughout), on realistic pairs.
//
// Tolerances, stated once:
//  * Sums (RMS, DDE, L1, L2, CO's sums): each term is rounded once or twice in float
//    (2 eps32), a workgroup adds 256 terms in a tree of depth 8 (8 eps32 of the sum of
//    |terms|); the host adds the partials in double. Every term is >= 0 except A B,
//    which is >= 0 for our images, so each sum has a relative error <= 10 eps32 = 6e-7.
//    RMS = sqrt(sum) halves it. Allowed: 1e-5 relative (16x margin).
//  * CO = 1 - S_ab / sqrt(S_aa S_bb): the ratio's relative error <= 2 x 6e-7, so CO's
//    absolute error <= 1.2e-6. Allowed: 4e-6.
//  * PSNR = -10 log10(MSE): d PSNR = 4.34 d MSE / MSE <= 4.34 x 6e-7 dB. Allowed: 1e-4 dB.
//  * SSIM: per pixel, float variances E[Y^2] - mu^2 lose ~4 eps32 E[Y^2] <= 2.4e-7 to
//    cancellation; they enter next to C2 = 9e-4, so one pixel's SSIM may move by up to
//    ~3 x 2.4e-7 / 9e-4 = 8e-4 in flat, bright regions, and far less elsewhere. The mean
//    over thousands of pixels of such rounding (unbiased, independent) is much smaller:
//    measured below 1e-6 on these pairs. Allowed: 5e-5 absolute on the mean.
//  * Hausdorff: min and max select values exactly; the selected d^2 is rounded in float
//    (~6 eps32), so HD's relative error <= 3 eps32. Allowed: 1e-5 relative. The exactness
//    flag must agree.
#include "metrics/image_metrics.h"
#include "vulkan_env.h"

#include "../metrics/metrics_scene.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

namespace specula::metrics {
namespace {

void expect_conformant(const FrameMetrics& cpu, const FrameMetrics& vk, const char* what) {
    SCOPED_TRACE(what);
    EXPECT_EQ(vk.pixels, cpu.pixels);
    EXPECT_EQ(vk.channels, cpu.channels);
    const auto rel = [](double a, double b, double tol) { EXPECT_NEAR(a, b, tol * std::max(std::abs(b), 1e-12)); };
    rel(vk.mse, cpu.mse, 1e-5);
    rel(vk.rms, cpu.rms, 1e-5);
    rel(vk.dde, cpu.dde, 1e-5);
    rel(vk.l1, cpu.l1, 1e-5);
    rel(vk.l2, cpu.l2, 1e-5);
    EXPECT_NEAR(vk.ncc, cpu.ncc, 4e-6);
    EXPECT_NEAR(vk.psnr, cpu.psnr, 1e-4);
    EXPECT_NEAR(vk.ssim, cpu.ssim, 5e-5);
    rel(vk.hausdorff, cpu.hausdorff, 1e-5);
    EXPECT_EQ(vk.hausdorff_exact, cpu.hausdorff_exact);
    std::printf("[ %-22s] N %8llu  rms %.3e (d %.1e)  ncc %.3e (d %.1e)  ssim %.6f (d %.1e)  hd %.5f (d %.1e)\n", what,
                static_cast<unsigned long long>(cpu.pixels), cpu.rms, std::abs(vk.rms - cpu.rms) / std::max(cpu.rms, 1e-300),
                cpu.ncc, std::abs(vk.ncc - cpu.ncc), cpu.ssim, std::abs(vk.ssim - cpu.ssim), cpu.hausdorff,
                std::abs(vk.hausdorff - cpu.hausdorff));
}

class ImageMetricsKernelTest : public test::VulkanTest {};

// RGB, sizes that are not multiples of the workgroup (tail groups), masked and full frame.
TEST_F(ImageMetricsKernelTest, RgbPairMatchesReference) {
    const auto pair = test::metrics_pair(317, 211, 3, 7);
    ImageMetricsVk vk(ctx());
    const MetricsInputs masked{pair.captured, pair.rendered, pair.mask};
    const MetricsInputs full{pair.captured, pair.rendered};
    expect_conformant(image_metrics_cpu(masked), vk.run(masked), "rgb masked");
    expect_conformant(image_metrics_cpu(full), vk.run(full), "rgb full");
}

TEST_F(ImageMetricsKernelTest, GrayAndRgbaMatchReference) {
    ImageMetricsVk vk(ctx());
    for (int channels : {1, 4}) {
        const auto pair = test::metrics_pair(150, 97, channels, 3);
        const MetricsInputs masked{pair.captured, pair.rendered, pair.mask};
        expect_conformant(image_metrics_cpu(masked), vk.run(masked), channels == 1 ? "gray masked" : "rgba masked");
    }
    // A thin strip (the SSIM window is truncated on every side).
    const auto strip = test::metrics_pair(400, 3, 3, 5);
    const MetricsInputs full{strip.captured, strip.rendered};
    expect_conformant(image_metrics_cpu(full), vk.run(full), "strip full");
}

// Unrelated images (black/white checker halves): the ring search runs to the cap,
// and with a small cap the results are flagged inexact on both sides alike.
TEST_F(ImageMetricsKernelTest, WorstCaseHausdorffAndCap) {
    Image a(48, 40, 3, 0.0f), b(48, 40, 3, 1.0f);
    for (int y = 0; y < 40; ++y)
        for (int x = 0; x < 24; ++x)
            for (int c = 0; c < 3; ++c) b.at(x, y, c) = 0.0f;
    ImageMetricsVk vk(ctx());
    const MetricsInputs in{a, b};
    expect_conformant(image_metrics_cpu(in), vk.run(in), "black/white");
    MetricsOptions o;
    o.hausdorff_max_radius = 4;
    const FrameMetrics cpu = image_metrics_cpu(in, o);
    EXPECT_FALSE(cpu.hausdorff_exact);
    expect_conformant(cpu, vk.run(in, o), "black/white cap 4");
}

// The kernel reuses its buffers: a large run, then a smaller one, then the large again.
TEST_F(ImageMetricsKernelTest, BufferReuseAcrossSizes) {
    ImageMetricsVk vk(ctx());
    const auto big = test::metrics_pair(256, 256, 3, 11);
    const auto small = test::metrics_pair(33, 17, 3, 12);
    const MetricsInputs ib{big.captured, big.rendered, big.mask};
    const MetricsInputs is{small.captured, small.rendered, small.mask};
    const FrameMetrics b1 = vk.run(ib);
    expect_conformant(image_metrics_cpu(is), vk.run(is), "small after big");
    const FrameMetrics b2 = vk.run(ib);
    EXPECT_EQ(b1.rms, b2.rms);
    EXPECT_EQ(b1.ssim, b2.ssim);
    EXPECT_EQ(b1.hausdorff, b2.hausdorff);
    expect_conformant(image_metrics_cpu(ib), b2, "big again");
}

TEST_F(ImageMetricsKernelTest, SkippedMeasures) {
    const auto pair = test::metrics_pair(64, 64, 3, 2);
    MetricsOptions o;
    o.ssim = false;
    o.hausdorff = false;
    ImageMetricsVk vk(ctx());
    const MetricsInputs in{pair.captured, pair.rendered, pair.mask};
    const FrameMetrics m = vk.run(in, o);
    EXPECT_FALSE(m.has_ssim);
    EXPECT_FALSE(m.has_hausdorff);
    EXPECT_EQ(m.ssim, 0.0);
    EXPECT_EQ(m.hausdorff, 0.0);
    expect_conformant(image_metrics_cpu(in, o), m, "skipped ssim/hd");
}

} // namespace
} // namespace specula::metrics
