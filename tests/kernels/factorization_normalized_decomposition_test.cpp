// normalized_decomposition: CPU reference (double) vs Vulkan (float) on the same F.
//
// Tolerance. Every sum has non-negative terms and is blocked by kGshdSumBlock = 64, so a
// float sum of K terms has relative error <= (64 + K/64) eps32. G(h): the row maximum is
// exact, each term (f/m)^p costs <= 3 eps32 for p in {1, 2} (divide, multiply), the mean
// and root and the final product <= 4 eps32:
//     tol_G = kSafety ((64 + cols/64) + 8) eps32                      (relative)
// For other p, Vulkan's pow (exp2(p log2 x), log2 absolute error 2^-21, plus ulps that grow
// with |p log2 x|) adds about (p + 1/p) ln2 (2^-21 + 200 eps32) relative.
// H(d) = mean_h F/G: each quotient inherits G's error, then one more blocked sum:
//     tol_H = tol_G + kSafety ((64 + rows/64) + 4) eps32             (relative)
// Energy weighting, H = sum w (F / G_max) / sum w^2 with w = G / G_max: w carries twice
// G's error, so numerator and denominator carry <= 3 and 4 tol_G plus their sums:
//     tol_H = 8 tol_G + 2 kSafety ((64 + rows/64) + 4) eps32
// Both are relative to the reference value (which is 0 exactly where the GPU's is 0).
#include "factorization/brdf_matrix.h"
#include "factorization/factorization.h"
#include "vulkan_env.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace specula::factorization {
namespace {

constexpr double kEps32 = 5.96e-8;
constexpr double kSafety = 4.0;

LafortuneRgb gray(float cx, float cz, float n) { return {glm::vec3(cx), glm::vec3(cz), glm::vec3(n)}; }

// A random non-negative matrix with ~10% invalid entries, a zero row and a tiny row.
BrdfMatrix random_matrix(uint32_t res_h, uint32_t res_d, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> uni(0.0f, 1.0f);
    BrdfMatrix m{.res_h = res_h, .res_d = res_d, .values = {}};
    m.values.resize(3 * m.rows() * m.cols());
    for (float& v : m.values) v = uni(rng) < 0.1f ? shared::kGshdInvalid : std::exp(8.0f * uni(rng) - 4.0f);
    for (uint32_t c = 0; c < 3; ++c)
        for (std::size_t col = 0; col < m.cols(); ++col) {
            m.values[(c * m.rows() + 0) * m.cols() + col] = 0.0f;
            m.values[(c * m.rows() + 1) * m.cols() + col] = 1e-35f; // below kGshdMinValue: G = 0
        }
    return m;
}

void expect_conformant(const BrdfMatrix& m, float p, const Decomposition& ref, const Decomposition& vk, const char* what,
                       DecompositionWeighting weighting = DecompositionWeighting::Uniform) {
    const double pow_err = (p == 1.0f || p == 2.0f) ? 0.0
                                                     : kSafety * (p + 1.0 / p) * std::log(2.0) *
                                                           (std::ldexp(1.0, -21) + 200.0 * kEps32);
    const double tol_g = kSafety * (64.0 + m.cols() / 64.0 + 8.0) * kEps32 + pow_err;
    const double sum_h = kSafety * (64.0 + m.rows() / 64.0 + 4.0) * kEps32;
    const double tol_h = weighting == DecompositionWeighting::Uniform ? tol_g + sum_h : 8.0 * tol_g + 2.0 * sum_h;
    ASSERT_EQ(vk.g.size(), ref.g.size());
    ASSERT_EQ(vk.h.size(), ref.h.size());
    double worst_g = 0.0, worst_h = 0.0;
    for (std::size_t i = 0; i < ref.g.size(); ++i)
        for (int c = 0; c < 3; ++c) {
            const double r = ref.g[i][c], v = vk.g[i][c];
            ASSERT_TRUE(std::isfinite(v));
            const double e = std::abs(v - r);
            EXPECT_LE(e, tol_g * r + 1e-37) << what << " G[" << i << "][" << c << "] ref " << r << " vk " << v;
            if (r > 0.0) worst_g = std::max(worst_g, e / r);
        }
    for (std::size_t i = 0; i < ref.h.size(); ++i)
        for (int c = 0; c < 3; ++c) {
            const double r = ref.h[i][c], v = vk.h[i][c];
            ASSERT_TRUE(std::isfinite(v));
            const double e = std::abs(v - r);
            EXPECT_LE(e, tol_h * r + 1e-37) << what << " H[" << i << "][" << c << "] ref " << r << " vk " << v;
            if (r > 0.0) worst_h = std::max(worst_h, e / r);
        }
    std::printf("[ %s p=%g ] worst relative G %.3g (tol %.3g), H %.3g (tol %.3g)\n", what, p, worst_g, tol_g, worst_h,
                tol_h);
}

class NormalizedDecompositionConformance : public test::VulkanTest {};

TEST_F(NormalizedDecompositionConformance, RandomMatrixAllP) {
    const BrdfMatrix m = random_matrix(9, 12, 5);
    NormalizedDecompositionVk kernel(ctx());
    for (float p : {1.0f, 2.0f, 3.0f})
        for (auto w : {DecompositionWeighting::Uniform, DecompositionWeighting::Energy}) {
            const DecompositionInputs in{.matrix = &m, .p = p, .weighting = w};
            expect_conformant(m, p, normalized_decomposition_cpu(in), kernel.run(in), to_string(w), w);
        }
}

TEST_F(NormalizedDecompositionConformance, LafortuneLobes) {
    NormalizedDecompositionVk kernel(ctx());
    for (const LafortuneRgb& lobe : {gray(-0.8962f, 0.7587f, 10.11f), gray(-1.4299f, -0.7763f, 9.74f),
                                     gray(-1.0f, 1.0f, 1000.0f), gray(-1.5f, 1.5f, 10000.0f)}) {
        const BrdfMatrix m = brdf_matrix_cpu({.model = lobe, .res_h = 16, .res_d = 12});
        for (auto w : {DecompositionWeighting::Uniform, DecompositionWeighting::Energy}) {
            const DecompositionInputs in{.matrix = &m, .p = 2.0f, .weighting = w};
            expect_conformant(m, 2.0f, normalized_decomposition_cpu(in), kernel.run(in), to_string(w), w);
        }
    }
}

// The decomposition is exact for a separable F = a_c(h) b_c(d), on both backends.
TEST_F(NormalizedDecompositionConformance, SeparableMatrixIsExact) {
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> uni(0.05f, 2.0f);
    BrdfMatrix m{.res_h = 12, .res_d = 10, .values = {}};
    std::vector<glm::vec3> a(m.rows()), b(m.cols());
    for (auto& x : a) x = {uni(rng), uni(rng), uni(rng)};
    for (auto& x : b) x = {uni(rng), uni(rng), uni(rng)};
    m.values.resize(3 * m.rows() * m.cols());
    for (int c = 0; c < 3; ++c)
        for (std::size_t r = 0; r < m.rows(); ++r)
            for (std::size_t d = 0; d < m.cols(); ++d)
                m.values[(c * m.rows() + r) * m.cols() + d] = a[r][c] * b[d][c];
    NormalizedDecompositionVk kernel(ctx());
    for (float p : {1.0f, 2.0f, 4.0f})
      for (auto w : {DecompositionWeighting::Uniform, DecompositionWeighting::Energy}) {
        const DecompositionInputs in{.matrix = &m, .p = p, .weighting = w};
        const double e_cpu = matrix_relative_rms(m, normalized_decomposition_cpu(in));
        const double e_vk = matrix_relative_rms(m, kernel.run(in));
        EXPECT_LT(e_cpu, 1e-6) << "p = " << p; // float rounding of F, G, H only
        EXPECT_LT(e_vk, (p == 4.0f ? 1e-5 : 2e-6)) << "p = " << p;
        std::printf("[ separable p=%g %s ] relative RMS cpu %.3g vulkan %.3g\n", p, to_string(w), e_cpu, e_vk);
    }
}

} // namespace
} // namespace specula::factorization
