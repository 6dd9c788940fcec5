#pragma once
// A captured/rendered pair like the ones `specula evaluate` compares: a shaded, textured
// sphere with a highlight on a dark background; the "capture" has sensor noise, the
// "render" a slightly wrong albedo, a weaker, shifted highlight and a one-pixel offset.
// The mask is the sphere's disc in the render.
#include "core/image.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

namespace specula::test {

struct MetricsPair {
    Image captured;
    Image rendered;
    std::vector<uint8_t> mask;
};

inline MetricsPair metrics_pair(int w, int h, int channels = 3, uint32_t seed = 1) {
    MetricsPair p{Image(w, h, channels), Image(w, h, channels), std::vector<uint8_t>(static_cast<std::size_t>(w) * h)};
    std::mt19937 rng(seed);
    std::normal_distribution<float> noise(0.0f, 0.01f);
    const auto shade = [&](double x, double y, double albedo_scale, double hl_x, double hl_gain, int c) {
        const double cx = 0.5 * w, cy = 0.5 * h, r = 0.38 * std::min(w, h);
        const double u = (x - cx) / r, v = (y - cy) / r, d2 = u * u + v * v;
        if (d2 >= 1.0) return 0.02 + 0.01 * c; // background
        const double nz = std::sqrt(1.0 - d2);
        const double lambert = std::max(0.0, 0.3 * u - 0.4 * v + 0.866 * nz);
        const double tex = 0.5 + 0.25 * std::sin(12.0 * u + c) * std::cos(9.0 * v);
        const double hu = u - hl_x, hv = v + 0.3;
        const double highlight = hl_gain * std::exp(-(hu * hu + hv * hv) / 0.01);
        return albedo_scale * tex * lambert * (0.6 + 0.2 * c) + highlight;
    };
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            for (int c = 0; c < channels; ++c) {
                const int cc = std::min(c, 2);
                p.captured.at(x, y, c) =
                    c == 3 ? 1.0f : std::clamp(static_cast<float>(shade(x, y, 1.0, 0.2, 0.9, cc)) + noise(rng), 0.0f, 1.0f);
                p.rendered.at(x, y, c) =
                    c == 3 ? 1.0f : std::clamp(static_cast<float>(shade(x + 1.0, y, 0.97, 0.25, 0.7, cc)), 0.0f, 1.0f);
            }
            const double u = (x + 1.0 - 0.5 * w) / (0.38 * std::min(w, h)), v = (y - 0.5 * h) / (0.38 * std::min(w, h));
            p.mask[static_cast<std::size_t>(y) * w + x] = u * u + v * v < 1.0 ? 1 : 0;
        }
    return p;
}

} // namespace specula::test
