#pragma once
// Vulkan for tests: one shared, validated gpu::Context per test process, a skip when
// the machine has no Vulkan device, and a fixture that fails a test on any
// validation message (warnings included) that the test did not ask for.
#include "gpu/context.h"

#include <gtest/gtest.h>

#include <functional>
#include <string>
#include <vector>

namespace specula::test {

/// The shared context: validation on (SPECULA_VALIDATION=0 turns it off; a missing
/// layer is an error, not a skip). nullptr when there is no usable Vulkan device.
[[nodiscard]] gpu::Context* vulkan_context();
/// Why vulkan_context() is nullptr.
[[nodiscard]] std::string vulkan_unavailable_reason();

/// Runs fn and returns the validation messages it produced. They are "taken": a
/// VulkanTest does not fail because of them (deliberate-misuse tests use this).
[[nodiscard]] std::vector<gpu::ValidationMessage> take_validation_messages(const std::function<void()>& fn);

/// Fails the current test for each validation message since `first` not taken.
void expect_no_validation_messages_since(std::size_t first);

/// Fixture for GPU tests: skips without Vulkan; fails on validation messages.
class VulkanTest : public ::testing::Test {
protected:
    void SetUp() override;
    void TearDown() override;
    [[nodiscard]] gpu::Context& ctx() const { return *m_ctx; }

private:
    gpu::Context* m_ctx = nullptr;
    std::size_t m_first_message = 0;
};

} // namespace specula::test

/// Skips the current test (GTEST_SKIP) when no Vulkan device exists.
#define SPECULA_REQUIRE_VULKAN()                                                            \
    do {                                                                                    \
        if (::specula::test::vulkan_context() == nullptr)                                   \
            GTEST_SKIP() << "no Vulkan device: " << ::specula::test::vulkan_unavailable_reason(); \
    } while (0)
