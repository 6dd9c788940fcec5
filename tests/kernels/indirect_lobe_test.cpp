// indirect_lobe: the directed lobe's first bounce (engine/indirect/lobe.h), Vulkan (float) and
// the C++ float path against the C++ reference (double), on seeded random transfers with entry
// directions and lights (tests/indirect/random_transfer.h): entries that leave their source
// from under its surface (v.w <= 0, some exactly 0), lights behind the source, unlit sources,
// empty rows, lafortune lobes (sharp and broad, N below 1 too) and coated materials (rough and
// sharp); frame counts on both sides of the kernel's block of 8 frames; the split into row
// chunks and frame batches (a lowered binding cap stands in for lavapipe's 128 MiB); the
// refusals.
//
// Tolerance. The float paths compute each term t = (pi w g) f_s(ci, co, cuv) I from float
// inputs; the reference computes it in double from the same inputs, so the float term's error
// comes from (u = 2^-24):
//  - ci = N.u and cuv = u.v, float dot products of unit vectors: within 3u each;
//  - f_s's own arithmetic. Lafortune, f = max(0, base)^N with base = Cx (cuv - ci co) + Cz ci co:
//    the inputs' errors and the products' and sums' roundings move base by at most
//    E = 16 u (|Cx| + |Cz|) (a and b are at most 2 in modulus), and x^N rises with x, so the
//    float f is within [P(base - E), P(base + E)] (P(x) = max(0, x)^N), times the power's own
//    error: GLSL's pow is exp2(N log2 x), log2 within 2^-21 absolute near 1 (3 ulp elsewhere),
//    exp2 within 3 + 2 |x| ulp (Vulkan spec, "Precision of GLSL.std.450 instructions"), so
//    N 2^-21 + (4 + 6 N |log2 x|) u relative. Coated: the microfacet terms are smooth in
//    (ci, cuv) away from the mirror peak of a near-zero alpha; their float evaluation is that
//    of exact ones at (ci, cuv) moved by at most ~8u (the inputs' 3u and the roundings of n.h
//    and of D's c^2 (alpha^2 - 1) + 1, carried back to ci and cuv), bounded by the largest
//    change of f_s over the 3 x 3 points (ci + a h, cuv + b h), a, b in {-1, 0, 1}, h = 16u
//    (twice that), plus 128u relative for its ~40 roundings (division 2.5 ulp, sqrt from
//    inversesqrt 2 ulp and a division in GLSL);
//  - the products pi w, (pi w) g, that times f_s, times I: 6u relative with pi's rounding;
//  - the sum of a row's n terms in float, in entry order, all >= 0: (n - 1) u times the sum of
//    the float terms (Higham 3.1), and the add to out and the reference's rounding: 2u of the result.
// Asserted per output value and channel: |float - reference| <= 1.01 sum_k d_k + (n + 1) u S' +
// 2u (out + S'), d_k the bound on term k's error above, S' the exact sum plus sum_k d_k. The
// printed ratio is the worst |error| / bound. It reaches ~0.9 where the added light is small
// against out's value (random_radiosity's, over four decades): there the float result and the
// reference's are two roundings of nearly the same value to float, which may differ by one ulp,
// up to 2u of it, the floor of any bound. Where the added light is at least out's value the
// ratio stays below 0.16 (the bound adds every error at its largest). A wrong lobe by 1e-4 (N or alpha times 1.0001) fails it on
// most values (TheBoundSeesAWrongLobe), so the bound cannot hide a wrong term. A split
// must not change any value: the chunks and batches sum each row in the same order, so the split
// run is compared bit for bit.
#include "indirect/lobe.h"

#include "core/error.h"
#include "gpu/vk_check.h"
#include "random_transfer.h"
#include "vulkan_env.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <random>
#include <string>

