// glTF's core material for ordinary viewers (material/core_material.h) and its image-space fit
// (specular/core_fit.h): the fit recovers a core truth's roughness, F0 and F90 from its own
// samples; on a Lafortune truth (another model) it explains most of the specular light; its glTF
// fields give the material back.
#include "specular/core_fit.h"

#include "material/core_material.h"
#include "material/material.h"
#include "shared/material.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace specula {
namespace {

glm::dvec3 random_direction(std::mt19937& rng, double min_cos) {
    std::uniform_real_distribution<double> u01(0.0, 1.0);
    const double cz = min_cos + (1.0 - min_cos) * u01(rng);
    const double phi = 6.283185307179586 * u01(rng);
    const double s = std::sqrt(std::max(0.0, 1.0 - cz * cz));
    return {s * std::cos(phi), s * std::sin(phi), cz};
}

/// Samples b = (rho / pi) k_d + f_s of a material the shaders evaluate, on the spread rig,
/// per-sample albedos, weight E^2 (E = ci).
std::vector<MaterialSample> make_samples(const shared::MaterialGpu& m, std::size_t count, unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> albedo(0.1, 0.8);
    std::vector<MaterialSample> out;
    while (out.size() < count) {
        const glm::dvec3 v = random_direction(rng, 0.15), u = random_direction(rng, 0.15);
        const glm::dvec3 rho_pi = glm::dvec3(albedo(rng), albedo(rng), albedo(rng)) / 3.141592653589793;
        const double ci = u.z, co = v.z, cuv = glm::dot(u, v);
        const glm::dvec3 b = rho_pi * shared::f64::material_diffuse_factor_uv(m, ci, co, cuv) +
                             shared::f64::material_specular(m, ci, co, cuv);
        out.push_back({.u = glm::vec3(u), .v = glm::vec3(v), .b = glm::vec3(b), .rho_over_pi = glm::vec3(rho_pi),
                       .weight = static_cast<float>(ci * ci)});
    }
    return out;
}

TEST(CoreFit, RecoversTheCoreMaterialFromItsOwnSamples) {
    for (const CoreMaterial truth : {CoreMaterial{.roughness = 0.4, .f0 = 0.05, .f90 = 0.8},
                                     CoreMaterial{.roughness = 0.7, .f0 = 0.04, .f90 = 1.0},
                                     CoreMaterial{.roughness = 0.25, .f0 = 0.1, .f90 = 0.1}}) {
        const std::vector<MaterialSample> samples = make_samples(core_material_gpu(truth), 30000, 5);
        const CoreFit fit = fit_core_material(samples);
        ASSERT_TRUE(fit.fitted) << fit.note;
        // The hypotheses searched side by side: the same fit.
        const CoreFit two = fit_core_material(samples, {.threads = 2});
        EXPECT_EQ(two.material.roughness, fit.material.roughness);
        EXPECT_EQ(two.material.f0, fit.material.f0);
        EXPECT_EQ(two.material.clearcoat, fit.material.clearcoat);
        EXPECT_EQ(two.rms, fit.rms);
        EXPECT_NEAR(fit.material.roughness, truth.roughness, 0.005);
        EXPECT_NEAR(fit.material.f0, truth.f0, 0.002);
        EXPECT_NEAR(fit.material.f90, truth.f90, 0.01);
        EXPECT_LT(fit.rms, 1e-3 * fit.diffuse_only_rms);
    }
}

TEST(CoreFit, ExplainsMostOfALafortuneLobesLight) {
    // The demo can's lobe (another model: the fit cannot be exact).
    const LafortuneRgb lobe{.cx = glm::vec3(-0.9f), .cz = glm::vec3(0.76f), .n = glm::vec3(10.5f)};
    const CoreFit fit = fit_core_material(make_samples(material_gpu(SpecularModel(lobe)), 30000, 9));
    ASSERT_TRUE(fit.fitted) << fit.note;
    EXPECT_LT(fit.rms, 0.5 * fit.diffuse_only_rms);
    EXPECT_GT(fit.material.roughness, 0.1);
    EXPECT_LT(fit.material.roughness, 0.9);
    EXPECT_GE(fit.material.f0, 0.0);
    EXPECT_LE(fit.material.f0, fit.material.f90);
    EXPECT_LE(fit.material.f90, 1.0);
}

TEST(CoreFit, ACoatedTruthGetsAClearcoatOfItsRoughness) {
    // The coated family (another model: exact Fresnel, separable Smith, T(ci) T(co) diffuse): its
    // coating is what glTF's clearcoat layer is, so the fit takes it, with glTF's roughness sqrt(alpha).
    const CoatedParams truth{.eta = 1.5f, .alpha = 0.12f};
    const CoreFit fit = fit_core_material(make_samples(material_gpu(SpecularModel(truth)), 30000, 11));
    ASSERT_TRUE(fit.fitted) << fit.note;
    EXPECT_GT(fit.material.clearcoat, 0.9);
    EXPECT_NEAR(fit.material.clearcoat_roughness, std::sqrt(0.12), 0.03);
    EXPECT_EQ(fit.material.f90, 0.0);
    EXPECT_LT(fit.rms, 0.5 * fit.diffuse_only_rms);
}

TEST(CoreFit, NoSampleGivesTheDiffuseOnlyCore) {
    const CoreFit fit = fit_core_material({});
    EXPECT_FALSE(fit.fitted);
    EXPECT_FALSE(fit.note.empty());
    EXPECT_EQ(fit.material.f90, 0.0);
    EXPECT_EQ(fit.material.base_color_scale(), 1.0);
    EXPECT_FALSE(fit.material.has_specular());
}

TEST(CoreMaterial, GltfFieldsGiveTheMaterialBack) {
    for (const CoreMaterial c : {CoreMaterial{.roughness = 0.4, .f0 = 0.05, .f90 = 0.8},   // through the IOR
                                 CoreMaterial{.roughness = 0.5, .f0 = 0.058, .f90 = 0.058}, // F0 = F90: the colour too
                                 CoreMaterial{.roughness = 1.0, .f0 = 0.0, .f90 = 0.0, .clearcoat = 1.0, .clearcoat_roughness = 0.33},
                                 CoreMaterial{.roughness = 1.0, .f0 = 0.0, .f90 = 0.0}}) {
        const CoreGltfFields g = core_gltf_fields(c);
        EXPECT_GE(g.ior, 1.0);
        EXPECT_LE(g.ior, 3.0);
        const CoreMaterial back = core_from_gltf_fields(g);
        EXPECT_NEAR(back.roughness, c.roughness, 1e-12);
        EXPECT_NEAR(back.f0, c.f0, 1e-12);
        EXPECT_NEAR(back.f90, c.f90, 1e-12);
        EXPECT_EQ(back.clearcoat, c.clearcoat);
        EXPECT_EQ(back.clearcoat_roughness, c.clearcoat_roughness);
    }
}

} // namespace
} // namespace specula
