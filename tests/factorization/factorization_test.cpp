// Factorization behaviour: GSHD and grid math, exactness on separable data, convergence
// with the grid, the default-resolution rule, no NaN on extreme lobes (both backends).
#include "core/error.h"
#include "factorization/factorization.h"
#include "vulkan_env.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

namespace specula::factorization {
namespace {

namespace f64 = shared::f64;

LafortuneRgb gray(float cx, float cz, float n) { return {glm::vec3(cx), glm::vec3(cz), glm::vec3(n)}; }

glm::dvec3 random_hemisphere(std::mt19937& rng) {
    std::normal_distribution<double> n(0.0, 1.0);
    glm::dvec3 v = glm::normalize(glm::dvec3(n(rng), n(rng), n(rng)));
    v.z = std::abs(v.z);
    return v;
}

TEST(Gshd, RoundTripAndHemispheres) {
    std::mt19937 rng(1);
    for (int i = 0; i < 10000; ++i) {
        const glm::dvec3 u = random_hemisphere(rng), v = random_hemisphere(rng);
        const f64::GshdCoords c = f64::gshd_from_uv(u, v);
        EXPECT_GE(c.h.z, 0.0);
        EXPECT_GE(c.d.z, 0.0); // u.h >= 0 always
        EXPECT_NEAR(glm::length(c.d), 1.0, 1e-12);
        const f64::GshdPair p = f64::gshd_to_uv(c.h, c.d);
        EXPECT_NEAR(glm::length(p.u - u), 0.0, 1e-9);
        EXPECT_NEAR(glm::length(p.v - v), 0.0, 1e-9);
        // the float instantiation (what the shaders run) agrees
        const shared::GshdCoords cf = shared::gshd_from_uv(glm::vec3(u), glm::vec3(v));
        EXPECT_NEAR(glm::length(glm::dvec3(cf.d) - c.d), 0.0, 1e-5);
    }
}

// The mirrored parametrization (shared/gshd.h part 4): the GSHD of (r(u), v), inverted.
TEST(Gshd, MirroredRoundTrip) {
    std::mt19937 rng(3);
    for (int i = 0; i < 10000; ++i) {
        const glm::dvec3 u = random_hemisphere(rng), v = random_hemisphere(rng);
        const f64::GshdCoords c = f64::gshd_from_uv_param(u, v, shared::kGshdMirrored);
        const f64::GshdCoords m = f64::gshd_from_uv(glm::dvec3(-u.x, -u.y, u.z), v);
        EXPECT_EQ(c.h, m.h);
        EXPECT_EQ(c.d, m.d);
        EXPECT_GE(c.h.z, 0.0);
        EXPECT_GE(c.d.z, 0.0);
        const f64::GshdPair p = f64::gshd_to_uv_param(c.h, c.d, shared::kGshdMirrored);
        EXPECT_NEAR(glm::length(p.u - u), 0.0, 1e-9);
        EXPECT_NEAR(glm::length(p.v - v), 0.0, 1e-9);
        // kGshdPlain is gshd_from_uv itself.
        const f64::GshdCoords plain = f64::gshd_from_uv_param(u, v, shared::kGshdPlain);
        EXPECT_EQ(plain.d, f64::gshd_from_uv(u, v).d);
        const shared::GshdCoords cf = shared::gshd_from_uv_param(glm::vec3(u), glm::vec3(v), shared::kGshdMirrored);
        EXPECT_NEAR(glm::length(glm::dvec3(cf.d) - c.d), 0.0, 1e-5);
    }
}

TEST(Gshd, HemiOctMapRoundTripAndCellAreas) {
    std::mt19937 rng(2);
    for (int i = 0; i < 10000; ++i) {
        const glm::dvec3 w = random_hemisphere(rng);
        const glm::dvec2 e = f64::hemi_oct_encode(w);
        EXPECT_LE(std::max(std::abs(e.x), std::abs(e.y)), 1.0 + 1e-12);
        EXPECT_NEAR(glm::length(f64::hemi_oct_decode(e) - w), 0.0, 1e-12);
    }
    // Solid angle per cell (Monte Carlo over cell corners' spherical quads, approximated by
    // the cross product of the decoded cell edges): largest / smallest.
    const uint32_t res = 64;
    double lo = 1e9, hi = 0.0;
    for (uint32_t j = 0; j < res; ++j)
        for (uint32_t i = 0; i < res; ++i) {
            const double s = 2.0 / res;
            const glm::dvec2 e0(-1.0 + i * s, -1.0 + j * s);
            const glm::dvec3 a = f64::hemi_oct_decode(e0), b = f64::hemi_oct_decode(e0 + glm::dvec2(s, 0.0)),
                             c = f64::hemi_oct_decode(e0 + glm::dvec2(0.0, s)),
                             d = f64::hemi_oct_decode(e0 + glm::dvec2(s, s));
            const double area = 0.5 * (glm::length(glm::cross(b - a, c - a)) + glm::length(glm::cross(b - d, c - d)));
            lo = std::min(lo, area);
            hi = std::max(hi, area);
        }
    std::printf("hemi-oct cell area ratio (largest / smallest) at res %u: %.3f\n", res, hi / lo);
    EXPECT_LT(hi / lo, 6.0);
}

TEST(Factorization, SeparableLobeIsExact) {
    // Cx = 0: f = (Cz uz vz)^N = Cz^N uz^N vz^N is not separable in (h, d) in general, so
    // the separable case is built directly in normalized_decomposition's kernel test; here
    // a constant lobe (N -> 0 limit: N = 1e-6, base > 0 everywhere) is separable: F = 1.
    const LafortuneRgb flat = gray(0.0f, 1.0f, 1e-6f);
    auto f = factorize_cpu(flat, {.grid_h = 8, .grid_d = 8, .keep_matrix = true});
    EXPECT_LT(matrix_relative_rms(*f.matrix, f.grids[0]), 1e-5);
}

TEST(Factorization, ErrorDecreasesAsGridRefines) {
    // vase and woodenpot (thesis table 5.2): the direct error (sampling + decomposition +
    // interpolation) falls as the grids refine, towards the lobe's separability floor.
    for (const LafortuneRgb& lobe : {gray(-1.2127f, 0.5653f, 20.36f), gray(-1.4299f, -0.7763f, 9.74f)}) {
        double last = 1e9;
        for (uint32_t res : {6u, 12u, 24u}) {
            auto f = factorize_cpu(lobe, {.grid_h = res, .grid_d = res, .keep_matrix = true});
            const DirectError e = direct_relative_rms(lobe, f.grids[0], &f.cubes.terms[0].g, &f.cubes.terms[0].h, 1u << 16);
            std::printf("res %u: matrix %.4f direct(grid) %.4f direct(cube) %.4f\n", res,
                        matrix_relative_rms(*f.matrix, f.grids[0]), e.grid, e.cube);
            EXPECT_LT(e.grid, last);
            last = e.grid;
        }
    }
}

TEST(Factorization, DefaultResolutionFollowsLobeWidth) {
    const FactorizationResolution broad = default_resolution(gray(-1.0f, 1.0f, 10.0f));
    const FactorizationResolution mirror = default_resolution(gray(-1.0f, 1.0f, 1000.0f));
    EXPECT_GT(mirror.grid_h, broad.grid_h);
    EXPECT_GE(mirror.cube_g, broad.cube_g);
    EXPECT_GE(broad.grid_h, kMinGridRes);
    EXPECT_LE(uint64_t{mirror.grid_h} * mirror.grid_d, uint64_t{kMaxGridProduct});
    EXPECT_FALSE(mirror.reason.empty());
    std::printf("N=10: %s\nN=1000: %s\n", broad.reason.c_str(), mirror.reason.c_str());
    // Garbage exponents do not break the rule.
    const FactorizationResolution odd = default_resolution(gray(-1.0f, 1.0f, std::nanf("")));
    EXPECT_EQ(odd.grid_h, kMinGridRes);
}

bool all_finite(const Factorization& f) {
    const auto ok = [](const std::vector<glm::vec3>& v) {
        for (const auto& x : v)
            if (!std::isfinite(x.x) || !std::isfinite(x.y) || !std::isfinite(x.z)) return false;
        return true;
    };
    return ok(f.grids[0].g) && ok(f.grids[0].h) && ok(f.cubes.terms[0].g.texels) && ok(f.cubes.terms[0].h.texels);
}

const LafortuneRgb kExtreme[] = {
    gray(-1.0f, 1.0f, 10000.0f),   // near mirror
    gray(-1.4299f, -0.7763f, 9.74f), // Cz < 0 (woodenpot)
    gray(-1.2f, -1.5f, 10000.0f),  // Cz < 0, huge N, height overflows float
    gray(0.5f, -1.0f, 1.0f),       // Cx > 0 (retro-reflective), Cz < 0
    gray(-1.0f, 1.0f, 0.0f),       // N = 0
};

TEST(Factorization, NeverNaNOnCpu) {
    for (const LafortuneRgb& lobe : kExtreme) {
        auto f = factorize_cpu(lobe, {.grid_h = 10, .grid_d = 8, .keep_matrix = true});
        EXPECT_TRUE(all_finite(f));
        const DirectError e = direct_relative_rms(lobe, f.grids[0], &f.cubes.terms[0].g, &f.cubes.terms[0].h, 4096);
        EXPECT_TRUE(std::isfinite(e.grid) && std::isfinite(e.cube));
        EXPECT_TRUE(std::isfinite(matrix_relative_rms(*f.matrix, f.grids[0])));
    }
}

// The largest texel difference of two cube-maps, relative to the first one's largest texel
// component (infinite when their sizes differ).
double relative_cube_difference(const CubeMap& a, const CubeMap& b) {
    EXPECT_EQ(a.texels.size(), b.texels.size());
    if (a.texels.size() != b.texels.size()) return std::numeric_limits<double>::infinity();
    double scale = 0.0, worst = 0.0;
    for (std::size_t i = 0; i < a.texels.size(); ++i)
        for (int c = 0; c < 3; ++c) {
            scale = std::max<double>(scale, std::abs(a.texels[i][c]));
            worst = std::max<double>(worst, std::abs(a.texels[i][c] - b.texels[i][c]));
        }
    return worst / scale;
}

class FactorizationVulkan : public test::VulkanTest {};

TEST_F(FactorizationVulkan, NeverNaNAndMatchesCpuEndToEnd) {
    FactorizeVk vk(ctx());
    for (const LafortuneRgb& lobe : kExtreme) {
        auto f = vk.run(lobe, {.grid_h = 10, .grid_d = 8});
        EXPECT_TRUE(all_finite(f));
    }
    // End to end on a thesis lobe: the cube-maps agree with the reference path (the
    // per-kernel tolerances are in tests/kernels/factorization_*_test.cpp; here 1e-4
    // relative to the largest texel covers their sum).
    const LafortuneRgb pepsi = gray(-0.8962f, 0.7587f, 10.11f);
    const auto a = factorize_cpu(pepsi, {.grid_h = 16, .grid_d = 12});
    const auto b = vk.run(pepsi, {.grid_h = 16, .grid_d = 12});
    for (const auto* pair : {&a.cubes.terms[0].g, &a.cubes.terms[0].h}) {
        const CubeMap& ca = *pair;
        const CubeMap& cb = pair == &a.cubes.terms[0].g ? b.cubes.terms[0].g : b.cubes.terms[0].h;
        ASSERT_EQ(ca.texels.size(), cb.texels.size());
        double mx = 0.0, worst = 0.0;
        for (std::size_t i = 0; i < ca.texels.size(); ++i)
            for (int k = 0; k < 3; ++k) {
                mx = std::max<double>(mx, ca.texels[i][k]);
                worst = std::max<double>(worst, std::abs(ca.texels[i][k] - cb.texels[i][k]));
            }
        EXPECT_LE(worst, 1e-4 * mx);
    }
    if (ctx().info().timestamps_supported()) {
        EXPECT_TRUE(b.timings.gpu_total_ns().has_value());
    }
}

// ---- several separable terms (issue 5) -------------------------------------------------

struct PresetLobe {
    const char* name;
    LafortuneRgb lobe;
};
// The synth presets' lobes (engine/synth/presets.cpp, red channel) and a near-mirror lobe.
const PresetLobe kPresetLobes[] = {
    {"can", gray(-0.8962f, 0.7587f, 10.11f)},     {"cologne", gray(-0.8874f, 1.1162f, 18.09f)},
    {"vase", gray(-1.2127f, 0.5653f, 20.36f)},    {"woodenpot", gray(-1.4299f, -0.7763f, 9.74f)},
    {"mirror300", gray(-1.0f, 1.0f, 300.0f)},
};

// Every further term lowers the error of the sum, on the grid (matrix) and against the lobe
// through the cube-maps (direct), at the default resolutions. Measured (factorization_sweep
// --terms): matrix relative RMS K = 1 -> 4: can 0.41 -> 0.15, cologne 0.095 -> 0.039, vase
// 0.39 -> 0.10, woodenpot 0.35 -> 0.027, mirror300 0.67 -> 0.42. Asserted: strictly
// decreasing with K, and K = 4 at most 0.7 (matrix) and 0.8 (direct: cologne 0.77, woodenpot
// 0.75, where interpolation between grid cells is most of what is left) of K = 1.
// (The thesis's GSHD, forced; the mirrored parametrization's figures are below.)
TEST(FactorizationTerms, ErrorDecreasesWithKOnThePresetLobes) {
    for (const PresetLobe& l : kPresetLobes) {
        const Factorization f = factorize_cpu(l.lobe, {.keep_matrix = true, .terms = kMaxFactorTerms, .param = FactorParam::Gshd});
        ASSERT_EQ(f.term_count(), kMaxFactorTerms) << l.name;
        ASSERT_EQ(f.terms.matrix_rms.size(), kMaxFactorTerms) << l.name;
        EXPECT_TRUE(f.terms.forced);
        std::vector<const Decomposition*> grids;
        std::vector<double> direct;
        for (uint32_t k = 0; k < kMaxFactorTerms; ++k) {
            grids.push_back(&f.grids[k]);
            EXPECT_NEAR(matrix_relative_rms(*f.matrix, grids), f.terms.matrix_rms[k], 1e-12) << l.name;
            direct.push_back(direct_relative_rms(l.lobe, f, k + 1, 1u << 15).cube);
            if (k > 0) {
                EXPECT_LT(f.terms.matrix_rms[k], f.terms.matrix_rms[k - 1]) << l.name << " K = " << k + 1;
                EXPECT_LT(direct[k], direct[k - 1]) << l.name << " K = " << k + 1;
            }
            EXPECT_EQ(f.cubes.terms[k].g.resolution, f.resolution.cube_g);
            EXPECT_EQ(f.cubes.terms[k].h.resolution, f.resolution.cube_h);
        }
        EXPECT_LE(f.terms.matrix_rms.back(), 0.7 * f.terms.matrix_rms.front()) << l.name;
        EXPECT_LE(direct.back(), 0.8 * direct.front()) << l.name; // the grids' interpolation error stays
        // Term 1 is the thesis's: the same as a one-term factorization.
        const Factorization one = factorize_cpu(l.lobe, {.terms = 1, .param = FactorParam::Gshd});
        EXPECT_EQ(one.term_count(), 1u);
        EXPECT_EQ(one.grids[0].g, f.grids[0].g);
        EXPECT_EQ(one.cubes.terms[0].h.texels, f.cubes.terms[0].h.texels);
    }
}

// The automatic rule: the fewest terms whose matrix relative RMS meets the target, else the
// K of least error; the reason says which.
TEST(FactorizationTerms, AutomaticKMeetsTheTargetOrSaysItCannot) {
    // The mirrored parametrization: the warped one, which the automatic choice keeps for these
    // lobes, is rank 1 and takes one term without trying more (HugeLobeKeepsOneTerm).
    for (const PresetLobe& l : kPresetLobes) {
        const Factorization f = factorize_cpu(l.lobe, {.param = FactorParam::Mirrored});
        const TermChoice& t = f.terms;
        ASSERT_EQ(t.matrix_rms.size(), kMaxFactorTerms) << l.name;
        EXPECT_FALSE(t.forced);
        EXPECT_EQ(f.term_count(), t.count);
        const auto hit = std::find_if(t.matrix_rms.begin(), t.matrix_rms.end(), [&](double e) { return e <= t.target; });
        if (hit != t.matrix_rms.end()) {
            EXPECT_EQ(t.count, static_cast<uint32_t>(hit - t.matrix_rms.begin()) + 1) << l.name;
            EXPECT_NE(t.reason.find("the fewest terms"), std::string::npos) << t.reason;
        } else {
            EXPECT_EQ(t.count, static_cast<uint32_t>(std::min_element(t.matrix_rms.begin(), t.matrix_rms.end()) -
                                                     t.matrix_rms.begin()) + 1) << l.name;
            EXPECT_NE(t.reason.find("not reached"), std::string::npos) << t.reason;
        }
    }
    // A looser target is met with fewer terms: woodenpot 0.35, 0.062, 0.034, 0.027.
    const Factorization wp = factorize_cpu(kPresetLobes[3].lobe, {.term_target = 0.1, .param = FactorParam::Gshd});
    EXPECT_EQ(wp.term_count(), 2u) << wp.terms.reason;
    EXPECT_LE(wp.terms.matrix_rms[1], 0.1);
    // Forcing K = 1 is the thesis.
    const Factorization forced = factorize_cpu(kPresetLobes[0].lobe, {.terms = 1});
    EXPECT_EQ(forced.cubes.terms.size(), 1u); // no further terms
    EXPECT_NE(forced.terms.reason.find("forced K = 1"), std::string::npos) << forced.terms.reason;
    EXPECT_THROW((void)factorize_cpu(kPresetLobes[0].lobe, {.terms = kMaxFactorTerms + 1}), Error);
    EXPECT_THROW((void)factorize_cpu(kPresetLobes[0].lobe, {.max_terms = 0}), Error);
}

// A lobe too high for the residual kernels' float sums keeps one term and says why (in the
// parametrizations whose F is the lobe itself; the warped F is in [0, 1] and needs one term).
TEST(FactorizationTerms, HugeLobeKeepsOneTerm) {
    const LafortuneRgb huge = gray(-4.0f, 4.0f, 40.0f); // height 4^40 = 1.2e24
    for (const FactorParam param : {FactorParam::Gshd, FactorParam::Mirrored}) {
        const Factorization f = factorize_cpu(huge, {.grid_h = 8, .grid_d = 8, .param = param});
        EXPECT_EQ(f.term_count(), 1u);
        EXPECT_NE(f.terms.reason.find("one term only"), std::string::npos) << f.terms.reason;
    }
    const Factorization w = factorize_cpu(huge, {.grid_h = 8, .grid_d = 8, .param = FactorParam::Warped});
    EXPECT_EQ(w.term_count(), 1u) << w.terms.reason;
    EXPECT_NE(w.terms.reason.find("rank 1 per channel: one term"), std::string::npos) << w.terms.reason;
    EXPECT_LT(w.terms.matrix_rms[0], 1e-5);
    EXPECT_TRUE(all_finite(w));
}

TEST_F(FactorizationVulkan, SeveralTermsMatchCpuEndToEnd) {
    // The whole multi-term path: same K chosen, the same matrix errors, and every term's
    // cube-maps agree (tolerance: see tests/kernels/factorization_residual_term_test.cpp,
    // which bounds the terms' products; 1e-3 of the largest |texel| of term 1 here).
    FactorizeVk vk(ctx());
    for (const LafortuneRgb& lobe : {gray(-0.8962f, 0.7587f, 10.11f), gray(-1.4299f, -0.7763f, 9.74f)}) {
        // Mirrored: these gray lobes are exactly rank 1 warped, where terms 2..3 would fit round-off.
        const auto a = factorize_cpu(lobe, {.grid_h = 12, .grid_d = 10, .terms = 3, .param = FactorParam::Mirrored});
        const auto b = vk.run(lobe, {.grid_h = 12, .grid_d = 10, .terms = 3, .param = FactorParam::Mirrored});
        ASSERT_EQ(b.term_count(), 3u);
        ASSERT_EQ(b.terms.matrix_rms.size(), 3u);
        for (std::size_t k = 0; k < 3; ++k) EXPECT_NEAR(a.terms.matrix_rms[k], b.terms.matrix_rms[k], 1e-4);
        double mx = 0.0;
        for (const glm::vec3& t : a.cubes.terms[0].g.texels) mx = std::max<double>(mx, glm::length(t));
        for (uint32_t k = 1; k < 3; ++k)
            for (const bool g : {true, false})
                EXPECT_LE(relative_cube_difference(g ? a.cubes.terms[k].g : a.cubes.terms[k].h,
                                                   g ? b.cubes.terms[k].g : b.cubes.terms[k].h),
                          1e-3)
                    << "term " << k + 1 << (g ? " G" : " H");
        const auto autok = vk.run(lobe, {.grid_h = 12, .grid_d = 10, .param = FactorParam::Mirrored});
        const auto autoc = factorize_cpu(lobe, {.grid_h = 12, .grid_d = 10, .param = FactorParam::Mirrored});
        EXPECT_EQ(autok.term_count(), autoc.term_count()) << autok.terms.reason << " / " << autoc.terms.reason;
        if (ctx().info().timestamps_supported()) {
            EXPECT_TRUE(b.timings.residual_gpu_ns.has_value());
        }
    }
}

// ---- the mirrored parametrization (shared/gshd.h part 4) -------------------------------

LafortuneRgb negated_cx(LafortuneRgb l) {
    l.cx = -l.cx;
    return l;
}

// F in the mirrored parametrization is, bit for bit, F in the plain one of the lobe with Cx
// negated: the lobe at (r(u), v) has base Cx (-ux vx - uy vy) + Cz uz vz, and negating a float
// is exact. So a lobe about the mirror direction (Cx < 0) looks, mirrored, as a retro-reflective
// one (Cx > 0) looks plain, and conversely.
TEST(MirroredGshd, MatrixIsThePlainMatrixOfTheNegatedCx) {
    for (const PresetLobe& l : kPresetLobes) {
        const BrdfMatrix m = brdf_matrix_cpu({.model = l.lobe, .res_h = 12, .res_d = 10, .param = FactorParam::Mirrored});
        const BrdfMatrix p = brdf_matrix_cpu({.model = negated_cx(l.lobe), .res_h = 12, .res_d = 10, .param = FactorParam::Gshd});
        EXPECT_EQ(m.param, FactorParam::Mirrored);
        EXPECT_EQ(m.values, p.values) << l.name;
    }
}

/// Best rank-1 approximation g(h) x(d) of F over its valid entries (alternating least
/// squares, per channel, in double): relative RMS, all channels.
double best_rank1_rms(const BrdfMatrix& m, int iterations) {
    const std::size_t rows = m.rows(), cols = m.cols();
    double err = 0.0, ref = 0.0;
    for (uint32_t c = 0; c < 3; ++c) {
        std::vector<double> g(rows, 1.0), h(cols, 1.0);
        for (int it = 0; it < iterations; ++it) {
            for (std::size_t col = 0; col < cols; ++col) {
                double num = 0.0, den = 0.0;
                for (std::size_t row = 0; row < rows; ++row)
                    if (const double f = m.at(c, row, col); f >= 0.0) num += f * g[row], den += g[row] * g[row];
                h[col] = den > 0.0 ? num / den : 0.0;
            }
            for (std::size_t row = 0; row < rows; ++row) {
                double num = 0.0, den = 0.0;
                for (std::size_t col = 0; col < cols; ++col)
                    if (const double f = m.at(c, row, col); f >= 0.0) num += f * h[col], den += h[col] * h[col];
                g[row] = den > 0.0 ? num / den : 0.0;
            }
        }
        for (std::size_t row = 0; row < rows; ++row)
            for (std::size_t col = 0; col < cols; ++col)
                if (const double f = m.at(c, row, col); f >= 0.0) err += (g[row] * h[col] - f) * (g[row] * h[col] - f), ref += f * f;
    }
    return std::sqrt(err / ref);
}

// A Phong lobe about the mirror direction, Cx = -Cz: f = Cz^N (r(u).v)^N = Cz^N cos(2 theta_d)^N
// is a function of the mirrored d alone, so the mirrored F is exactly rank 1 (every valid entry
// of a column equal), the plain one far from it. The thesis's normalized decomposition (term 1)
// does not find the exact rank-1 term of a matrix with invalid entries (G(h) is the RMS over the
// row's valid entries, and the valid set changes from row to row: measured 33% mirrored vs 47%
// plain at K = 1), the residual terms do: K = 3 1.6% mirrored, plain K = 4 still 16%.
TEST(MirroredGshd, PhongLobeIsRankOneMirroredNotPlain) {
    const LafortuneRgb phong = gray(-1.0f, 1.0f, 10.0f);
    for (const FactorParam param : {FactorParam::Mirrored, FactorParam::Gshd}) {
        const BrdfMatrix m = brdf_matrix_cpu({.model = phong, .res_h = 16, .res_d = 16, .param = param});
        double spread = 0.0; // largest (max - min) / max over a column's valid entries
        for (std::size_t col = 0; col < m.cols(); ++col) {
            double lo = 1e300, hi = 0.0;
            for (std::size_t row = 0; row < m.rows(); ++row)
                if (const double f = m.at(0, row, col); f >= 0.0) lo = std::min(lo, f), hi = std::max(hi, f);
            if (hi > 1e-6) spread = std::max(spread, (hi - lo) / hi);
        }
        const double rank1 = best_rank1_rms(m, 30);
        const Factorization f = factorize_cpu(phong, {.grid_h = 16, .grid_d = 16, .terms = kMaxFactorTerms, .param = param});
        std::printf("%s: column spread %.3g, best rank-1 relative RMS %.3g, factorization K = 1..4: %.3f %.3f %.3f %.3f\n",
                    to_string(param), spread, rank1, f.terms.matrix_rms[0], f.terms.matrix_rms[1], f.terms.matrix_rms[2],
                    f.terms.matrix_rms[3]);
        if (param == FactorParam::Mirrored) {
            EXPECT_LT(spread, 1e-6);           // float rounding of the stored entries
            EXPECT_LT(rank1, 1e-6);
            EXPECT_LT(f.terms.matrix_rms[2], 0.03);
        } else {
            EXPECT_GT(spread, 0.5);
            EXPECT_GT(rank1, 0.2);
            EXPECT_GT(f.terms.matrix_rms[3], 0.1);
        }
    }
    // And the converse: a retro-reflective lobe, Cx = +Cz, is rank 1 in the plain GSHD.
    EXPECT_LT(best_rank1_rms(brdf_matrix_cpu({.model = gray(1.0f, 1.0f, 10.0f), .res_h = 16, .res_d = 16}), 30), 1e-6);
}

// The can's lobe (|Cx| > Cz, issue 5's unmet criterion) at the default resolutions and the
// automatic K: measured (factorization_sweep --terms) plain (16 x 16) K = 4 matrix 15.5%,
// against the lobe through the cube-maps 25.8%; mirrored (16 x 51) K = 3 2.0% and 3.3% (on a
// 16 x 16 grid 1.8% and 10.1%: the rest is interpolation). The automatic choice keeps the
// mirrored one and says why with both errors.
TEST(MirroredGshd, ImprovesTheCanLobe) {
    const LafortuneRgb can = kPresetLobes[0].lobe;
    const Factorization plain = factorize_cpu(can, {.param = FactorParam::Gshd});
    const Factorization mirrored = factorize_cpu(can, {.param = FactorParam::Mirrored});
    EXPECT_EQ(plain.cubes.param, FactorParam::Gshd);
    EXPECT_EQ(mirrored.cubes.param, FactorParam::Mirrored);
    EXPECT_TRUE(mirrored.param_choice.forced);
    EXPECT_FALSE(mirrored.param_choice.of(FactorParam::Gshd).computed);
    const ParamCandidate& a = plain.param_choice.of(FactorParam::Gshd);
    const ParamCandidate& b = mirrored.param_choice.of(FactorParam::Mirrored);
    EXPECT_LE(b.terms.matrix_rms[b.terms.count - 1], 0.25 * a.terms.matrix_rms[a.terms.count - 1]);
    EXPECT_LE(b.direct_rms, 0.2 * a.direct_rms);
    EXPECT_LE(b.terms.count, a.terms.count);
    // The errors of what is rendered, from the factorization itself.
    EXPECT_NEAR(direct_relative_rms(can, mirrored, 0, kParamChoicePairs).cube, b.direct_rms, 1e-12);
    // The automatic choice keeps the warped one (tests below).
    const Factorization chosen = factorize_cpu(can, {});
    EXPECT_EQ(chosen.cubes.param, FactorParam::Warped) << chosen.param_choice.reason;
    EXPECT_FALSE(chosen.param_choice.forced);
}

// Between the thesis's GSHD and the mirrored one, the choice follows the sign of Cx (the
// rendered comparisons agree: tests/render): mirrored for the presets (Cx < 0), plain for a
// retro-reflective lobe, and plain (the thesis) when both matrices are equal (Cx = 0).
TEST(MirroredGshd, ChoiceBetweenPlainAndMirroredFollowsTheSignOfCx) {
    const auto plain_or_mirrored = [](const LafortuneRgb& lobe, FactorizationOptions o) {
        const Factorization a = factorize_cpu(lobe, (o.param = FactorParam::Gshd, o));
        const Factorization b = factorize_cpu(lobe, (o.param = FactorParam::Mirrored, o));
        const double ea = a.param_choice.of(FactorParam::Gshd).direct_rms;
        const double eb = b.param_choice.of(FactorParam::Mirrored).direct_rms;
        return std::abs(ea - eb) <= kParamTieMargin * std::max(ea, eb) ? FactorParam::Gshd
               : eb < ea                                               ? FactorParam::Mirrored
                                                                       : FactorParam::Gshd;
    };
    for (const PresetLobe& l : kPresetLobes) EXPECT_EQ(plain_or_mirrored(l.lobe, {}), FactorParam::Mirrored) << l.name;
    EXPECT_EQ(plain_or_mirrored(gray(0.9f, 0.8f, 12.0f), {}), FactorParam::Gshd);
    EXPECT_EQ(plain_or_mirrored(gray(0.0f, 1.0f, 8.0f), {.grid_h = 8, .grid_d = 8}), FactorParam::Gshd);
}

// ---- the warped parametrization (shared/gshd.h part 5) ---------------------------------

TEST(WarpedGshd, RoundTripAndHemispheres) {
    std::mt19937 rng(5);
    for (const glm::dvec2 warp : {glm::dvec2(-1.0, 0.47), glm::dvec2(1.0, 2.3), glm::dvec2(-1.0, 1.0)})
        for (int i = 0; i < 5000; ++i) {
            const glm::dvec3 u = random_hemisphere(rng), v = random_hemisphere(rng);
            const f64::GshdCoords c = f64::gshd_from_uv_warped(u, v, shared::kGshdWarped, warp);
            EXPECT_GE(c.h.z, 0.0);
            EXPECT_GE(c.d.z, 0.0);
            const f64::GshdPair p = f64::gshd_to_uv_warped(c.h, c.d, shared::kGshdWarped, warp);
            EXPECT_NEAR(glm::length(p.u - u), 0.0, 1e-9);
            EXPECT_NEAR(glm::length(p.v - v), 0.0, 1e-9);
            if (warp == glm::dvec2(-1.0, 1.0)) { // the warp (-1, 1) is the mirror direction
                const f64::GshdCoords m = f64::gshd_from_uv_param(u, v, shared::kGshdMirrored);
                EXPECT_NEAR(glm::length(c.d - m.d), 0.0, 1e-12);
            }
            // Other parametrizations ignore the warp.
            EXPECT_EQ(f64::gshd_from_uv_warped(u, v, shared::kGshdMirrored, warp).d,
                      f64::gshd_from_uv_param(u, v, shared::kGshdMirrored).d);
        }
}

// f = |C u|^N max(0, sign(Cz) w(u).v)^N (shared/gshd.h part 5): the radial factor times the
// normalized lobe is the lobe, for every sign of Cx and Cz.
TEST(WarpedGshd, RadialFactorTimesNormalizedLobeIsTheLobe) {
    std::mt19937 rng(6);
    for (const LafortuneRgb& l : {gray(-1.2127f, 0.5653f, 20.36f), gray(-1.43f, -0.78f, 9.7f), gray(0.9f, 0.8f, 12.0f),
                                  gray(0.5f, -1.0f, 3.0f)}) {
        for (int i = 0; i < 2000; ++i) {
            const glm::dvec3 u = random_hemisphere(rng), v = random_hemisphere(rng);
            const double f = shared::f64::lafortune_eval(l.cx.x, l.cz.x, l.n.x, u, v);
            const double g = shared::f64::lafortune_radial(l.cx.x, l.cz.x, l.n.x, u) * shared::f64::lafortune_normalized(l.cx.x, l.cz.x, l.n.x, u, v);
            EXPECT_NEAR(g, f, 1e-12 * (1.0 + f));
            EXPECT_LE(shared::f64::lafortune_normalized(l.cx.x, l.cz.x, l.n.x, u, v), 1.0);
        }
    }
}

// The warped F of every Lafortune lobe is exactly rank 1 per channel (shared/gshd.h part 5):
// every valid entry of a column equal, off-specular and Cz < 0 lobes and differing channels
// included; with term 1 refined by ALS (refine_first_term_cpu) one term has no matrix error,
// where the thesis's normalized decomposition alone keeps ~34% (the valid set changes from
// row to row), and the factor G is flat. Measured: 4e-8 after the 12 ALS iterations, but
// 6e-4 for woodenpot's Cz < 0 (F = max(0, 1 - 2 dz^2)^N is 0 on most of each row's valid
// entries, so rows see the peak through few columns and converge more slowly; G is 0 on rows
// whose valid entries are all 0).
TEST(WarpedGshd, EveryLafortuneLobeIsRankOnePerChannel) {
    std::vector<PresetLobe> lobes(std::begin(kPresetLobes), std::end(kPresetLobes));
    lobes.push_back({"vase_rgb", {{-1.2127f, -1.2050f, -1.1980f}, {0.5653f, 0.5700f, 0.5750f}, {20.36f, 20.00f, 19.70f}}});
    lobes.push_back({"retro_mixed", {{0.9f, 1.1f, 0.5f}, {0.8f, 0.7f, 2.0f}, {12.0f, 8.0f, 30.0f}}});
    for (const PresetLobe& l : lobes) {
        const std::optional<glm::vec4> warp = warp_for_lobe(l.lobe);
        ASSERT_TRUE(warp.has_value()) << l.name;
        const BrdfMatrix m = brdf_matrix_cpu({.model = l.lobe, .res_h = 12, .res_d = 16, .param = FactorParam::Warped, .warp = *warp});
        for (uint32_t c = 0; c < 3; ++c) {
            double spread = 0.0;
            for (std::size_t col = 0; col < m.cols(); ++col) {
                double lo = 1e300, hi = 0.0;
                for (std::size_t row = 0; row < m.rows(); ++row)
                    if (const double f = m.at(c, row, col); f >= 0.0) lo = std::min(lo, f), hi = std::max(hi, f);
                if (hi > 1e-6) spread = std::max(spread, (hi - lo) / hi);
            }
            EXPECT_LT(spread, 1e-5) << l.name << " channel " << c;
        }
        const Factorization plain_term = factorize_cpu(l.lobe, {.grid_h = 12, .grid_d = 16, .keep_matrix = true, .terms = 1,
                                                               .first_iterations = 0, .param = FactorParam::Warped});
        const Factorization f = factorize_cpu(l.lobe, {.grid_h = 12, .grid_d = 16, .keep_matrix = true,
                                                      .param = FactorParam::Warped});
        std::printf("%s: warp (%g, %g, %g, %g); K = 1 matrix RMS %.4f normalized decomposition alone, %.2g with ALS\n",
                    l.name, f.cubes.warp.x, f.cubes.warp.y, f.cubes.warp.z, f.cubes.warp.w, plain_term.terms.matrix_rms[0], f.terms.matrix_rms[0]);
        EXPECT_EQ(f.cubes.warp, *warp);
        EXPECT_EQ(f.term_count(), 1u) << f.terms.reason;
        EXPECT_GT(plain_term.terms.matrix_rms[0], 0.1);
        const bool horizon_peak = l.lobe.cz.x < 0.0f;
        EXPECT_LT(f.terms.matrix_rms[0], horizon_peak ? 1e-3 : 1e-6);
        EXPECT_LT(best_rank1_rms(*f.matrix, 30), 1e-5);
        if (horizon_peak) continue;
        for (uint32_t c = 0; c < 3; ++c) {
            float lo = 1e30f, hi = 0.0f;
            for (const glm::vec3& g : f.grids[0].g) lo = std::min(lo, g[c]), hi = std::max(hi, g[c]);
            EXPECT_LT(hi - lo, 1e-4f * hi) << l.name << ": G is flat";
        }
    }
}

// The automatic choice keeps the warped parametrization for every preset lobe without
// factorizing the other two (its error against the lobe through the cube-maps is within
// kWarpedGoodEnough, with one term), and says why; a lobe whose warped error is above that
// (the N = 300 mirror: its d grid is capped at 128 cells, 485 by the rule) gets all three and
// the least error, still warped; a lobe it does not fit (Cx = 0) is not offered it, and the
// reason says so.
TEST(WarpedGshd, AutomaticChoiceKeepsWarpedForThePresets) {
    for (const PresetLobe& l : kPresetLobes) {
        const Factorization f = factorize_cpu(l.lobe, {});
        EXPECT_EQ(f.cubes.param, FactorParam::Warped) << l.name << ": " << f.param_choice.reason;
        const double e = f.param_choice.of(FactorParam::Warped).direct_rms;
        const bool good = e <= kWarpedGoodEnough;
        std::printf("%s: %s\n", l.name, f.param_choice.reason.c_str());
        EXPECT_EQ(good, l.lobe.n.x < 100.0f) << l.name << " " << e; // measured 0.2% to 0.4%; mirror300 5.3%
        for (const FactorParam p : {FactorParam::Gshd, FactorParam::Mirrored}) {
            EXPECT_EQ(f.param_choice.of(p).computed, !good) << l.name;
            if (!good) {
                EXPECT_LT(e, f.param_choice.of(p).direct_rms) << l.name;
            }
        }
        if (good) {
            EXPECT_NE(f.param_choice.reason.find("left out"), std::string::npos) << f.param_choice.reason;
        }
        EXPECT_EQ(f.grids[0].param, f.cubes.param);
        EXPECT_EQ(f.grids[0].warp, f.cubes.warp);
        EXPECT_EQ(f.term_count(), 1u);
        EXPECT_LT(e, l.lobe.n.x < 100.0f ? 0.01 : 0.08) << l.name;
    }
    const Factorization flat = factorize_cpu(gray(0.0f, 1.0f, 8.0f), {.grid_h = 8, .grid_d = 8});
    EXPECT_EQ(flat.cubes.param, FactorParam::Gshd) << flat.param_choice.reason;
    EXPECT_FALSE(flat.param_choice.of(FactorParam::Warped).computed);
    EXPECT_NE(flat.param_choice.reason.find("warped not offered"), std::string::npos) << flat.param_choice.reason;
    EXPECT_THROW((void)factorize_cpu(gray(0.0f, 1.0f, 8.0f), {.grid_h = 8, .grid_d = 8, .param = FactorParam::Warped}), Error);
    // The channels' signs of Cx Cz differ: no single warp.
    EXPECT_FALSE(warp_for_lobe(LafortuneRgb{{-1.0f, 1.0f, -1.0f}, {1.0f, 1.0f, 1.0f}, {8.0f, 8.0f, 8.0f}}).has_value());
}

// A lobe whose channels' warps differ a little (knot_hd's fit: k = |Cz| / |Cx| 0.932, 0.960,
// 0.991) keeps one warp shared by the channels, the geometric mean, at an error within
// kSharedWarpGoodEnough, and report.json's warped_per_channel keeps the exact one's figures; one
// whose warps differ by a factor of 4 keeps a warp per channel and says why; either can be forced.
TEST(WarpedGshd, OneWarpForTheChannelsWhereItsErrorAllows) {
    const LafortuneRgb near{{-1.0213f, -1.0105f, -0.9771f}, {0.9515f, 0.9702f, 0.9683f}, {14.2f, 14.7f, 15.0f}};
    const glm::vec4 exact = *warp_for_lobe(near);
    const Factorization f = factorize_cpu(near, {});
    std::printf("near: %s\n", f.param_choice.reason.c_str());
    ASSERT_EQ(f.cubes.param, FactorParam::Warped);
    EXPECT_TRUE(is_shared_warp(f.cubes.warp)) << f.param_choice.reason;
    EXPECT_NEAR(f.cubes.warp.y, std::cbrt(double(exact.y) * exact.z * exact.w), 1e-6);
    EXPECT_EQ(f.cubes.warp.x, exact.x);
    EXPECT_EQ(f.grids[0].warp, f.cubes.warp);
    ASSERT_TRUE(f.param_choice.warped_per_channel.has_value());
    const double shared_rms = f.param_choice.of(FactorParam::Warped).direct_rms;
    const double per_rms = f.param_choice.warped_per_channel->direct_rms;
    EXPECT_LE(shared_rms, kSharedWarpGoodEnough);
    EXPECT_LT(per_rms, shared_rms); // the exact warps are the better fit, at three times the lookups
    EXPECT_LE(f.term_count(), 3 * f.param_choice.warped_per_channel->terms.count);
    EXPECT_NE(f.param_choice.reason.find("kept"), std::string::npos) << f.param_choice.reason;
    // The error the choice measured is that of the cube-maps kept.
    EXPECT_NEAR(direct_relative_rms(near, f, 0, kParamChoicePairs).cube, shared_rms, 1e-12);

    const Factorization per = factorize_cpu(near, {.shared_warp = false});
    EXPECT_EQ(per.cubes.warp, exact);
    EXPECT_FALSE(per.param_choice.warped_per_channel.has_value());
    EXPECT_NEAR(per.param_choice.of(FactorParam::Warped).direct_rms, per_rms, 1e-12);
    const Factorization forced = factorize_cpu(near, {.shared_warp = true});
    EXPECT_EQ(forced.cubes.warp, f.cubes.warp);

    const LafortuneRgb apart{{-1.6f, -1.0f, -0.4f}, {0.8f, 1.0f, 1.2f}, {14.0f, 14.0f, 14.0f}}; // k 0.5, 1, 3
    const Factorization g = factorize_cpu(apart, {});
    std::printf("apart: %s\n", g.param_choice.reason.c_str());
    ASSERT_EQ(g.cubes.param, FactorParam::Warped);
    EXPECT_EQ(g.cubes.warp, *warp_for_lobe(apart));
    EXPECT_FALSE(g.param_choice.warped_per_channel.has_value());
    EXPECT_NE(g.param_choice.reason.find("so a warp per channel"), std::string::npos) << g.param_choice.reason;
}

// The mirrored grids swap the plain rule's axes (resolution.cpp), the peak's (d) finer: a narrow
// lobe needs the fine grid along d there.
TEST(MirroredGshd, DefaultResolutionSwapsTheAxes) {
    for (const LafortuneRgb& lobe : {gray(-1.0f, 1.0f, 1000.0f), gray(-1.2127f, 0.5653f, 400.0f), kPresetLobes[0].lobe,
                                     kPresetLobes[1].lobe}) { // the can and cologne: h 16 as plain
        const FactorizationResolution p = default_resolution(lobe, FactorParam::Gshd);
        const FactorizationResolution m = default_resolution(lobe, FactorParam::Mirrored);
        const double n = lobe.n[0];
        EXPECT_LE(m.grid_h, p.grid_d); // reduced first when F would exceed one binding (N = 400: 24 for 30)
        EXPECT_EQ(m.cube_g, cube_res_for_grid(m.grid_h));
        EXPECT_LE(m.grid_h * m.grid_d, kMaxGridProduct);
        EXPECT_EQ(m.grid_d, std::clamp(static_cast<uint32_t>(std::ceil(kMirroredPeakCellsPerHalfWidth * std::sqrt(n))),
                                       kMinGridRes, kMaxGridResH));
        EXPECT_EQ(m.cube_h, cube_res_for_grid(m.grid_d));
        EXPECT_GE(m.grid_d, p.grid_h);
        EXPECT_GT(m.grid_d, m.grid_h);
        EXPECT_NE(m.reason.find("mirrored"), std::string::npos);
    }
    EXPECT_EQ(default_resolution(kPresetLobes[0].lobe, FactorParam::Mirrored).grid_d, 51u); // the can, N = 10.11
    // The mirror lobe at N = 1000: the mirrored factorization on its own grids (16 x 128) beats the
    // plain one (64 x 16) against the lobe (measured at K = 2: 16% vs 55% through the cube-maps).
    const LafortuneRgb mirror = gray(-1.0f, 1.0f, 1000.0f);
    const Factorization f = factorize_cpu(mirror, {.max_terms = 2});
    std::printf("mirror N = 1000: %s\n", f.param_choice.reason.c_str());
    EXPECT_NE(f.cubes.param, FactorParam::Gshd) << f.param_choice.reason;
    EXPECT_EQ(f.resolution.grid_d, default_resolution(mirror, f.cubes.param).grid_d);
}

// ---- the coated family (shared/coated.h) ----------------------------------------------

CoatedParams coated(float alpha, float eta = 1.5f, glm::vec3 tint = glm::vec3(1.0f)) {
    return CoatedParams{.eta = eta, .alpha = alpha, .tint = tint};
}

// The coated grids (resolution.cpp coated_resolution): the grazing axis (d plain, h mirrored)
// grows with alpha within [32, 64], the GGX peak's axis takes the rest of F's budget; in
// the mirrored parametrization the axes swap.
TEST(CoatedFamily, DefaultResolutionFollowsAlpha) {
    const struct {
        float alpha;
        uint32_t peak, grazing;
    } expected[] = {{0.05f, 96, 32}, {0.12f, 64, 48}, {0.25f, 48, 64}, {0.4f, 48, 64}, {0.002f, 96, 32}, {1.0f, 48, 64}};
    for (const auto& e : expected) {
        const FactorizationResolution p = default_resolution(coated(e.alpha), FactorParam::Gshd);
        const FactorizationResolution m = default_resolution(coated(e.alpha), FactorParam::Mirrored);
        EXPECT_EQ(p.grid_h, e.peak) << e.alpha;
        EXPECT_EQ(p.grid_d, e.grazing) << e.alpha;
        EXPECT_EQ(m.grid_h, e.grazing) << e.alpha;
        EXPECT_EQ(m.grid_d, e.peak) << e.alpha;
        EXPECT_LE(p.grid_h * p.grid_d, kMaxGridProduct);
        EXPECT_EQ(p.cube_g, cube_res_for_grid(p.grid_h));
        EXPECT_EQ(m.cube_h, cube_res_for_grid(m.grid_d));
        EXPECT_NE(p.reason.find("coated"), std::string::npos) << p.reason;
    }
}

// The weight exponent: 0 for every lobe and for a sharp coated lobe, rising linearly to
// kCoatedWeightExponent between alpha kCoatedWeightAlphaLow and kCoatedWeightAlphaHigh.
TEST(CoatedFamily, WeightExponentFollowsAlpha) {
    EXPECT_EQ(default_weight_exponent(gray(-1.0f, 1.0f, 10.0f)), 0.0f);
    EXPECT_EQ(default_weight_exponent(coated(0.05f)), 0.0f);
    EXPECT_EQ(default_weight_exponent(coated(kCoatedWeightAlphaLow)), 0.0f);
    EXPECT_NEAR(default_weight_exponent(coated(0.5f * (kCoatedWeightAlphaLow + kCoatedWeightAlphaHigh))),
                0.5f * kCoatedWeightExponent, 1e-6f);
    EXPECT_EQ(default_weight_exponent(coated(kCoatedWeightAlphaHigh)), kCoatedWeightExponent);
    EXPECT_EQ(default_weight_exponent(coated(0.4f)), kCoatedWeightExponent);
    const Factorization f = factorize_cpu(coated(0.4f), {.grid_h = 12, .grid_d = 10, .param = FactorParam::Gshd});
    EXPECT_EQ(f.weight_q, kCoatedWeightExponent);
    EXPECT_NE(f.resolution.reason.find("weighted"), std::string::npos) << f.resolution.reason;
    EXPECT_THROW((void)factorize_cpu(coated(0.4f), {.grid_h = 8, .grid_d = 8, .param = FactorParam::Gshd, .weight_q = -1.0f}),
                 Error);
}

// unweight_decomposition divides G by h.z^q and H by d.z^q at the cell centres: the inverse of
// the weight brdf_matrix applies, so a separable F = x(h) y(d) weighted and decomposed gives back
// x and y up to one scale (the decomposition of a rank-1 matrix is exact).
TEST(CoatedFamily, UnweightingInvertsTheWeight) {
    const uint32_t rh = 7, rd = 5;
    const float q = 1.7f;
    BrdfMatrix m{.res_h = rh, .res_d = rd, .weight_q = q, .values = {}};
    m.values.assign(3 * m.rows() * m.cols(), 0.0f);
    const auto x = [](std::size_t i, int c) { return 0.5 + 0.1 * static_cast<double>((i * 7 + c) % 11); };
    const auto y = [](std::size_t j, int c) { return 0.2 + 0.05 * static_cast<double>((j * 3 + c) % 13); };
    for (int c = 0; c < 3; ++c)
        for (std::size_t i = 0; i < m.rows(); ++i)
            for (std::size_t j = 0; j < m.cols(); ++j) {
                const double w = std::pow(f64::gshd_grid_dir(static_cast<uint32_t>(i), rh).z *
                                              f64::gshd_grid_dir(static_cast<uint32_t>(j), rd).z,
                                          static_cast<double>(q));
                m.values[(c * m.rows() + i) * m.cols() + j] = static_cast<float>(x(i, c) * y(j, c) * w);
            }
    Decomposition d = normalized_decomposition_cpu({.matrix = &m});
    unweight_decomposition(d, q);
    for (int c = 0; c < 3; ++c) {
        const double scale = d.g[0][c] / x(0, c);
        for (std::size_t i = 0; i < m.rows(); ++i) EXPECT_NEAR(d.g[i][c] / x(i, c), scale, 1e-5 * scale) << i;
        for (std::size_t j = 0; j < m.cols(); ++j) EXPECT_NEAR(d.h[j][c] * scale, y(j, c), 1e-5 * y(j, c)) << j;
    }
    Decomposition same = d;
    unweight_decomposition(same, 0.0f); // q = 0: nothing to undo
    EXPECT_EQ(same.g, d.g);
    EXPECT_EQ(same.h, d.h);
}

// The automatic choice for a coated model: the warped parametrization is not offered (its F
// divides by the Lafortune lobe's radial factor), nor the mirrored one (measured far worse), and
// the reason says both and why. The plain GSHD suits the GGX reflection (h is its half vector:
// D(n.h) is a function of h alone, the Fresnel factor of d alone): the forced mirrored one,
// against the model through the cube-maps, keeps more than twice the plain one's error (measured
// at alpha 0.25, plain 48 x 64 K = 3, mirrored 64 x 48 K = 4: 2.9% vs 67.5%).
TEST(CoatedFamily, AutomaticChoiceIsThePlainGshdAndSaysWhy) {
    const SpecularModel model = coated(0.25f);
    const Factorization f = factorize_cpu(model, {});
    std::printf("coated alpha 0.25: %s\n  %s\n  %s\n", f.param_choice.reason.c_str(), f.resolution.reason.c_str(),
                f.terms.reason.c_str());
    EXPECT_FALSE(f.param_choice.of(FactorParam::Warped).computed);
    EXPECT_TRUE(f.param_choice.of(FactorParam::Gshd).computed);
    EXPECT_FALSE(f.param_choice.of(FactorParam::Mirrored).computed);
    EXPECT_NE(f.param_choice.reason.find("warped not offered: the coated family has no Lafortune radial factor"),
              std::string::npos)
        << f.param_choice.reason;
    EXPECT_NE(f.param_choice.reason.find("mirrored not offered"), std::string::npos) << f.param_choice.reason;
    EXPECT_EQ(f.cubes.param, FactorParam::Gshd);
    const double plain = f.param_choice.of(FactorParam::Gshd).direct_rms;
    const Factorization m = factorize_cpu(model, {.param = FactorParam::Mirrored});
    const double mirrored = m.param_choice.of(FactorParam::Mirrored).direct_rms;
    EXPECT_LT(plain, 0.1);
    EXPECT_GT(mirrored, 2.0 * plain);
    EXPECT_EQ(f.grids[0].param, FactorParam::Gshd);
    EXPECT_TRUE(all_finite(f));
    EXPECT_THROW((void)factorize_cpu(model, {.grid_h = 8, .grid_d = 8, .param = FactorParam::Warped}), Error);
    std::string why;
    EXPECT_FALSE(warp_for_model(model, &why).has_value());
    EXPECT_NE(why.find("coated"), std::string::npos);
    EXPECT_TRUE(warp_for_model(gray(-1.0f, 0.8f, 10.0f)).has_value());
}

// The Vulkan path of a weighted coated factorization (the grids unweighted on the host, every
// cube-map made in a second submit) agrees with the reference: term 1's cube-maps within 1e-3
// of their largest texel (the per-kernel tolerances are in tests/kernels), the same matrix
// errors for every K and the same error of the K terms' sum against the model. Terms 2..K are
// compared through these sums, not one by one: the coated F's residual singular values lie
// close together (the masking's variation is spread over several), so 12 ALS iterations from
// float and double round-off split the same sum differently between terms 2 and 3 (measured,
// alpha 0.08: the matrix errors agree to 1.3e-4, a term-2 texel differs by 0.6).
TEST_F(FactorizationVulkan, CoatedMatchesCpuEndToEnd) {
    FactorizeVk vk(ctx());
    for (const CoatedParams& c : {coated(0.3f, 1.6f, {1.0f, 0.9f, 0.7f}), coated(0.08f)}) {
        const FactorizationOptions o{.grid_h = 14, .grid_d = 12, .terms = 3, .param = FactorParam::Gshd};
        const auto a = factorize_cpu(c, o);
        const auto b = vk.run(c, o);
        EXPECT_EQ(a.weight_q, b.weight_q);
        ASSERT_EQ(b.term_count(), 3u);
        ASSERT_EQ(a.term_count(), 3u);
        for (std::size_t k = 0; k < 3; ++k) EXPECT_NEAR(a.terms.matrix_rms[k], b.terms.matrix_rms[k], 5e-4);
        for (const bool g : {true, false}) // term 1 (see above for terms 2..K)
            EXPECT_LE(relative_cube_difference(g ? a.cubes.terms[0].g : a.cubes.terms[0].h,
                                               g ? b.cubes.terms[0].g : b.cubes.terms[0].h),
                      1e-3)
                << "alpha " << c.alpha << (g ? " G" : " H");
        EXPECT_NEAR(direct_relative_rms(c, a, 0, 1u << 14).cube, direct_relative_rms(c, b, 0, 1u << 14).cube, 1e-3);
        if (ctx().info().timestamps_supported()) {
            EXPECT_TRUE(b.timings.gpu_total_ns().has_value());
        }
    }
}

// The C++ path's workers change nothing: each G and H entry is one worker's sum in the shader's
// order, each matrix entry is computed alone. A warped lobe (term 1 refined by ALS) and a rough
// coated lobe on several terms (residual terms), on 1 and 3 workers, equal bit for bit.
TEST(Factorization, TheSameForAnyThreadCount) {
    const std::vector<SpecularModel> models{kPresetLobes[0].lobe, coated(0.3f)};
    for (const SpecularModel& model : models) {
        FactorizationOptions o{.grid_h = 16, .grid_d = 24, .keep_matrix = true, .max_terms = 3, .term_target = 0.0};
        o.threads = 1;
        const Factorization one = factorize_cpu(model, o);
        o.threads = 3;
        const Factorization three = factorize_cpu(model, o);
        ASSERT_EQ(one.grids.size(), three.grids.size());
        EXPECT_GE(one.grids.size(), family_of(model) == MaterialFamily::Coated ? 2u : 1u);
        for (std::size_t k = 0; k < one.grids.size(); ++k) {
            EXPECT_EQ(one.grids[k].g, three.grids[k].g) << "term " << k;
            EXPECT_EQ(one.grids[k].h, three.grids[k].h) << "term " << k;
        }
        ASSERT_TRUE(one.matrix && three.matrix);
        EXPECT_EQ(one.matrix->values, three.matrix->values);
    }
}

} // namespace
} // namespace specula::factorization
