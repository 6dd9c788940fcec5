#include "vulkan_env.h"

#include <cstdio>
#include <cstdlib>
#include <memory>
#include <mutex>

namespace specula::test {

namespace {

struct Shared {
    std::unique_ptr<gpu::Context> ctx;
    std::string reason;
    std::size_t taken = 0;           // messages taken by take_validation_messages
    std::vector<std::size_t> taken_at; // their positions
};

Shared& shared_state() {
    static Shared s = [] {
        Shared out;
        const auto devices = gpu::enumerate_devices();
        const auto selection = gpu::select_device(devices, std::getenv("SPECULA_DEVICE") ? std::getenv("SPECULA_DEVICE") : "");
        if (!selection.index) {
            out.reason = selection.reason;
            return out;
        }
        gpu::ContextOptions options;
        options.application_name = "specula-tests";
        const char* env = std::getenv("SPECULA_VALIDATION");
        options.validation = !(env != nullptr && std::string(env) == "0");
        out.ctx = std::make_unique<gpu::Context>(options); // a missing layer throws: the test fails, loudly
        out.ctx->set_validation_handler([](const gpu::ValidationMessage& m) {
            std::fprintf(stderr, "[vulkan %s] %s: %s\n", m.severity == gpu::MessageSeverity::Error ? "error" : "warning",
                         m.id_name.c_str(), m.text.c_str());
        });
        return out;
    }();
    return s;
}

bool is_taken(const Shared& s, std::size_t position) {
    for (std::size_t p : s.taken_at)
        if (p == position) return true;
    return false;
}

} // namespace

gpu::Context* vulkan_context() { return shared_state().ctx.get(); }

std::string vulkan_unavailable_reason() { return shared_state().reason; }

std::vector<gpu::ValidationMessage> take_validation_messages(const std::function<void()>& fn) {
    Shared& s = shared_state();
    if (!s.ctx) return {};
    const std::size_t first = s.ctx->validation_message_count();
    fn();
    auto messages = s.ctx->validation_messages(first);
    for (std::size_t i = 0; i < messages.size(); ++i) s.taken_at.push_back(first + i);
    return messages;
}

void expect_no_validation_messages_since(std::size_t first) {
    const Shared& s = shared_state();
    if (!s.ctx) return;
    const auto messages = s.ctx->validation_messages(first);
    for (std::size_t i = 0; i < messages.size(); ++i) {
        if (is_taken(s, first + i)) continue;
        ADD_FAILURE() << "Vulkan validation " << (messages[i].severity == gpu::MessageSeverity::Error ? "error" : "warning")
                      << " [" << messages[i].id_name << "]: " << messages[i].text;
    }
}

void VulkanTest::SetUp() {
    SPECULA_REQUIRE_VULKAN();
    m_ctx = vulkan_context();
    m_first_message = m_ctx->validation_message_count();
}

void VulkanTest::TearDown() {
    if (m_ctx != nullptr) expect_no_validation_messages_since(m_first_message);
}

} // namespace specula::test
