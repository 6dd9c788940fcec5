// The Lafortune fit on a near-camera rig and the white-furnace bound (issue 15 item 3;
// engine/specular/lafortune_fit.h, top): residual samples from truths the free lobe is not
// fitted from (a GGX + Fresnel coated truth, or a Lafortune truth seen only by the thesis's
// rig: lights on a ring about 15 degrees around each camera), from noise alone, and from
// lobes above the white-furnace bound. The fit must keep a specular (free or constrained)
// wherever the residuals hold energy, never a retro-reflective or energy-creating guess.
#include "material/material.h"
#include "shared/lafortune.h"
#include "shared/material.h"
#include "specular/lafortune_fit.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <numbers>
#include <random>
#include <string>
#include <vector>

namespace specula {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

/// The true specular BRDF f_s(u, v) per channel, u and v in the tangent frame.
using Truth = std::function<glm::dvec3(const glm::dvec3& u, const glm::dvec3& v)>;

Truth lafortune_truth(double cx, double cz, double n) {
    return [=](const glm::dvec3& u, const glm::dvec3& v) { return glm::dvec3(shared::f64::lafortune_eval(cx, cz, n, u, v)); };
}

/// The coated family's specular (GGX, Smith G1 G1, exact dielectric Fresnel), through the
/// one evaluation of every family (shared/material.h).
Truth coated_truth(double eta, double alpha, glm::vec3 tint = glm::vec3(1.0f)) {
    const shared::MaterialGpu g = material_gpu(SpecularModel{CoatedParams{float(eta), float(alpha), tint}});
    return [=](const glm::dvec3& u, const glm::dvec3& v) { return shared::f64::material_specular(g, u.z, v.z, glm::dot(u, v)); };
}

/// How light and view are drawn: the view's polar angle up to `max_view_deg` (uniform in
/// cos: many views of a curved object), the light at `sep_lo`..`sep_hi` degrees from the
/// view (uniform azimuth around it: the ring's lights in a particle's tangent frame), lights
/// below 1 degree above the horizon dropped. `keep` filters the pairs.
struct Rig {
    double sep_lo = 13.0, sep_hi = 17.0; ///< the thesis's ring: about 15 degrees off the camera
    double max_view_deg = 80.0;
    std::function<bool(const glm::dvec3&, const glm::dvec3&)> keep;
};

/// The spread rig of `specula synth` (lights 15 to 130 degrees off the camera): where the
/// error of a near-camera fit is stated, not bounded (those directions were never seen).
const Rig kSpreadRig{.sep_lo = 15.0, .sep_hi = 130.0};

glm::dvec3 around(const glm::dvec3& axis, double theta, double phi) {
    const glm::dvec3 helper = std::abs(axis.z) < 0.9 ? glm::dvec3(0, 0, 1) : glm::dvec3(1, 0, 0);
    const glm::dvec3 t = glm::normalize(glm::cross(helper, axis));
    const glm::dvec3 b = glm::cross(axis, t);
    return glm::normalize(std::cos(theta) * axis + std::sin(theta) * (std::cos(phi) * t + std::sin(phi) * b));
}

/// Samples of `truth` on `rig`, weight n.u (the irradiance cosine), with Gaussian noise of
/// sigma = noise_rel times the largest true value plus noise_abs (returned in `sigma`).
std::vector<LafortuneSample> make_samples(const Truth& truth, const Rig& rig, std::size_t count, double noise_rel,
                                          double noise_abs, std::uint64_t seed, double* sigma = nullptr) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> uniform(0.0, 1.0);
    std::normal_distribution<double> gauss;
    std::vector<LafortuneSample> out;
    std::vector<glm::dvec3> values;
    double fmax = 0.0;
    const double cos_max = std::cos(rig.max_view_deg * kDeg);
    while (out.size() < count) {
        const double ct = cos_max + uniform(rng) * (1.0 - cos_max);
        const double st = std::sqrt(1.0 - ct * ct), az = 2.0 * std::numbers::pi * uniform(rng);
        const glm::dvec3 v(st * std::cos(az), st * std::sin(az), ct);
        const double sep = (rig.sep_lo + (rig.sep_hi - rig.sep_lo) * uniform(rng)) * kDeg;
        const glm::dvec3 u = around(v, sep, 2.0 * std::numbers::pi * uniform(rng));
        if (u.z < std::sin(1.0 * kDeg) || (rig.keep && !rig.keep(u, v))) continue;
        LafortuneSample s;
        s.u = glm::vec3(u);
        s.v = glm::vec3(v);
        s.weight = float(u.z);
        values.push_back(truth(u, v));
        fmax = std::max({fmax, values.back().x, values.back().y, values.back().z});
        out.push_back(s);
    }
    const double sd = noise_rel * fmax + noise_abs;
    for (std::size_t i = 0; i < out.size(); ++i) {
        const glm::dvec3 f = values[i];
        out[i].f = glm::vec3(float(f.x + sd * gauss(rng)), float(f.y + sd * gauss(rng)), float(f.z + sd * gauss(rng)));
    }
    if (sigma) *sigma = sd;
    return out;
}

