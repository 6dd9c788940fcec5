// lsq3_solve: known truth (constructed systems), status handling, and CPU (double)
// vs Vulkan (float) conformance on a realistic mixed input.
//
// Tolerance, stated once (solve3.h): for an element solved in float with K rows
// and reciprocal condition rcond of the Jacobi-scaled normal matrix C, perturbation
// theory for C x = y gives
//     |x_vk - x_ref| / |x_ref|  <=  cond_2(C) * (relative perturbation of C and y)
// where accumulating K rows in float perturbs C and y by at most ~(K + 8) eps32
// (K additions plus the scaling, the LDL^T factorization and the substitutions), and
// cond_2(C) <= 3 / rcond (solve3.h). x = D^1/2 g are the unknowns in data units
// (D = diag(M)), so the test measures errors in that norm and allows
//     |D^1/2 (g_vk - g_ref)|  <=  kSafety * (K + 8) * eps32 * 3 / rcond * |D^1/2 g_ref|,
// with kSafety = 4 for the rounding of inputs and outputs. The CPU reference
// (double) contributes ~1e-16 relative and is treated as exact. rcond itself is
// 3 det(C) / (|C|_F |adj C|_F); a perturbation dC moves det(C) by at most
// |adj C|_F |dC|_F, so |rcond_vk - rcond_ref| <= 3 |dC|_F / |C|_F, which the test
// allows as 3 * kSafety * (K + 8) * eps32 (absolute).
#include "gpu/kernels/lsq3_solve.h"
#include "vulkan_env.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <random>

namespace specula::gpu {
namespace {

constexpr double kEps32 = 5.96e-8; // 2^-24
constexpr double kSafety = 4.0;
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();

struct Problem {
    std::vector<uint32_t> offsets{0};
    std::vector<Lsq3Row> rows;
    std::vector<glm::dvec3> truth; // g used to make b (meaningful for well-posed elements)

