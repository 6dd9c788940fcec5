#include "gpu/pass_clock.h"

#include "core/error.h"
#include "gpu/vk_check.h"


namespace specula::gpu {

PassClock::PassClock(Context& ctx, uint32_t max_marks) : m_ctx(&ctx), m_max(max_marks) {
    if (!ctx.info().timestamps_supported() || max_marks == 0) return;
    const VkQueryPoolCreateInfo info{.sType = VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO,
                                     .queryType = VK_QUERY_TYPE_TIMESTAMP,
                                     .queryCount = max_marks + 1};
    VkQueryPool pool = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(vkCreateQueryPool(ctx.device(), &info, nullptr, &pool), "pass clock query pool");
    m_queries = UniqueQueryPool(ctx.device(), pool);
}

void PassClock::start(VkCommandBuffer cmd) {
    m_labels.clear();
    if (!m_queries) return;
    vkCmdResetQueryPool(cmd, m_queries.get(), 0, m_max + 1);
    vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, m_queries.get(), 0);
}

void PassClock::mark(VkCommandBuffer cmd, std::string label) {
    if (!m_queries) return;
    if (m_labels.size() >= m_max) throw LimitError("PassClock holds at most " + std::to_string(m_max) + " marks");
    m_labels.push_back(std::move(label));
    vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, m_queries.get(), static_cast<uint32_t>(m_labels.size()));
}

std::vector<std::pair<std::string, double>> PassClock::read() const {
    std::vector<std::pair<std::string, double>> out;
    if (!m_queries || m_labels.empty()) return out;
    const auto n = static_cast<uint32_t>(m_labels.size() + 1);
    std::vector<uint64_t> ticks(n);
    SPECULA_VK_CHECK(vkGetQueryPoolResults(m_ctx->device(), m_queries.get(), 0, n, n * sizeof(uint64_t), ticks.data(),
                                           sizeof(uint64_t), VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT),
                     "reading the pass clock");
    for (std::size_t i = 0; i < m_labels.size(); ++i)
        out.emplace_back(m_labels[i], m_ctx->info().timestamp_ns(ticks[i], ticks[i + 1]).value_or(0.0) * 1e-6);
    return out;
}

} // namespace specula::gpu
