// residual_term: CPU reference (double) vs Vulkan (float) on the same F and term 1.
//
// Tolerance. Unlike the other kernels, a term is the result of 12 alternating least-squares
// iterations (power iteration), and each term's residual subtracts the earlier terms, so
// float rounding is carried from pass to pass and term to term rather than bounded per
// sum. Power iteration is contracting towards the dominant singular pair (the error in the
// direction of the other pairs shrinks by sigma_2 / sigma_1 per iteration), so rounding does
// not grow; what is left is of the order of the last pass's blocked-sum rounding,
// kSafety (64 + n/64) eps32 ~ 2e-5 relative, times the conditioning of the pair
// (sigma_1 / (sigma_1 - sigma_2)), which is not known in advance. The comparison is on what
// the terms are used for, the products G_k(h) H_k(d) (G and H alone are defined up to a
// scale), relative to max |F|: measured worst 1.5e-7 (woodenpot lobe) to 1.4e-6 (random
// matrix); asserted 2e-5, the per-sum bound above (14x the measured worst).
#include "core/error.h"
#include "factorization/brdf_matrix.h"
#include "factorization/factorization.h"
#include "vulkan_env.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <utility>
#include <random>
#include <tuple>

namespace specula::factorization {
namespace {

constexpr double kTolerance = 2e-5;

LafortuneRgb gray(float cx, float cz, float n) { return {glm::vec3(cx), glm::vec3(cz), glm::vec3(n)}; }

class ResidualTermKernel : public test::VulkanTest {};

double max_abs(const BrdfMatrix& m) {
    double mx = 0.0;
    for (float v : m.values) mx = std::max<double>(mx, v);
    return mx;
}

/// Worst |G_k H_k (cpu) - G_k H_k (vk)| / max |F| over valid entries, channels and terms.
double worst_product_difference(const BrdfMatrix& m, const std::vector<Decomposition>& a, const std::vector<Decomposition>& b) {
    double worst = 0.0;
    for (std::size_t k = 0; k < a.size(); ++k)
        for (uint32_t c = 0; c < 3; ++c)
            for (std::size_t row = 0; row < m.rows(); ++row)
                for (std::size_t col = 0; col < m.cols(); ++col) {
                    if (m.at(c, row, col) < 0.0f) continue;
                    const int ci = static_cast<int>(c);
                    const double pa = static_cast<double>(a[k].g[row][ci]) * a[k].h[col][ci];
                    const double pb = static_cast<double>(b[k].g[row][ci]) * b[k].h[col][ci];
                    worst = std::max(worst, std::abs(pa - pb));
                }
    return worst / max_abs(m);
}

void check(gpu::Context& ctx, const BrdfMatrix& m, uint32_t terms, const char* what) {
    const Decomposition first = normalized_decomposition_cpu({.matrix = &m});
    const ResidualTermsInputs in{.matrix = &m, .first = &first, .terms = terms};
    const std::vector<Decomposition> ref = residual_terms_cpu(in);
    ResidualTermsVk vk(ctx);
    const std::vector<Decomposition> got = vk.run(in);
    ASSERT_EQ(ref.size(), terms - 1);
    ASSERT_EQ(got.size(), terms - 1);
    for (const Decomposition& d : got) {
        for (const glm::vec3& v : d.g) ASSERT_TRUE(std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z));
        for (const glm::vec3& v : d.h) ASSERT_TRUE(std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z));
    }
    const double worst = worst_product_difference(m, ref, got);
    std::printf("%s: K = %u, worst |G H| difference %.3g of max F\n", what, terms, worst);
    EXPECT_LE(worst, kTolerance) << what;
    // And the terms do their job: the error of the sum falls with each one (both paths).
    std::vector<const Decomposition*> sa{&first}, sb{&first};
    double prev = matrix_relative_rms(m, sa);
    for (std::size_t k = 0; k < ref.size(); ++k) {
        sa.push_back(&ref[k]);
        sb.push_back(&got[k]);
        const double ea = matrix_relative_rms(m, sa), eb = matrix_relative_rms(m, sb);
        EXPECT_LT(ea, prev) << what;
        EXPECT_NEAR(ea, eb, 1e-4) << what;
        prev = ea;
    }
}

