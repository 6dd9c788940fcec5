#pragma once
// Stage 8 (pipeline.md section 8): image quality metrics between a captured image A
// and the rendered image B of the same view and light, over a pixel set P: the
// object's pixels (a mask: primary) or the full frame (comparable with the thesis,
// whose figures include the background).
//
// Definitions (thesis chapter 5, eq. 5.1-5.10). N = |P|, C = colour channels used
// (1 for a one-channel image, else R, G, B: a fourth channel, alpha, is ignored);
// sums run over p in P and c < C. Values are linear (core/image.h).
//
//   MSE  = sum (A-B)^2 / (N C)
//   RMS  = sqrt(MSE)                                          eq. 5.5, per channel value
//   DDE  = sum |A-B| / (N C)                                  eq. 5.6
//   RMS% = 100 RMS / G,  DDE% = 100 DDE / G                    eq. 5.8, 5.10
//          G = the maximum intensity value = MetricsOptions::peak = 1.0: full scale of
//          our linear images (an 8-bit file decodes to [0, 1]). The thesis compared
//          display-encoded 8-bit values with G = 255; ours are linear, so our figures
//          are not the same numbers even on identical renders (an error in linear
//          values is smaller in the darks and larger in the brights than in sRGB).
//   L1   = mean over P of  sum_c |A_pc - B_pc|                 eq. 5.1, r = 1 (= C DDE)
//   L2   = mean over P of  sqrt(sum_c (A_pc - B_pc)^2)         eq. 5.1, r = 2
//   NCC  = CO = 1 - sum A B / sqrt(sum A^2 sum B^2)             eq. 5.4 (0 = identical up to
//          a positive scale; it is not mean-centred). Both sums of squares 0 (both images
//          black on P): CO = 0 (they are identical). Exactly one 0: CO = 1 (no correlation).
//          Clamped to [0, 2] against rounding (Cauchy-Schwarz).
//   PSNR = 10 log10(peak^2 / MSE), peak = 1.0, capped at psnr_cap_db = 100 dB (MSE = 0,
//          identical images, gives the cap: never inf or NaN, so means over frames and the
//          JSON stay finite; 100 dB is an RMS of 1e-5, below float noise of our renders).
//   SSIM = the mean over P of the SSIM map of Wang et al. 2004 on linear luminance
//          (image_metrics_shared.h: 11x11 Gaussian, sigma 1.5, K1 0.01, K2 0.03, L = peak;
//          the window sees every pixel of the frame, in P or not; truncated and
//          renormalised at the image border).
//   HD   = Hausdorff distance, eq. 5.2-5.3: HD = max(h(A,B), h(B,A)),
//          h(X,Y) = max over p in P of min over q in P of d(X_p, Y_q), where a pixel is the
//          point (delta x, delta y, c_1..c_C) and d is the Euclidean distance:
//              d(X_p, Y_q)^2 = delta^2 |p - q|^2 + sum_c (X_pc - Y_qc)^2
//          The thesis leaves d open ("Euclidean or city-block"); a distance on values alone
//          ignores where a pixel is (two shuffled images would be at HD 0), a distance on
//          positions alone ignores the images. The (position, value) point set is the usual
//          image Hausdorff: HD is small when every pixel of one image has a pixel of similar
//          colour nearby in the other, so it tolerates small misalignments (geometry error)
//          that RMS punishes. delta = hausdorff_delta = 1/16 per pixel: a shift of 16 pixels
//          costs as much as a full-scale error in one channel.
//          Search: q is sought in Chebyshev rings around p, stopping at ring k once
//          (k delta)^2 >= the best d^2 so far (no closer q can lie further out): exact, and
//          cheap where the images agree. Rings are capped at hausdorff_max_radius = 32
//          pixels. The result is exact whenever every pixel's colour distance
//          |X_p - Y_p| <= delta (R + 1): with the defaults, for every pair of images with
//          values in [0, 1] (|X_p - Y_p| <= sqrt(3) < 33/16). Otherwise it is an upper bound
//          and FrameMetrics::hausdorff_exact is false. Cost: O(N (2r+1)^2) with r the ring
//          reached, r = 0..1 for images that agree, up to N 65^2 for unrelated images.
//
// Empty P (a mask with no pixel): pixels = 0 and every measure 0; to_json writes null
// and summaries skip the frame. Inputs with a non-finite value among the colour
// channels (anywhere in the frame: SSIM windows reach outside P) are refused with an
// Error, so no measure is ever NaN.
//
// Backends: image_metrics_cpu (the reference: accumulates in double) and ImageMetricsVk
// (shaders/metrics/image_metrics*.comp: per-workgroup float partial sums reduced on the
// host in double; the SSIM map in two separable passes; Hausdorff ring search per pixel).
#include "gpu/buffer.h"
#include "gpu/pipeline.h"
#include "gpu/sequence.h"

