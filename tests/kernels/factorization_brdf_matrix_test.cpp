// brdf_matrix: CPU reference (double) vs Vulkan (float) conformance, in all three
// parametrizations (shared/gshd.h parts 1, 4 and 5: the mirror r(u) only negates two components,
// exactly, so the same bounds hold; the warped one's pairs are per channel and its F is the
// lobe over its radial factor, below).
//
// Tolerance, per entry, from a float error analysis of the shader's steps:
// - the GSHD directions (decode, normalize, Gram-Schmidt, cross, u = .., v = 2 (u.h) h - u)
//   carry an error of a few tens of eps32 per component, so the lobe's base
//   b = Cx (ux vx + uy vy) + Cz uz vz is off by at most
//       db = kSafety * 32 eps32 (|Cx| + |Cz|);
// - Vulkan's pow(b, N) is exp2(N log2 b) with log2's absolute error 2^-21 (b in [0.5, 2],
//   else 3 ulp) and exp2's (3 + 2|x|) ulp, i.e. a relative error of at most
//       r = kSafety ((N (2^-21 + 3 eps32 |log2 b|)) ln 2 + (4 + 3 N |log2 b|) eps32).
// So F_vk must lie in [flush((b - db)^N (1 - r)), flush((b + db)^N (1 + r))] (flush: the
// kGshdMinValue / kGshdMaxValue clamping, monotone). A near-mirror lobe (N = 1000) is
// allowed ~1% at its peak: the float base's own rounding, amplified N times, not slack.
// Validity (u.z, v.z > kGshdMinCos) may differ only within 1e-6 of the threshold.
// Warped: b is the base over |C u| (in [-1, 1]), with each channel's pair from its own warp;
// the warp's normalize and unwarp, and the base's inversesqrt, add a few eps32 each:
//     db = kSafety * 48 eps32.
// Lafortune entries go through shared/material.h material_specular, whose base is
// Cx (u.v - uz vz) + Cz uz vz: u.v and uz vz in float are off by a few eps32 more than
// ux vx + uy vy, well inside db.
// Coated (shared/coated.h, through material_specular): the model is a smooth function of
// ci = u.z, co = v.z and cuv = u.v, each off by at most dc = kSafety * 32 eps32 in float (the
// directions' error), so the entry must lie within the model's range over the box
// [ci +- dc] x [co +- dc] x [cuv +- dc] (its 27 corner and mid points in double: the box is far
// smaller than the lobe's width, so the model is monotone along each edge), widened by the
// float evaluation's own relative error: Fresnel (a sqrt and three divisions), D, two G1 (a
// sqrt and a division each) and the final product, r = kSafety * 64 eps32. A sharp lobe (alpha
// 0.05) is allowed ~1% at its peak: D's slope over dc, not slack.
// Weighted entries (weight_q = q): both bounds times w = (h.z d.z)^q, with pow's relative error
// as above for the base w and the exponent q (the cell centres are exact to a few eps32, inside it).
#include "factorization/brdf_matrix.h"
#include "core/error.h"
#include "vulkan_env.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

