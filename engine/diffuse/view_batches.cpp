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
    const std::uint32_t view_count = static_cast<std::uint32_t>(in.views.size());
    std::vector<ViewBatch> batches;
    for (std::uint32_t first = 0; first < view_count;) {
        std::uint32_t last = first;
        std::uint64_t px = 0;
        while (last < view_count) {
            const Intrinsics& k = in.views[last].camera.intrinsics;
            const std::uint64_t view_px =
                std::uint64_t(k.w) * std::uint64_t(k.h) * (in.views[last].frames.size() + (surfaces != nullptr ? 1 : 0));
            if ((px + view_px) * kBytesPerPackedPixel > binding_bytes) break;
            px += view_px;
            ++last;
        }
        if (last == first)
            throw gpu::LimitError(who + ": the images of view " + std::to_string(first) + " exceed one storage binding");
        batches.push_back({first, last, px});
        first = last;
    }
    return batches;
}

void pack_view_batch(const LambertInputs& in, const std::vector<SurfaceMap>* surfaces, const ViewBatch& batch,
                     PackedViewBatch& out) {
    out.views.clear();
    out.frames.clear();
    out.pixel_words.assign(batch.pixels * 4, 0u);
    std::uint64_t pixel_at = 0;
    std::uint32_t batch_frames = 0;
    for (std::uint32_t v = batch.first; v < batch.last; ++v) {
        const LambertView& lv = in.views[v];
        const Intrinsics& k = lv.camera.intrinsics;
        const glm::mat4 w2c(lv.camera.world_to_camera);
        shared::LambertViewGpu g{};
        g.w2c0 = glm::vec4(w2c[0][0], w2c[1][0], w2c[2][0], w2c[3][0]); // rows of the column-major matrix
        g.w2c1 = glm::vec4(w2c[0][1], w2c[1][1], w2c[2][1], w2c[3][1]);
        g.w2c2 = glm::vec4(w2c[0][2], w2c[1][2], w2c[2][2], w2c[3][2]);
        g.intrinsics = glm::vec4(static_cast<float>(k.fl_x), static_cast<float>(k.fl_y), static_cast<float>(k.cx),
                                 static_cast<float>(k.cy));
        g.center = glm::vec4(glm::vec3(lv.camera.center()), 0.0f);
        g.width = static_cast<std::uint32_t>(k.w);
        g.height = static_cast<std::uint32_t>(k.h);
        g.frame_first = batch_frames;
        g.frame_count = static_cast<std::uint32_t>(lv.frames.size());
        out.views.push_back(g);
        for (std::uint32_t f : lv.frames) {
            const FrameImage& im = in.images[f];
            shared::LambertFrameGpu fr{};
            fr.light = glm::vec4(glm::vec3(in.lights[f].position), std::isfinite(im.saturation) ? im.saturation : 3.0e38f);
            fr.intensity = glm::vec4(glm::vec3(in.lights[f].intensity), 0.0f);
            fr.frame = f;
            fr.pixel_offset = static_cast<std::uint32_t>(pixel_at);
            out.frames.push_back(fr);
            const std::size_t n = im.flags.size();
            std::uint32_t* dst = out.pixel_words.data() + pixel_at * 4;
            for (std::size_t i = 0; i < n; ++i) {
                std::memcpy(dst + 4 * i, &im.color.pixels[3 * i], 12);
                dst[4 * i + 3] = im.flags[i];
            }
            pixel_at += n;
            ++batch_frames;
        }
        out.views.back().surface_offset = shared::kLambertNoSurface;
        if (surfaces != nullptr) {
            const SurfaceMap& m = (*surfaces)[v];
            out.views.back().surface_offset = static_cast<std::uint32_t>(pixel_at);
            std::memcpy(out.pixel_words.data() + pixel_at * 4, m.words.data(), m.words.size() * sizeof(std::uint32_t));
            pixel_at += m.words.size() / 4;
        }
    }
}

} // namespace specula