/// Relative RMS error of a fitted channel against the truth on fresh (held-out) directions
/// of `rig`: sqrt(sum (fit - truth)^2 / sum truth^2), unweighted, noise-free.
double held_out_error(const LafortuneChannelFit& f, int channel, const Truth& truth, const Rig& rig) {
    const std::vector<LafortuneSample> held = make_samples(truth, rig, 20000, 0.0, 0.0, 4242);
    double num = 0.0, den = 0.0;
    for (const LafortuneSample& s : held) {
        const double g = shared::f64::lafortune_eval(f.cx, f.cz, f.n, glm::dvec3(s.u), glm::dvec3(s.v));
        const double t = s.f[channel];
        num += (g - t) * (g - t);
        den += t * t;
    }
    return std::sqrt(num / den);
}

/// The largest directional albedo of a lobe per channel, on a finer quadrature than the
/// fit's (material.h's white-furnace integral, 256 polar cells, outgoing angles every 5 degrees).
glm::dvec3 fine_max_albedo(const LafortuneRgb& lobe) {
    glm::dvec3 best(0.0);
    for (double t = 0.0; t <= 89.0; t += 5.0)
        best = glm::max(best, directional_albedo(SpecularModel{lobe}, glm::dvec3(0.0), std::cos(t * kDeg), 256));
    return best;
}
double fine_max_albedo(const LafortuneChannelFit& f) {
    return fine_max_albedo(LafortuneRgb{glm::vec3(float(f.cx), 0.0f, 0.0f), glm::vec3(float(f.cz), 0.0f, 0.0f),
                                        glm::vec3(float(f.n), 1.0f, 1.0f)})
        .x;
}

bool contains(const std::string& s, const std::string& what) { return s.find(what) != std::string::npos; }

// ---- (a) a Lafortune truth seen only from the near-camera rig ----------------------------

TEST(NearCameraRig, LafortuneTruthKeepsASpecularWithSmallHeldOutNearCameraError) {
    // The rig sees every sample at one light-view angle (15 +- 2 degrees), so the free lobe's
    // off-specular part is not observed: the fit falls back to the mirror lobe, and must
    // still reproduce the rig's own (held-out) directions. Measured: 0.6% (can), 1.0%
    // (cologne), 2.3% (off-specular), 5.4% (the grazing lobe); bounded at 10%.
    struct Case {
        const char* name;
        double cx, cz, n;
    };
    for (const Case c : {Case{"can (table 5.2)", -0.8962, 0.7587, 10.11}, Case{"cologne (table 5.2)", -0.8874, 1.1162, 18.09},
                         Case{"off-specular", -1.06, 0.98, 100.0}, Case{"grazing peak", -2.3, 0.67, 7.6}}) {
        const Truth truth = lafortune_truth(c.cx, c.cz, c.n);
        const std::vector<LafortuneSample> samples = make_samples(truth, Rig{}, 20000, 0.01, 0.0, 7);
        const LafortuneFitRgb fit = fit_lafortune(samples);
        for (int k = 0; k < 3; ++k) {
            const LafortuneChannelFit& f = fit.channel[k];
            const double near = held_out_error(f, k, truth, Rig{});
            const double spread = held_out_error(f, k, truth, kSpreadRig);
            if (k == 0)
                std::printf("  %-20s %-12s Cx %.4f Cz %.4f N %.4g: held-out error near-camera %.4f, spread rig %.3f "
                            "(not seen; stated only), light-view spread %.2f deg\n",
                            c.name, to_string(f.status), f.cx, f.cz, f.n, near, spread, f.light_view_spread_deg);
            EXPECT_TRUE(has_lobe(f.status)) << c.name << ": diffuse only although the residuals hold the lobe: " << f.reason;
            EXPECT_EQ(f.status, LafortuneFitStatus::Constrained) << c.name << ": " << f.reason;
            EXPECT_LT(f.light_view_spread_deg, 10.0);
            EXPECT_TRUE(contains(f.reason, "one light-view angle")) << f.reason;
            EXPECT_DOUBLE_EQ(f.cx, -f.cz) << "the constrained lobe is about the mirror direction";
            EXPECT_DOUBLE_EQ(f.n, fit.channel[0].n) << "one N shared by the channels";
            EXPECT_LT(near, 0.10) << c.name << " channel " << k;
        }
        EXPECT_FALSE(fit.converged_lobe().is_zero()) << "the bundle must carry the constrained lobe";
    }
}

