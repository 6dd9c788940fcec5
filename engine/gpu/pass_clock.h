#pragma once
/// \file
/// GPU timestamps at pass boundaries inside a command buffer the caller records and submits
/// (the viewer's frame, which gpu::Sequence's spans cannot wrap: its passes share a render pass
/// and go to the presenter's command buffer). start() at the top, mark(label) after each pass, and
/// once the commands have completed, read(): the time between each mark and the one before.
///
///   gpu::PassClock clock(ctx);
///   clock.start(cmd); ...draw...; clock.mark(cmd, "g-buffer"); ...; clock.mark(cmd, "shading");
///   submit, wait;  for (auto& [label, ms] : clock.read()) ...
///
/// On a device without timestamps every call is a no-op and read() is empty. A timestamp inside a
/// render pass is allowed (vkCmdWriteTimestamp); on lavapipe it flushes the work before it, so the
/// marks split a render pass's subpasses too.
#include "gpu/context.h"
#include "gpu/vk_unique.h"

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace specula::gpu {

class PassClock {
public:
    explicit PassClock(Context& ctx, uint32_t max_marks = 16);
    [[nodiscard]] bool available() const noexcept { return static_cast<bool>(m_queries); }
    /// Resets the marks (outside a render pass) and writes the first timestamp.
    void start(VkCommandBuffer cmd);
    /// The time since the previous timestamp is `label`'s. Throws LimitError past max_marks.
    void mark(VkCommandBuffer cmd, std::string label);
    /// After the recorded commands have completed: (label, milliseconds) per mark, in order.
    [[nodiscard]] std::vector<std::pair<std::string, double>> read() const;

private:
    Context* m_ctx;
    uint32_t m_max;
    UniqueQueryPool m_queries;
    std::vector<std::string> m_labels;
};

} // namespace specula::gpu
