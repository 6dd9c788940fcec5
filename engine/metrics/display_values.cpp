// Display values: display_values.h states the definitions.
#include "metrics/display_values.h"

#include <algorithm>
#include <cmath>

namespace specula::metrics {

std::string DisplayEncoding::name() const {
    const std::string base = transfer == ColorSpace::Srgb ? "srgb" : "linear";
    return bits > 0 ? base + std::to_string(bits) : base;
}

DisplayEncoding display_encoding_of(const std::optional<ImageFileInfo>& file, ColorSpace integer_encoding) noexcept {
    if (!file || file->is_float) return {.transfer = ColorSpace::Srgb, .bits = 0};
    return {.transfer = integer_encoding, .bits = file->bits_per_channel};
}

float to_display(float linear, const DisplayEncoding& e) noexcept {
    if (std::isnan(linear)) return linear;
    const double v = std::clamp(static_cast<double>(linear), 0.0, 1.0);
    // The sRGB transfer function (IEC 61966-2-1), in double: 1 encodes to 1 (core's float
    // linear_to_srgb gives 1 - 2^-24), and a code boundary is not moved by float rounding.
    const double encoded = e.transfer == ColorSpace::Srgb
                               ? std::clamp(v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1.0 / 2.4) - 0.055, 0.0, 1.0)
                               : v;
    if (e.bits <= 0) return static_cast<float>(encoded);
    // The nearest code, as Specula's image writers quantize (core/image.h); exact in double
    // for every depth up to 32 bits.
    const double max_code = std::ldexp(1.0, std::min(e.bits, 32)) - 1.0;
    return static_cast<float>(std::floor(encoded * max_code + 0.5) / max_code);
}

Image to_display(const Image& linear, const DisplayEncoding& e) {
    Image out = linear;
    for (float& v : out.pixels) v = to_display(v, e);
    return out;
}

MetricsOptions display_metrics_options(const MetricsOptions& linear) noexcept {
    MetricsOptions o = linear;
    o.peak = 1.0;
    o.ssim = false;
    o.hausdorff = false;
    return o;
}

} // namespace specula::metrics