TEST(NearCameraRig, AMirrorLobeTruthIsRecoveredExactly) {
    // A truth inside the constrained family (Cx = -Cz) is recovered by it, on the rig's
    // samples and everywhere else.
    const Truth truth = lafortune_truth(-1.02, 1.02, 50.0);
    const std::vector<LafortuneSample> samples = make_samples(truth, Rig{}, 20000, 0.01, 0.0, 8);
    const LafortuneChannelFit f = fit_lafortune_channel(samples, 0);
    ASSERT_EQ(f.status, LafortuneFitStatus::Constrained) << f.reason;
    EXPECT_NEAR(f.cz, 1.02, 0.005 * 1.02);
    EXPECT_NEAR(f.n, 50.0, 0.02 * 50.0);
    EXPECT_LT(held_out_error(f, 0, truth, kSpreadRig), 0.02);
}

// ---- (b) a coated truth (GGX + Fresnel) on the same rig ----------------------------------

TEST(NearCameraRig, CoatedTruthKeepsAMirrorLobeWithinTheWhiteFurnaceBound) {
    // The free fit of a rough coated truth settles on a retro-reflective lobe (Cx > 0) with a
    // standard error of 0.01: the rig cannot tell retro from mirror. The fit keeps a lobe
    // about the mirror direction instead, per channel of the tinted specular, with one N.
    const glm::vec3 tint(1.0f, 0.8f, 0.5f);
    for (const double alpha : {0.05, 0.1, 0.3, 0.5}) {
        const Truth truth = coated_truth(1.5, alpha, tint);
        const std::vector<LafortuneSample> samples = make_samples(truth, Rig{}, 20000, 0.01, 0.0, 9);
        const LafortuneFitRgb fit = fit_lafortune(samples);
        const double truth_albedo =
            directional_albedo(SpecularModel{CoatedParams{1.5f, float(alpha), glm::vec3(1.0f)}}, glm::dvec3(0.0), 1.0, 256).x;
        const glm::dvec3 albedos = fine_max_albedo(fit.converged_lobe());
        for (int k = 0; k < 3; ++k) {
            const LafortuneChannelFit& f = fit.channel[k];
            const double albedo = albedos[k];
            if (k == 0)
                std::printf("  coated alpha %.2f: %-12s Cx %.4g Cz %.4g N %.4g, largest directional albedo %.4f (truth's "
                            "specular at normal incidence %.4f), held-out error near-camera %.3f, spread rig %.3f\n",
                            alpha, to_string(f.status), f.cx, f.cz, f.n, albedo, truth_albedo,
                            held_out_error(f, k, truth, Rig{}), held_out_error(f, k, truth, kSpreadRig));
            ASSERT_TRUE(has_lobe(f.status)) << "alpha " << alpha << ": no specular kept: " << f.reason;
            EXPECT_LE(f.cx, 0.0) << "alpha " << alpha << ": a retro-reflective lobe";
            EXPECT_LE(albedo, 1.0) << "alpha " << alpha;
            EXPECT_LE(f.max_albedo, 1.0);
            EXPECT_DOUBLE_EQ(f.n, fit.channel[0].n);
        }
        // The kept lobe carries the truth's energy (its albedo near the truth's specular
        // albedo; measured 0.76 to 0.84 of it), not a token lobe.
        EXPECT_GT(albedos.x, truth_albedo / 1.5) << "alpha " << alpha;
        EXPECT_LT(albedos.x, truth_albedo * 1.5) << "alpha " << alpha;
        // The tint is the heights' ratio (one N: the same highlight shape in every channel).
        for (int k = 1; k < 3; ++k) {
            const double ratio = std::pow(fit.channel[k].cz, fit.channel[k].n) / std::pow(fit.channel[0].cz, fit.channel[0].n);
            EXPECT_NEAR(ratio, tint[k], 0.02 * tint[k]) << "alpha " << alpha << " channel " << k;
        }
    }
    // Without the fallback the free lobe of the rough truth is retro-reflective (what the
    // fallback replaces).
    LafortuneFitOptions free_only;
    free_only.constrained_fallback = false;
    const LafortuneChannelFit f = fit_lafortune_channel(make_samples(coated_truth(1.5, 0.3), Rig{}, 20000, 0.01, 0.0, 9), 0, free_only);
    EXPECT_EQ(f.status, LafortuneFitStatus::Converged) << f.reason;
    EXPECT_GT(f.cx, 0.0);
}