namespace specula::factorization {
namespace {

constexpr double kEps32 = 5.96e-8;
constexpr double kSafety = 4.0;

double flush(double x) {
    if (x < shared::kGshdMinValue) return 0.0;
    return std::min(x, static_cast<double>(shared::kGshdMaxValue));
}

struct Case {
    const char* name;
    SpecularModel model;
    uint32_t res_h;
    uint32_t res_d;
    FactorParam param = FactorParam::Gshd;
    float weight_q = 0.0f;
};

/// The allowed range of a Lafortune entry at the pair (u, v) (the header's analysis).
std::pair<double, double> lafortune_bounds(const LafortuneRgb& lobe, int ch, const glm::dvec3& u, const glm::dvec3& v,
                                           bool warped) {
    const double cx = lobe.cx[ch], cz = lobe.cz[ch], n = lobe.n[ch];
    double b = cx * (u.x * v.x + u.y * v.y) + cz * u.z * v.z;
    double db = kSafety * 32.0 * kEps32 * (std::abs(cx) + std::abs(cz));
    if (warped) {
        b /= std::sqrt(cx * cx * (u.x * u.x + u.y * u.y) + cz * cz * u.z * u.z);
        db = kSafety * 48.0 * kEps32;
    }
    const double lb = b > 0.0 ? std::abs(std::log2(b)) : 0.0;
    const double r =
        kSafety * (n * (std::ldexp(1.0, -21) + 3.0 * kEps32 * lb) * std::log(2.0) + (4.0 + 3.0 * n * lb) * kEps32);
    return {flush(std::pow(std::max(b - db, 0.0), n) * (1.0 - r)), flush(std::pow(std::max(b + db, 0.0), n) * (1.0 + r))};
}

/// The allowed range of a coated entry (the header's analysis): the double model over the box of
/// float input errors, widened by the float evaluation's relative error.
std::pair<double, double> coated_bounds(const shared::MaterialGpu& m, int ch, double ci, double co, double cuv) {
    const double dc = kSafety * 32.0 * kEps32;
    double lo = std::numeric_limits<double>::infinity(), hi = 0.0;
    for (int a = -1; a <= 1; ++a)
        for (int b = -1; b <= 1; ++b)
            for (int c = -1; c <= 1; ++c) {
                const double f = shared::f64::material_specular(m, ci + a * dc, co + b * dc, std::clamp(cuv + c * dc, -1.0, 1.0))[ch];
                lo = std::min(lo, f);
                hi = std::max(hi, f);
            }
    const double r = kSafety * 64.0 * kEps32;
    return {flush(lo * (1.0 - r)), flush(hi * (1.0 + r))};
}

LafortuneRgb gray(float cx, float cz, float n) { return {glm::vec3(cx), glm::vec3(cz), glm::vec3(n)}; }

class BrdfMatrixConformance : public test::VulkanTest, public ::testing::WithParamInterface<Case> {};
using BrdfMatrixConformanceRefusal = test::VulkanTest;

TEST_P(BrdfMatrixConformance, VulkanMatchesReference) {
    const Case& c = GetParam();
    const bool warped = c.param == FactorParam::Warped;
    const auto* lobe = std::get_if<LafortuneRgb>(&c.model);
    const glm::vec4 warp = warped ? warp_for_lobe(*lobe).value() : glm::vec4(1.0f);
    const shared::MaterialGpu material = material_gpu(c.model);
    const BrdfMatrixInputs in{.model = c.model, .res_h = c.res_h, .res_d = c.res_d, .param = c.param, .warp = warp,
                              .weight_q = c.weight_q};
    const BrdfMatrix ref = brdf_matrix_cpu(in);
    BrdfMatrixVk kernel(ctx());
    const BrdfMatrix vk = kernel.run(in);
    ASSERT_EQ(vk.values.size(), ref.values.size());
    EXPECT_EQ(vk.param, c.param);
    EXPECT_EQ(ref.param, c.param);
    EXPECT_EQ(vk.weight_q, c.weight_q);
    const std::size_t rows = ref.rows(), cols = ref.cols();
    std::size_t flips = 0, bad = 0, valid = 0;
    double worst_rel = 0.0;
    for (std::size_t row = 0; row < rows; ++row) {
        const glm::dvec3 h = shared::f64::gshd_grid_dir(static_cast<uint32_t>(row), c.res_h);
        for (std::size_t col = 0; col < cols; ++col) {
            const glm::dvec3 d = shared::f64::gshd_grid_dir(static_cast<uint32_t>(col), c.res_d);
            for (uint32_t ch = 0; ch < 3; ++ch) {
                const auto p = shared::f64::gshd_to_uv_warped(h, d, static_cast<uint32_t>(c.param),
                                                              glm::dvec2(channel_warp(warp, static_cast<int>(ch))));
                const float fr = ref.at(ch, row, col);
                const float fv = vk.at(ch, row, col);
                ASSERT_TRUE(std::isfinite(fv));
                if ((fr < 0.0f) != (fv < 0.0f)) {
                    ++flips;
                    const double m = shared::kGshdMinCos;
                    EXPECT_LT(std::min(std::abs(p.u.z - m), std::abs(p.v.z - m)), 1e-6)
                        << "validity differs away from the horizon threshold";
                    continue;
                }
                if (fr < 0.0f) {
                    EXPECT_EQ(fv, shared::kGshdInvalid);
                    continue;
                }
                ++valid;
                auto [lo, hi] = lobe ? lafortune_bounds(*lobe, static_cast<int>(ch), p.u, p.v, warped)
                                     : coated_bounds(material, static_cast<int>(ch), p.u.z, p.v.z, glm::dot(p.u, p.v));
                if (c.weight_q != 0.0f) {
                    const double q = c.weight_q, w = std::pow(h.z * d.z, q), lw = std::abs(std::log2(w));
                    const double r = kSafety * (q * (std::ldexp(1.0, -21) + 3.0 * kEps32 * lw) * std::log(2.0) +
                                                (4.0 + 3.0 * q * lw) * kEps32);
                    lo = flush(lo * w * (1.0 - r));
                    hi = flush(hi * w * (1.0 + r));
                }
                if (fv < lo || fv > hi) {
                    if (++bad < 10)
                        ADD_FAILURE() << c.name << " F[" << ch << "][" << row << "][" << col << "] vk " << fv << " ref "
                                      << fr << " allowed [" << lo << ", " << hi << "]";
                }
                if (fr > 0.0f) worst_rel = std::max(worst_rel, std::abs(static_cast<double>(fv) - fr) / fr);
            }
        }
    }
    EXPECT_EQ(bad, 0u);
    EXPECT_LE(flips, rows * cols / 1000 + 3);
    EXPECT_GT(valid, rows * cols);
    std::printf("[ %s ] valid %zu, validity flips %zu, worst relative difference %.3g\n", c.name, valid, flips,
                worst_rel);
}

INSTANTIATE_TEST_SUITE_P(
    Lobes, BrdfMatrixConformance,
    ::testing::Values(Case{"pepsi", gray(-0.8962f, 0.7587f, 10.11f), 16, 12},
                      Case{"woodenpot_cz_negative", gray(-1.4299f, -0.7763f, 9.74f), 12, 16},
                      Case{"mirror_n1000_odd_grid", gray(-1.0f, 1.0f, 1000.0f), 17, 9},
                      Case{"rgb_mixed", LafortuneRgb{{-0.9f, -1.2f, -1.0f}, {0.8f, 0.5f, 1.0f}, {5.0f, 20.0f, 100.0f}}, 10, 10},
                      Case{"overflowing_height", gray(-1.5f, 1.5f, 10000.0f), 8, 8},
                      Case{"pepsi_mirrored", gray(-0.8962f, 0.7587f, 10.11f), 16, 12, FactorParam::Mirrored},
                      Case{"woodenpot_mirrored", gray(-1.4299f, -0.7763f, 9.74f), 12, 16, FactorParam::Mirrored},
                      Case{"mirror_n1000_mirrored", gray(-1.0f, 1.0f, 1000.0f), 17, 9, FactorParam::Mirrored},
                      Case{"rgb_mixed_mirrored",
                           LafortuneRgb{{-0.9f, -1.2f, 1.0f}, {0.8f, 0.5f, 1.0f}, {5.0f, 20.0f, 100.0f}}, 10, 10,
                           FactorParam::Mirrored},
                      Case{"vase_rgb_warped",
                           LafortuneRgb{{-1.2127f, -1.2050f, -1.1980f}, {0.5653f, 0.5700f, 0.5750f}, {20.36f, 20.0f, 19.7f}},
                           16, 24, FactorParam::Warped},
                      Case{"woodenpot_warped", gray(-1.4299f, -0.7763f, 9.74f), 12, 16, FactorParam::Warped},
                      Case{"mirror_n1000_warped", gray(-1.0f, 1.0f, 1000.0f), 9, 17, FactorParam::Warped},
                      Case{"retro_mixed_warped", LafortuneRgb{{0.9f, 1.1f, 0.5f}, {0.8f, 0.7f, 2.0f}, {12.0f, 8.0f, 30.0f}},
                           10, 10, FactorParam::Warped},
                      Case{"overflowing_height_warped", gray(-1.5f, 1.5f, 10000.0f), 8, 8, FactorParam::Warped},
                      // The coated family (GGX under a dielectric coating), plain and mirrored: a sharp
                      // lobe on a fine h grid, a rough tinted one with a high index, odd grids.
                      Case{"coated_sharp", CoatedParams{.eta = 1.5f, .alpha = 0.05f, .tint = glm::vec3(1.0f)}, 40, 12},
                      Case{"coated_rough_tinted", CoatedParams{.eta = 2.2f, .alpha = 0.4f, .tint = {0.9f, 0.6f, 0.3f}}, 13, 17},
                      Case{"coated_sharp_mirrored", CoatedParams{.eta = 1.5f, .alpha = 0.05f, .tint = glm::vec3(1.0f)}, 12, 40,
                           FactorParam::Mirrored},
                      Case{"coated_mid_mirrored", CoatedParams{.eta = 1.33f, .alpha = 0.12f, .tint = {1.0f, 0.8f, 0.8f}}, 17, 15,
                           FactorParam::Mirrored},
                      // Weighted entries (the coated family's default from alpha 0.25 on; any q).
                      Case{"coated_rough_weighted", CoatedParams{.eta = 1.5f, .alpha = 0.4f, .tint = glm::vec3(1.0f)}, 14, 22,
                           FactorParam::Gshd, 2.0f},
                      Case{"coated_mid_weighted_mirrored", CoatedParams{.eta = 1.5f, .alpha = 0.2f, .tint = {0.7f, 0.8f, 0.9f}},
                           19, 11, FactorParam::Mirrored, 1.3f},
                      Case{"pepsi_weighted", gray(-0.8962f, 0.7587f, 10.11f), 16, 12, FactorParam::Gshd, 0.5f}),
    [](const ::testing::TestParamInfo<Case>& info) { return std::string(info.param.name); });

// The warped parametrization divides by the Lafortune lobe's radial factor: another family is
// refused, by the reference and by the kernel alike, before anything is computed.
TEST_F(BrdfMatrixConformanceRefusal, WarpedCoatedIsRefused) {
    const BrdfMatrixInputs in{.model = CoatedParams{}, .res_h = 8, .res_d = 8, .param = FactorParam::Warped,
                              .warp = glm::vec4(1.0f)};
    EXPECT_THROW((void)brdf_matrix_cpu(in), Error);
    BrdfMatrixVk kernel(ctx());
    EXPECT_THROW((void)kernel.run(in), Error);
}

} // namespace
} // namespace specula::factorization
