#pragma once
// Sensor noise and saturation of synthetic frames. Noise is counter-based: the
// value added to a pixel channel depends only on (seed, stream, pixel, channel),
// so it is the same whatever the thread count or the order frames are made in.
#include "core/image.h"

#include <cstdint>
#include <vector>

namespace specula::synth {

struct NoiseOptions {
    double sigma = 0.0; // read noise: standard deviation, relative to full scale 1.0
    double shot = 0.0;  // shot noise: variance = shot * value (linear), added to sigma^2
    [[nodiscard]] bool enabled() const noexcept { return sigma > 0.0 || shot > 0.0; }
};

/// Adds zero-mean Gaussian noise of variance sigma^2 + shot * max(value, 0) to
/// every channel of every pixel. `stream` separates frames of one capture.
void apply_noise(Image& image, const NoiseOptions& noise, std::uint64_t seed, std::uint64_t stream);

/// SplitMix64's finaliser (Steele, Lea, Flood 2014): a bijective 64-bit mix, the hash of every
/// counter-based random number of synth (this noise and the renderer's path samples, render.h).
[[nodiscard]] std::uint64_t mix64(std::uint64_t z);

/// Uniform in (0, 1) from 64 random bits: 53 of them, never exactly 0 or 1.
[[nodiscard]] double uniform01(std::uint64_t bits);

/// Standard normal deviate number `counter` of (seed, stream): a pure function.
[[nodiscard]] double gaussian_deviate(std::uint64_t seed, std::uint64_t stream, std::uint64_t counter);

/// Pixels with any channel at or above `saturation`, counted where mask != 0
/// (every pixel when mask is empty).
[[nodiscard]] std::size_t count_clipped(const Image& image, const std::vector<std::uint8_t>& mask, float saturation);

} // namespace specula::synth
