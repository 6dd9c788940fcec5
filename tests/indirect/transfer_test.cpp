// The transfer matrix's checks (validate_transfer, validate_gather) and the gather's C++
// reference on a matrix small enough to sum by hand.
#include "indirect/transfer.h"
#include "random_transfer.h"

#include "core/error.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <vector>

namespace specula {
namespace {

// Three particles, K = 4 rays each:
//   row 0: two rays reach particle 1, one reaches particle 2  -> {1: 0.5, 2: 0.25}
//   row 1: every ray leaves the object                         -> {}
//   row 2: one ray reaches particle 0, three reach particle 1  -> {0: 0.25, 1: 0.75}
IndirectTransfer hand_made() {
    IndirectTransfer t;
    t.rows = 3;
    t.rays_per_row = 4;
    t.row_begin = {0, 2, 2, 4};
    t.entries = {{1, 0.5f}, {2, 0.25f}, {0, 0.25f}, {1, 0.75f}};
    return t;
}

// The Error that fn throws (a failure when it throws nothing or something else).
std::string error_of(const std::function<void()>& fn) {
    try {
        fn();
    } catch (const Error& e) {
        return e.what();
    } catch (const std::exception& e) {
        ADD_FAILURE() << "expected an Error, got: " << e.what();
        return {};
    }
    ADD_FAILURE() << "expected an Error, nothing was thrown";
    return {};
}

void expect_refused(const IndirectTransfer& t, const std::string& naming) {
    const std::string what = error_of([&] { validate_transfer(t); });
    EXPECT_NE(what.find(naming), std::string::npos) << "message: " << what << "\nshould name: " << naming;
}

TEST(IndirectTransfer, AcceptsWellFormedMatrices) {
    EXPECT_NO_THROW(validate_transfer(hand_made()));
    EXPECT_NO_THROW(validate_transfer(IndirectTransfer{.rows = 0, .rays_per_row = 0, .row_begin = {0}, .entries = {}}));
    // A row of exactly 1 (every ray hits), and 1 plus float rounding.
    IndirectTransfer t = hand_made();
    t.entries[2].weight = 0.25f;
    t.entries[3].weight = 0.75f + 1e-6f;
    EXPECT_NO_THROW(validate_transfer(t));
}

TEST(IndirectTransfer, RefusesMalformedMatrices) {
    {
        IndirectTransfer t = hand_made();
        t.row_begin.pop_back();
        expect_refused(t, "row_begin holds 3 offsets, 3 rows need 4");
    }
    {
        IndirectTransfer t = hand_made();
        t.row_begin = {1, 2, 2, 4};
        expect_refused(t, "row_begin[0] is 1");
    }
    {
        IndirectTransfer t = hand_made();
        t.entries.push_back({2, 0.1f});
        expect_refused(t, "row_begin[3] is 4, but there are 5 entries");
    }
    {
        IndirectTransfer t = hand_made();
        t.row_begin = {0, 3, 2, 4};
        expect_refused(t, "row_begin falls at row 1 (3 then 2)");
    }
    {
        IndirectTransfer t = hand_made();
        t.entries[1].source = 3;
        expect_refused(t, "row 0, entry 1: source 3 out of range (3 rows)");
    }
    {
        IndirectTransfer t = hand_made();
        t.entries[3].source = 0; // the same source twice
        expect_refused(t, "row 2, entry 3: source 0 not above the previous entry's 0");
    }
    {
        IndirectTransfer t = hand_made();
        std::swap(t.entries[0], t.entries[1]); // sources falling
        expect_refused(t, "row 0, entry 1: source 1 not above the previous entry's 2");
    }
    for (const float bad : {-0.25f, std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity()}) {
        IndirectTransfer t = hand_made();
        t.entries[2].weight = bad;
        expect_refused(t, "row 2, entry 2: weight");
        expect_refused(t, "is not a finite value >= 0");
    }
    {
        IndirectTransfer t = hand_made();
        t.entries[3].weight = 0.76f;
        expect_refused(t, "row 2: weights sum to 1.01");
    }
    {
        IndirectTransfer t = hand_made();
        t.row_of = {0, 2, 1, 2, 0};
        EXPECT_NO_THROW(validate_transfer(t));
        t.row_of[3] = 3;
        expect_refused(t, "particle 3: row 3 out of range (3 rows)");
    }
    {
        IndirectTransfer t = hand_made();
        t.entry_direction.assign(t.entries.size(), glm::vec4(0.0f, 0.0f, 1.0f, 0.5f));
        EXPECT_NO_THROW(validate_transfer(t));
        t.entry_direction[2] = glm::vec4(0.0f, 0.0f, 2.0f, 0.5f);
        expect_refused(t, "row 2, entry 2: direction (0.000000, 0.000000, 2.000000) with cosine 0.500000 is not a unit vector");
        t.entry_direction[2] = glm::vec4(0.0f, 0.0f, 1.0f, std::numeric_limits<float>::quiet_NaN());
        expect_refused(t, "row 2, entry 2: direction");
        t.entry_direction.pop_back();
        expect_refused(t, "3 entry directions for 4 entries");
    }
}

TEST(IndirectTransfer, GatherChecksItsSpans) {
    const IndirectTransfer t = hand_made();
    std::vector<glm::vec4> b(6), out(6);
    EXPECT_NO_THROW(gather_indirect_cpu(t, b, 2, out));
    const std::string what = error_of([&] { gather_indirect_cpu(t, std::span(b).first(5), 2, out); });
    EXPECT_NE(what.find("gather_indirect_cpu: 2 frames of 3 particles need 6 radiosity and output values, got 5 and 6"),
              std::string::npos)
        << what;
    (void)error_of([&] { gather_indirect_cpu(t, b, 2, std::span(out).first(3)); });
    (void)error_of([&] { gather_indirect_cpu(t, b, 3, out); });
    IndirectTransfer bad = t;
    bad.entries[0].source = 7;
    EXPECT_NE(error_of([&] { gather_indirect_cpu(bad, b, 2, out); }).find("source 7 out of range"), std::string::npos);
}

// Two frames; radiosity B (rgb; w must be ignored):
//   frame 0: B0 = (1, 2, 4), B1 = (8, 0, 2), B2 = (4, 4, 0)
//   frame 1: B0 = (0.5, 0, 1), B1 = (0, 16, 2), B2 = (2, 1, 3)
// E_0 = 0.5 B1 + 0.25 B2,  E_1 = 0,  E_2 = 0.25 B0 + 0.75 B1:
//   frame 0: E_0 = (4 + 1, 0 + 1, 1 + 0) = (5, 1, 1)
//            E_2 = (0.25 + 6, 0.5 + 0, 1 + 1.5) = (6.25, 0.5, 2.5)
//   frame 1: E_0 = (0 + 0.5, 8 + 0.25, 1 + 0.75) = (0.5, 8.25, 1.75)
//            E_2 = (0.125 + 0, 0 + 12, 0.25 + 1.5) = (0.125, 12, 1.75)
// (every product and sum is exact in float and double).
// The float gather the pipeline runs on the CPU against the reference: every value within the
// bound of a float sum of n non-negative terms, (n + 2) 2^-24 S (the kernel's bound,
// tests/kernels/indirect_gather_test.cpp), on rows of 0 to 300 entries, for 1 and 11 frames.
TEST(IndirectTransfer, FloatGatherStaysWithinTheBoundOfAFloatSum) {
    const IndirectTransfer t = test::random_transfer(
        {.rows = 3000, .rays = 300, .hit_fraction = 0.3, .min_hits = 0, .max_hits = 300, .empty_rows = 0.05, .seed = 7});
    for (const std::uint32_t frames : {1u, 11u}) {
        const std::vector<glm::vec4> b = test::random_radiosity(t.rows, frames, 3);
        std::vector<glm::vec4> ref(b.size(), glm::vec4(-1.0f)), fast(b.size(), glm::vec4(-1.0f));
        gather_indirect_cpu(t, b, frames, ref);
        gather_indirect_float(t, b, frames, fast, 3);
        std::size_t failures = 0;
        for (std::uint32_t f = 0; f < frames; ++f)
            for (std::uint32_t i = 0; i < t.rows; ++i) {
                const std::size_t at = std::size_t{f} * t.rows + i, n = t.row_begin[i + 1] - t.row_begin[i];
                for (int c = 0; c < 3; ++c) {
                    double sum = 0.0;
                    for (std::uint32_t k = t.row_begin[i]; k < t.row_begin[i + 1]; ++k)
                        sum += double(t.entries[k].weight) * b[std::size_t{f} * t.rows + t.entries[k].source][c];
                    if (std::abs(double(fast[at][c]) - double(ref[at][c])) > double(n + 2) * 0x1p-24 * sum) ++failures;
                }
                if (fast[at].w != 0.0f) ++failures;
            }
        EXPECT_EQ(failures, 0u) << frames << " frames";
    }
}

TEST(IndirectTransfer, GatherOnAHandMadeMatrix) {
    const IndirectTransfer t = hand_made();
    const std::vector<glm::vec4> b = {{1, 2, 4, 9}, {8, 0, 2, 9}, {4, 4, 0, 9}, {0.5f, 0, 1, 9}, {0, 16, 2, 9}, {2, 1, 3, 9}};
    const std::vector<glm::vec4> want = {{5, 1, 1, 0},      {0, 0, 0, 0}, {6.25f, 0.5f, 2.5f, 0},
                                         {0.5f, 8.25f, 1.75f, 0}, {0, 0, 0, 0}, {0.125f, 12, 1.75f, 0}};
    for (const unsigned threads : {1u, 2u, 5u}) {
        std::vector<glm::vec4> out(6, glm::vec4(-1.0f));
        gather_indirect_cpu(t, b, 2, out, threads);
        for (std::size_t i = 0; i < out.size(); ++i)
            for (int c = 0; c < 4; ++c) EXPECT_EQ(out[i][c], want[i][c]) << "value " << i << " channel " << c;
    }
    // One frame: the first frame's values.
    std::vector<glm::vec4> one(3);
    gather_indirect_cpu(t, std::span(b).first(3), 1, one);
    for (std::size_t i = 0; i < 3; ++i) EXPECT_EQ(one[i], want[i]) << "value " << i;
}

} // namespace
} // namespace specula
