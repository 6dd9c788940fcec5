#pragma once
// Display values (pipeline.md section 8.2): the images as the capture stores them, so that
// error figures compare with the field's, which are computed on stored (usually 8-bit sRGB)
// images. The thesis, too, compared display-encoded 8-bit values (G = 255).
//
// A capture's integer file (docs/capture-format.md, "Images") stores
//     code = round(E(clip(v, 0, 1)) (2^bits - 1))
// with E the sRGB transfer function (IEC 61966-2-1) for `color_space` "srgb", the identity
// for "linear"; Specula decodes it to the linear v = E^-1(code / (2^bits - 1)). The display
// value of a linear v is code / (2^bits - 1): the capture's own encoding applied to a render
// gives what the camera (or the other renderer) would have stored, and applied to a decoded
// capture it gives back the stored codes exactly (tests/metrics: every 8- and 16-bit code).
// The measures on display values (RMS, PSNR, Q1 with G = 1, the full code range) are the
// field's 8-bit figures: RMS 1/255 is one code.
//
// A float file (EXR, HDR) has no display encoding of its own (linear, unbounded): its display
// values are those of the conventional display of a linear image, E = sRGB, clipped to
// [0, 1], not quantized (DisplayEncoding::bits = 0), as the evaluation sheets show it.
#include "core/image.h"
#include "metrics/image_metrics.h"

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace specula::metrics {

struct DisplayEncoding {
    ColorSpace transfer = ColorSpace::Srgb; ///< sRGB transfer function, or none (Linear)
    int bits = 8;                           ///< integer code depth; 0: not quantized (float files)

    /// "srgb8", "srgb16", "linear8", ...; "srgb" / "linear" when not quantized.
    [[nodiscard]] std::string name() const;
    [[nodiscard]] bool operator==(const DisplayEncoding&) const = default;
};

/// The display encoding of a capture's frame: its file's header (absent: an image made in
/// memory, treated as a float file) and the capture's `color_space` for integer files.
[[nodiscard]] DisplayEncoding display_encoding_of(const std::optional<ImageFileInfo>& file, ColorSpace integer_encoding) noexcept;

/// The display value of a linear value (see the file comment): in [0, 1], a multiple of
/// 1 / (2^bits - 1) when bits > 0. NaN stays NaN (image_metrics refuses it).
[[nodiscard]] float to_display(float linear, const DisplayEncoding& e) noexcept;

/// to_display for whole images, fast: for a quantized encoding of up to 16 bits, the code of a
/// value is found among the smallest floats of each code (computed once with to_display itself,
/// so the result is the same, value for value), not by a power per value: the value's float bits
/// give a bucket (2^-8 of an octave), whose first and last codes a second table holds, and a
/// binary search between them (for 8 bits, 0 to 2 codes; the whole table's search took a
/// third of an evaluation's measures).
class DisplayEncoder {
public:
    explicit DisplayEncoder(const DisplayEncoding& e);
    [[nodiscard]] const DisplayEncoding& encoding() const noexcept { return m_encoding; }
    [[nodiscard]] float operator()(float linear) const noexcept;
    /// Every value of the image (all channels).
    [[nodiscard]] Image operator()(const Image& linear) const;

private:
    DisplayEncoding m_encoding;
    double m_max_code = 0.0;
    std::vector<float> m_first; ///< m_first[k]: the smallest float whose code is k + 1
    /// m_bucket[b]: the code of the smallest float in [0, 1) whose bits shifted right by
    /// kBucketShift are b, and one more entry, the code of 1.
    std::vector<std::uint32_t> m_bucket;
    static constexpr int kBucketShift = 15;
};

/// Every value of an image through to_display (DisplayEncoder(e)(linear)).
[[nodiscard]] Image to_display(const Image& linear, const DisplayEncoding& e);

/// The options for measures on display values: G = peak = 1 (the full code range), the
/// caller's PSNR cap, and neither SSIM nor the Hausdorff distance (the display figures are
/// RMS, PSNR and Q1; the others stay on linear values).
[[nodiscard]] MetricsOptions display_metrics_options(const MetricsOptions& linear) noexcept;

} // namespace specula::metrics
