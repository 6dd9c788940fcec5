// Vulkan side of image_metrics: uploads A, B and the mask, then records in one
// submission: the per-pixel sums pass (which also writes luminance), the two SSIM
// passes, and the two directed Hausdorff passes; reads back the per-workgroup partials
// and adds them in double on the host (no float atomics). The measures come from
// finish_metrics, shared with the CPU reference.
#include "metrics/image_metrics.h"

#include "core/error.h"
#include "metrics/image_metrics_shared.h"

#include "metrics/image_metrics.comp.h"
#include "metrics/image_metrics_hausdorff.comp.h"
#include "metrics/image_metrics_ssim_h.comp.h"
#include "metrics/image_metrics_ssim_v.comp.h"

#include <algorithm>
#include <limits>
#include <vector>

namespace specula::metrics {

namespace {

using gpu::Buffer;

constexpr uint32_t kGroup = shared::kMetricsGroupSize;

gpu::ComputePipeline make(gpu::Context& ctx, const char* name, std::span<const uint32_t> spirv, uint32_t buffers,
                          uint32_t push) {
    return gpu::ComputePipeline(ctx, gpu::ComputePipelineDesc{.name = name,
                                                              .spirv = spirv,
                                                              .storage_buffers = buffers,
                                                              .push_constant_bytes = push,
                                                              .workgroup_size = kGroup});
}

// Grows `buffer` to hold at least `bytes` (never shrinks).
void ensure(std::optional<Buffer>& buffer, gpu::Context& ctx, uint64_t bytes, const char* name) {
    if (buffer && buffer->size() >= bytes) return;
    buffer.reset();
    buffer.emplace(ctx, std::max<uint64_t>(bytes, 16), name);
}

} // namespace

ImageMetricsVk::ImageMetricsVk(gpu::Context& ctx)
    : m_ctx(&ctx),
      m_sums(make(ctx, "image_metrics", metrics_image_metrics_comp, 5, sizeof(shared::MetricsSumsPush))),
      m_ssim_h(make(ctx, "image_metrics_ssim_h", metrics_image_metrics_ssim_h_comp, 2, sizeof(shared::SsimHPush))),
      m_ssim_v(make(ctx, "image_metrics_ssim_v", metrics_image_metrics_ssim_v_comp, 3, sizeof(shared::SsimVPush))),
      m_hausdorff(make(ctx, "image_metrics_hausdorff", metrics_image_metrics_hausdorff_comp, 4, sizeof(shared::HausdorffPush))),
      m_sequence(ctx, 8) {}

FrameMetrics ImageMetricsVk::run(const MetricsInputs& in, const MetricsOptions& options) {
    validate_metrics_inputs(in, options);
    m_last_gpu_ns.reset();
    const Image& a = in.captured;
    const int cc = metrics_color_channels(a.channels);
    const uint64_t n64 = static_cast<uint64_t>(a.width) * static_cast<uint64_t>(a.height);
    if (n64 > std::numeric_limits<uint32_t>::max() / 2)
        throw gpu::LimitError("image metrics: " + std::to_string(n64) + " pixels is more than one dispatch indexes");
    const auto n = static_cast<uint32_t>(n64);
    const uint32_t groups = (n + kGroup - 1) / kGroup;
    const bool has_mask = !in.mask.empty();

    ensure(m_a, *m_ctx, a.pixels.size() * sizeof(float), "metrics captured image");
    ensure(m_b, *m_ctx, a.pixels.size() * sizeof(float), "metrics rendered image");
    ensure(m_mask, *m_ctx, has_mask ? n64 * sizeof(uint32_t) : 16, "metrics mask");
    ensure(m_luma, *m_ctx, n64 * 2 * sizeof(float), "metrics luminance");
    ensure(m_moments, *m_ctx, n64 * sizeof(shared::SsimMoments), "metrics ssim moments");
    ensure(m_partials, *m_ctx, uint64_t{groups} * sizeof(shared::MetricsPartial), "metrics partial sums");
    ensure(m_ssim_partials, *m_ctx, uint64_t{groups} * 2 * sizeof(float), "metrics ssim partials");
    ensure(m_hd_ab, *m_ctx, uint64_t{groups} * 2 * sizeof(float), "metrics hausdorff A->B partials");
    ensure(m_hd_ba, *m_ctx, uint64_t{groups} * 2 * sizeof(float), "metrics hausdorff B->A partials");
    m_a->upload(a.pixels);
    m_b->upload(in.rendered.pixels);
    if (has_mask) {
        std::vector<uint32_t> mask(in.mask.begin(), in.mask.end());
        m_mask->upload(mask);
    }

    const auto w = static_cast<uint32_t>(a.width);
    const auto h = static_cast<uint32_t>(a.height);
    const auto ch = static_cast<uint32_t>(a.channels);
    const auto ucc = static_cast<uint32_t>(cc);
    const uint32_t um = has_mask ? 1u : 0u;
    m_sequence.reset();
    m_sequence.dispatch_1d(m_sums, {*m_a, *m_b, *m_mask, *m_partials, *m_luma}, n,
                           shared::MetricsSumsPush{.dispatch = {}, .width = w, .height = h, .channels = ch, .color_channels = ucc, .has_mask = um},
                           "metrics sums");
    if (options.ssim) {
        const double c1 = (shared::kSsimK1 * options.peak) * (shared::kSsimK1 * options.peak);
        const double c2 = (shared::kSsimK2 * options.peak) * (shared::kSsimK2 * options.peak);
        m_sequence.barrier(gpu::Barrier::ComputeToCompute)
            .dispatch_1d(m_ssim_h, {*m_luma, *m_moments}, n, shared::SsimHPush{.dispatch = {}, .width = w, .height = h},
                         "metrics ssim h")
            .barrier(gpu::Barrier::ComputeToCompute)
            .dispatch_1d(m_ssim_v, {*m_moments, *m_mask, *m_ssim_partials}, n,
                         shared::SsimVPush{.dispatch = {}, .width = w, .height = h, .has_mask = um,
                                   .c1 = static_cast<float>(c1), .c2 = static_cast<float>(c2)},
                         "metrics ssim v");
    }
    if (options.hausdorff) {
        // Reads only the uploaded images: no barrier needed against the passes above.
        const shared::HausdorffPush push{.dispatch = {}, .width = w, .height = h, .channels = ch, .color_channels = ucc,
                                 .has_mask = um, .max_radius = options.hausdorff_max_radius,
                                 .delta = static_cast<float>(options.hausdorff_delta)};
        m_sequence.dispatch_1d(m_hausdorff, {*m_a, *m_b, *m_mask, *m_hd_ab}, n, push, "metrics hausdorff A->B")
            .dispatch_1d(m_hausdorff, {*m_b, *m_a, *m_mask, *m_hd_ba}, n, push, "metrics hausdorff B->A");
    }
    m_sequence.barrier(gpu::Barrier::ComputeToHost).submit_and_wait();

    MetricsSums s;
    {
        const auto parts = m_partials->download<shared::MetricsPartial>(groups);
        double count = 0.0;
        for (const auto& p : parts) {
            count += p.count;
            s.sum_sq += p.sum_sq;
            s.sum_abs += p.sum_abs;
            s.sum_l2 += p.sum_l2;
            s.sum_ab += p.sum_ab;
            s.sum_aa += p.sum_aa;
            s.sum_bb += p.sum_bb;
        }
        s.count = static_cast<uint64_t>(count + 0.5);
    }
    if (options.ssim) {
        const auto parts = m_ssim_partials->download<float>(uint64_t{groups} * 2);
        for (uint32_t g = 0; g < groups; ++g) s.sum_ssim += parts[2 * g];
    }
    if (options.hausdorff) {
        for (const auto* buf : {&m_hd_ab, &m_hd_ba}) {
            const auto parts = (*buf)->download<float>(uint64_t{groups} * 2);
            for (uint32_t g = 0; g < groups; ++g) {
                s.hausdorff_d2 = std::max(s.hausdorff_d2, static_cast<double>(parts[2 * g]));
                if (parts[2 * g + 1] != 0.0f) s.hausdorff_capped = true;
            }
        }
    }
    double gpu_ns = 0.0;
    bool timed = !m_sequence.timings().empty();
    for (const auto& t : m_sequence.timings()) {
        if (t.ns)
            gpu_ns += *t.ns;
        else
            timed = false;
    }
    if (timed) m_last_gpu_ns = gpu_ns;
    if (s.count == 0) s = MetricsSums{};
    return finish_metrics(s, cc, options);
}

} // namespace specula::metrics
