#include "diffuse/view_batches.h"

#include "gpu/vk_check.h"

#include <cmath>
#include <cstring>

namespace specula {

const std::vector<SurfaceMap>* tap_surfaces(const LambertInputs& in, bool wanted) {
    if (!wanted || in.visibility == nullptr || in.visibility->surfaces.empty()) return nullptr;
    return &in.visibility->surfaces;
}

std::vector<ViewBatch> plan_view_batches(const LambertInputs& in, const std::vector<SurfaceMap>* surfaces,
                                         std::uint64_t binding_bytes, const std::string& who) {
    const std::uint64_t max_pixels = binding_bytes / kBytesPerPackedPixel;
    std::vector<ViewBatch> batches;
    ViewBatch open;
    for (std::uint32_t v = 0; v < in.views.size(); ++v) {
        const Intrinsics& k = in.views[v].camera.intrinsics;
        const std::uint64_t frame_px = std::uint64_t(k.w) * std::uint64_t(k.h);
        const std::uint64_t surface_px = surfaces != nullptr ? frame_px : 0;
        const auto frames = static_cast<std::uint32_t>(in.views[v].frames.size());
        if (frame_px + surface_px > max_pixels)
            throw gpu::LimitError(who + ": one image of view " + std::to_string(v) + " (" + std::to_string(k.w) + "x" +
                                  std::to_string(k.h) + (surfaces != nullptr ? ", with its surface map" : "") +
                                  ") exceeds one storage binding (" + std::to_string(binding_bytes) + " bytes)");
        for (std::uint32_t first = 0; first < frames;) {
            // As many of the view's remaining frames as the open batch holds beside the surface map.
            const std::uint64_t room = max_pixels - open.pixels;
            const std::uint64_t fit = room > surface_px ? (room - surface_px) / frame_px : 0;
            if (fit == 0) {
                batches.push_back(std::move(open));
                open = ViewBatch{};
                continue;
            }
            const std::uint32_t last = static_cast<std::uint32_t>(std::min<std::uint64_t>(frames, first + fit));
            open.segments.push_back({v, first, last});
            open.pixels += frame_px * (last - first) + surface_px;
            first = last;
        }
    }
    if (!open.segments.empty()) batches.push_back(std::move(open));
    return batches;
}

shared::LambertViewGpu gpu_view(const LambertInputs& in, std::uint32_t v) {
    const LambertView& lv = in.views[v];
    const Intrinsics& k = lv.camera.intrinsics;
    const glm::mat4 w2c(lv.camera.world_to_camera);
    shared::LambertViewGpu g{};
    g.w2c0 = glm::vec4(w2c[0][0], w2c[1][0], w2c[2][0], w2c[3][0]); // rows of the column-major matrix
    g.w2c1 = glm::vec4(w2c[0][1], w2c[1][1], w2c[2][1], w2c[3][1]);
    g.w2c2 = glm::vec4(w2c[0][2], w2c[1][2], w2c[2][2], w2c[3][2]);
    g.intrinsics =
        glm::vec4(static_cast<float>(k.fl_x), static_cast<float>(k.fl_y), static_cast<float>(k.cx), static_cast<float>(k.cy));
    g.center = glm::vec4(glm::vec3(lv.camera.center()), 0.0f);
    g.width = static_cast<std::uint32_t>(k.w);
    g.height = static_cast<std::uint32_t>(k.h);
    g.surface_offset = shared::kLambertNoSurface;
    return g;
}

shared::LambertFrameGpu gpu_frame(const LambertInputs& in, std::uint32_t f) {
    const FrameImage& im = in.images[f];
    shared::LambertFrameGpu fr{};
    fr.light = glm::vec4(glm::vec3(in.lights[f].position), std::isfinite(im.saturation) ? im.saturation : 3.0e38f);
    fr.intensity = glm::vec4(glm::vec3(in.lights[f].intensity), 0.0f);
    fr.frame = f;
    return fr;
}

void pack_view_batch(const LambertInputs& in, const std::vector<SurfaceMap>* surfaces, const ViewBatch& batch,
                     PackedViewBatch& out) {
    out.views.clear();
    out.frames.clear();
    out.pixel_words.assign(batch.pixels * 4, 0u);
    std::uint64_t pixel_at = 0;
    for (const ViewSegment& s : batch.segments) {
        const LambertView& lv = in.views[s.view];
        shared::LambertViewGpu g = gpu_view(in, s.view);
        g.frame_first = static_cast<std::uint32_t>(out.frames.size());
        g.frame_count = s.frame_last - s.frame_first;
        for (std::uint32_t i = s.frame_first; i < s.frame_last; ++i) {
            const std::uint32_t f = lv.frames[i];
            const FrameImage& im = in.images[f];
            shared::LambertFrameGpu fr = gpu_frame(in, f);
            fr.pixel_offset = static_cast<std::uint32_t>(pixel_at);
            out.frames.push_back(fr);
            const std::size_t n = im.flags.size();
            std::uint32_t* dst = out.pixel_words.data() + pixel_at * 4;
            for (std::size_t p = 0; p < n; ++p) {
                std::memcpy(dst + 4 * p, &im.color.pixels[3 * p], 12);
                dst[4 * p + 3] = im.flags[p];
            }
            pixel_at += n;
        }
        if (surfaces != nullptr) {
            const SurfaceMap& m = (*surfaces)[s.view];
            g.surface_offset = static_cast<std::uint32_t>(pixel_at);
            std::memcpy(out.pixel_words.data() + pixel_at * 4, m.words.data(), m.words.size() * sizeof(std::uint32_t));
            pixel_at += m.words.size() / 4;
        }
        out.views.push_back(g);
    }
}

UploadedViewBatch upload_view_batch(gpu::Context& ctx, const PackedViewBatch& packed, const std::string& who) {
    UploadedViewBatch u{.views = gpu::Buffer::of<shared::LambertViewGpu>(ctx, packed.views.size(), who + " views"),
                        .frames = gpu::Buffer::of<shared::LambertFrameGpu>(ctx, packed.frames.size(), who + " frames"),
                        .pixels = gpu::Buffer::of<std::uint32_t>(ctx, packed.pixel_words.size(), who + " images")};
    u.views.upload(packed.views);
    u.frames.upload(packed.frames);
    u.pixels.upload(packed.pixel_words);
    return u;
}

} // namespace specula