#include "core/image.h"

#include <cstdint>
#include <optional>
#include <span>

namespace specula::metrics {

struct MetricsOptions {
    double peak = 1.0;                  // G of eq. 5.8/5.10, the PSNR peak and SSIM's L
    double psnr_cap_db = 100.0;         // PSNR of identical images (and the largest reported)
    double hausdorff_delta = 1.0 / 16;  // intensity units per pixel of displacement
    int hausdorff_max_radius = 32;      // ring cap (pixels); see above for exactness
    bool hausdorff = true;              // false: skip it (hausdorff = 0, reported as null)
    bool ssim = true;                   // false: skip it (ssim = 0, reported as null)
};

/// A pair of images of the same size and channel count (1, 3 or 4) and an optional
/// mask (width * height bytes, nonzero = in P; empty = the full frame).
struct MetricsInputs {
    const Image& captured; // A
    const Image& rendered; // B
    std::span<const uint8_t> mask = {};
};

/// Every measure of one frame over one pixel set (plain data).
struct FrameMetrics {
    uint64_t pixels = 0; // N = |P|
    int channels = 0;    // C
    double mse = 0.0;
    double rms = 0.0;
    double rms_percent = 0.0;
    double dde = 0.0;
    double dde_percent = 0.0;
    double ncc = 0.0; // CO, eq. 5.4
    double l1 = 0.0;
    double l2 = 0.0;
    double psnr = 0.0;
    double ssim = 0.0;
    double hausdorff = 0.0;
    bool hausdorff_exact = true;
    bool has_ssim = false;
    bool has_hausdorff = false;

    [[nodiscard]] bool empty() const noexcept { return pixels == 0; }
};

/// The raw sums over P of one frame (double), from either backend.
struct MetricsSums {
    uint64_t count = 0;
    double sum_sq = 0.0, sum_abs = 0.0, sum_l2 = 0.0, sum_ab = 0.0, sum_aa = 0.0, sum_bb = 0.0;
    double sum_ssim = 0.0;       // of the SSIM map over P
    double hausdorff_d2 = 0.0;   // max of both directed squared distances
    bool hausdorff_capped = false;
};

/// Checks sizes, channels, the mask and finiteness; throws specula::Error naming the problem.
void validate_metrics_inputs(const MetricsInputs& in, const MetricsOptions& options);
/// Number of colour channels used (1 or 3) for an image of `channels`.
[[nodiscard]] int metrics_color_channels(int channels) noexcept;
/// The measures from the sums (shared by both backends).
[[nodiscard]] FrameMetrics finish_metrics(const MetricsSums& sums, int color_channels, const MetricsOptions& options);

/// The reference (double accumulation). Throws specula::Error on invalid inputs.
[[nodiscard]] FrameMetrics image_metrics_cpu(const MetricsInputs& in, const MetricsOptions& options = {});

/// The Vulkan kernels. Owns its pipelines and grows its buffers as needed (reused between runs).
class ImageMetricsVk {
public:
    explicit ImageMetricsVk(gpu::Context& ctx);
    [[nodiscard]] FrameMetrics run(const MetricsInputs& in, const MetricsOptions& options = {});
    /// Sum of the GPU times of the last run's dispatches, in ns (nullopt without timestamps).
    [[nodiscard]] std::optional<double> last_gpu_ns() const noexcept { return m_last_gpu_ns; }

private:
    gpu::Context* m_ctx;
    gpu::ComputePipeline m_sums;
    gpu::ComputePipeline m_ssim_h;
    gpu::ComputePipeline m_ssim_v;
    gpu::ComputePipeline m_hausdorff;
    gpu::Sequence m_sequence;
    std::optional<gpu::Buffer> m_a, m_b, m_mask, m_luma, m_moments;
    std::optional<gpu::Buffer> m_partials, m_ssim_partials, m_hd_ab, m_hd_ba;
    std::optional<double> m_last_gpu_ns;
};

} // namespace specula::metrics