    void add(const std::vector<Lsq3Row>& element, glm::dvec3 g = {}) {
        rows.insert(rows.end(), element.begin(), element.end());
        offsets.push_back(static_cast<uint32_t>(rows.size()));
        truth.push_back(g);
    }
    [[nodiscard]] Lsq3Inputs inputs() const { return {offsets, rows}; }
    [[nodiscard]] std::size_t size() const { return truth.size(); }
};

Lsq3Row row(glm::dvec3 a, double b, double w = 1.0) {
    return {static_cast<float>(a.x), static_cast<float>(a.y), static_cast<float>(a.z), static_cast<float>(b),
            static_cast<float>(w)};
}

// A row of a photometric-stereo system: light direction u around the normal n,
// irradiance factor I/d^2, pixel value b = a.g (+ noise).
glm::dvec3 random_unit(std::mt19937& rng) {
    std::normal_distribution<double> n(0.0, 1.0);
    glm::dvec3 v(n(rng), n(rng), n(rng));
    return glm::normalize(v);
}

glm::dvec3 hemisphere_dir(std::mt19937& rng, glm::dvec3 n) {
    glm::dvec3 u = random_unit(rng);
    if (glm::dot(u, n) < 0.0) u = -u;
    return u;
}

// Per-element quantities the tolerance needs, from the rows in double.
struct Scale {
    glm::dvec3 sqrt_diag; // D^1/2
};
Scale element_scale(std::span<const Lsq3Row> rows) {
    glm::dvec3 d(0.0);
    for (const auto& r : rows) {
        if (!(r.w > 0.0f)) continue;
        const glm::dvec3 a(r.a_x, r.a_y, r.a_z);
        d += static_cast<double>(r.w) * a * a;
    }
    return {glm::sqrt(d)};
}

glm::dvec3 g_of(const Lsq3Result& r) { return {r.g_x, r.g_y, r.g_z}; }

bool all_finite(const Lsq3Result& r) {
    return std::isfinite(r.g_x) && std::isfinite(r.g_y) && std::isfinite(r.g_z) && std::isfinite(r.rcond) &&
           std::isfinite(r.rss);
}

enum class Backend { Cpu, Vulkan };

std::vector<Lsq3Result> run(Backend backend, const Problem& p) {
    if (backend == Backend::Cpu) return lsq3_solve_cpu(p.inputs());
    Lsq3SolveVk kernel(*test::vulkan_context());
    return kernel.run(p.inputs());
}

class Lsq3SolveTest : public test::VulkanTest, public ::testing::WithParamInterface<Backend> {
protected:
    void SetUp() override {
        if (GetParam() == Backend::Vulkan) test::VulkanTest::SetUp();
    }
    void TearDown() override {
        if (GetParam() == Backend::Vulkan) test::VulkanTest::TearDown();
    }
};

// Well-conditioned photometric systems with exact b: the solve recovers g.
TEST_P(Lsq3SolveTest, RecoversKnownSolutions) {
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    Problem p;
    for (int e = 0; e < 5000; ++e) {
        const glm::dvec3 n = random_unit(rng);
        const glm::dvec3 g = (0.05 + 0.9 * uni(rng)) / 3.14159265358979 * n;
        const int k = 3 + static_cast<int>(uni(rng) * 14);
        std::vector<Lsq3Row> rows;
        for (int i = 0; i < k; ++i) {
            const glm::dvec3 a = (0.2 + 4.8 * uni(rng)) * hemisphere_dir(rng, n);
            rows.push_back(row(a, glm::dot(a, g), 0.25 + 0.75 * uni(rng)));
        }
        p.add(rows, g);
    }
    const auto out = run(GetParam(), p);
    ASSERT_EQ(out.size(), p.size());
    std::size_t ok = 0;
    double worst = 0.0;
    for (std::size_t e = 0; e < p.size(); ++e) {
        ASSERT_TRUE(all_finite(out[e])) << "element " << e;
        if (out[e].status != shared::kLsq3Ok) continue; // random directions can be nearly coplanar
        ++ok;
        const auto rows = std::span<const Lsq3Row>(p.rows).subspan(p.offsets[e], p.offsets[e + 1] - p.offsets[e]);
        const glm::dvec3 s = element_scale(rows).sqrt_diag;
        const double err = glm::length(s * (g_of(out[e]) - p.truth[e]));
        const double tol = kSafety * (rows.size() + 8) * kEps32 * 3.0 / out[e].rcond * glm::length(s * p.truth[e]);
        worst = std::max(worst, err / tol);
        ASSERT_LE(err, tol) << "element " << e << " rcond " << out[e].rcond;
        EXPECT_LE(out[e].rss, 1e-6 * glm::dot(s * p.truth[e], s * p.truth[e]) + 1e-12) << "element " << e;
    }
    EXPECT_GT(ok, p.size() * 9 / 10);
    std::printf("known truth: %zu of %zu solved, worst error / tolerance = %.3g\n", ok, p.size(), worst);
}

// The statuses, on systems built to hit each one; every output is finite.
TEST_P(Lsq3SolveTest, ReportsStatusesAndNeverNaN) {
    const glm::dvec3 g(0.1, -0.2, 0.3);
    const glm::dvec3 x(1, 0, 0), y(0, 1, 0), z(0, 0, 1);
    const auto exact = [&](glm::dvec3 a, double w = 1.0) { return row(a, glm::dot(a, g), w); };
    Problem p;
    p.add({});                                                                         // 0: no rows
    p.add({exact(x), exact(y)});                                                       // 1: two rows
    p.add({exact(x), exact(y), exact(z, 0.0)});                                        // 2: zero weight does not count
    p.add({exact(x), exact(y), exact(x + y)});                                         // 3: rank 2 (coplanar)
    p.add({exact(x), exact(2.0 * x), exact(3.0 * x), exact(-x)});                      // 4: rank 1
    p.add({exact(x + z), exact(y + z), exact(x + y + 2.001 * z)});                     // 5: nearly coplanar
    p.add({exact(x), exact(y), exact(z)}, g);                                          // 6: identity
    p.add({exact(1e12 * x), exact(1e12 * y), exact(1e12 * z)}, g);                     // 7: huge scale
    p.add({exact(1e-12 * x), exact(1e-12 * y), exact(1e-12 * z)}, g);                  // 8: tiny scale
    p.add({exact(glm::dvec3(1e6, 1, 0)), exact(glm::dvec3(0, 1, 1)), exact(glm::dvec3(1e6, 0, 1))}, g); // 9: unit mix
    p.add({exact(x), exact(y), exact(z), row(glm::dvec3(kNaN, 0, 0), 1.0)});            // 10: NaN
    p.add({exact(x), exact(y), exact(z), row(z, kInf)});                               // 11: infinite b
    p.add({exact(x), exact(y), exact(z), exact(x + y, -1.0)});                         // 12: negative weight
    p.add({exact(x), exact(y), exact(x), exact(y)});                                   // 13: z unconstrained
    const auto out = run(GetParam(), p);
    const uint32_t expected[] = {shared::kLsq3TooFewRows,      shared::kLsq3TooFewRows,     shared::kLsq3TooFewRows,
                                 shared::kLsq3IllConditioned,  shared::kLsq3IllConditioned, shared::kLsq3IllConditioned,
                                 shared::kLsq3Ok,              shared::kLsq3Ok,             shared::kLsq3Ok,
                                 shared::kLsq3Ok,              shared::kLsq3InvalidInput,   shared::kLsq3InvalidInput,
                                 shared::kLsq3InvalidInput,    shared::kLsq3IllConditioned};
    ASSERT_EQ(out.size(), std::size(expected));
    for (std::size_t e = 0; e < out.size(); ++e) {
        EXPECT_EQ(out[e].status, expected[e]) << "element " << e << ": " << lsq3_status_name(out[e].status);
        EXPECT_TRUE(all_finite(out[e])) << "element " << e;
        if (out[e].status != shared::kLsq3Ok) {
            EXPECT_EQ(g_of(out[e]), glm::dvec3(0.0)) << "element " << e;
        } else { // error in data units: inputs are float, so b carries a relative error of eps32
            const auto rows = std::span<const Lsq3Row>(p.rows).subspan(p.offsets[e], p.offsets[e + 1] - p.offsets[e]);
            const glm::dvec3 s = element_scale(rows).sqrt_diag;
            EXPECT_LT(glm::length(s * (g_of(out[e]) - g)), 1e-5 * glm::length(s * g)) << "element " << e;
        }
    }
    // Scale invariance: the unit matrix at any scale, and a 1e6 unit mix, keep their conditioning.
    // Element 9's scaled matrix is [[1,.5,.5],[.5,1,.5],[.5,.5,1]]: rcond = 1.5 / (sqrt(4.5) sqrt(2.0625)).
    for (std::size_t e : {6u, 7u, 8u}) EXPECT_NEAR(out[e].rcond, 1.0f, 1e-6f) << "element " << e;
    EXPECT_NEAR(out[9].rcond, 1.5 / (std::sqrt(4.5) * std::sqrt(2.0625)), 1e-5);
    EXPECT_EQ(out[2].rows, 2u);
    EXPECT_EQ(out[4].rows, 4u);
    EXPECT_LT(out[5].rcond, shared::kLsq3MinRcond);
}

INSTANTIATE_TEST_SUITE_P(Backends, Lsq3SolveTest, ::testing::Values(Backend::Cpu, Backend::Vulkan),
                         [](const auto& info) { return info.param == Backend::Cpu ? "Cpu" : "Vulkan"; });

// A realistic mix: photometric systems (noisy, weighted), nearly coplanar lights across the
// threshold, exactly coplanar ones, too few rows, invalid rows, wildly scaled unknowns.
Problem realistic_problem(std::size_t count, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    std::normal_distribution<double> noise(0.0, 1.0);
    Problem p;
    p.rows.reserve(count * 10);
    for (std::size_t e = 0; e < count; ++e) {
        const double kind = uni(rng);
        const glm::dvec3 n = random_unit(rng);
        const glm::dvec3 g = (0.05 + 0.9 * uni(rng)) / 3.14159265358979 * n;
        std::vector<Lsq3Row> rows;
        if (kind < 0.08) { // too few rows: 0, 1 or 2
            const int k = static_cast<int>(uni(rng) * 3);
            for (int i = 0; i < k; ++i) rows.push_back(row(hemisphere_dir(rng, n), uni(rng)));
        } else {
            const int k = 3 + static_cast<int>(uni(rng) * 14);
            const bool coplanar = kind < 0.25;
            const double out_of_plane = kind < 0.13 ? 0.0 : std::pow(10.0, -5.0 + 4.0 * uni(rng));
            const glm::dvec3 col_scale = kind > 0.95 ? glm::dvec3(std::pow(10.0, -4 + 8 * uni(rng)),
                                                                  std::pow(10.0, -4 + 8 * uni(rng)), 1.0)
                                                     : glm::dvec3(1.0);
            const glm::dvec3 plane_normal = random_unit(rng);
            for (int i = 0; i < k; ++i) {
                glm::dvec3 u = hemisphere_dir(rng, n);
                if (coplanar) {
                    u -= glm::dot(u, plane_normal) * plane_normal;
                    u = glm::normalize(u) + out_of_plane * noise(rng) * plane_normal;
                }
                const glm::dvec3 a = (0.2 + 4.8 * uni(rng)) * u * col_scale;
                const double b = glm::dot(a, g / col_scale) * (1.0 + 0.02 * noise(rng));
                const double w = uni(rng) < 0.1 ? 0.0 : 0.1 + 0.9 * uni(rng);
                rows.push_back(row(a, b, w));
            }
            if (kind > 0.93 && kind <= 0.95) { // invalid: a NaN, an infinity or a negative weight
                const double which = uni(rng);
                rows[0] = which < 0.33 ? row(glm::dvec3(kNaN, 0, 0), 0.0)
                                       : (which < 0.66 ? row(glm::dvec3(1, 0, 0), kInf) : row(glm::dvec3(1, 0, 0), 0.5, -1.0));
            }
            p.add(rows, g / col_scale);
            continue;
        }
        p.add(rows, g);
    }
    return p;
}

using Lsq3Conformance = test::VulkanTest;

// Vulkan (float) against the C++ reference (double) on 400,000 elements.
TEST_F(Lsq3Conformance, VulkanMatchesCpuReference) {
    const Problem p = realistic_problem(400'000, 2024);
    const auto ref = lsq3_solve_cpu(p.inputs());
    Lsq3SolveVk kernel(ctx());
    const auto vk = kernel.run(p.inputs());
    ASSERT_EQ(vk.size(), ref.size());

    std::size_t by_status[4] = {};
    std::size_t status_flips = 0, both_ok = 0;
    double worst_g = 0.0, worst_rcond = 0.0, worst_rss = 0.0;
    for (std::size_t e = 0; e < p.size(); ++e) {
        const Lsq3Result& r = ref[e];
        const Lsq3Result& v = vk[e];
        ASSERT_TRUE(all_finite(v)) << "element " << e;
        ASSERT_LT(r.status, 4u);
        ++by_status[r.status];
        ASSERT_EQ(v.rows, r.rows) << "element " << e;
        const auto rows = std::span<const Lsq3Row>(p.rows).subspan(p.offsets[e], p.offsets[e + 1] - p.offsets[e]);
        const double k_term = kSafety * (static_cast<double>(rows.size()) + 8.0) * kEps32;

        // rcond (see the top): absolute tolerance 3 * k_term.
        const double tol_rcond = 3.0 * k_term;
        if (r.status == shared::kLsq3Ok || r.status == shared::kLsq3IllConditioned) {
            const double d = std::abs(static_cast<double>(v.rcond) - r.rcond);
            worst_rcond = std::max(worst_rcond, d / tol_rcond);
            ASSERT_LE(d, tol_rcond) << "element " << e << " rcond " << r.rcond << " vs " << v.rcond;
        }
        if (v.status != r.status) {
            // Only allowed across the rcond threshold, within the rcond tolerance of it.
            const bool near = std::abs(static_cast<double>(r.rcond) - shared::kLsq3MinRcond) <= tol_rcond;
            ASSERT_TRUE(near) << "element " << e << ": cpu " << lsq3_status_name(r.status) << " vk "
                              << lsq3_status_name(v.status) << " rcond " << r.rcond;
            ++status_flips;
            continue;
        }
        if (r.status != shared::kLsq3Ok) {
            ASSERT_EQ(g_of(v), glm::dvec3(0.0)) << "element " << e;
            continue;
        }
        ++both_ok;
        // g, in data units (see the tolerance at the top).
        const glm::dvec3 s = element_scale(rows).sqrt_diag;
        const glm::dvec3 gr = g_of(r);
        const double err_x = glm::length(s * (g_of(v) - gr));
        const double tol_x = k_term * 3.0 / r.rcond * glm::length(s * gr);
        worst_g = std::max(worst_g, err_x / tol_x);
        ASSERT_LE(err_x, tol_x) << "element " << e << " rcond " << r.rcond;
        // rss: the g difference adds at most lambda_max(C) |dx|^2 <= 3 tol_x^2; evaluating the
        // residuals in float adds k_term * (rss + 2 sum w |e| (|a||g| + |b|)).
        double spread = 0.0;
        for (const auto& row_i : rows) {
            if (!(row_i.w > 0.0f)) continue;
            const glm::dvec3 a(row_i.a_x, row_i.a_y, row_i.a_z);
            const double res = glm::dot(a, gr) - row_i.b;
            spread += row_i.w * std::abs(res) * (glm::length(a) * glm::length(gr) + std::abs(row_i.b));
        }
        const double tol_rss = 3.0 * tol_x * tol_x + k_term * (r.rss + 2.0 * spread) + 1e-30;
        const double d_rss = std::abs(static_cast<double>(v.rss) - r.rss);
        worst_rss = std::max(worst_rss, d_rss / tol_rss);
        ASSERT_LE(d_rss, tol_rss) << "element " << e << " rss " << r.rss << " vs " << v.rss;
    }
    std::printf("conformance: %zu elements: ok %zu, ill-conditioned %zu, too few rows %zu, invalid %zu (reference)\n"
                "  status flips across the rcond threshold: %zu; worst error/tolerance: g %.3g, rcond %.3g, rss %.3g\n",
                p.size(), by_status[0], by_status[1], by_status[2], by_status[3], status_flips, worst_g, worst_rcond,
                worst_rss);
    // The input must exercise every status.
    for (std::size_t count : by_status) EXPECT_GT(count, 1000u);
    EXPECT_LT(status_flips, p.size() / 1000);
    EXPECT_GT(both_ok, p.size() / 2);
}

// Chunking (rows larger than one binding) gives bit-identical results to a single chunk.
TEST_F(Lsq3Conformance, ChunkedRunMatchesSingleRun) {
    const Problem p = realistic_problem(100'000, 7);
    Lsq3SolveVk whole(ctx());
    Lsq3SolveVk chunked(ctx(), {.max_binding_bytes = 1 << 20});
    const auto a = whole.run(p.inputs());
    const auto b = chunked.run(p.inputs());
    EXPECT_EQ(whole.last_chunk_count(), 1u);
    EXPECT_GT(chunked.last_chunk_count(), 10u);
    ASSERT_EQ(a.size(), b.size());
    for (std::size_t e = 0; e < a.size(); ++e)
        ASSERT_EQ(std::memcmp(&a[e], &b[e], sizeof(Lsq3Result)), 0) << "element " << e;
    // Empty input: nothing to do, no dispatch.
    EXPECT_TRUE(whole.run({}).empty());
}

} // namespace
} // namespace specula::gpu