// ---- (c) noise alone ---------------------------------------------------------------------

TEST(NearCameraRig, PureNoiseResidualsAreDiffuseOnly) {
    for (const bool tell : {false, true})
        for (const std::uint64_t seed : {21u, 22u, 23u}) {
            double sigma = 0.0;
            const std::vector<LafortuneSample> samples =
                make_samples([](const glm::dvec3&, const glm::dvec3&) { return glm::dvec3(0.0); }, Rig{}, 20000, 0.0, 0.01,
                             seed, &sigma);
            LafortuneFitOptions o;
            if (tell) o.noise_sigma = sigma;
            const LafortuneFitRgb fit = fit_lafortune(samples, o);
            for (int k = 0; k < 3; ++k)
                EXPECT_EQ(fit.channel[k].status, LafortuneFitStatus::NoSpecularEnergy)
                    << "seed " << seed << (tell ? " (sigma told)" : "") << " channel " << k << ": " << fit.channel[k].reason;
            EXPECT_TRUE(fit.converged_lobe().is_zero());
        }
}

// ---- (d) the white-furnace bound and the far peak ----------------------------------------

/// A spread capture rig (lights up to 60 degrees off the view) that never comes within
/// `min_angle` degrees of the mirror configuration: r.v <= cos(min_angle).
Rig away_from_mirror(double min_angle) {
    return Rig{.sep_lo = 0.0, .sep_hi = 60.0, .max_view_deg = 75.0, .keep = [c = std::cos(min_angle * kDeg)](
                                                                          const glm::dvec3& u, const glm::dvec3& v) {
                   return 2.0 * u.z * v.z - glm::dot(u, v) <= c; // r.v, r = u mirrored about the normal
               }};
}

TEST(WhiteFurnace, AFreeLobeAboveTheBoundThatTheSamplesDoNotDetermineIsRefitConstrained) {
    // Truth: Cx = -Cz = 1.08, N = 10, directional albedo 1.13 at normal incidence; 1000
    // samples with 20% noise, none within 20 degrees of the mirror direction. The free fit
    // converges above the bound, but not by 2 standard errors of ln(albedo): refused, and
    // the mirror lobe, not above it by 2 standard errors either, is bounded.
    const Truth truth = lafortune_truth(-1.08, 1.08, 10.0);
    const std::vector<LafortuneSample> samples = make_samples(truth, away_from_mirror(20.0), 1000, 0.2, 0.0, 31);
    LafortuneFitOptions free_only;
    free_only.constrained_fallback = false;
    const LafortuneChannelFit free = fit_lafortune_channel(samples, 0, free_only);
    ASSERT_EQ(free.status, LafortuneFitStatus::Converged) << free.reason;
    EXPECT_GT(free.max_albedo, 1.0);

    const LafortuneChannelFit f = fit_lafortune_channel(samples, 0);
    std::printf("  refused: %s\n", f.reason.c_str());
    ASSERT_EQ(f.status, LafortuneFitStatus::Constrained) << f.reason;
    EXPECT_TRUE(contains(f.reason, "white-furnace bound 1, but not by 2 standard errors")) << f.reason;
    EXPECT_TRUE(contains(f.reason, "refitted")) << f.reason;
    EXPECT_LE(fine_max_albedo(f), 1.0 + 1e-3);
    EXPECT_GT(fine_max_albedo(f), 0.99) << "bounded, not shrunk beyond the bound";
}