namespace specula {
namespace {

constexpr double kU = 0x1p-24; // float's unit roundoff

shared::MaterialGpu lafortune(glm::vec3 cx, glm::vec3 cz, glm::vec3 n) {
    return {.family = glm::uvec4(shared::kMaterialLafortune, 0, 0, 0), .a = glm::vec4(cx, 0.0f), .b = glm::vec4(cz, 0.0f),
            .c = glm::vec4(n, 0.0f)};
}
shared::MaterialGpu coated(float eta, float alpha, glm::vec3 tint) {
    return {.family = glm::uvec4(shared::kMaterialCoated, 0, 0, 0), .a = glm::vec4(eta, alpha, 0.0f, 0.0f),
            .b = glm::vec4(tint, 0.0f), .c = glm::vec4(0.0f)};
}

// A retro-reflective lobe peaked at N 8, 20 and 60; a broad forward lobe with N below 1 in red;
// a rough and a sharp coating.
struct NamedMaterial {
    const char* name;
    shared::MaterialGpu m;
};
const NamedMaterial kMaterials[] = {
    {"lafortune sharp", lafortune({-1.0f, -0.9f, -1.05f}, {0.95f, 0.9f, 1.0f}, {8.0f, 20.0f, 60.0f})},
    {"lafortune broad", lafortune({0.4f, -0.6f, 0.8f}, {0.9f, 0.7f, 0.5f}, {0.7f, 1.5f, 3.0f})},
    {"coated rough", coated(1.5f, 0.3f, {1.0f, 0.9f, 0.8f})},
    {"coated sharp", coated(1.8f, 0.05f, {0.7f, 1.0f, 0.9f})},
};

// Per channel: the bound on |float f_s - f_s| at (ci, co, cuv) (the tolerance above).
glm::dvec3 specular_error(const shared::MaterialGpu& m, double ci, double co, double cuv) {
    if (m.family.x == shared::kMaterialCoated) {
        const double eta = m.a.x, alpha = m.a.y;
        constexpr double h = 16 * kU;
        const double f = shared::f64::coated_specular(ci, co, cuv, alpha, eta);
        double change = 0.0;
        for (int a = -1; a <= 1; ++a)
            for (int b = -1; b <= 1; ++b)
                change = std::max(change, std::abs(shared::f64::coated_specular(ci + a * h, co, cuv + b * h, alpha, eta) - f));
        return glm::dvec3(glm::vec3(m.b)) * (change + 128 * kU * f);
    }
    glm::dvec3 err;
    for (int c = 0; c < 3; ++c) {
        const double cx = m.a[c], cz = m.b[c], n = m.c[c];
        EXPECT_GT(n, 0.0) << "the bracket needs a rising x^N";
        const double base = cx * (cuv - ci * co) + cz * ci * co;
        const double e = 16 * kU * (std::abs(cx) + std::abs(cz));
        const auto p = [n](double x) { return x > 0.0 ? std::pow(x, n) : 0.0; };
        const double f = p(base), hi = p(base + e), lo = p(base - e);
        const double log2x = base + e > 0.0 ? std::abs(std::log2(base + e)) : 0.0;
        err[c] = std::max(hi - f, f - lo) + (n * 0x1p-21 + (4 + 6 * n * log2x) * kU) * hi;
    }
    return err;
}

struct Inputs {
    IndirectTransfer t;
    test::RandomLobeInputs lobe;
    std::vector<glm::vec4> out0; // what the term is added to: >= 0, as a gathered irradiance (w kept)
    std::uint32_t frames = 0;
};

Inputs make_inputs(const test::RandomTransferOptions& transfer, std::uint32_t frames, std::uint32_t seed) {
    Inputs in{.t = test::random_transfer(transfer), .lobe = {}, .out0 = {}, .frames = frames};
    in.lobe = test::random_lobe_inputs(in.t, frames, {}, seed);
    in.out0 = test::random_radiosity(in.t.rows, frames, seed + 1);
    for (std::size_t k = 0; k < in.out0.size(); ++k) in.out0[k].w = static_cast<float>(k % 3); // w must come back as it was
    return in;
}

using Path = std::function<void(std::span<glm::vec4>)>;

struct Checked {
    std::vector<glm::vec4> out;
    std::size_t failures = 0;
};

// Runs `path` on a copy of out0 and checks every value against the bound above, and the
// reference (add_directed_lobe_cpu) against this loop's own exact sums; returns the output.
Checked check(const Inputs& in, const shared::MaterialGpu& m, const Path& path, const std::string& what) {
    const IndirectTransfer& t = in.t;
    const std::uint32_t frames = in.frames;
    const std::size_t rows = t.rows;
    std::vector<glm::vec4> ref = in.out0;
    add_directed_lobe_cpu(t, m, in.lobe.row_normal, in.lobe.light_geometry, in.lobe.intensity, frames, ref);
    Checked c{in.out0, 0};
    path(c.out);
    double worst = 0.0, worst_lobe = 0.0; // the latter where the added light is at least out's value
    std::size_t lit = 0, reference_failures = 0;
    std::string first_failure;
    std::vector<glm::dvec3> sum(frames), bound_terms(frames);
    std::vector<std::uint32_t> terms(frames);
    for (std::size_t i = 0; i < rows; ++i) {
        std::fill(sum.begin(), sum.end(), glm::dvec3(0.0));
        std::fill(bound_terms.begin(), bound_terms.end(), glm::dvec3(0.0));
        std::fill(terms.begin(), terms.end(), 0u);
        for (std::uint32_t k = t.row_begin[i]; k < t.row_begin[i + 1]; ++k) {
            const glm::dvec4 v(t.entry_direction[k]);
            if (!(v.w > 0.0)) continue;
            const std::uint32_t j = t.entries[k].source;
            const glm::dvec3 normal(in.lobe.row_normal[j]);
            for (std::uint32_t f = 0; f < frames; ++f) {
                const glm::dvec4 l(in.lobe.light_geometry[std::size_t{j} * frames + f]);
                const double ci = glm::dot(normal, glm::dvec3(l));
                if (!(l.w > 0.0) || !(ci > 0.0)) continue;
                const double cuv = glm::dot(glm::dvec3(l), glm::dvec3(v));
                const glm::dvec3 amp = kPi * double(t.entries[k].weight) * l.w * glm::dvec3(in.lobe.intensity[f]);
                const glm::dvec3 fs = glm::max(shared::f64::material_specular(m, ci, v.w, cuv), glm::dvec3(0.0));
                const glm::dvec3 d = amp * specular_error(m, ci, v.w, cuv);
                sum[f] += amp * fs;
                bound_terms[f] += d + 6 * kU * (amp * fs + d);
                ++terms[f];
            }
        }
        for (std::uint32_t f = 0; f < frames; ++f) {
            const std::size_t at = f * rows + i;
            lit += sum[f].x + sum[f].y + sum[f].z > 0.0 ? 1 : 0;
            for (int ch = 0; ch < 4; ++ch) {
                const double out0 = in.out0[at][ch];
                if (ch == 3) { // w: kept as it was
                    if (c.out[at].w != in.out0[at].w || ref[at].w != in.out0[at].w) ++reference_failures;
                    continue;
                }
                const double exact = out0 + sum[f][ch];
                // The reference: the exact sum, rounded once (to within a double's rounding of its sum).
                if (std::abs(double(ref[at][ch]) - exact) > kU * exact * (1 + 1e-9) && reference_failures++ == 0)
                    ADD_FAILURE() << what << ": the reference is off at frame " << f << " row " << i << " channel " << ch
                                  << ": " << ref[at][ch] << " against " << exact;
                const double s = sum[f][ch] + bound_terms[f][ch];
                const double bound = 1.01 * bound_terms[f][ch] + double(terms[f] + 1) * kU * s + 2 * kU * (out0 + s);
                const double err = std::abs(double(c.out[at][ch]) - double(ref[at][ch]));
                if (bound > 0.0) worst = std::max(worst, err / bound);
                if (bound > 0.0 && sum[f][ch] >= out0) worst_lobe = std::max(worst_lobe, err / bound);
                if (err > bound && c.failures++ == 0)
                    first_failure = "frame " + std::to_string(f) + " row " + std::to_string(i) + " channel " +
                                    std::to_string(ch) + " (" + std::to_string(terms[f]) + " terms): " +
                                    std::to_string(c.out[at][ch]) + ", reference " + std::to_string(ref[at][ch]) +
                                    ", bound " + std::to_string(bound);
            }
        }
    }
    EXPECT_EQ(reference_failures, 0u) << what;
    std::printf("%s: %u rows, %zu entries, %u frames, %.0f%% of the values lit: worst error %.3g of the bound (%.3g where "
                "the lobe's light is at least out's), %zu failures%s%s\n",
                what.c_str(), t.rows, t.entry_count(), frames,
                100.0 * double(lit) / double(std::max<std::size_t>(rows * frames, 1)), worst, worst_lobe, c.failures,
                c.failures > 0 ? ", first at " : "", first_failure.c_str());
    // Not vacuous: most values get lobe light (a tenth of the entries leave from under their
    // source, a fifth of the lights are behind it, a tenth of the sources unlit, some rows empty).
    if (rows * frames >= 100 && t.entry_count() > 0) {
        EXPECT_GT(lit, rows * frames / 2) << what;
    }
    return c;
}

Path float_path(const Inputs& in, const shared::MaterialGpu& m) {
    return [&in, m](std::span<glm::vec4> out) {
        add_directed_lobe_float(in.t, m, in.lobe.row_normal, in.lobe.light_geometry, in.lobe.intensity, in.frames, out);
    };
}
Path vulkan_path(IndirectLobeVk& kernel, const Inputs& in, const shared::MaterialGpu& m) {
    return [&kernel, &in, m](std::span<glm::vec4> out) {
        kernel.run(in.t, m, in.lobe.row_normal, in.lobe.light_geometry, in.lobe.intensity, in.frames, out);
    };
}

const test::RandomTransferOptions kTransfer{.rows = 3000, .rays = 64, .hit_fraction = 0.5, .max_hits = 64,
                                            .empty_rows = 0.05, .hub = 17, .hub_fraction = 0.1, .seed = 3};

// The C++ float path's two ways for the lafortune family: 8 frames at a time where the
// processor allows it (detail::lobe_simd), and one at a time. Restores the setting.
struct SimdWays {
    const bool had = detail::lobe_simd();
    ~SimdWays() { detail::set_lobe_simd(had); }
    // Each way this machine has, by name, turned on in turn.
    std::vector<std::pair<bool, std::string>> ways() const {
        std::vector<std::pair<bool, std::string>> w{{false, "one frame at a time"}};
        detail::set_lobe_simd(true);
        if (detail::lobe_simd()) w.emplace_back(true, "8 frames at a time");
        return w;
    }
};

// The reference and both float paths, without Vulkan: runs wherever the tests build. Frame
// counts below, at and above 8 (the padded lanes of the 8-wide way).
TEST(IndirectLobeCpu, FloatPathWithinTheBoundOfTheReference) {
    const SimdWays simd;
    for (const auto& [on, way] : simd.ways()) {
        detail::set_lobe_simd(on);
        for (const std::uint32_t frames : {1u, 5u, 8u, 11u}) {
            const Inputs in = make_inputs(kTransfer, frames, 100 + frames);
            for (const NamedMaterial& nm : kMaterials)
                EXPECT_EQ(check(in, nm.m, float_path(in, nm.m), std::string("cpu float, ") + nm.name + ", " + way).failures, 0u);
        }
    }
}

TEST(IndirectLobeCpu, TheBoundSeesAWrongLobe) {
    const SimdWays simd;
    const Inputs in = make_inputs(kTransfer, 3, 7);
    for (const auto& [on, way] : simd.ways()) {
        detail::set_lobe_simd(on);
        for (const NamedMaterial& nm : {kMaterials[0], kMaterials[2]}) {
            shared::MaterialGpu wrong = nm.m;
            if (wrong.family.x == shared::kMaterialCoated) wrong.a.y *= 1.0001f; // alpha
            else wrong.c *= 1.0001f;                                            // N
            const Checked c = check(in, nm.m, float_path(in, wrong), std::string("a wrong lobe, ") + nm.name + ", " + way);
            EXPECT_GT(c.failures, in.t.rows * in.frames / 4) << nm.name << ", " << way;
        }
    }
}

TEST(IndirectLobeCpu, ZeroMaterialAddsNothing) {
    const Inputs in = make_inputs(kTransfer, 3, 9);
    std::vector<glm::vec4> out = in.out0;
    const shared::MaterialGpu zero{};
    add_directed_lobe_float(in.t, zero, in.lobe.row_normal, in.lobe.light_geometry, in.lobe.intensity, in.frames, out);
    EXPECT_EQ(std::memcmp(out.data(), in.out0.data(), out.size() * sizeof(glm::vec4)), 0);
    add_directed_lobe_cpu(in.t, zero, in.lobe.row_normal, in.lobe.light_geometry, in.lobe.intensity, in.frames, out);
    EXPECT_EQ(std::memcmp(out.data(), in.out0.data(), out.size() * sizeof(glm::vec4)), 0);
}

// One implementation of the term with its material fixed: (transfer, row_normal, light_geometry,
// intensity, frames, out).
using Runner = std::function<void(const IndirectTransfer&, std::span<const glm::vec3>, std::span<const glm::vec4>,
                                  std::span<const glm::vec3>, std::uint32_t, std::span<glm::vec4>)>;
using Normals = std::span<const glm::vec3>;
using Geometry = std::span<const glm::vec4>;

// Every input of the wrong size, and a transfer without entry directions, is refused by name.
void expect_refusals(const Runner& run, const char* who) {
    Inputs in = make_inputs({.rows = 50, .rays = 16, .hit_fraction = 0.5, .max_hits = 16, .seed = 11}, 3, 12);
    const test::RandomLobeInputs& l = in.lobe;
    std::vector<glm::vec4> out = in.out0;
    const auto refused = [&](const std::function<void()>& fn, const std::string& field) {
        try {
            fn();
            ADD_FAILURE() << who << ": a wrong " << field << " was accepted";
        } catch (const gpu::LimitError& e) {
            ADD_FAILURE() << who << ": a wrong " << field << " throws a LimitError: " << e.what();
        } catch (const Error& e) {
            const std::string message = e.what();
            EXPECT_NE(message.find(field), std::string::npos) << who << ": " << message;
            EXPECT_NE(message.find(who), std::string::npos) << message;
        }
    };
    const std::span<glm::vec4> all(out);
    refused([&] { run(in.t, std::span(l.row_normal).first(49), l.light_geometry, l.intensity, 3, all); }, "row_normal");
    refused([&] { run(in.t, l.row_normal, std::span(l.light_geometry).first(149), l.intensity, 3, all); }, "light_geometry");
    refused([&] { run(in.t, l.row_normal, l.light_geometry, std::span(l.intensity).first(2), 3, all); }, "intensity");
    refused([&] { run(in.t, l.row_normal, l.light_geometry, l.intensity, 3, all.first(149)); }, "out");
    // frames disagreeing with every size: the first field checked is named.
    refused([&] { run(in.t, l.row_normal, l.light_geometry, l.intensity, 2, all); }, "light_geometry");
    IndirectTransfer bare = in.t;
    bare.entry_direction.clear();
    refused([&] { run(bare, l.row_normal, l.light_geometry, l.intensity, 3, all); }, "entry directions");
    // A malformed transfer, as the gather's checks say (validate_transfer's message).
    IndirectTransfer bad = in.t;
    bad.entries[3].weight = -1.0f;
    EXPECT_THROW(run(bad, l.row_normal, l.light_geometry, l.intensity, 3, all), Error) << who;
}

TEST(IndirectLobeCpu, RefusesMismatchedSizes) {
    const shared::MaterialGpu m = kMaterials[0].m;
    expect_refusals([&](const IndirectTransfer& t, Normals n, Geometry g, Normals i, std::uint32_t f,
                        std::span<glm::vec4> o) { add_directed_lobe_cpu(t, m, n, g, i, f, o); },
                    "add_directed_lobe_cpu");
    expect_refusals([&](const IndirectTransfer& t, Normals n, Geometry g, Normals i, std::uint32_t f,
                        std::span<glm::vec4> o) { add_directed_lobe_float(t, m, n, g, i, f, o); },
                    "add_directed_lobe_float");
}

using IndirectLobeConformance = test::VulkanTest;

TEST_F(IndirectLobeConformance, MatchesReferenceOnEveryMaterialAndFrameCount) {
    IndirectLobeVk kernel(ctx());
    // 1, 5: the one-at-a-time loop alone; 8, 16: blocks alone; 13: both.
    for (const std::uint32_t frames : {1u, 5u, 8u, 13u, 16u}) {
        const Inputs in = make_inputs(kTransfer, frames, 200 + frames);
        for (const NamedMaterial& nm : kMaterials) {
            const std::string what = std::string("vulkan, ") + nm.name;
            EXPECT_EQ(check(in, nm.m, vulkan_path(kernel, in, nm.m), what).failures, 0u) << what << ", " << frames << " frames";
            EXPECT_EQ(kernel.last_run().row_chunks, 1u);
            EXPECT_EQ(kernel.last_run().frame_batches, 1u);
            if (frames == 13) {
                EXPECT_EQ(check(in, nm.m, float_path(in, nm.m), std::string("cpu float, ") + nm.name).failures, 0u);
            }
        }
    }
}

TEST_F(IndirectLobeConformance, ZeroMaterialAddsNothing) {
    const Inputs in = make_inputs(kTransfer, 6, 21);
    std::vector<glm::vec4> out = in.out0;
    IndirectLobeVk kernel(ctx());
    kernel.run(in.t, shared::MaterialGpu{}, in.lobe.row_normal, in.lobe.light_geometry, in.lobe.intensity, in.frames, out);
    EXPECT_EQ(std::memcmp(out.data(), in.out0.data(), out.size() * sizeof(glm::vec4)), 0);
}

TEST_F(IndirectLobeConformance, SplitsRowsAndFramesWithinTheBindingCap) {
    const Inputs in = make_inputs({.rows = 2000, .rays = 64, .hit_fraction = 0.5, .max_hits = 64, .empty_rows = 0.05,
                                   .hub = 3, .hub_fraction = 0.1, .seed = 7},
                                  19, 31);
    const shared::MaterialGpu m = kMaterials[0].m;
    // One frame's light geometry is 2000 x 16 = 32,000 bytes: a 300,000-byte cap holds 9 frames
    // (3 batches: 9, 9, 1; a block of 8 and one frame in the first two) and 18,750 entries'
    // directions (the ~56k entries go in 4 chunks).
    IndirectLobeVk whole(ctx());
    IndirectLobeVk split(ctx(), 300000);
    const Checked a = check(in, m, vulkan_path(whole, in, m), "unsplit");
    EXPECT_EQ(a.failures, 0u);
    EXPECT_EQ(whole.last_run().row_chunks, 1u);
    EXPECT_EQ(whole.last_run().frame_batches, 1u);
    const Checked b = check(in, m, vulkan_path(split, in, m), "split");
    EXPECT_EQ(b.failures, 0u);
    EXPECT_EQ(split.last_run().frame_batches, 3u);
    EXPECT_GE(split.last_run().row_chunks, 3u);
    // A split changes no value: every row's terms are summed in the same order.
    ASSERT_EQ(a.out.size(), b.out.size());
    EXPECT_EQ(std::memcmp(a.out.data(), b.out.data(), a.out.size() * sizeof(glm::vec4)), 0) << "the split changed a value";
    // A cap of 4,000 bytes on 200 rows: one frame (200 x 16 bytes) a batch, 250 directions a chunk.
    const Inputs small = make_inputs({.rows = 200, .rays = 64, .hit_fraction = 0.5, .max_hits = 64, .seed = 9}, 5, 33);
    IndirectLobeVk tiny(ctx(), 4000);
    EXPECT_EQ(check(small, kMaterials[2].m, vulkan_path(tiny, small, kMaterials[2].m), "tiny cap").failures, 0u);
    EXPECT_EQ(tiny.last_run().frame_batches, 5u);
    EXPECT_GE(tiny.last_run().row_chunks, 20u);
}

TEST_F(IndirectLobeConformance, HandlesEmptyAndDegenerateInputs) {
    IndirectLobeVk kernel(ctx());
    const shared::MaterialGpu m = kMaterials[1].m;
    // Every row empty: out unchanged.
    const Inputs empty = make_inputs({.rows = 300, .empty_rows = 1.0}, 2, 41);
    EXPECT_EQ(check(empty, m, vulkan_path(kernel, empty, m), "all rows empty").failures, 0u);
    // No rows, no frames: nothing to do, nothing dispatched.
    const IndirectTransfer none{.rows = 0, .rays_per_row = 8, .row_begin = {0}, .entries = {}};
    kernel.run(none, m, {}, {}, std::vector<glm::vec3>(3), 3, {});
    EXPECT_EQ(kernel.last_run().row_chunks, 0u);
    kernel.run(empty.t, m, empty.lobe.row_normal, {}, {}, 0, {});
    EXPECT_EQ(kernel.last_run().frame_batches, 0u);
}

TEST_F(IndirectLobeConformance, RefusesWhatNoSplitCanHoldAndMismatchedSizes) {
    const Inputs in = make_inputs({.rows = 100, .rays = 64, .hit_fraction = 0.5, .max_hits = 64, .seed = 13}, 2, 51);
    const shared::MaterialGpu m = kMaterials[0].m;
    std::vector<glm::vec4> out = in.out0;
    // One frame's light geometry (1,600 bytes) above the cap. (Nothing else can be: a row has at
    // most `rows` entries, whose directions are 16 bytes each, as a frame's light geometry a row.)
    IndirectLobeVk narrow(ctx(), 1000);
    EXPECT_THROW(narrow.run(in.t, m, in.lobe.row_normal, in.lobe.light_geometry, in.lobe.intensity, 2, out), gpu::LimitError);
    IndirectLobeVk kernel(ctx());
    expect_refusals([&](const IndirectTransfer& t, Normals n, Geometry g, Normals i, std::uint32_t f,
                        std::span<glm::vec4> o) { kernel.run(t, m, n, g, i, f, o); },
                    "indirect_lobe");
}

} // namespace
} // namespace specula
