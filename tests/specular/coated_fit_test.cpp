// The coated family's fit (engine/specular/coated_fit.h) on total-BRDF samples made from a
// known material: the coated truth on the spread rig and on the thesis's near-camera rig, a
// Lafortune truth it must fit worse than its own family does, and outliers it must resist.
#include "specular/coated_fit.h"

#include "material/material.h"
#include "shared/material.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace specula {
namespace {

glm::vec3 random_direction(std::mt19937& rng, float min_cos) {
    std::uniform_real_distribution<float> u01(0.0f, 1.0f);
    const float cz = min_cos + (1.0f - min_cos) * u01(rng);
    const float phi = 6.2831853f * u01(rng);
    const float s = std::sqrt(std::max(0.0f, 1.0f - cz * cz));
    return {s * std::cos(phi), s * std::sin(phi), cz};
}

/// A light `degrees` away from v, around a random axis (the thesis's ring, chapter 3).
glm::vec3 near(const glm::vec3& v, float degrees, std::mt19937& rng) {
    const glm::vec3 any = std::abs(v.x) < 0.9f ? glm::vec3(1, 0, 0) : glm::vec3(0, 1, 0);
    const glm::vec3 a = glm::normalize(glm::cross(v, any)), b = glm::cross(v, a);
    const float phi = std::uniform_real_distribution<float>(0.0f, 6.2831853f)(rng);
    const float t = glm::radians(degrees);
    return glm::normalize(std::cos(t) * v + std::sin(t) * (std::cos(phi) * a + std::sin(phi) * b));
}

enum class Rig { Spread, Thesis };

/// Samples of b = (rho / pi) k_d + f_s for `truth`, with per-particle albedos, weight E^2.
std::vector<MaterialSample> make_samples(const SpecularModel& truth, Rig rig, std::size_t count, unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> albedo(0.1f, 0.8f);
    const shared::MaterialGpu m = material_gpu(truth);
    std::vector<MaterialSample> out;
    while (out.size() < count) {
        const glm::vec3 v = random_direction(rng, 0.15f);
        const glm::vec3 u = rig == Rig::Spread ? random_direction(rng, 0.15f) : near(v, 15.0f, rng);
        if (u.z < 0.15f) continue;
        const glm::vec3 rho_pi = glm::vec3(albedo(rng), albedo(rng), albedo(rng)) / 3.14159265f;
        const float ci = u.z, co = v.z, cuv = glm::dot(u, v);
        const glm::vec3 b = rho_pi * shared::material_diffuse_factor(m, ci, co) + shared::material_specular(m, ci, co, cuv);
        out.push_back({.u = u, .v = v, .b = b, .rho_over_pi = rho_pi, .weight = ci * ci});
    }
    return out;
}

TEST(CoatedFit, RecoversAlphaAndEtaOnTheSpreadRig) {
    for (const CoatedParams truth : {CoatedParams{.eta = 1.5f, .alpha = 0.12f}, CoatedParams{.eta = 1.35f, .alpha = 0.3f},
                                     CoatedParams{.eta = 1.65f, .alpha = 0.05f}}) {
        const std::vector<MaterialSample> s = make_samples(truth, Rig::Spread, 40000, 7);
        const CoatedFit fit = fit_coated(s);
        ASSERT_EQ(fit.status, CoatedFitStatus::Converged) << fit.reason;
        EXPECT_NEAR(fit.params.alpha, truth.alpha, 0.01 * truth.alpha);
        EXPECT_NEAR(fit.params.eta, truth.eta, 0.01 * truth.eta);
        EXPECT_LT(fit.rms, 1e-4);
        EXPECT_LT(fit.std_error_alpha, 0.01 * truth.alpha);
        EXPECT_LT(material_mean_square_error(fit.params, s), 1e-8);
    }
}

TEST(CoatedFit, FreeTintIsRecoveredBesideAlphaAndEta) {
    const CoatedParams truth{.eta = 1.5f, .alpha = 0.15f, .tint = {0.9f, 0.7f, 0.5f}};
    const CoatedFit fit = fit_coated(make_samples(truth, Rig::Spread, 40000, 3), {.fit_tint = true});
    ASSERT_TRUE(fit.usable()) << fit.reason;
    EXPECT_NEAR(fit.params.alpha, truth.alpha, 0.02 * truth.alpha);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(fit.params.tint[c], truth.tint[c], 0.03 * truth.tint[c]) << c;
}

// The sums run in fixed chunks added in order, the LM starts side by side: one thread or
// three give the same fit, bit for bit (40,000 samples: several chunks).
TEST(CoatedFit, TheSameFitOnAnyThreadCount) {
    const CoatedParams truth{.eta = 1.5f, .alpha = 0.15f, .tint = {0.9f, 0.7f, 0.5f}};
    const std::vector<MaterialSample> s = make_samples(truth, Rig::Spread, 40000, 3);
    const CoatedFit one = fit_coated(s, {.fit_tint = true, .threads = 1});
    const CoatedFit three = fit_coated(s, {.fit_tint = true, .threads = 3});
    ASSERT_TRUE(one.usable()) << one.reason;
    EXPECT_EQ(one.params.eta, three.params.eta);
    EXPECT_EQ(one.params.alpha, three.params.alpha);
    for (int c = 0; c < 3; ++c) EXPECT_EQ(one.params.tint[c], three.params.tint[c]) << c;
    EXPECT_EQ(one.cost, three.cost);
    EXPECT_EQ(one.iterations, three.iterations);
    EXPECT_EQ(one.std_error_alpha, three.std_error_alpha);
}

TEST(CoatedFit, ThesisRigEitherRecoversOrNamesWhatItCannotDetermine) {
    const CoatedParams truth{.eta = 1.5f, .alpha = 0.15f};
    const CoatedFit fit = fit_coated(make_samples(truth, Rig::Thesis, 40000, 11));
    ASSERT_TRUE(fit.usable()) << fit.reason;
    // Noise-free: the truth is the minimum, so whatever the rig leaves loose, the fit lands there.
    EXPECT_NEAR(fit.params.alpha, truth.alpha, 0.05 * truth.alpha);
    if (fit.status == CoatedFitStatus::Underdetermined) EXPECT_NE(fit.reason.find("eta"), std::string::npos);
    else EXPECT_NEAR(fit.params.eta, truth.eta, 0.05 * truth.eta);
}

TEST(CoatedFit, RobustToOutliersFromBouncedLightAndShadowEdges) {
    const CoatedParams truth{.eta = 1.45f, .alpha = 0.2f};
    std::vector<MaterialSample> s = make_samples(truth, Rig::Spread, 40000, 5);
    // 5% of the samples too bright (light that bounced off the object) or too dark (shadow edges).
    for (std::size_t i = 0; i < s.size(); i += 20) s[i].b *= (i / 20) % 2 == 0 ? 1.8f : 0.3f;
    const CoatedFit fit = fit_coated(s);
    ASSERT_TRUE(fit.usable()) << fit.reason;
    EXPECT_NEAR(fit.params.alpha, truth.alpha, 0.03 * truth.alpha);
    EXPECT_NEAR(fit.params.eta, truth.eta, 0.02 * truth.eta);
    CoatedFitOptions plain;
    plain.robust_passes = 0;
    const CoatedFit ls = fit_coated(s, plain);
    EXPECT_GT(std::abs(ls.params.alpha - truth.alpha), std::abs(fit.params.alpha - truth.alpha));
}

TEST(CoatedFit, ALafortuneTruthIsFittedWorseThanByItsOwnFamily) {
    LafortuneRgb lobe;
    lobe.cx = glm::vec3(-1.0f);
    lobe.cz = glm::vec3(1.0f);
    lobe.n = glm::vec3(20.0f);
    const std::vector<MaterialSample> s = make_samples(lobe, Rig::Spread, 20000, 13);
    const CoatedFit fit = fit_coated(s);
    ASSERT_TRUE(fit.usable()) << fit.reason;
    EXPECT_LT(material_mean_square_error(lobe, s), 1e-10);
    EXPECT_GT(material_mean_square_error(fit.params, s), 1e-7);
}

TEST(CoatedFit, TooFewSamplesIsSaidNotGuessed) {
    const std::vector<MaterialSample> s = make_samples(CoatedParams{}, Rig::Spread, 4, 1);
    const CoatedFit fit = fit_coated(s);
    EXPECT_EQ(fit.status, CoatedFitStatus::TooFewSamples);
    EXPECT_FALSE(fit.usable());
}

} // namespace
} // namespace specula
