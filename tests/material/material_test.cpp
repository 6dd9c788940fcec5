// The material module's physics (engine/material, shaders/shared/material.h, coated.h): every
// family is reciprocal and, at its most reflective, conserves energy (white furnace); the coated
// family's pieces match their closed forms; float and double agree; parameters are checked.
#include "material/material.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace specula {
namespace {

struct Pair {
    double ci, co, cuv;
};

// Random pairs of unit directions above the horizon, as (n.u, n.v, u.v).
std::vector<Pair> random_pairs(unsigned seed, int count) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    std::vector<Pair> out;
    for (int i = 0; i < count; ++i) {
        const double ci = 0.02 + 0.98 * uni(rng), co = 0.02 + 0.98 * uni(rng);
        const double phi = 2.0 * kPi * uni(rng);
        const double cuv = ci * co + std::sqrt((1 - ci * ci) * (1 - co * co)) * std::cos(phi);
        out.push_back({ci, co, cuv});
    }
    return out;
}

std::vector<SpecularModel> models() {
    return {LafortuneRgb{glm::vec3(-0.9f), glm::vec3(0.76f), glm::vec3(10.0f)},
            LafortuneRgb{glm::vec3(-1.43f), glm::vec3(-0.78f), glm::vec3(9.7f)},
            CoatedParams{.eta = 1.5f, .alpha = 0.1f, .tint = glm::vec3(1.0f)},
            CoatedParams{.eta = 1.3f, .alpha = 0.4f, .tint = glm::vec3(0.9f, 1.0f, 0.8f)},
            CoatedParams{.eta = 1.7f, .alpha = 0.05f, .tint = glm::vec3(1.0f)}};
}

TEST(Material, EveryFamilyIsReciprocal) {
    for (const SpecularModel& m : models()) {
        const shared::MaterialGpu g = material_gpu(m);
        for (const Pair& p : random_pairs(7, 2000)) {
            const glm::dvec3 a = shared::f64::material_specular(g, p.ci, p.co, p.cuv);
            const glm::dvec3 b = shared::f64::material_specular(g, p.co, p.ci, p.cuv);
            for (int c = 0; c < 3; ++c) EXPECT_NEAR(a[c], b[c], 1e-12 * (1.0 + std::abs(a[c])));
            EXPECT_DOUBLE_EQ(shared::f64::material_diffuse_factor(g, p.ci, p.co), shared::f64::material_diffuse_factor(g, p.co, p.ci));
        }
    }
}

TEST(Material, CoatedConservesEnergyAtItsLargestAlbedo) {
    // A white base under the coating reflects at most all the light, at every angle and roughness.
    for (const float eta : {1.3f, 1.5f, 1.7f})
        for (const float alpha : {0.05f, 0.2f, 0.4f}) {
            const CoatedParams c{.eta = eta, .alpha = alpha, .tint = glm::vec3(1.0f)};
            const double rho = coated_max_albedo(eta);
            for (const double cos_o : {1.0, 0.7, 0.3, 0.1}) {
                const glm::dvec3 a = directional_albedo(c, glm::dvec3(rho), cos_o, 192);
                EXPECT_LE(a.x, 1.0 + 2e-3) << "eta " << eta << " alpha " << alpha << " cos_o " << cos_o;
                if (alpha <= 0.05f && cos_o >= 0.7) {
                    EXPECT_GT(a.x, 0.9) << "a smooth white coating keeps most of the light";
                }
            }
        }
}

TEST(Material, LafortunePresetLobesStayUnderOneWithTheirAlbedo) {
    // The thesis's can lobe with a mid-grey albedo: a lobe the white-furnace bound allows.
    const LafortuneRgb l{glm::vec3(-0.9f), glm::vec3(0.76f), glm::vec3(10.11f)};
    for (const double cos_o : {1.0, 0.5, 0.2}) EXPECT_LE(directional_albedo(l, glm::dvec3(0.5), cos_o).x, 1.0);
    // A lobe that is not: ten times brighter, so the bound can fail.
    const LafortuneRgb hot{glm::vec3(-1.6f), glm::vec3(1.6f), glm::vec3(10.0f)};
    EXPECT_GT(directional_albedo(hot, glm::dvec3(0.5), 1.0).x, 1.0);
}

