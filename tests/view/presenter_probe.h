#pragma once
// What tests/view/presenter_probe draws through gpu::Presenter, shared with the test
// that checks the screenshots it writes (view_test.cpp, XvfbPresenter...): a window of
// kWindowW x kWindowH pixels; a target cleared to kClear; a kImageW x kImageH texture of
// known 8-bit sRGB codes blitted 1:1 into kRect and scaled 2x into kScaledRect.
#include "core/image.h"

#include <array>

namespace specula::view::probe {

constexpr int kWindowW = 40, kWindowH = 30;
constexpr int kImageW = 8, kImageH = 6;
struct Rect {
    int x0, y0, x1, y1;
    [[nodiscard]] bool contains(int x, int y) const { return x >= x0 && x < x1 && y >= y0 && y < y1; }
};
constexpr Rect kRect{13, 9, 13 + kImageW, 9 + kImageH};
constexpr Rect kScaledRect{4, 3, 4 + 2 * kImageW, 3 + 2 * kImageH};
constexpr std::array<float, 3> kClear{0.25f, 0.5f, 0.75f};

/// The 8-bit sRGB code of texel (x, y), channel c: from 10 to 245, neighbours at least
/// 11 codes apart, so a texel shown one pixel off is caught.
inline int code(int x, int y, int c) { return 10 + (20 + 11 * x + 37 * y + 71 * c) % 236; }

/// The texture: linear values whose sRGB encodings are exactly code(x, y, c) / 255.
inline Image known_image() {
    Image img(kImageW, kImageH, 3);
    for (int y = 0; y < kImageH; ++y)
        for (int x = 0; x < kImageW; ++x)
            for (int c = 0; c < 3; ++c) img.at(x, y, c) = srgb_to_linear(static_cast<float>(code(x, y, c)) / 255.0f);
    return img;
}

} // namespace specula::view::probe
