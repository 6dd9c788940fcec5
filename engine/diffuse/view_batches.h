#pragma once
// The GPU form of a solve's images, shared by the passes that sample them (the Lambert
// solve, the residual samples). The images of a capture do not fit one storage binding
// (120 frames of 512^2 at 16 bytes per pixel = 480 MiB; lavapipe allows 128 MiB), so
// consecutive views are cut into batches whose pixels fit one binding.
// Pixel layout: 4 words per pixel, the RGB floats' bits then the PixelFlag bits (exact,
// so the GPU reads what the C++ reference reads). With per-tap irradiance each view's
// surface map (visibility.h, 4 words per pixel too) follows its frames in the same buffer.
#include "diffuse/lambert_solve.h"

#include "shared/lambert.h"

#include <cstdint>
#include <string>
#include <vector>

namespace specula {

struct ViewBatch {
    std::uint32_t first = 0; ///< views [first, last) of LambertInputs::views
    std::uint32_t last = 0;
    std::uint64_t pixels = 0; ///< pixels of all their frames
};

inline constexpr std::uint64_t kBytesPerPackedPixel = 16;

/// The surface maps the passes use for per-tap irradiance (shared/lambert.h): the
/// visibility's, when `wanted` and it has them; else null (no gains: the thesis's sampling).
[[nodiscard]] const std::vector<SurfaceMap>* tap_surfaces(const LambertInputs& in, bool wanted);

/// Cuts the views into batches of at most `binding_bytes` of packed pixels (images and, with
/// `surfaces`, surface maps). Throws gpu::LimitError (naming `who`) when one view alone exceeds it.
[[nodiscard]] std::vector<ViewBatch> plan_view_batches(const LambertInputs& in, const std::vector<SurfaceMap>* surfaces,
                                                       std::uint64_t binding_bytes, const std::string& who);

/// The views, frames and packed pixels of one batch, ready for upload.
struct PackedViewBatch {
    std::vector<shared::LambertViewGpu> views;
    std::vector<shared::LambertFrameGpu> frames;
    std::vector<std::uint32_t> pixel_words; ///< 4 per pixel
};

/// Fills `out` for `batch` (its vectors are reused: call it in a loop without reallocating).
void pack_view_batch(const LambertInputs& in, const std::vector<SurfaceMap>* surfaces, const ViewBatch& batch,
                     PackedViewBatch& out);

} // namespace specula
