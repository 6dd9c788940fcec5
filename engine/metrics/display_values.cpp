// Display values: display_values.h states the definitions.
#include "metrics/display_values.h"

#include <algorithm>
#include <bit>
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

DisplayEncoder::DisplayEncoder(const DisplayEncoding& e) : m_encoding(e) {
    if (e.bits <= 0 || e.bits > 16) return; // unquantized, or too many codes for a table
    m_max_code = std::ldexp(1.0, e.bits) - 1.0;
    const auto code = [&](float v) { return std::lround(static_cast<double>(to_display(v, e)) * m_max_code); };
    const auto codes = static_cast<std::size_t>(m_max_code);
    m_first.resize(codes);
    for (std::size_t k = 0; k < codes; ++k) {
        // Start at the inverse transfer of the code boundary (k + 1/2) / max, then step by one
        // float until f is the smallest float of code k + 1 (a few steps: the start is within
        // rounding of it). to_display is non-decreasing, so the codes of the table's floats are.
        const double boundary = (static_cast<double>(k) + 0.5) / m_max_code;
        const double start = e.transfer == ColorSpace::Srgb
                                 ? (boundary <= 0.04045 ? boundary / 12.92 : std::pow((boundary + 0.055) / 1.055, 2.4))
                                 : boundary;
        auto f = static_cast<float>(start);
        const auto k1 = static_cast<long>(k) + 1;
        while (code(f) >= k1) f = std::nextafter(f, -1.0f);
        while (code(f) < k1) f = std::nextafter(f, 2.0f);
        m_first[k] = f;
    }
    // The buckets: every float in [0, 1) by its exponent and first 8 mantissa bits.
    const auto code_of = [&](float v) {
        return static_cast<std::uint32_t>(std::upper_bound(m_first.begin(), m_first.end(), v) - m_first.begin());
    };
    const std::uint32_t one = std::bit_cast<std::uint32_t>(1.0f) >> kBucketShift;
    m_bucket.resize(std::size_t{one} + 1);
    for (std::uint32_t b = 0; b < one; ++b) m_bucket[b] = code_of(std::bit_cast<float>(b << kBucketShift));
    m_bucket[one] = code_of(1.0f);
}

float DisplayEncoder::operator()(float linear) const noexcept {
    if (m_first.empty() || std::isnan(linear)) return to_display(linear, m_encoding);
    // The number of codes whose smallest float is <= linear is linear's code: below 0 none, from 1
    // on all, between them at least its bucket's first code and at most the next bucket's.
    std::size_t k = 0;
    if (linear >= 1.0f) {
        k = m_first.size();
    } else if (linear > 0.0f) {
        const std::uint32_t b = std::bit_cast<std::uint32_t>(linear) >> kBucketShift;
        const auto first = m_first.begin();
        k = static_cast<std::size_t>(std::upper_bound(first + m_bucket[b], first + m_bucket[b + 1], linear) - first);
    }
    return static_cast<float>(static_cast<double>(k) / m_max_code);
}

Image DisplayEncoder::operator()(const Image& linear) const {
    Image out = linear;
    for (float& v : out.pixels) v = (*this)(v);
    return out;
}

Image to_display(const Image& linear, const DisplayEncoding& e) { return DisplayEncoder(e)(linear); }

MetricsOptions display_metrics_options(const MetricsOptions& linear) noexcept {
    MetricsOptions o = linear;
    o.peak = 1.0;
    o.ssim = false;
    o.hausdorff = false;
    return o;
}

} // namespace specula::metrics
