#include "synth/noise.h"

#include "core/error.h"

#include <glm/gtc/constants.hpp>

#include <cmath>

namespace specula::synth {

// SplitMix64 finaliser: a bijective 64-bit mix.
std::uint64_t mix64(std::uint64_t z) {
    z += 0x9e3779b97f4a7c15ull;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}

// 53 random bits, never 0 (Box-Muller takes its log) nor 1.
double uniform01(std::uint64_t bits) { return (static_cast<double>(bits >> 11) + 0.5) * 0x1.0p-53; }

double gaussian_deviate(std::uint64_t seed, std::uint64_t stream, std::uint64_t counter) {
    const std::uint64_t key = mix64(mix64(seed) ^ mix64(stream + 0x632be59bd9b4e019ull)) ^ counter * 0x2545f4914f6cdd1dull;
    const double u1 = uniform01(mix64(key));
    const double u2 = uniform01(mix64(key ^ 0xd6e8feb86659fd93ull));
    // Box-Muller (1958), one of the pair.
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(glm::two_pi<double>() * u2);
}

void apply_noise(Image& image, const NoiseOptions& noise, std::uint64_t seed, std::uint64_t stream) {
    if (noise.sigma < 0.0 || noise.shot < 0.0 || !std::isfinite(noise.sigma) || !std::isfinite(noise.shot))
        throw Error("noise sigma and shot factor must be finite and non-negative");
    if (!noise.enabled()) return;
    const double var0 = noise.sigma * noise.sigma;
    for (std::size_t i = 0; i < image.pixels.size(); ++i) {
        const double v = image.pixels[i];
        const double sd = std::sqrt(var0 + noise.shot * std::max(v, 0.0));
        image.pixels[i] = static_cast<float>(v + sd * gaussian_deviate(seed, stream, i));
    }
}

std::size_t count_clipped(const Image& image, const std::vector<std::uint8_t>& mask, float saturation) {
    std::size_t clipped = 0;
    const std::size_t n = static_cast<std::size_t>(image.width) * image.height;
    for (std::size_t p = 0; p < n; ++p) {
        if (!mask.empty() && mask[p] == 0) continue;
        for (int c = 0; c < image.channels; ++c) {
            if (image.pixels[p * image.channels + c] >= saturation) {
                ++clipped;
                break;
            }
        }
    }
    return clipped;
}

} // namespace specula::synth
