// Vulkan side of the residual samples (memory plan in residuals.h):
//  1. particles, `lit` masks and rho/pi per particle are uploaded once;
//  2. the train frames are cut into batches whose images fit one binding (RGBA32: rgb floats
//     and the flags word, exactly as the diffuse solve packs them; a view may span batches,
//     diffuse/view_batches.h);
//  3. per batch: the host lists the (particle, view segment) pairs and their slots (one per
//     lit frame), cuts them into chunks whose slots fit one binding, and per chunk dispatches
//     residuals.comp and downloads the slots into their view's list; a complete view's list
//     keeps its used samples in the reference's order (view, particle, frame).
#include "specular/residuals.h"

#include "diffuse/view_batches.h"

#include "core/error.h"
#include "core/timer.h"
#include "shared/prelude.h"
#include "gpu/buffer.h"
#include "gpu/context.h"
#include "gpu/pipeline.h"
#include "gpu/sequence.h"

#include "specular/residuals.comp.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <list>

namespace specula {

namespace {

} // namespace

struct ResidualsVk::Impl {
    gpu::Context* ctx;
    gpu::ComputePipeline kernel;
    explicit Impl(gpu::Context& c)
        : ctx(&c), kernel(c, gpu::ComputePipelineDesc{.name = "residuals",
                                                      .spirv = specular_residuals_comp,
                                                      .storage_buffers = 8,
                                                      .push_constant_bytes = sizeof(shared::ResidualPush),
                                                      .workgroup_size = 64}) {}
};

ResidualsVk::ResidualsVk(gpu::Context& ctx) : m_impl(std::make_unique<Impl>(ctx)) {}
ResidualsVk::~ResidualsVk() = default;

ResidualSamples ResidualsVk::run(const LambertInputs& in, const LambertOutputs& diffuse, const ResidualOptions& o) {
    const Stopwatch sw;
    lambert_validate(in);
    if (diffuse.particles.size() != in.particles.size())
        throw Error("residual_samples: the diffuse solution has " + std::to_string(diffuse.particles.size()) +
                    " particles, the inputs " + std::to_string(in.particles.size()));
    gpu::Context& ctx = *m_impl->ctx;
    const Visibility& vis = *in.visibility;
    ResidualSamples out;
    ResidualCounts& cnt = out.counts;
    const std::size_t count = in.particles.size();
    if (count == 0) return out;
    const std::uint64_t device_limit = ctx.info().max_storage_buffer_range;
    std::uint64_t limit = device_limit;
    if (o.max_binding_bytes != 0) limit = std::min(limit, o.max_binding_bytes);
    if (count * sizeof(Particle) > device_limit || vis.lit.size() * sizeof(std::uint32_t) > device_limit)
        throw gpu::LimitError("residual_samples: " + std::to_string(count) +
                              " particles (or their lit masks) exceed one storage binding; particle chunking is not implemented");
    const std::uint64_t max_slots = limit / sizeof(ResidualSample);
    out.keep_stride = residual_keep_stride(in, diffuse, o);

    // Per particle: rho/pi (w = 1 when the particle has a diffuse solution).
    std::vector<glm::vec4> rpi(count, glm::vec4(0.0f));
    for (std::size_t p = 0; p < count; ++p)
        if (residual_particle_usable(diffuse.particles[p], o))
            rpi[p] = glm::vec4(diffuse.albedo(p) / static_cast<float>(kPi), 1.0f);

    gpu::Buffer particles_buf = gpu::Buffer::of<Particle>(ctx, count, "residual particles");
    particles_buf.upload(in.particles);
    gpu::Buffer lit_buf = gpu::Buffer::of<std::uint32_t>(ctx, vis.lit.size(), "residual lit masks");
    lit_buf.upload(vis.lit);
    gpu::Buffer rpi_buf = gpu::Buffer::of<glm::vec4>(ctx, count, "residual rho/pi");
    rpi_buf.upload(rpi);

    // View batches whose images fit one binding (diffuse/view_batches.h).
    const std::vector<SurfaceMap>* surfaces = tap_surfaces(in, o.tap_irradiance);
    const std::vector<ViewBatch> batches = plan_view_batches(in, surfaces, limit, "residual_samples");
    out.view_batches = static_cast<std::uint32_t>(batches.size());

    double gpu_ns = 0.0;
    bool timed = true;
    PackedViewBatch packed;
    std::vector<ResidualSample> slots;
    // The samples of a view come out in the reference's order (view, particle, frame) even when
    // its frames span batches: each segment's slots land in the view's own list at the place
    // of their frames, and a view's list is kept (counted, used samples appended) once its
    // last segment is done. Views end in order, so at most two lists are open.
    struct OpenView {
        std::uint32_t view = 0;
        std::vector<ResidualSample> slots;      // lit (particle, frame) slots of the view, reference order
        std::vector<std::uint64_t> pair_first;  // per particle: its first slot in `slots`
        std::vector<std::uint32_t> lit_before;  // per particle: its lit frames in the segments done so far
    };
    std::list<OpenView> open; // a list: the keys point into its elements
    const auto keep_view = [&](OpenView& ov) {
        for (const ResidualSample& s : ov.slots) {
            switch (s.status) {
            case shared::kResidualUsed: // every keep_stride-th (ResidualOptions::max_kept_samples)
                if (cnt.used++ % out.keep_stride == 0) out.samples.push_back(s);
                break;
            case shared::kResidualGrazing: ++cnt.dropped_grazing; break;
            case shared::kResidualMissing: ++cnt.dropped_missing; break;
            case shared::kResidualClipped: ++cnt.dropped_clipped; break;
            default: throw Error("residual_samples: the kernel wrote an unknown status " + std::to_string(s.status));
            }
        }
    };
    const auto open_view = [&](std::uint32_t v) -> OpenView& {
        for (OpenView& ov : open)
            if (ov.view == v) return ov;
        OpenView ov;
        ov.view = v;
        ov.pair_first.assign(count, 0);
        ov.lit_before.assign(count, 0);
        std::uint64_t total = 0;
        for (std::uint32_t p = 0; p < count; ++p) {
            ov.pair_first[p] = total;
            if (!vis.sees(p, v) || rpi[p].w == 0.0f) continue;
            for (std::uint32_t f : in.views[v].frames) total += vis.lights(p, f) ? 1u : 0u;
        }
        ov.slots.resize(total);
        open.push_back(std::move(ov));
        return open.back();
    };
    for (const ViewBatch& b : batches) {
        // Pairs of the batch's segments, in segment order then particle order, with their slot
        // counts and where their slots go in their view's list.
        std::vector<shared::LambertPairKey> keys;
        std::vector<std::uint64_t> key_slots; // first slot of key i within the batch; back() = total
        std::vector<std::pair<OpenView*, std::uint64_t>> key_dest; // key i's view list and first slot there
        key_slots.push_back(0);
        for (std::uint32_t si = 0; si < b.segments.size(); ++si) {
            const ViewSegment& seg = b.segments[si];
            const LambertView& lv = in.views[seg.view];
            OpenView& ov = open_view(seg.view);
            const std::size_t n_frames = seg.frame_last - seg.frame_first;
            for (std::uint32_t p = 0; p < count; ++p) {
                if (!vis.sees(p, seg.view)) continue;
                cnt.candidates += n_frames;
                if (rpi[p].w == 0.0f) {
                    cnt.dropped_no_diffuse += n_frames;
                    continue;
                }
                std::uint32_t lit = 0;
                for (std::uint32_t i = seg.frame_first; i < seg.frame_last; ++i) lit += vis.lights(p, lv.frames[i]) ? 1u : 0u;
                cnt.dropped_shadow += n_frames - lit;
                if (lit == 0) continue;
                keys.push_back({p, si, 0u});
                key_slots.push_back(key_slots.back() + lit);
                key_dest.push_back({&ov, ov.pair_first[p] + ov.lit_before[p]});
                ov.lit_before[p] += lit;
            }
        }

        if (!keys.empty()) {
            pack_view_batch(in, surfaces, b, packed);
            const UploadedViewBatch up = upload_view_batch(ctx, packed, "residual");

            // Chunks of whole pairs whose slots fit one binding.
            for (std::size_t first = 0; first < keys.size();) {
                std::size_t last = first;
                while (last < keys.size() && key_slots[last + 1] - key_slots[first] <= max_slots) ++last;
                if (last == first)
                    throw gpu::LimitError("residual_samples: the " + std::to_string(key_slots[first + 1] - key_slots[first]) +
                                          " samples of one pair exceed one storage binding");
                const std::uint64_t base = key_slots[first];
                const std::uint64_t n_slots = key_slots[last] - base;
                std::vector<shared::LambertPairKey> chunk_keys(keys.begin() + static_cast<std::ptrdiff_t>(first),
                                                               keys.begin() + static_cast<std::ptrdiff_t>(last));
                for (std::size_t i = 0; i < chunk_keys.size(); ++i)
                    chunk_keys[i].slot = static_cast<std::uint32_t>(key_slots[first + i] - base);
                gpu::Buffer keys_buf = gpu::Buffer::of<shared::LambertPairKey>(ctx, chunk_keys.size(), "residual pair keys");
                keys_buf.upload(chunk_keys);
                gpu::Buffer samples_buf = gpu::Buffer::of<ResidualSample>(ctx, n_slots, "residual samples");
                const shared::ResidualPush push{.dispatch = {},
                                                .frame_words = vis.frame_words,
                                                .min_light_cos = o.min_light_cos,
                                                .material = material_gpu(o.material)};
                gpu::Sequence seq(ctx, 2);
                seq.dispatch_1d(m_impl->kernel,
                                {particles_buf, lit_buf, rpi_buf, up.views, up.frames, up.pixels, keys_buf, samples_buf},
                                static_cast<std::uint32_t>(chunk_keys.size()), push, "residuals")
                    .barrier(gpu::Barrier::ComputeToHost)
                    .submit_and_wait();
                for (const auto& t : seq.timings()) {
                    if (t.ns) gpu_ns += *t.ns;
                    else timed = false;
                }
                ++out.chunks;
                slots.resize(n_slots);
                samples_buf.download(std::span<ResidualSample>(slots));
                for (std::size_t i = first; i < last; ++i)
                    std::copy(slots.begin() + static_cast<std::ptrdiff_t>(key_slots[i] - base),
                              slots.begin() + static_cast<std::ptrdiff_t>(key_slots[i + 1] - base),
                              key_dest[i].first->slots.begin() + static_cast<std::ptrdiff_t>(key_dest[i].second));
                first = last;
            }
        }
        // Views whose last segment this batch held are complete.
        for (const ViewSegment& seg : b.segments)
            if (seg.frame_last == in.views[seg.view].frames.size()) {
                auto it = std::find_if(open.begin(), open.end(), [&](const OpenView& ov) { return ov.view == seg.view; });
                keep_view(*it);
                open.erase(it);
            }
    }
    if (timed) out.gpu_ms = gpu_ns * 1e-6;
    out.seconds = sw.seconds();
    return out;
}

} // namespace specula
