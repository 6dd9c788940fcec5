// The GPU layer: device choice, buffers, split dispatches, barriers, timestamps, and
// proof that validation (with synchronization checks) is on in the tests.
#include "gpu/buffer.h"
#include "gpu/context.h"
#include "gpu/pipeline.h"
#include "gpu/sequence.h"
#include "vulkan_env.h"

#include "test/dispatch_probe.comp.h"
#include "test/dispatch_probe.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>

namespace specula::gpu {
namespace {

using test::VulkanTest;

using shared::ProbePush; // shaders/test/dispatch_probe.h

uint32_t probe_value(uint32_t e, uint32_t tag) { return e * 2654435761u + tag; }

ComputePipeline make_probe(Context& ctx) {
    return ComputePipeline(ctx, {.name = "dispatch_probe",
                                 .spirv = test_dispatch_probe_comp,
                                 .storage_buffers = 1,
                                 .push_constant_bytes = sizeof(ProbePush),
                                 .workgroup_size = 64});
}

DeviceInfo fake_device(uint32_t index, const char* name, DeviceKind kind) {
    DeviceInfo d;
    d.index = index;
    d.name = name;
    d.kind = kind;
    d.api_version = VK_API_VERSION_1_3;
    d.queue_family = 0;
    return d;
}

// ---------------------------------------------------------------------------------------------
// Device choice (pure logic, no Vulkan needed)

TEST(DeviceSelection, DefaultPrefersDiscreteThenIntegratedThenVirtualThenCpu) {
    std::vector<DeviceInfo> devices{fake_device(0, "llvmpipe (LLVM 15.0.6, 256 bits)", DeviceKind::Cpu),
                                    fake_device(1, "Intel(R) UHD Graphics", DeviceKind::Integrated),
                                    fake_device(2, "NVIDIA GeForce RTX 4090", DeviceKind::Discrete),
                                    fake_device(3, "virgl", DeviceKind::Virtual)};
    EXPECT_EQ(select_device(devices, "").index, 2u);
    devices[2].unusable_reason = "Vulkan 1.1.0 < 1.2";
    EXPECT_EQ(select_device(devices, "").index, 1u);
    devices.erase(devices.begin() + 1, devices.begin() + 3);
    EXPECT_EQ(select_device(devices, "").index, 3u);
}

TEST(DeviceSelection, ByIndexOrCaseInsensitiveNameSubstring) {
    const std::vector<DeviceInfo> devices{fake_device(0, "llvmpipe (LLVM 15.0.6, 256 bits)", DeviceKind::Cpu),
                                          fake_device(1, "NVIDIA GeForce RTX 4090", DeviceKind::Discrete)};
    EXPECT_EQ(select_device(devices, "0").index, 0u);
    EXPECT_EQ(select_device(devices, "LLVMpipe").index, 0u);
    EXPECT_EQ(select_device(devices, "nvidia").index, 1u);
    const DeviceSelection none = select_device(devices, "radeon");
    EXPECT_FALSE(none.index);
    EXPECT_NE(none.reason.find("radeon"), std::string::npos) << none.reason;
    EXPECT_FALSE(select_device(devices, "7").index);
    EXPECT_FALSE(select_device({}, "").index);
}

// ---------------------------------------------------------------------------------------------
// Context

TEST_F(VulkanTest, ContextReportsDeviceAndLimits) {
    const DeviceInfo& info = ctx().info();
    EXPECT_FALSE(info.name.empty());
    EXPECT_GE(info.api_version, VK_API_VERSION_1_2);
    EXPECT_GT(info.max_storage_buffer_range, 0u);
    EXPECT_GE(info.max_compute_work_group_count[0], 65535u);
    EXPECT_GE(info.max_push_constants_size, 128u);
    ASSERT_TRUE(info.queue_family.has_value());
    if (info.timestamps_supported()) {
        EXPECT_GT(info.timestamp_period, 0.0f);
    }
    const auto devices = enumerate_devices();
    ASSERT_FALSE(devices.empty());
    EXPECT_TRUE(std::any_of(devices.begin(), devices.end(), [&](const DeviceInfo& d) { return d.name == info.name; }));
}

TEST_F(VulkanTest, ValidationIsOnAndCountsDeliberateMisuse) {
    ASSERT_TRUE(ctx().validation_enabled()) << "tests must run with the validation layer (SPECULA_VALIDATION=1)";
    std::vector<ValidationMessage> seen_by_handler;
    const ValidationCounts before = ctx().validation_counts();
    const auto messages = test::take_validation_messages([&] {
        // Misuse: a buffer with no usage flags (VUID-VkBufferCreateInfo-usage-requiredbitmask).
        const VkBufferCreateInfo info{.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO,
                                      .size = 256,
                                      .usage = 0,
                                      .sharingMode = VK_SHARING_MODE_EXCLUSIVE};
        VkBuffer raw = VK_NULL_HANDLE;
        if (vkCreateBuffer(ctx().device(), &info, nullptr, &raw) == VK_SUCCESS) UniqueBuffer(ctx().device(), raw).reset();
    });
    ASSERT_FALSE(messages.empty()) << "the validation layer did not report a buffer without usage flags";
    EXPECT_TRUE(std::any_of(messages.begin(), messages.end(), [](const ValidationMessage& m) {
        return m.severity == MessageSeverity::Error && m.id_name.find("usage") != std::string::npos;
    })) << messages.front().id_name;
    EXPECT_GT(ctx().validation_counts().errors, before.errors);
}

TEST_F(VulkanTest, SynchronizationValidationReportsAMissingBarrier) {
    const ComputePipeline probe = make_probe(ctx());
    Buffer out = Buffer::of<uint32_t>(ctx(), 1024, "sync hazard probe");
    const ProbePush push{.dispatch = {.element_base = 0, .element_count = 1024}, .tag = 1};
    const auto bytes = std::as_bytes(std::span<const ProbePush>(&push, 1));
    const auto messages = test::take_validation_messages([&] {
        // A shader write, then a transfer write of the same buffer with no barrier between.
        // (Layer 1.3.239 does not report two dispatches writing one storage buffer, so
        // the probe uses compute -> transfer, which it does report.)
        Sequence seq(ctx());
        seq.dispatch(probe, {out}, bytes, 16).fill(out, 0u);
        seq.barrier(Barrier::TransferToHost).submit_and_wait();
    });
    EXPECT_TRUE(std::any_of(messages.begin(), messages.end(), [](const ValidationMessage& m) {
        return m.id_name.find("SYNC-HAZARD-WRITE") != std::string::npos;
    })) << "synchronization validation is not on: " << messages.size() << " messages"
        << (messages.empty() ? std::string() : ", first: " + messages.front().id_name + ": " + messages.front().text);
}

// ---------------------------------------------------------------------------------------------
// Buffers

class BufferRoundTrip : public VulkanTest, public ::testing::WithParamInterface<BufferAccess> {};

TEST_P(BufferRoundTrip, UploadDownloadIsExact) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> dist(-1e6f, 1e6f);
    std::vector<float> data(100'003);
    for (float& v : data) v = dist(rng);
    Buffer buffer = Buffer::of<float>(ctx(), data.size(), "round trip", GetParam());
    EXPECT_EQ(buffer.mapped(), GetParam() == BufferAccess::Auto && ctx().info().host_visible_device_local);
    buffer.upload(data);
    EXPECT_EQ(buffer.download<float>(data.size()), data);
    // A sub-range at an offset, read back through a different range.
    const std::vector<float> patch{1.0f, 2.0f, 3.0f};
    buffer.upload(patch, 500);
    const auto back = buffer.download<float>(5, 499);
    EXPECT_EQ(back, (std::vector<float>{data[499], 1.0f, 2.0f, 3.0f, data[503]}));
    EXPECT_THROW(buffer.upload(patch, data.size() - 1), LimitError);
}

TEST_P(BufferRoundTrip, DispatchWritesAreVisibleAfterDownload) {
    const ComputePipeline probe = make_probe(ctx());
    const uint32_t count = 10'000;
    Buffer out = Buffer::of<uint32_t>(ctx(), count, "probe out", GetParam());
    Sequence seq(ctx());
    seq.fill(out, 0xFFFFFFFFu)
        .barrier(Barrier::TransferToCompute)
        .dispatch_1d(probe, {out}, count, ProbePush{.tag = 5})
        .barrier(Barrier::ComputeToHost)
        .submit_and_wait();
    const auto values = out.download<uint32_t>(count);
    for (uint32_t e = 0; e < count; ++e) ASSERT_EQ(values[e], probe_value(e, 5)) << "element " << e;
}

INSTANTIATE_TEST_SUITE_P(Access, BufferRoundTrip, ::testing::Values(BufferAccess::Auto, BufferAccess::Staged),
                         [](const auto& info) { return info.param == BufferAccess::Auto ? "Auto" : "Staged"; });

TEST_F(VulkanTest, BufferLargerThanMaxStorageBufferRangeIsRefusedByName) {
    const uint64_t range = ctx().info().max_storage_buffer_range;
    try {
        Buffer huge(ctx(), range + 4, "lsq3 oversized rows");
        FAIL() << "expected a LimitError";
    } catch (const LimitError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("lsq3 oversized rows"), std::string::npos) << what;
        EXPECT_NE(what.find("maxStorageBufferRange"), std::string::npos) << what;
    }
    EXPECT_THROW(Buffer(ctx(), 0, "empty"), LimitError);
}

// ---------------------------------------------------------------------------------------------
// Dispatch splitting

TEST_F(VulkanTest, DispatchBeyondMaxWorkGroupCountIsSplitAndCoversEveryElement) {
    const ComputePipeline probe = make_probe(ctx());
    // 65,535 groups of 64 is lavapipe's limit; larger limits (real GPUs) are capped to it
    // so that the test always needs two dispatches.
    const uint32_t max_groups = std::min<uint32_t>(ctx().info().max_compute_work_group_count[0], 65535u);
    const uint32_t count = max_groups * 64u + 1001u; // 4,195,241 on lavapipe
    const uint32_t guard = 64;                        // elements past the end that must stay untouched
    Buffer out = Buffer::of<uint32_t>(ctx(), count + guard, "split probe out");
    Sequence seq(ctx());
    seq.set_max_groups_per_dispatch(max_groups);
    seq.fill(out, 0xFFFFFFFFu)
        .barrier(Barrier::TransferToCompute)
        .dispatch_1d(probe, {out}, count, ProbePush{.tag = 0x1234u}, "probe")
        .barrier(Barrier::ComputeToHost)
        .submit_and_wait();
    EXPECT_EQ(seq.dispatch_count(), 2u);
    const auto values = out.download<uint32_t>(count + guard);
    std::size_t wrong = 0;
    for (uint32_t e = 0; e < count; ++e)
        if (values[e] != probe_value(e, 0x1234u) && wrong++ < 5) ADD_FAILURE() << "element " << e << ": " << values[e];
    EXPECT_EQ(wrong, 0u);
    for (uint32_t e = count; e < count + guard; ++e) EXPECT_EQ(values[e], 0xFFFFFFFFu) << "guard element " << e;
}

TEST_F(VulkanTest, ManySmallSplitsCoverEveryElementOnce) {
    const ComputePipeline probe = make_probe(ctx());
    const uint32_t count = 1000;
    Buffer out = Buffer::of<uint32_t>(ctx(), count + 64, "small split probe out");
    Sequence seq(ctx());
    seq.set_max_groups_per_dispatch(3); // 192 elements per split
    seq.fill(out, 0xFFFFFFFFu)
        .barrier(Barrier::TransferToCompute)
        .dispatch_1d(probe, {out}, count, ProbePush{.tag = 9})
        .barrier(Barrier::ComputeToHost)
        .submit_and_wait();
    EXPECT_EQ(seq.dispatch_count(), 6u);
    const auto values = out.download<uint32_t>(count + 64);
    for (uint32_t e = 0; e < count; ++e) ASSERT_EQ(values[e], probe_value(e, 9)) << "element " << e;
    for (uint32_t e = count; e < count + 64; ++e) ASSERT_EQ(values[e], 0xFFFFFFFFu) << "guard element " << e;
}

TEST_F(VulkanTest, SequenceCanBeResetAndReused) {
    const ComputePipeline probe = make_probe(ctx());
    Buffer out = Buffer::of<uint32_t>(ctx(), 256, "reuse probe out");
    Sequence seq(ctx());
    for (uint32_t round = 0; round < 3; ++round) {
        seq.reset();
        seq.dispatch_1d(probe, {out}, 256, ProbePush{.tag = round}).barrier(Barrier::ComputeToHost).submit_and_wait();
        EXPECT_EQ(out.download<uint32_t>(1, 17)[0], probe_value(17, round));
    }
    EXPECT_THROW(seq.barrier(Barrier::ComputeToCompute), Error); // recording after submit needs reset()
}

TEST_F(VulkanTest, PipelineRefusesTooManyPushConstantBytes) {
    EXPECT_THROW(ComputePipeline(ctx(), {.name = "too much push",
                                         .spirv = test_dispatch_probe_comp,
                                         .storage_buffers = 1,
                                         .push_constant_bytes = 132}),
                 LimitError);
}

// ---------------------------------------------------------------------------------------------
// Timestamps

TEST_F(VulkanTest, TimestampsAreFiniteAndNonNegativeOrReportedUnavailable) {
    const ComputePipeline probe = make_probe(ctx());
    const uint32_t count = 1 << 20;
    Buffer out = Buffer::of<uint32_t>(ctx(), count, "timed probe out");
    Sequence seq(ctx());
    seq.dispatch_1d(probe, {out}, count, ProbePush{.tag = 3}, "probe 1M")
        .barrier(Barrier::ComputeToCompute)
        .time_begin("two dispatches")
        .dispatch_1d(probe, {out}, count, ProbePush{.tag = 4})
        .barrier(Barrier::ComputeToCompute)
        .dispatch_1d(probe, {out}, count, ProbePush{.tag = 5})
        .time_end()
        .barrier(Barrier::ComputeToHost)
        .submit_and_wait();
    ASSERT_EQ(seq.timings().size(), 2u);
    EXPECT_EQ(seq.timings()[0].label, "probe 1M");
    for (const GpuTiming& t : seq.timings()) {
        if (ctx().info().timestamps_supported()) {
            ASSERT_TRUE(t.ns.has_value()) << t.label << ": " << t.note;
            EXPECT_TRUE(std::isfinite(*t.ns)) << t.label;
            EXPECT_GE(*t.ns, 0.0) << t.label;
            EXPECT_LT(*t.ns, 60e9) << t.label; // a minute: anything longer is garbage
        } else {
            EXPECT_FALSE(t.ns.has_value());
            EXPECT_NE(t.note.find("unavailable"), std::string::npos);
        }
    }
    EXPECT_EQ(out.download<uint32_t>(1, 99)[0], probe_value(99, 5));
}

} // namespace
} // namespace specula::gpu