TEST_F(ResidualTermKernel, MatchesReferenceOnPresetLobes) {
    for (const auto& [name, lobe] : {std::pair{"can", gray(-0.8962f, 0.7587f, 10.11f)},
                                     std::pair{"woodenpot", gray(-1.4299f, -0.7763f, 9.74f)},
                                     std::pair{"cologne", LafortuneRgb{glm::vec3(-0.8874f, -0.895f, -0.902f),
                                                                       glm::vec3(1.1162f, 1.11f, 1.105f),
                                                                       glm::vec3(18.09f, 18.5f, 18.9f)}}}) {
        const BrdfMatrix m = brdf_matrix_cpu({.model = lobe, .res_h = 16, .res_d = 12});
        check(ctx(), m, kMaxFactorTerms, name);
    }
}

// Term 1's ALS refinement (refine_first_term_cpu: the same passes with R = F, warm from the
// normalized decomposition) agrees on the products, on the warped matrices it is for (exactly
// rank 1: the refined term leaves ~1e-7 matrix error on both paths) and on a plain one.
TEST_F(ResidualTermKernel, FirstTermRefinementMatchesReference) {
    ResidualTermsVk vk(ctx());
    for (const auto& [name, lobe, param] :
         {std::tuple{"vase_rgb_warped", LafortuneRgb{glm::vec3(-1.2127f, -1.205f, -1.198f), glm::vec3(0.5653f, 0.57f, 0.575f),
                                                     glm::vec3(20.36f, 20.0f, 19.7f)},
                     FactorParam::Warped},
          std::tuple{"woodenpot_warped", gray(-1.4299f, -0.7763f, 9.74f), FactorParam::Warped},
          std::tuple{"can_plain", gray(-0.8962f, 0.7587f, 10.11f), FactorParam::Gshd}}) {
        const glm::vec4 warp = param == FactorParam::Warped ? warp_for_lobe(lobe).value() : glm::vec4(1.0f);
        const BrdfMatrix m = brdf_matrix_cpu({.model = lobe, .res_h = 12, .res_d = 20, .param = param, .warp = warp});
        const Decomposition first = normalized_decomposition_cpu({.matrix = &m});
        const Decomposition ref = refine_first_term_cpu(m, first, kResidualIterations);
        const Decomposition got = vk.run_refine_first(m, first, kResidualIterations);
        EXPECT_EQ(got.param, param);
        EXPECT_EQ(got.warp, warp);
        for (const glm::vec3& v : got.g) ASSERT_TRUE(std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z));
        for (const glm::vec3& v : got.h) ASSERT_TRUE(std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z));
        const double worst = worst_product_difference(m, {ref}, {got});
        const double before = matrix_relative_rms(m, first), after_ref = matrix_relative_rms(m, ref),
                     after_vk = matrix_relative_rms(m, got);
        std::printf("%s: term 1 matrix RMS %.3g -> %.3g (cpu) / %.3g (vk); worst |G H| difference %.3g of max F\n", name,
                    before, after_ref, after_vk, worst);
        EXPECT_LE(worst, kTolerance) << name;
        EXPECT_LT(after_ref, before) << name;
        EXPECT_NEAR(after_vk, after_ref, 1e-4) << name;
        if (param == FactorParam::Warped) {
            EXPECT_LT(after_vk, 1e-3) << name;
        }
    }
}

TEST_F(ResidualTermKernel, MatchesReferenceOnARandomMatrixWithInvalidEntries) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> uni(0.0f, 1.0f);
    BrdfMatrix m{.res_h = 9, .res_d = 7, .values = {}};
    m.values.resize(3 * m.rows() * m.cols());
    for (float& v : m.values) v = uni(rng) < 0.1f ? shared::kGshdInvalid : std::exp(3.0f * uni(rng) - 1.5f);
    check(ctx(), m, 3, "random");
}

TEST_F(ResidualTermKernel, ValidatesItsInputs) {
    const BrdfMatrix m = brdf_matrix_cpu({.model = gray(-1.0f, 1.0f, 5.0f), .res_h = 4, .res_d = 4});
    const Decomposition first = normalized_decomposition_cpu({.matrix = &m});
    EXPECT_THROW((void)residual_terms_cpu({.matrix = &m, .first = &first, .terms = 1}), Error);
    EXPECT_THROW((void)residual_terms_cpu({.matrix = &m, .first = &first, .terms = kMaxFactorTerms + 1}), Error);
    EXPECT_THROW((void)residual_terms_cpu({.matrix = &m, .first = nullptr, .terms = 2}), Error);
    const BrdfMatrix other = brdf_matrix_cpu({.model = gray(-1.0f, 1.0f, 5.0f), .res_h = 5, .res_d = 4});
    EXPECT_THROW((void)residual_terms_cpu({.matrix = &other, .first = &first, .terms = 2}), Error);
}

} // namespace
} // namespace specula::factorization
