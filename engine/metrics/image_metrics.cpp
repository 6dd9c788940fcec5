// Shared by both backends: input checks and the measures from the sums (image_metrics.h
// states every definition).
#include "metrics/image_metrics.h"

#include "core/error.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace specula::metrics {

int metrics_color_channels(int channels) noexcept { return channels == 1 ? 1 : 3; }

void validate_metrics_inputs(const MetricsInputs& in, const MetricsOptions& options) {
    const Image& a = in.captured;
    const Image& b = in.rendered;
    const auto dims = [](const Image& i) {
        return std::to_string(i.width) + "x" + std::to_string(i.height) + "x" + std::to_string(i.channels);
    };
    if (a.width <= 0 || a.height <= 0) throw Error("image metrics: the captured image is empty");
    if (a.width != b.width || a.height != b.height || a.channels != b.channels)
        throw Error("image metrics: captured image is " + dims(a) + " but rendered image is " + dims(b));
    if (a.channels != 1 && a.channels != 3 && a.channels != 4)
        throw Error("image metrics: images must have 1, 3 or 4 channels, not " + std::to_string(a.channels));
    const std::size_t n = static_cast<std::size_t>(a.width) * static_cast<std::size_t>(a.height);
    if (a.pixels.size() != n * static_cast<std::size_t>(a.channels) || b.pixels.size() != a.pixels.size())
        throw Error("image metrics: pixel buffer size does not match " + dims(a));
    if (!in.mask.empty() && in.mask.size() != n)
        throw Error("image metrics: mask has " + std::to_string(in.mask.size()) + " entries for " +
                    std::to_string(n) + " pixels");
    if (!(options.peak > 0.0) || !std::isfinite(options.peak)) throw Error("image metrics: peak must be > 0");
    if (!(options.hausdorff_delta > 0.0) || !std::isfinite(options.hausdorff_delta))
        throw Error("image metrics: hausdorff_delta must be > 0");
    if (options.hausdorff_max_radius < 0) throw Error("image metrics: hausdorff_max_radius must be >= 0");
    const int cc = metrics_color_channels(a.channels);
    for (const Image* img : {&a, &b})
        for (std::size_t p = 0; p < n; ++p)
            for (int c = 0; c < cc; ++c)
                if (!std::isfinite(img->pixels[p * static_cast<std::size_t>(a.channels) + static_cast<std::size_t>(c)]))
                    throw Error(std::string("image metrics: the ") + (img == &a ? "captured" : "rendered") +
                                " image has a non-finite value at pixel (" + std::to_string(p % static_cast<std::size_t>(a.width)) +
                                ", " + std::to_string(p / static_cast<std::size_t>(a.width)) + ")");
}

FrameMetrics finish_metrics(const MetricsSums& s, int color_channels, const MetricsOptions& options) {
    FrameMetrics m;
    m.pixels = s.count;
    m.channels = color_channels;
    m.has_ssim = options.ssim;
    m.has_hausdorff = options.hausdorff;
    if (s.count == 0) return m;
    const double n = static_cast<double>(s.count);
    const double nc = n * color_channels;
    m.mse = s.sum_sq / nc;
    m.rms = std::sqrt(m.mse);                 // eq. 5.5
    m.dde = s.sum_abs / nc;                   // eq. 5.6
    m.rms_percent = 100.0 * m.rms / options.peak; // eq. 5.8
    m.dde_percent = 100.0 * m.dde / options.peak; // eq. 5.10
    m.l1 = s.sum_abs / n;                     // eq. 5.1, r = 1, mean over P
    m.l2 = s.sum_l2 / n;                      // eq. 5.1, r = 2, mean over P
    // eq. 5.4 with the black-image conventions of image_metrics.h.
    if (s.sum_aa == 0.0 && s.sum_bb == 0.0)
        m.ncc = 0.0;
    else if (s.sum_aa == 0.0 || s.sum_bb == 0.0)
        m.ncc = 1.0;
    else
        m.ncc = std::clamp(1.0 - s.sum_ab / std::sqrt(s.sum_aa * s.sum_bb), 0.0, 2.0);
    m.psnr = m.mse > 0.0 ? std::min(options.psnr_cap_db, 10.0 * std::log10(options.peak * options.peak / m.mse))
                         : options.psnr_cap_db;
    if (options.ssim) m.ssim = s.sum_ssim / n;
    if (options.hausdorff) {
        m.hausdorff = std::sqrt(s.hausdorff_d2);
        m.hausdorff_exact = !s.hausdorff_capped;
    }
    return m;
}

} // namespace specula::metrics
