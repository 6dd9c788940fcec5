// Image I/O: sRGB round trips, bit depths, float formats, refusal of missing files.
#include "core/error.h"
#include "core/image.h"
#include "test_dirs.h"

#include <gtest/gtest.h>

#include <cmath>

namespace specula {
namespace {

Image gradient(int w, int h) {
    Image img(w, h, 3);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            for (int c = 0; c < 3; ++c) img.at(x, y, c) = static_cast<float>(x + y * w + c) / static_cast<float>(w * h + 2);
    return img;
}

TEST(SrgbTransfer, InvertsAndMatchesKnownPoints) {
    EXPECT_FLOAT_EQ(srgb_to_linear(0.0f), 0.0f);
    EXPECT_FLOAT_EQ(srgb_to_linear(1.0f), 1.0f);
    EXPECT_NEAR(srgb_to_linear(0.5f), 0.214041f, 1e-5f); // ((0.5+0.055)/1.055)^2.4
    for (int i = 0; i <= 100; ++i) {
        const float v = static_cast<float>(i) / 100.0f;
        EXPECT_NEAR(srgb_to_linear(linear_to_srgb(v)), v, 1e-6f);
    }
}

TEST(ImageIo, Png16SrgbRoundTripWithinQuantization) {
    test::TempDir dir("img");
    const Image src = gradient(17, 9);
    write_image(dir / "a.png", src, ColorSpace::Srgb, 16);
    ImageFileInfo info;
    const Image back = read_image(dir / "a.png", ColorSpace::Srgb, "file_path", &info);
    EXPECT_EQ(info.bits_per_channel, 16);
    EXPECT_FALSE(info.is_float);
    ASSERT_EQ(back.width, 17);
    ASSERT_EQ(back.height, 9);
    for (std::size_t i = 0; i < src.pixels.size(); ++i) EXPECT_NEAR(back.pixels[i], src.pixels[i], 2e-4f);
}

TEST(ImageIo, Png8LinearRoundTripWithinHalfStep) {
    test::TempDir dir("img");
    const Image src = gradient(8, 8);
    write_image(dir / "a.png", src, ColorSpace::Linear, 8);
    const Image back = read_image(dir / "a.png", ColorSpace::Linear);
    for (std::size_t i = 0; i < src.pixels.size(); ++i) EXPECT_NEAR(back.pixels[i], src.pixels[i], 0.5f / 255.0f + 1e-6f);
}

TEST(ImageIo, ExrIsLinearAndExactIncludingOutOfRange) {
    test::TempDir dir("img");
    Image src = gradient(5, 4);
    src.at(1, 1, 0) = 7.5f; // HDR values survive
    write_image(dir / "a.exr", src, ColorSpace::Srgb);
    ImageFileInfo info;
    const Image back = read_image(dir / "a.exr", ColorSpace::Srgb, "", &info); // encoding ignored for float files
    EXPECT_TRUE(info.is_float);
    for (std::size_t i = 0; i < src.pixels.size(); ++i) EXPECT_EQ(back.pixels[i], src.pixels[i]);
}

TEST(ImageIo, MissingFileNamesFileAndField) {
    test::TempDir dir("img");
    try {
        (void)read_image(dir / "nope.png", ColorSpace::Srgb, "frames[3].file_path");
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("nope.png"), std::string::npos);
        EXPECT_EQ(e.field(), "frames[3].file_path");
    }
}

TEST(ImageIo, FailedWriteLeavesNoFile) {
    test::TempDir dir("img");
    EXPECT_THROW(write_image(dir / "a.unknownext", gradient(2, 2), ColorSpace::Srgb), InputError);
    EXPECT_TRUE(std::filesystem::is_empty(dir.path()));
}

} // namespace
} // namespace specula

namespace specula {
namespace {

TEST(ImageIo, AlphaIsIgnoredNotPremultiplied) {
    test::TempDir dir("img");
    Image rgba(2, 1, 4);
    for (int x = 0; x < 2; ++x) {
        rgba.at(x, 0, 0) = 0.8f;
        rgba.at(x, 0, 1) = 0.4f;
        rgba.at(x, 0, 2) = 0.2f;
        rgba.at(x, 0, 3) = x == 0 ? 0.0f : 1.0f; // transparent, then opaque
    }
    write_image(dir / "a.png", rgba, ColorSpace::Linear, 16);
    const Image back = read_image(dir / "a.png", ColorSpace::Linear);
    ASSERT_EQ(back.channels, 4);
    for (int x = 0; x < 2; ++x) {
        EXPECT_NEAR(back.at(x, 0, 0), 0.8f, 1e-4f) << "pixel " << x;
        EXPECT_NEAR(back.at(x, 0, 1), 0.4f, 1e-4f) << "pixel " << x;
    }
}

} // namespace
} // namespace specula