TEST(WhiteFurnace, APeakFarOutsideTheSamplesIsRefused) {
    // Truth: Cx = -Cz = 1.03, N = 100 (albedo 1.18); no sample within 25 degrees of the
    // mirror direction: the largest value seen is about 1/20000 of the peak (K = 256). Noise-
    // free, the mirror lobe recovers the truth, above the bound by many standard errors;
    // with 5% noise and 2000 samples it is not, and is bounded.
    const Truth truth = lafortune_truth(-1.03, 1.03, 100.0);
    const LafortuneChannelFit exact = fit_lafortune_channel(make_samples(truth, away_from_mirror(25.0), 20000, 0.0, 0.0, 32), 0);
    std::printf("  refused: %s\n", exact.reason.c_str());
    ASSERT_EQ(exact.status, LafortuneFitStatus::Constrained) << exact.reason;
    EXPECT_TRUE(contains(exact.reason, "K = 256")) << exact.reason;
    EXPECT_NEAR(exact.cz, 1.03, 1e-4);
    EXPECT_NEAR(exact.n, 100.0, 0.01);
    EXPECT_TRUE(contains(exact.reason, "kept: the samples ask for it")) << exact.reason;

    const LafortuneChannelFit noisy = fit_lafortune_channel(make_samples(truth, away_from_mirror(25.0), 2000, 0.05, 0.0, 31), 0);
    ASSERT_EQ(noisy.status, LafortuneFitStatus::Constrained) << noisy.reason;
    EXPECT_TRUE(contains(noisy.reason, "K = 256")) << noisy.reason;
    EXPECT_TRUE(contains(noisy.reason, "refitted")) << noisy.reason;
    EXPECT_LE(fine_max_albedo(noisy), 1.0 + 1e-3);
}

TEST(WhiteFurnace, ALobeTheSamplesDetermineAboveTheBoundIsKeptAndSaid) {
    // The thesis's table 5.2 lobes exceed the bound (cologne 2.3 at normal incidence): where
    // the samples determine the excess, the measured values ask for it, and the lobe is kept.
    const Truth truth = lafortune_truth(-0.8874, 1.1162, 18.09);
    const std::vector<LafortuneSample> samples = make_samples(truth, Rig{.sep_lo = 0.0, .sep_hi = 90.0}, 20000, 0.0, 0.0, 33);
    const LafortuneChannelFit f = fit_lafortune_channel(samples, 0);
    ASSERT_EQ(f.status, LafortuneFitStatus::Converged) << f.reason;
    EXPECT_NEAR(f.cx, -0.8874, 1e-3);
    EXPECT_NEAR(f.max_albedo, 2.29, 0.05);
    EXPECT_TRUE(contains(f.reason, "by more than 2 standard errors")) << f.reason;
    EXPECT_TRUE(contains(f.reason, "kept")) << f.reason;
}

TEST(WhiteFurnace, TheMirrorLobesAlbedoIsLargestAtNormalIncidence) {
    // The constrained fit bounds its height with Cz^N 2 pi / (N + 2) (Lafortune and Willems
    // 1994): checked against material.h's quadrature over outgoing angles.
    for (const double n : {0.5, 1.0, 10.0, 100.0}) {
        const SpecularModel m = LafortuneRgb{glm::vec3(-1.0f), glm::vec3(1.0f), glm::vec3(float(n))};
        const int cells = std::max(64, int(4.0 * std::sqrt(n)));
        const double at_normal = directional_albedo(m, glm::dvec3(0.0), 1.0, cells).x;
        EXPECT_NEAR(at_normal, 2.0 * std::numbers::pi / (n + 2.0), 0.01 * at_normal) << n;
        for (double t = 5.0; t < 90.0; t += 5.0)
            EXPECT_LE(directional_albedo(m, glm::dvec3(0.0), std::cos(t * kDeg), cells).x, at_normal) << n << " at " << t;
    }
}

TEST(WhiteFurnace, MaxAlbedoMatchesAFineQuadrature) {
    struct L {
        double cx, cz, n, albedo;
    };
    // Largest albedos from material.h's quadrature with 256 polar cells every 0.5 degree
    // (vase at 81.5 deg, woodenpot at 89.5, an off-specular N = 100 lobe at 75, cologne at 0).
    for (const L l : {L{-1.2127, 0.5653, 20.36, 1.511}, L{-1.4299, -0.7763, 9.74, 2.130}, L{-1.06, 0.98, 100.0, 3.085},
                      L{-0.8874, 1.1162, 18.09, 2.285}}) {
        double theta = -1.0;
        const double a = lafortune_max_albedo(l.cx, l.cz, l.n, &theta);
        EXPECT_NEAR(a, l.albedo, 0.03 * l.albedo) << l.cx << " " << l.cz << " " << l.n;
        EXPECT_GE(theta, 0.0);
    }
    EXPECT_EQ(lafortune_max_albedo(0.0, 0.0, 1.0), 0.0);
    EXPECT_EQ(lafortune_max_albedo(-1.0, 1.0, std::numeric_limits<double>::quiet_NaN()), 0.0);
}

} // namespace
} // namespace specula
