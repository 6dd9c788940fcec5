#pragma once
// Records GPU work into one command buffer, with every barrier explicit, then
// submits it and waits on a fence (Kompute's Sequence, with the sync spelled out).
//
//   gpu::Sequence seq(ctx);
//   seq.dispatch_1d(pipeline, {in, out}, count, push, "my kernel")
//      .barrier(gpu::Barrier::ComputeToHost)
//      .submit_and_wait();
//   out.download(...);  seq.timings();
//
// Nothing is ordered implicitly: a dispatch that reads what an earlier one wrote
// needs barrier(ComputeToCompute) between them (the validation layer's
// synchronization checks report the hazard otherwise).
#include "gpu/buffer.h"
#include "gpu/pipeline.h"
#include "shared/dispatch.h"

#include <cstddef>
#include <functional>
#include <initializer_list>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace specula::gpu {

using shared::DispatchHeader;

/// Memory dependencies between the kinds of work Specula records.
enum class Barrier {
    ComputeToCompute,  // shader writes -> later shader reads and writes
    ComputeToHost,     // shader writes -> host reads after the fence (before download())
    ComputeToTransfer, // shader writes -> copy / fill
    TransferToCompute, // copy / fill writes -> shader reads and writes
    TransferToHost,    // copy / fill writes -> host reads after the fence
};

/// GPU time of one labelled span. ns is nullopt when the queue has no
/// timestamps (never a made-up number); `note` then says why.
struct GpuTiming {
    std::string label;
    std::optional<double> ns;
    std::string note;
};

using BufferList = std::initializer_list<std::reference_wrapper<const Buffer>>;

class Sequence {
public:
    /// `max_timers`: how many labelled spans (time_begin/end or labelled dispatches) one recording may hold.
    explicit Sequence(Context& ctx, uint32_t max_timers = 64);
    ~Sequence();
    Sequence(const Sequence&) = delete;
    Sequence& operator=(const Sequence&) = delete;
    Sequence(Sequence&&) noexcept = default;
    Sequence& operator=(Sequence&&) noexcept = default;

    /// One vkCmdDispatch of groups (x, y, z). `buffers` bind to set 0, bindings 0..N-1.
    /// A non-empty `label` times it.
    Sequence& dispatch(const ComputePipeline& pipeline, BufferList buffers, std::span<const std::byte> push,
                       uint32_t groups_x, uint32_t groups_y = 1, uint32_t groups_z = 1, std::string_view label = {});

    /// A 1D dispatch over `count` elements (shared/dispatch.h convention): as many
    /// vkCmdDispatch as maxComputeWorkGroupCount[0] requires, each with element_base and
    /// element_count written into the first 8 push-constant bytes; the caller's bytes
    /// 8.. follow unchanged. Splits are separated by a compute->compute barrier, so a
    /// kernel may read what an earlier split wrote (its cost is one pipeline drain per
    /// ~4M elements). count == 0
    /// records nothing. A non-empty `label` times all the splits as one span.
    Sequence& dispatch_1d(const ComputePipeline& pipeline, BufferList buffers, uint32_t count,
                          std::span<const std::byte> push = {}, std::string_view label = {});
    template <class Push>
    Sequence& dispatch_1d(const ComputePipeline& pipeline, BufferList buffers, uint32_t count, const Push& push,
                          std::string_view label = {}) {
        static_assert(std::is_trivially_copyable_v<Push> && sizeof(Push) >= sizeof(DispatchHeader));
        return dispatch_1d(pipeline, buffers, count, std::as_bytes(std::span<const Push>(&push, 1)), label);
    }

    Sequence& barrier(Barrier kind);
    Sequence& copy(const Buffer& src, const Buffer& dst, VkDeviceSize bytes, VkDeviceSize src_offset = 0,
                   VkDeviceSize dst_offset = 0);
    /// Fills `bytes` (multiple of 4, or VK_WHOLE_SIZE) with a 32-bit pattern.
    Sequence& fill(const Buffer& dst, uint32_t value, VkDeviceSize offset = 0, VkDeviceSize bytes = VK_WHOLE_SIZE);

    /// Records raw commands into the sequence's command buffer: graphics passes, image
    /// copies and their barriers (render_target.h). The callback records every barrier
    /// it needs and leaves no render pass open. Spans (time_begin/end) may surround it.
    Sequence& record(const std::function<void(VkCommandBuffer)>& commands);

    /// Labelled GPU timing span (not nested). Timestamps are written at the bottom of
    /// the pipe, after all earlier commands complete, so a span measures its own work.
    Sequence& time_begin(std::string label);
    Sequence& time_end();

    /// Ends the recording, submits it, waits on a fence, reads the timings.
    void submit_and_wait();
    /// Drops the recording (and timings) and starts a new one; buffers and pipelines are untouched.
    void reset();

    [[nodiscard]] const std::vector<GpuTiming>& timings() const noexcept { return m_timings; }
    /// vkCmdDispatch calls recorded since the last reset (tests check splitting with it).
    [[nodiscard]] uint32_t dispatch_count() const noexcept { return m_dispatch_count; }
    /// Lowers the groups per split below the device limit (tests; 0 = the device limit).
    void set_max_groups_per_dispatch(uint32_t groups) noexcept { m_max_groups_override = groups; }

private:
    enum class State { Recording, Submitted };
    void begin_recording();
    void require_recording(const char* op) const;
    VkDescriptorSet allocate_set(const ComputePipeline& pipeline, BufferList buffers);
    void write_timestamp(uint32_t query);

    Context* m_ctx;
    uint32_t m_max_timers;
    UniqueCommandPool m_pool;
    VkCommandBuffer m_cmd = VK_NULL_HANDLE; // freed with m_pool
    UniqueFence m_fence;
    std::vector<UniqueDescriptorPool> m_descriptor_pools; // grows; reset() keeps the first
    UniqueQueryPool m_queries;                           // empty when the queue has no timestamps
    std::vector<std::string> m_timer_labels;             // query 2i = begin, 2i+1 = end
    bool m_timer_open = false;
    std::vector<GpuTiming> m_timings;
    uint32_t m_dispatch_count = 0;
    uint32_t m_max_groups_override = 0;
    State m_state = State::Recording;
};

} // namespace specula::gpu
