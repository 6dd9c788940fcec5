#include "gpu/sequence.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>

namespace specula::gpu {

namespace {
constexpr uint32_t kSetsPerPool = 64;
constexpr uint32_t kBuffersPerSet = 8; // pool sizing only; a pipeline may bind more

struct BarrierSpec {
    VkPipelineStageFlags src_stage, dst_stage;
    VkAccessFlags src_access, dst_access;
};

BarrierSpec barrier_spec(Barrier kind) {
    switch (kind) {
    case Barrier::ComputeToCompute:
        return {VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_ACCESS_SHADER_WRITE_BIT,
                VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT};
    case Barrier::ComputeToHost:
        return {VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_HOST_BIT, VK_ACCESS_SHADER_WRITE_BIT,
                VK_ACCESS_HOST_READ_BIT};
    case Barrier::ComputeToTransfer:
        return {VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_SHADER_WRITE_BIT,
                VK_ACCESS_TRANSFER_READ_BIT | VK_ACCESS_TRANSFER_WRITE_BIT};
    case Barrier::TransferToCompute:
        return {VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT,
                VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT};
    case Barrier::TransferToHost:
        return {VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, VK_ACCESS_TRANSFER_WRITE_BIT,
                VK_ACCESS_HOST_READ_BIT};
    }
    return {};
}

UniqueDescriptorPool make_descriptor_pool(VkDevice dev, uint32_t min_descriptors) {
    const VkDescriptorPoolSize size{.type = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER,
                                    .descriptorCount = std::max(kSetsPerPool * kBuffersPerSet, min_descriptors)};
    const VkDescriptorPoolCreateInfo info{.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO,
                                          .maxSets = kSetsPerPool,
                                          .poolSizeCount = 1,
                                          .pPoolSizes = &size};
    VkDescriptorPool pool = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(vkCreateDescriptorPool(dev, &info, nullptr, &pool), "sequence descriptor pool");
    return UniqueDescriptorPool(dev, pool);
}
} // namespace

Sequence::Sequence(Context& ctx, uint32_t max_timers) : m_ctx(&ctx), m_max_timers(max_timers) {
    const VkDevice dev = ctx.device();
    const VkCommandPoolCreateInfo pool_info{.sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO,
                                            .flags = VK_COMMAND_POOL_CREATE_TRANSIENT_BIT,
                                            .queueFamilyIndex = ctx.queue_family()};
    VkCommandPool pool = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(vkCreateCommandPool(dev, &pool_info, nullptr, &pool), "sequence command pool");
    m_pool = UniqueCommandPool(dev, pool);
    const VkCommandBufferAllocateInfo alloc{.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO,
                                            .commandPool = pool,
                                            .level = VK_COMMAND_BUFFER_LEVEL_PRIMARY,
                                            .commandBufferCount = 1};
    SPECULA_VK_CHECK(vkAllocateCommandBuffers(dev, &alloc, &m_cmd), "sequence command buffer");
    const VkFenceCreateInfo fence_info{.sType = VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
    VkFence fence = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(vkCreateFence(dev, &fence_info, nullptr, &fence), "sequence fence");
    m_fence = UniqueFence(dev, fence);
    m_descriptor_pools.push_back(make_descriptor_pool(dev, 0));
    if (ctx.info().timestamps_supported() && m_max_timers > 0) {
        const VkQueryPoolCreateInfo query_info{.sType = VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO,
                                               .queryType = VK_QUERY_TYPE_TIMESTAMP,
                                               .queryCount = 2 * m_max_timers};
        VkQueryPool queries = VK_NULL_HANDLE;
        SPECULA_VK_CHECK(vkCreateQueryPool(dev, &query_info, nullptr, &queries), "sequence timestamp query pool");
        m_queries = UniqueQueryPool(dev, queries);
    }
    begin_recording();
}

Sequence::~Sequence() = default; // submit_and_wait() waits, so nothing is in flight here

void Sequence::begin_recording() {
    const VkCommandBufferBeginInfo begin{.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO,
                                         .flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT};
    SPECULA_VK_CHECK(vkBeginCommandBuffer(m_cmd, &begin), "beginning a sequence");
    if (m_queries) vkCmdResetQueryPool(m_cmd, m_queries.get(), 0, 2 * m_max_timers);
    m_state = State::Recording;
}

void Sequence::require_recording(const char* op) const {
    if (m_state != State::Recording)
        throw Error(std::string("Sequence::") + op + " after submit_and_wait(): call reset() to record again");
}

void Sequence::reset() {
    const VkDevice dev = m_ctx->device();
    if (m_state == State::Recording) SPECULA_VK_CHECK(vkEndCommandBuffer(m_cmd), "ending a dropped sequence");
    SPECULA_VK_CHECK(vkResetCommandPool(dev, m_pool.get(), 0), "resetting a sequence's command pool");
    m_descriptor_pools.resize(1);
    SPECULA_VK_CHECK(vkResetDescriptorPool(dev, m_descriptor_pools.front().get(), 0), "resetting descriptor pool");
    SPECULA_VK_CHECK(vkResetFences(dev, 1, std::array{m_fence.get()}.data()), "resetting a sequence's fence");
    m_timer_labels.clear();
    m_timer_open = false;
    m_timings.clear();
    m_dispatch_count = 0;
    begin_recording();
}

VkDescriptorSet Sequence::allocate_set(const ComputePipeline& pipeline, BufferList buffers) {
    if (buffers.size() != pipeline.storage_buffers())
        throw Error("pipeline '" + pipeline.name() + "' takes " + std::to_string(pipeline.storage_buffers()) +
                    " storage buffers, the dispatch gave " + std::to_string(buffers.size()));
    const VkDevice dev = m_ctx->device();
    const VkDescriptorSetLayout layout = pipeline.set_layout();
    VkDescriptorSetAllocateInfo alloc{.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO,
                                      .descriptorPool = m_descriptor_pools.back().get(),
                                      .descriptorSetCount = 1,
                                      .pSetLayouts = &layout};
    VkDescriptorSet set = VK_NULL_HANDLE;
    VkResult r = vkAllocateDescriptorSets(dev, &alloc, &set);
    if (r == VK_ERROR_OUT_OF_POOL_MEMORY || r == VK_ERROR_FRAGMENTED_POOL) {
        m_descriptor_pools.push_back(make_descriptor_pool(dev, pipeline.storage_buffers()));
        alloc.descriptorPool = m_descriptor_pools.back().get();
        r = vkAllocateDescriptorSets(dev, &alloc, &set);
    }
    SPECULA_VK_CHECK(r, "descriptor set for pipeline '" + pipeline.name() + "'");

    std::vector<VkDescriptorBufferInfo> infos;
    std::vector<VkWriteDescriptorSet> writes;
    infos.reserve(buffers.size());
    uint32_t binding = 0;
    for (const Buffer& b : buffers) {
        // Buffer's constructor already refused sizes above maxStorageBufferRange.
        infos.push_back({.buffer = b.handle(), .offset = 0, .range = VK_WHOLE_SIZE});
        writes.push_back({.sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET,
                          .dstSet = set,
                          .dstBinding = binding++,
                          .descriptorCount = 1,
                          .descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER,
                          .pBufferInfo = &infos.back()});
    }
    vkUpdateDescriptorSets(dev, static_cast<uint32_t>(writes.size()), writes.data(), 0, nullptr);
    return set;
}

Sequence& Sequence::dispatch(const ComputePipeline& pipeline, BufferList buffers, std::span<const std::byte> push,
                             uint32_t groups_x, uint32_t groups_y, uint32_t groups_z, std::string_view label) {
    require_recording("dispatch");
    const auto& max = m_ctx->limits().maxComputeWorkGroupCount;
    if (groups_x > max[0] || groups_y > max[1] || groups_z > max[2])
        throw LimitError("dispatch of pipeline '" + pipeline.name() + "' with " + std::to_string(groups_x) + "x" +
                         std::to_string(groups_y) + "x" + std::to_string(groups_z) +
                         " groups exceeds maxComputeWorkGroupCount (use dispatch_1d, which splits)");
    if (push.size() != pipeline.push_constant_bytes())
        throw Error("pipeline '" + pipeline.name() + "' takes " + std::to_string(pipeline.push_constant_bytes()) +
                    " push-constant bytes, the dispatch gave " + std::to_string(push.size()));
    const VkDescriptorSet set = allocate_set(pipeline, buffers);
    if (!label.empty()) time_begin(std::string(label));
    vkCmdBindPipeline(m_cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline.pipeline());
    vkCmdBindDescriptorSets(m_cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline.layout(), 0, 1, &set, 0, nullptr);
    if (!push.empty())
        vkCmdPushConstants(m_cmd, pipeline.layout(), VK_SHADER_STAGE_COMPUTE_BIT, 0,
                           static_cast<uint32_t>(push.size()), push.data());
    if (groups_x > 0 && groups_y > 0 && groups_z > 0) {
        vkCmdDispatch(m_cmd, groups_x, groups_y, groups_z);
        ++m_dispatch_count;
    }
    if (!label.empty()) time_end();
    return *this;
}

Sequence& Sequence::dispatch_1d(const ComputePipeline& pipeline, BufferList buffers, uint32_t count,
                                std::span<const std::byte> push, std::string_view label) {
    require_recording("dispatch_1d");
    if (pipeline.push_constant_bytes() < sizeof(DispatchHeader))
        throw Error("pipeline '" + pipeline.name() +
                    "' is dispatched with dispatch_1d but has fewer than 8 push-constant bytes "
                    "(see shaders/shared/dispatch.h)");
    if (!push.empty() && push.size() != pipeline.push_constant_bytes())
        throw Error("pipeline '" + pipeline.name() + "' takes " + std::to_string(pipeline.push_constant_bytes()) +
                    " push-constant bytes, dispatch_1d gave " + std::to_string(push.size()));
    if (count == 0) return *this;
    std::vector<std::byte> bytes(pipeline.push_constant_bytes());
    if (!push.empty()) std::memcpy(bytes.data(), push.data(), push.size());

    const uint64_t group = pipeline.workgroup_size();
    uint64_t max_groups = m_ctx->limits().maxComputeWorkGroupCount[0];
    if (m_max_groups_override != 0) max_groups = std::min<uint64_t>(max_groups, m_max_groups_override);
    const uint64_t per_split = max_groups * group; // elements per vkCmdDispatch
    const VkDescriptorSet set = allocate_set(pipeline, buffers);
    if (!label.empty()) time_begin(std::string(label));
    vkCmdBindPipeline(m_cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline.pipeline());
    vkCmdBindDescriptorSets(m_cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline.layout(), 0, 1, &set, 0, nullptr);
    for (uint64_t base = 0; base < count; base += per_split) {
        if (base > 0) barrier(Barrier::ComputeToCompute);
        const uint64_t n = std::min<uint64_t>(per_split, count - base);
        const DispatchHeader header{.element_base = static_cast<uint32_t>(base), .element_count = count};
        std::memcpy(bytes.data(), &header, sizeof header);
        vkCmdPushConstants(m_cmd, pipeline.layout(), VK_SHADER_STAGE_COMPUTE_BIT, 0,
                           static_cast<uint32_t>(bytes.size()), bytes.data());
        vkCmdDispatch(m_cmd, static_cast<uint32_t>((n + group - 1) / group), 1, 1);
        ++m_dispatch_count;
    }
    if (!label.empty()) time_end();
    return *this;
}

Sequence& Sequence::barrier(Barrier kind) {
    require_recording("barrier");
    const BarrierSpec s = barrier_spec(kind);
    const VkMemoryBarrier b{.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
                            .srcAccessMask = s.src_access,
                            .dstAccessMask = s.dst_access};
    vkCmdPipelineBarrier(m_cmd, s.src_stage, s.dst_stage, 0, 1, &b, 0, nullptr, 0, nullptr);
    return *this;
}

Sequence& Sequence::copy(const Buffer& src, const Buffer& dst, VkDeviceSize bytes, VkDeviceSize src_offset,
                         VkDeviceSize dst_offset) {
    require_recording("copy");
    if (src_offset + bytes > src.size() || dst_offset + bytes > dst.size())
        throw LimitError("copy of " + std::to_string(bytes) + " bytes from '" + src.name() + "' to '" + dst.name() +
                         "' overruns a buffer");
    const VkBufferCopy region{.srcOffset = src_offset, .dstOffset = dst_offset, .size = bytes};
    vkCmdCopyBuffer(m_cmd, src.handle(), dst.handle(), 1, &region);
    return *this;
}

Sequence& Sequence::fill(const Buffer& dst, uint32_t value, VkDeviceSize offset, VkDeviceSize bytes) {
    require_recording("fill");
    if (offset % 4 != 0 || (bytes != VK_WHOLE_SIZE && (bytes % 4 != 0 || offset + bytes > dst.size())))
        throw LimitError("fill of buffer '" + dst.name() + "': offset and size must be multiples of 4 inside it");
    vkCmdFillBuffer(m_cmd, dst.handle(), offset, bytes, value);
    return *this;
}

Sequence& Sequence::record(const std::function<void(VkCommandBuffer)>& commands) {
    require_recording("record");
    commands(m_cmd);
    return *this;
}

void Sequence::write_timestamp(uint32_t query) {
    vkCmdWriteTimestamp(m_cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, m_queries.get(), query);
}

Sequence& Sequence::time_begin(std::string label) {
    require_recording("time_begin");
    if (m_timer_open) throw Error("Sequence::time_begin(\"" + label + "\") inside another span (spans do not nest)");
    if (m_timer_labels.size() >= m_max_timers)
        throw LimitError("Sequence holds at most " + std::to_string(m_max_timers) + " timed spans");
    if (m_queries) write_timestamp(2 * static_cast<uint32_t>(m_timer_labels.size()));
    m_timer_labels.push_back(std::move(label));
    m_timer_open = true;
    return *this;
}

Sequence& Sequence::time_end() {
    require_recording("time_end");
    if (!m_timer_open) throw Error("Sequence::time_end() without time_begin()");
    if (m_queries) write_timestamp(2 * static_cast<uint32_t>(m_timer_labels.size()) - 1);
    m_timer_open = false;
    return *this;
}

void Sequence::submit_and_wait() {
    require_recording("submit_and_wait");
    if (m_timer_open) throw Error("Sequence::submit_and_wait() with an open time span '" + m_timer_labels.back() + "'");
    const VkDevice dev = m_ctx->device();
    SPECULA_VK_CHECK(vkEndCommandBuffer(m_cmd), "ending a sequence");
    m_state = State::Submitted;
    const VkSubmitInfo submit{.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO, .commandBufferCount = 1, .pCommandBuffers = &m_cmd};
    SPECULA_VK_CHECK(vkQueueSubmit(m_ctx->queue(), 1, &submit, m_fence.get()), "submitting a sequence");
    const VkFence fence = m_fence.get();
    SPECULA_VK_CHECK(vkWaitForFences(dev, 1, &fence, VK_TRUE, UINT64_MAX), "waiting for a sequence");

    m_timings.clear();
    if (m_timer_labels.empty()) return;
    if (!m_queries) {
        for (const auto& label : m_timer_labels)
            m_timings.push_back({label, std::nullopt, "unavailable: the queue family has no timestamp support"});
        return;
    }
    const auto n = static_cast<uint32_t>(2 * m_timer_labels.size());
    std::vector<uint64_t> ticks(n);
    SPECULA_VK_CHECK(vkGetQueryPoolResults(dev, m_queries.get(), 0, n, n * sizeof(uint64_t), ticks.data(),
                                           sizeof(uint64_t), VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT),
                     "reading timestamps");
    for (std::size_t i = 0; i < m_timer_labels.size(); ++i) {
        if (const std::optional<double> ns = m_ctx->info().timestamp_ns(ticks[2 * i], ticks[2 * i + 1]))
            m_timings.push_back({m_timer_labels[i], *ns, {}});
        else
            m_timings.push_back({m_timer_labels[i], std::nullopt, "unavailable: the timestamps were not usable"});
    }
}

} // namespace specula::gpu
