#pragma once
// The GPU form of a solve's images, shared by the passes that sample them (the Lambert
// solve, the residual samples). The images of a capture do not fit one storage binding
// (120 frames of 512^2 at 16 bytes per pixel = 480 MiB; lavapipe allows 128 MiB), and
// neither do those of one view of a photometric rig (96 lights of 512^2: 384 MiB), so the
// train frames are cut, in view order and frame order, into batches whose pixels fit one
// binding. A batch holds SEGMENTS: consecutive frames of one view; a view whose frames do
// not fit one binding is split over consecutive batches (at most one segment of a view
// per batch). Any number of frames per view is allowed.
// Pixel layout: 4 words per pixel, the RGB floats' bits then the PixelFlag bits (exact,
// so the GPU reads what the C++ reference reads). With per-tap irradiance each segment's
// surface map (visibility.h, 4 words per pixel too) follows its frames in the same buffer.
#include "diffuse/lambert_solve.h"

#include "gpu/buffer.h"
#include "shared/lambert.h"

#include <cstdint>
#include <string>
#include <vector>

namespace specula {

/// Frames [frame_first, frame_last) of LambertInputs::views[view].frames.
struct ViewSegment {
    std::uint32_t view = 0;
    std::uint32_t frame_first = 0;
    std::uint32_t frame_last = 0;
};

struct ViewBatch {
    std::vector<ViewSegment> segments; ///< in view order, then frame order
    std::uint64_t pixels = 0;          ///< pixels of all their frames (and surface maps)
};

inline constexpr std::uint64_t kBytesPerPackedPixel = 16;

/// The surface maps the passes use for per-tap irradiance (shared/lambert.h): the
/// visibility's, when `wanted` and it has them; else null (no gains: the thesis's sampling).
[[nodiscard]] const std::vector<SurfaceMap>* tap_surfaces(const LambertInputs& in, bool wanted);

/// Cuts the train frames into batches of at most `binding_bytes` of packed pixels (images
/// and, with `surfaces`, one surface map per segment). Views without frames get no segment.
/// Throws gpu::LimitError (naming `who`) when one frame and its view's surface map alone
/// exceed it.
[[nodiscard]] std::vector<ViewBatch> plan_view_batches(const LambertInputs& in, const std::vector<SurfaceMap>* surfaces,
                                                       std::uint64_t binding_bytes, const std::string& who);

/// The camera of view `v` as the kernels read it; frame_first, frame_count and
/// surface_offset are left for the caller.
[[nodiscard]] shared::LambertViewGpu gpu_view(const LambertInputs& in, std::uint32_t v);
/// Frame `f` (a global frame index) as the kernels read it; pixel_offset is left 0.
[[nodiscard]] shared::LambertFrameGpu gpu_frame(const LambertInputs& in, std::uint32_t f);

/// The segments, frames and packed pixels of one batch, ready for upload: views[i] is
/// batch.segments[i], its frame_first/frame_count index `frames`.
struct PackedViewBatch {
    std::vector<shared::LambertViewGpu> views;
    std::vector<shared::LambertFrameGpu> frames;
    std::vector<std::uint32_t> pixel_words; ///< 4 per pixel
};

/// Fills `out` for `batch` (its vectors are reused: call it in a loop without reallocating).
void pack_view_batch(const LambertInputs& in, const std::vector<SurfaceMap>* surfaces, const ViewBatch& batch,
                     PackedViewBatch& out);

/// A packed batch on the device: its views (segments), frames and pixels, one binding each.
struct UploadedViewBatch {
    gpu::Buffer views;
    gpu::Buffer frames;
    gpu::Buffer pixels;
};
/// Uploads `packed`; the buffers are named after `who` (e.g. "lambert views").
[[nodiscard]] UploadedViewBatch upload_view_batch(gpu::Context& ctx, const PackedViewBatch& packed, const std::string& who);

} // namespace specula
