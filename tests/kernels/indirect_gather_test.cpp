// indirect_gather: Vulkan (float) against the C++ reference (double) on seeded random
// transfers (tests/indirect/random_transfer.h): empty rows, rows of hundreds of entries, a
// source that many rows reach, one frame and several, and the split into row chunks and frame
// batches (a lowered binding cap stands in for lavapipe's 128 MiB).
//
// Tolerance. Per output value and channel the kernel sums the n products w_k B_k of its row in
// float, in entry order; the reference sums the same products in double and rounds once. With
// every w_k and B_k >= 0, the float dot product is within gamma_n S of the exact sum S
// (gamma_n = n u / (1 - n u), u = 2^-24; Higham, "Accuracy and Stability of Numerical
// Algorithms", 3.1, with or without fused multiply-adds), and the reference within u S. Asserted:
//     |vk - ref| <= (n + 2) u S
// (the (1 - n u) and the reference's rounding fit in the 2 extra units for n u << 1). The
// printed ratio is the worst error in units of n u S: rounding errors of random sign grow
// like sqrt(n), so it stays far below 1. A split must not change any value: the chunks and
// batches sum each row in the same order, so the split run is compared bit for bit.
#include "indirect/transfer.h"

#include "gpu/vk_check.h"
#include "random_transfer.h"
#include "vulkan_env.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>