TEST(Coated, FresnelMatchesItsClosedFormsAndTheInternalReflectanceItsIdentity) {
    for (const double eta : {1.3, 1.5, 1.7}) {
        const double f0 = (eta - 1) * (eta - 1) / ((eta + 1) * (eta + 1));
        EXPECT_NEAR(shared::f64::coated_fresnel(1.0, eta), f0, 1e-12);
        EXPECT_NEAR(shared::f64::coated_fresnel(0.0, eta), 1.0, 1e-12);
        EXPECT_DOUBLE_EQ(shared::f64::coated_diffuse_factor(1.0, 1.0, eta), 1.0);
        // (1 - F_ext) / eta^2 = 1 - F_int (the hemispherical averages of the external and internal reflectance).
        double f_ext = 0.0;
        for (int i = 0; i < 4096; ++i) {
            const double c = (i + 0.5) / 4096;
            f_ext += 2.0 * shared::f64::coated_fresnel(c, eta) * c / 4096;
        }
        EXPECT_NEAR((1.0 - f_ext) / (eta * eta), 1.0 - coated_internal_reflectance(eta), 1e-4) << eta;
    }
    EXPECT_NEAR(coated_internal_reflectance(1.5), 0.596, 0.002); // the classical value for glass
}

TEST(Coated, GgxDistributionIsNormalized) {
    for (const double alpha : {0.05, 0.2, 0.5}) {
        // int D(h) (n.h) dw_h over the hemisphere = 1, in cos(theta_h) (cells dense near the peak).
        const int n = 200000;
        double sum = 0.0;
        for (int i = 0; i < n; ++i) {
            const double c = (i + 0.5) / n;
            sum += shared::f64::coated_ggx_d(c, alpha) * c * 2.0 * kPi / n;
        }
        EXPECT_NEAR(sum, 1.0, 2e-3) << alpha;
    }
}

TEST(Material, FloatKernelsAgreeWithTheDoubleReference) {
    for (const SpecularModel& m : models()) {
        const shared::MaterialGpu g = material_gpu(m);
        for (const Pair& p : random_pairs(11, 500)) {
            const glm::dvec3 d = shared::f64::material_specular(g, p.ci, p.co, p.cuv);
            const glm::vec3 f = shared::material_specular(g, float(p.ci), float(p.co), float(p.cuv));
            for (int c = 0; c < 3; ++c) EXPECT_NEAR(f[c], d[c], 2e-4 * (1.0 + d[c]) + 1e-3 * d[c]);
            EXPECT_NEAR(shared::material_diffuse_factor(g, float(p.ci), float(p.co)),
                        shared::f64::material_diffuse_factor(g, p.ci, p.co), 1e-5);
        }
    }
}

TEST(Material, ParametersAreCheckedAndNamed) {
    EXPECT_FALSE(invalid_parameters(CoatedParams{}).has_value());
    EXPECT_NE(invalid_parameters(CoatedParams{.eta = 0.9f})->find("eta"), std::string::npos);
    EXPECT_NE(invalid_parameters(CoatedParams{.alpha = 2.0f})->find("alpha"), std::string::npos);
    EXPECT_NE(invalid_parameters(CoatedParams{.tint = glm::vec3(NAN)})->find("tint"), std::string::npos);
    EXPECT_NE(invalid_parameters(LafortuneRgb{glm::vec3(-1), glm::vec3(1), glm::vec3(0)})->find("n"), std::string::npos);
    EXPECT_EQ(material_gpu(std::nullopt).family.x, shared::kMaterialLafortune);
    EXPECT_EQ(material_gpu(SpecularModel{CoatedParams{}}).family.x, shared::kMaterialCoated);
    EXPECT_EQ(family_of(SpecularModel{CoatedParams{}}), MaterialFamily::Coated);
    EXPECT_EQ(material_family_from_string("coated"), MaterialFamily::Coated);
    EXPECT_FALSE(material_family_from_string("plastic").has_value());
}

} // namespace
} // namespace specula
