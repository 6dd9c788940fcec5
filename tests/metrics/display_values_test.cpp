// Display values (engine/metrics/display_values.h): the capture's own encoding applied to a
// linear image. The stored codes come back exactly from their decoded values, and the measures
// on display values match a hand computation on a tiny image whose values encode to known
// 8-bit codes. Also the evaluation's JSON summary keys (metrics_summary.h) do not depend on it:
// those are tested in tests/evaluate.
#include "metrics/display_values.h"
#include "metrics/image_metrics.h"
#include "metrics/metrics_summary.h"

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

namespace specula::metrics {
namespace {

constexpr DisplayEncoding kSrgb8{.transfer = ColorSpace::Srgb, .bits = 8};

// The sRGB transfer function written out from IEC 61966-2-1 in double (not core's float one).
double srgb_encode(double v) { return v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1.0 / 2.4) - 0.055; }

TEST(DisplayValues, DecodedCodesEncodeBackToThemselves) {
    // The capture loader decodes code k of an sRGB file to srgb_to_linear(k / max)
    // (capture.cpp's tables); its display value is k / max again, for every code.
    for (const int bits : {8, 16}) {
        const int max_code = (1 << bits) - 1;
        const DisplayEncoding srgb{.transfer = ColorSpace::Srgb, .bits = bits};
        const DisplayEncoding lin{.transfer = ColorSpace::Linear, .bits = bits};
        const DisplayEncoder table(srgb);
        for (int k = 0; k <= max_code; ++k) {
            const float stored = static_cast<float>(k) / static_cast<float>(max_code);
            ASSERT_EQ(to_display(srgb_to_linear(stored), srgb) * static_cast<float>(max_code), static_cast<float>(k)) << bits << " " << k;
            ASSERT_EQ(table(srgb_to_linear(stored)), to_display(srgb_to_linear(stored), srgb)) << bits << " " << k;
            ASSERT_EQ(to_display(stored, lin) * static_cast<float>(max_code), static_cast<float>(k)) << bits << " " << k;
        }
    }
}

// The image path (a table of each code's smallest float) gives exactly the scalar path's values:
// on random values over [-0.1, 1.1], and on both sides of every code boundary.
TEST(DisplayValues, TheEncoderTableAgreesWithTheScalarDefinition) {
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> u(-0.1f, 1.1f);
    for (const DisplayEncoding e : {DisplayEncoding{ColorSpace::Srgb, 8}, DisplayEncoding{ColorSpace::Linear, 8},
                                    DisplayEncoding{ColorSpace::Srgb, 16}, DisplayEncoding{ColorSpace::Srgb, 0}}) {
        const DisplayEncoder enc(e);
        for (int i = 0; i < 200000; ++i) {
            const float v = u(rng);
            ASSERT_EQ(enc(v), to_display(v, e)) << e.name() << " " << v;
        }
        // The encoder starts its search from the float's bits (2^15 floats a bucket): on both
        // sides of every bucket's edge in [0, 1], and at the ends.
        for (std::uint32_t bits = 0; bits <= std::bit_cast<std::uint32_t>(1.0f); bits += 1u << 15)
            for (const float v : {std::bit_cast<float>(bits), std::nextafter(std::bit_cast<float>(bits), -1.0f)})
                ASSERT_EQ(enc(v), to_display(v, e)) << e.name() << " " << v;
        for (const float v : {0.0f, -0.0f, 1.0f, std::nextafter(1.0f, 0.0f), std::numeric_limits<float>::denorm_min(),
                              std::numeric_limits<float>::infinity(), -std::numeric_limits<float>::infinity()})
            ASSERT_EQ(enc(v), to_display(v, e)) << e.name() << " " << v;
        if (e.bits != 8) continue;
        for (int k = 0; k < 255; ++k) { // around the boundary between codes k and k + 1
            const double b = (k + 0.5) / 255.0;
            const double lin = e.transfer == ColorSpace::Srgb ? (b <= 0.04045 ? b / 12.92 : std::pow((b + 0.055) / 1.055, 2.4)) : b;
            float f = static_cast<float>(lin);
            for (int step = 0; step < 8; ++step) f = std::nextafter(f, -1.0f);
            for (int step = 0; step < 16; ++step, f = std::nextafter(f, 2.0f)) ASSERT_EQ(enc(f), to_display(f, e)) << e.name() << " " << k;
        }
        const Image img = to_display(Image(2, 1, 3, 0.18f), e);
        EXPECT_EQ(img.at(1, 0, 2), to_display(0.18f, e));
    }
}

TEST(DisplayValues, KnownCodesClippingAndFloatFiles) {
    // 0.18 (mid grey): sRGB 0.46135, x 255 = 117.64 -> code 118; 0.5: 0.73536 x 255 = 187.52 -> 188.
    EXPECT_NEAR(srgb_encode(0.18) * 255.0, 117.64, 0.01);
    EXPECT_EQ(to_display(0.18f, kSrgb8), 118.0f / 255.0f);
    EXPECT_EQ(to_display(0.5f, kSrgb8), 188.0f / 255.0f);
    // Clipped to [0, 1] before quantizing: what the file can hold.
    EXPECT_EQ(to_display(1.7f, kSrgb8), 1.0f);
    EXPECT_EQ(to_display(-0.1f, kSrgb8), 0.0f);
    // Linear 8-bit: 0.5 x 255 = 127.5 -> 128 (to nearest, halves up).
    EXPECT_EQ(to_display(0.5f, {.transfer = ColorSpace::Linear, .bits = 8}), 128.0f / 255.0f);
    // A float file: sRGB, clipped, not quantized.
    const DisplayEncoding f = display_encoding_of(ImageFileInfo{.is_float = true, .bits_per_channel = 32}, ColorSpace::Linear);
    EXPECT_EQ(f.bits, 0);
    EXPECT_EQ(f.transfer, ColorSpace::Srgb);
    EXPECT_EQ(f.name(), "srgb");
    EXPECT_NEAR(to_display(0.18f, f), srgb_encode(0.18), 1e-6);
    EXPECT_EQ(to_display(3.0f, f), 1.0f);
    EXPECT_TRUE(std::isnan(to_display(std::nanf(""), f)));
    // Integer files: the capture's color_space and the file's depth.
    EXPECT_EQ(display_encoding_of(ImageFileInfo{.bits_per_channel = 8}, ColorSpace::Srgb), kSrgb8);
    EXPECT_EQ(display_encoding_of(ImageFileInfo{.bits_per_channel = 16}, ColorSpace::Linear).name(), "linear16");
    EXPECT_EQ(display_encoding_of(std::nullopt, ColorSpace::Srgb).name(), "srgb"); // made in memory: as a float file
}

// A 4 x 1 RGB image, grey pixels. Captured codes (as an 8-bit sRGB file stores them) and the
// rendered linear values:
//   pixel 0: code 118, render 0.18  -> code 118   difference 0
//   pixel 1: code 180, render 0.5   -> code 188   difference 8
//   pixel 2: code 250, render 1.7   -> code 255   difference 5 (clipped)
//   pixel 3: code 3,   render -0.1  -> code 0     difference 3 (clipped)
// Display MSE = (0 + 64 + 25 + 9) / (4 x 255^2) (the same in all 3 channels), so
// RMS = sqrt(24.5) / 255, PSNR = 10 log10(255^2 / 24.5), Q1 = 100 - 100 RMS (one frame, G = 1).
TEST(DisplayValues, MetricsOnDisplayValuesMatchAHandComputation) {
    const int codes[4] = {118, 180, 250, 3};
    const float render[4] = {0.18f, 0.5f, 1.7f, -0.1f};
    Image captured(4, 1, 3), rendered(4, 1, 3);
    for (int x = 0; x < 4; ++x)
        for (int c = 0; c < 3; ++c) {
            captured.at(x, 0, c) = srgb_to_linear(static_cast<float>(codes[x]) / 255.0f); // as decoded
            rendered.at(x, 0, c) = render[x];
        }
    const MetricsOptions o = display_metrics_options({});
    EXPECT_FALSE(o.ssim);
    EXPECT_FALSE(o.hausdorff);
    const Image cd = to_display(captured, kSrgb8), rd = to_display(rendered, kSrgb8);
    const FrameMetrics m = image_metrics_cpu({cd, rd}, o);
    // The display values are floats (k / 255 rounded to float): relative error ~1e-7.
    const double rms = std::sqrt(24.5) / 255.0;
    EXPECT_NEAR(m.mse / (98.0 / (4.0 * 255.0 * 255.0)), 1.0, 1e-6);
    EXPECT_NEAR(m.rms / rms, 1.0, 1e-6);
    EXPECT_NEAR(m.psnr, 10.0 * std::log10(255.0 * 255.0 / 24.5), 1e-5);
    const MetricsSummary s = summarize(std::vector<FrameMetrics>{m}, o);
    EXPECT_NEAR(s.q1, 100.0 - 100.0 * rms, 1e-5);
    // On linear values the same pair scores differently (the clipped 1.7 counts in full).
    const FrameMetrics lin = image_metrics_cpu({captured, rendered}, {});
    EXPECT_GT(std::abs(lin.psnr - m.psnr), 1.0);
}

} // namespace
} // namespace specula::metrics