namespace specula {
namespace {

constexpr double kU = 0x1p-24; // float's unit roundoff

using IndirectGatherConformance = test::VulkanTest;

struct Outputs {
    std::vector<glm::vec4> ref, vk;
};

// Runs both and checks every value against the bound above; returns both outputs.
Outputs check(IndirectGatherVk& kernel, const IndirectTransfer& t, std::uint32_t frames, std::uint32_t seed,
              const char* what) {
    const std::vector<glm::vec4> b = test::random_radiosity(t.rows, frames, seed);
    Outputs o{std::vector<glm::vec4>(b.size(), glm::vec4(-1.0f)), std::vector<glm::vec4>(b.size(), glm::vec4(-1.0f))};
    gather_indirect_cpu(t, b, frames, o.ref);
    kernel.run(t, b, frames, o.vk);
    double worst = 0.0; // in units of n u S
    std::size_t max_n = 0, failures = 0;
    std::string first_failure;
    for (std::uint32_t f = 0; f < frames; ++f)
        for (std::uint32_t i = 0; i < t.rows; ++i) {
            const std::size_t at = std::size_t{f} * t.rows + i;
            const std::size_t n = t.row_begin[i + 1] - t.row_begin[i];
            max_n = std::max(max_n, n);
            for (int c = 0; c < 4; ++c) {
                double s = 0.0; // the exact sum S (every term >= 0), to double precision
                for (std::uint32_t k = t.row_begin[i]; c < 3 && k < t.row_begin[i + 1]; ++k)
                    s += double(t.entries[k].weight) * b[std::size_t{f} * t.rows + t.entries[k].source][c];
                // Empty rows and w: exactly 0.
                const double err = std::abs(double(o.vk[at][c]) - double(o.ref[at][c]));
                const bool ok = n == 0 || c == 3 ? o.vk[at][c] == 0.0f && o.ref[at][c] == 0.0f : err <= double(n + 2) * kU * s;
                if (!ok && failures++ == 0)
                    first_failure = "frame " + std::to_string(f) + " row " + std::to_string(i) + " channel " +
                                    std::to_string(c) + " (" + std::to_string(n) + " entries): vk " +
                                    std::to_string(o.vk[at][c]) + ", reference " + std::to_string(o.ref[at][c]);
                if (n > 0 && c < 3 && s > 0.0) worst = std::max(worst, err / (double(n) * kU * s));
            }
        }
    EXPECT_EQ(failures, 0u) << what << ": first at " << first_failure;
    std::printf("%s: %u rows, %zu entries (longest row %zu), %u frames: worst error %.3g n u S; %u row chunks, %u frame "
                "batches\n",
                what, t.rows, t.entry_count(), max_n, frames, worst, kernel.last_run().row_chunks,
                kernel.last_run().frame_batches);
    return o;
}

// The rows that reach `source`.
std::uint32_t rows_reaching(const IndirectTransfer& t, std::uint32_t source) {
    std::uint32_t n = 0;
    for (const TransferEntry& e : t.entries) n += e.source == source ? 1u : 0u;
    return n;
}

std::uint32_t empty_rows(const IndirectTransfer& t) {
    std::uint32_t n = 0;
    for (std::uint32_t i = 0; i < t.rows; ++i) n += t.row_begin[i] == t.row_begin[i + 1] ? 1u : 0u;
    return n;
}

TEST_F(IndirectGatherConformance, MatchesReferenceWithEmptyRowsAndASharedSource) {
    // K = 128, about 40 hits a row, 10% of the rows empty, particle 17 reached by ~25% of the rays.
    const IndirectTransfer t = test::random_transfer({.rows = 3000, .rays = 128, .hit_fraction = 0.3, .max_hits = 128,
                                                      .empty_rows = 0.1, .hub = 17, .hub_fraction = 0.25, .seed = 3});
    ASSERT_GT(empty_rows(t), 200u);
    ASSERT_GT(rows_reaching(t, 17), 2500u);
    IndirectGatherVk kernel(ctx());
    for (const std::uint32_t frames : {1u, 5u, 11u}) { // 11: one pass of 8 frames, then 3 of one
        (void)check(kernel, t, frames, 11 + frames, "shared source");
        EXPECT_EQ(kernel.last_run().row_chunks, 1u);
        EXPECT_EQ(kernel.last_run().frame_batches, 1u);
    }
}

TEST_F(IndirectGatherConformance, MatchesReferenceOnRowsOfHundredsOfEntries) {
    // K = 1024 rays, ~600 hits over 400 particles: ~310 distinct sources a row.
    const IndirectTransfer t =
        test::random_transfer({.rows = 400, .rays = 1024, .hit_fraction = 0.6, .max_hits = 1024, .seed = 5});
    std::uint32_t longest = 0;
    for (std::uint32_t i = 0; i < t.rows; ++i) longest = std::max(longest, t.row_begin[i + 1] - t.row_begin[i]);
    ASSERT_GT(longest, 300u);
    IndirectGatherVk kernel(ctx());
    (void)check(kernel, t, 1, 21, "long rows");
    (void)check(kernel, t, 3, 22, "long rows");
    (void)check(kernel, t, 16, 23, "long rows");
}

TEST_F(IndirectGatherConformance, MatchesReferenceOnEmptyAndDegenerateInputs) {
    IndirectGatherVk kernel(ctx());
    // Every row empty: all zeros.
    (void)check(kernel, test::random_transfer({.rows = 300, .empty_rows = 1.0}), 2, 31, "all rows empty");
    // One particle reaching itself with every ray.
    const IndirectTransfer one{.rows = 1, .rays_per_row = 1, .row_begin = {0, 1}, .entries = {{0, 1.0f}}};
    (void)check(kernel, one, 4, 32, "one particle");
    // No rows, no frames: nothing to do, nothing dispatched.
    const IndirectTransfer none{.rows = 0, .rays_per_row = 8, .row_begin = {0}, .entries = {}};
    kernel.run(none, {}, 3, {});
    EXPECT_EQ(kernel.last_run().row_chunks, 0u);
    kernel.run(one, {}, 0, {});
    EXPECT_EQ(kernel.last_run().frame_batches, 0u);
}

TEST_F(IndirectGatherConformance, SplitsRowsAndFramesWithinTheBindingCap) {
    const IndirectTransfer t = test::random_transfer({.rows = 2000, .rays = 256, .hit_fraction = 0.3, .max_hits = 256,
                                                      .empty_rows = 0.05, .hub = 3, .hub_fraction = 0.1, .seed = 7});
    constexpr std::uint32_t kFrames = 19;
    // One frame's radiosity is 2000 x 16 = 32,000 bytes: a 300,000-byte cap holds 9 frames (3
    // batches: 9, 9, 1; a pass of 8 frames and one of 1 in the first two) and 37,500 entries
    // (the ~140k entries go in 4 or more chunks).
    constexpr std::uint64_t kCap = 300000;
    IndirectGatherVk whole(ctx());
    IndirectGatherVk split(ctx(), kCap);
    const Outputs a = check(whole, t, kFrames, 41, "unsplit");
    EXPECT_EQ(whole.last_run().row_chunks, 1u);
    EXPECT_EQ(whole.last_run().frame_batches, 1u);
    const Outputs b = check(split, t, kFrames, 41, "split");
    EXPECT_EQ(split.last_run().frame_batches, 3u);
    EXPECT_GE(split.last_run().row_chunks, 4u);
    ASSERT_EQ(a.vk.size(), b.vk.size());
    EXPECT_EQ(std::memcmp(a.vk.data(), b.vk.data(), a.vk.size() * sizeof(glm::vec4)), 0) << "the split changed a value";
    // A cap of 4,000 bytes: one frame (200 x 16 bytes) a batch, ~3,000 entries in 6 or more chunks.
    const IndirectTransfer small =
        test::random_transfer({.rows = 200, .rays = 64, .hit_fraction = 0.25, .max_hits = 64, .seed = 9});
    IndirectGatherVk tiny(ctx(), 4000);
    (void)check(tiny, small, 3, 43, "tiny cap");
    EXPECT_EQ(tiny.last_run().frame_batches, 3u);
    EXPECT_GE(tiny.last_run().row_chunks, 6u);
}

TEST_F(IndirectGatherConformance, RefusesWhatNoSplitCanHold) {
    const IndirectTransfer t = test::random_transfer({.rows = 100, .rays = 64, .hit_fraction = 0.5, .max_hits = 64, .seed = 13});
    std::vector<glm::vec4> b(2 * t.rows), out(2 * t.rows);
    // One frame's radiosity (1,600 bytes) above the cap. (Nothing else can be: a row has at most
    // `rows` entries of 8 bytes, a chunk at most rows + 1 offsets of 4, both below a frame's 16 a row.)
    IndirectGatherVk narrow(ctx(), 1000);
    EXPECT_THROW(narrow.run(t, b, 2, out), gpu::LimitError);
    // And malformed inputs, as the reference.
    IndirectTransfer bad = t;
    bad.entries[5].weight = -1.0f;
    IndirectGatherVk kernel(ctx());
    EXPECT_THROW(kernel.run(bad, b, 2, out), Error);
    EXPECT_THROW(kernel.run(t, b, 3, out), Error);
}

} // namespace
} // namespace specula
