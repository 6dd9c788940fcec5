// residuals: Vulkan (float) against the C++ reference (double) on a synthetic capture: the
// cologne with its lobe, png8 at exposure 2 (clipping, shadows and grazing light all occur),
// both fed the same diffuse solution (the reference's).
//
// Tolerance. u and v are unit vectors from float math: |d| <= 1e-5 per component. f_s:
// the GPU projects in float, which moves the image position by ~1e-5 pixel at 96 px, so the
// bilinear value c moves by at most that times the local pixel step (<= full scale 1), and
// r = c - (rho/pi) E has float rounding of ~1e-7 relative; f_s = r / E. So in image units
//     |f_vk - f_ref| Ebar <= 2e-5 + 1e-5 |f_ref| Ebar       per channel
// and the weight Ebar^2 agrees to 1e-5 relative. Decisions against thresholds (n.u at
// min_light_cos) could flip within rounding; the counts per reason must agree exactly here
// (they do on this scene), so the used samples line up slot for slot.
#include "specular/residuals.h"
#include "specular/coated_fit.h"
#include "specular/material_fit.h"

#include "diffuse_scene.h"
#include "vulkan_env.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

namespace specula {
namespace {

const test::DiffuseScene& scene() { return test::conformance_scene(); }

const LambertOutputs& diffuse() {
    static const LambertOutputs d = lambert_solve_cpu(scene().inputs(), {});
    return d;
}

void expect_same_counts(const ResidualCounts& a, const ResidualCounts& b) {
    EXPECT_EQ(a.candidates, b.candidates);
    EXPECT_EQ(a.used, b.used);
    EXPECT_EQ(a.dropped_shadow, b.dropped_shadow);
    EXPECT_EQ(a.dropped_grazing, b.dropped_grazing);
    EXPECT_EQ(a.dropped_missing, b.dropped_missing);
    EXPECT_EQ(a.dropped_clipped, b.dropped_clipped);
    EXPECT_EQ(a.dropped_no_diffuse, b.dropped_no_diffuse);
}

void expect_same_samples(const ResidualSamples& ref, const ResidualSamples& vk) {
    ASSERT_EQ(ref.samples.size(), vk.samples.size());
    double worst = 0.0;
    for (std::size_t i = 0; i < ref.samples.size(); ++i) {
        const ResidualSample& a = ref.samples[i];
        const ResidualSample& b = vk.samples[i];
        for (int c = 0; c < 3; ++c) {
            ASSERT_NEAR(a.u[c], b.u[c], 1e-5) << "sample " << i;
            ASSERT_NEAR(a.v[c], b.v[c], 1e-5) << "sample " << i;
            const double e = static_cast<double>(a.v.w);
            const double diff = std::abs(static_cast<double>(a.f[c]) - static_cast<double>(b.f[c])) * e;
            worst = std::max(worst, diff);
            ASSERT_LE(diff, 2e-5 + 1e-5 * std::abs(static_cast<double>(a.f[c])) * e) << "sample " << i << " channel " << c;
        }
        ASSERT_NEAR(a.u.w, b.u.w, 1e-5 * std::abs(a.u.w) + 1e-12) << "sample " << i;
        ASSERT_NEAR(a.v.w, b.v.w, 1e-5 * std::abs(a.v.w) + 1e-12) << "sample " << i;
        for (int c = 0; c < 4; ++c) ASSERT_NEAR(a.d[c], b.d[c], 1e-5 * std::abs(a.d[c]) + 1e-7) << "sample " << i << " d " << c;
    }
    std::printf("residuals: %zu samples, worst |df| Ebar = %.3g\n", ref.samples.size(), worst);
}

TEST(Residuals, CountsAddUpAndDropReasonsOccur) {
    const ResidualSamples ref = residual_samples_cpu(scene().inputs(), diffuse(), {});
    const ResidualCounts& c = ref.counts;
    EXPECT_EQ(c.candidates, c.used + c.dropped_shadow + c.dropped_grazing + c.dropped_missing + c.dropped_clipped +
                                c.dropped_no_diffuse);
    EXPECT_EQ(c.used, ref.samples.size());
    EXPECT_GT(c.used, 1000u);
    EXPECT_GT(c.dropped_shadow, 0u);
    EXPECT_GT(c.dropped_grazing, 0u);
    EXPECT_GT(c.dropped_clipped, 0u);
    for (const ResidualSample& s : ref.samples) {
        ASSERT_GE(s.u.z, 0.1f - 1e-6f); // n.u >= min_light_cos
        ASSERT_GT(s.u.w, 0.0f);
        ASSERT_TRUE(std::isfinite(s.f.x) && std::isfinite(s.f.y) && std::isfinite(s.f.z));
    }
}

// The C++ reference on several threads: the same samples, in the same order, with the same
// particles and counts, bit for bit, with and without the memory bound's stride.
TEST(Residuals, ThreadsGiveTheSameSamplesInTheSameOrder) {
    const LambertInputs in = scene().inputs();
    ASSERT_GT(in.particles.size(), 3u * 2048u); // several chunks of particles per view
    for (const std::uint64_t max_kept : {std::uint64_t{0}, std::uint64_t{5000}}) {
        std::vector<std::uint32_t> p1, p3;
        const ResidualSamples one = residual_samples_cpu(in, diffuse(), {.max_kept_samples = max_kept, .threads = 1}, &p1);
        const ResidualSamples three = residual_samples_cpu(in, diffuse(), {.max_kept_samples = max_kept, .threads = 3}, &p3);
        if (max_kept != 0) {
            EXPECT_GE(one.keep_stride, 2u);
        }
        EXPECT_EQ(one.keep_stride, three.keep_stride);
        expect_same_counts(one.counts, three.counts);
        ASSERT_EQ(one.samples.size(), three.samples.size());
        ASSERT_EQ(p1, p3);
        EXPECT_EQ(p1.size(), one.samples.size());
        EXPECT_EQ(0, std::memcmp(one.samples.data(), three.samples.data(), one.samples.size() * sizeof(ResidualSample)));
        // The stride keeps every k-th used slot: about used / k samples.
        EXPECT_EQ(one.samples.size(), (one.counts.used + one.keep_stride - 1) / one.keep_stride);
    }
}

// The fits' converters with a sample bound take the same samples, in the same order, as the
// stride subsample of the whole conversion (what the fits took before), dropped ones skipped.
TEST(Residuals, BoundedConversionIsTheStrideSubsampleOfTheWhole) {
    std::vector<ResidualSample> all = residual_samples_cpu(scene().inputs(), diffuse(), {}).samples;
    ASSERT_GT(all.size(), 3000u);
    for (std::size_t i = 0; i < all.size(); i += 7) all[i].status = 0; // not used: skipped before the stride
    for (const std::size_t max : {std::size_t{0}, std::size_t{1000}, std::size_t{2999}, all.size()}) {
        const std::vector<LafortuneSample> l = to_lafortune_samples(all, max);
        const std::vector<LafortuneSample> lw = stride_subsample(to_lafortune_samples(all), max);
        ASSERT_EQ(l.size(), lw.size()) << max;
        if (max != 0) {
            EXPECT_LE(l.size(), max);
        }
        for (std::size_t i = 0; i < l.size(); ++i) {
            ASSERT_EQ(l[i].u, lw[i].u) << max << " " << i;
            ASSERT_EQ(l[i].f, lw[i].f) << max << " " << i;
        }
        const std::vector<MaterialSample> m = to_material_samples(all, max);
        const std::vector<MaterialSample> mw = stride_subsample(to_material_samples(all), max);
        ASSERT_EQ(m.size(), mw.size()) << max;
        for (std::size_t i = 0; i < m.size(); ++i) ASSERT_EQ(m[i].b, mw[i].b) << max << " " << i;
    }
    // The validation error over the residual samples, converted one at a time, is the error over
    // their conversion to the last bit, for either family.
    for (const SpecularModel& model : {SpecularModel(LafortuneRgb{.cx = glm::vec3(-0.8f), .cz = glm::vec3(0.7f), .n = glm::vec3(12.0f)}),
                                       SpecularModel(CoatedParams{.eta = 1.5f, .alpha = 0.2f})}) {
        const double converted = material_mean_square_error(model, to_material_samples(all));
        EXPECT_GT(converted, 0.0);
        EXPECT_EQ(material_mean_square_error(model, all), converted);
    }
}

// With fit_samples the pass returns only what a fit of that many takes from all of them: the
// same samples byte for byte, in the same order (the C++ pass makes them again from their
// names), with the counts of the whole; with the memory bound's stride too, and any threads.
TEST(Residuals, ThinnedForAFitAreTheFitsSubsampleOfTheWhole) {
    const LambertInputs in = scene().inputs();
    for (const std::uint64_t max_kept : {std::uint64_t{0}, std::uint64_t{5000}}) {
        std::vector<std::uint32_t> pa;
        const ResidualSamples all = residual_samples_cpu(in, diffuse(), {.max_kept_samples = max_kept, .threads = 2}, &pa);
        for (const std::size_t fit : {std::size_t{700}, std::size_t{2999}, all.samples.size()}) {
            for (const unsigned threads : {1u, 3u}) {
                std::vector<std::uint32_t> pt;
                const ResidualSamples thin = residual_samples_cpu(
                    in, diffuse(), {.max_kept_samples = max_kept, .fit_samples = fit, .threads = threads}, &pt);
                expect_same_counts(all.counts, thin.counts);
                EXPECT_EQ(all.keep_stride, thin.keep_stride);
                // The energy sums are every kept sample's, thinned or not, as the test sums them.
                const ResidualEnergy whole = residual_energy(all.samples, 0.004);
                const ResidualEnergy sums = residual_energy(thin.energy, 0.004);
                EXPECT_EQ(thin.energy.samples, all.samples.size());
                EXPECT_EQ(whole.mean_square, sums.mean_square);
                EXPECT_EQ(whole.mean, sums.mean);
                EXPECT_GT(whole.mean_square, 0.0);
                const std::size_t stride = used_sample_stride(all.samples, fit);
                if (fit < all.samples.size()) {
                    EXPECT_GE(stride, 2u) << fit;
                }
                ASSERT_EQ(thin.samples.size(), (all.samples.size() + stride - 1) / stride) << fit;
                EXPECT_LE(thin.samples.size(), fit);
                ASSERT_EQ(pt.size(), thin.samples.size());
                for (std::size_t i = 0; i < thin.samples.size(); ++i) {
                    ASSERT_EQ(0, std::memcmp(&thin.samples[i], &all.samples[i * stride], sizeof(ResidualSample)))
                        << "fit " << fit << " sample " << i;
                    ASSERT_EQ(pt[i], pa[i * stride]) << "fit " << fit << " sample " << i;
                }
                // The whole thinned after the pass: the same.
                std::vector<ResidualSample> after = all.samples;
                thin_for_fit(after, fit);
                ASSERT_EQ(after.size(), thin.samples.size());
                EXPECT_EQ(0, std::memcmp(after.data(), thin.samples.data(), after.size() * sizeof(ResidualSample)));
                // What the fit converts: the same with or without the thinning.
                const std::vector<MaterialSample> m = to_material_samples(all.samples, fit);
                const std::vector<MaterialSample> mt = to_material_samples(thin.samples, fit);
                ASSERT_EQ(m.size(), mt.size());
                for (std::size_t i = 0; i < m.size(); ++i) ASSERT_EQ(m[i].b, mt[i].b) << i;
            }
        }
    }
}

// The validation error without the samples: the error over the samples the pass returns, to
// the last bit, for either family, with a known material in the solve, under the memory bound's
// stride, and any threads; the counts the pass's.
TEST(Residuals, ScoredWithoutTheSamplesAsOverThem) {
    const LambertInputs in = scene().inputs();
    const std::vector<SpecularModel> models{SpecularModel(LafortuneRgb{.cx = glm::vec3(-0.8f), .cz = glm::vec3(0.7f), .n = glm::vec3(12.0f)}),
                                            SpecularModel(CoatedParams{.eta = 1.5f, .alpha = 0.2f}),
                                            SpecularModel(LafortuneRgb{})};
    for (const std::optional<SpecularModel>& known : {std::optional<SpecularModel>{}, std::optional(models[1])})
        for (const std::uint64_t max_kept : {std::uint64_t{0}, std::uint64_t{5000}})
            for (const unsigned threads : {1u, 3u}) {
                const ResidualOptions o{.material = known, .max_kept_samples = max_kept, .threads = threads};
                const ResidualSamples all = residual_samples_cpu(in, diffuse(), o);
                ASSERT_GT(all.samples.size(), 1000u);
                for (const SpecularModel& model : models) {
                    const ResidualScore score = residual_mean_square_error_cpu(in, diffuse(), o, model);
                    const double over = material_mean_square_error(model, all.samples);
                    EXPECT_GT(over, 0.0);
                    EXPECT_EQ(score.mean_square, over) << max_kept << " " << threads;
                    expect_same_counts(all.counts, score.counts);
                }
            }
}

using ResidualsConformance = test::VulkanTest;

TEST_F(ResidualsConformance, VulkanMatchesCpuReference) {
    const LambertInputs in = scene().inputs();
    const ResidualSamples ref = residual_samples_cpu(in, diffuse(), {});
    ResidualsVk kernel(ctx());
    const ResidualSamples vk = kernel.run(in, diffuse(), {});
    expect_same_counts(ref.counts, vk.counts);
    expect_same_samples(ref, vk);
    EXPECT_EQ(vk.view_batches, 1u);
    // The thesis's sampling (no per-tap irradiance) agrees too.
    const ResidualSamples ref_plain = residual_samples_cpu(in, diffuse(), {.tap_irradiance = false});
    const ResidualSamples vk_plain = kernel.run(in, diffuse(), {.tap_irradiance = false});
    expect_same_counts(ref_plain.counts, vk_plain.counts);
    expect_same_samples(ref_plain, vk_plain);
    // A known coated material: its diffuse factor k_d in each sample's diffuse term and in d.w.
    const ResidualOptions coated{.material = CoatedParams{.eta = 1.5f, .alpha = 0.12f}};
    const ResidualSamples ref_coated = residual_samples_cpu(in, diffuse(), coated);
    const ResidualSamples vk_coated = kernel.run(in, diffuse(), coated);
    expect_same_counts(ref_coated.counts, vk_coated.counts);
    expect_same_samples(ref_coated, vk_coated);
    bool below_one = false;
    for (const ResidualSample& q : ref_coated.samples)
        if (q.status == shared::kResidualUsed) {
            ASSERT_GT(q.d.w, 0.0f);
            ASSERT_LE(q.d.w, 1.0001f);
            below_one = below_one || q.d.w < 0.95f;
        }
    EXPECT_TRUE(below_one); // the coating's fall-off reaches the samples
    // Thinned for a fit: the kernel's samples thinned as the C++ pass makes them.
    const ResidualOptions thin{.fit_samples = 2999};
    const ResidualSamples ref_thin = residual_samples_cpu(in, diffuse(), thin);
    const ResidualSamples vk_thin = residual_samples(in, diffuse(), thin, Backend::Vulkan, &ctx());
    EXPECT_LE(ref_thin.samples.size(), 2999u);
    EXPECT_LT(ref_thin.samples.size(), ref.samples.size());
    expect_same_counts(ref_thin.counts, vk_thin.counts);
    expect_same_samples(ref_thin, vk_thin);
    EXPECT_EQ(vk_thin.energy.samples, ref.samples.size()); // the sums over every sample, before the thinning
    EXPECT_NEAR(vk_thin.energy.square, ref_thin.energy.square, 1e-4 * ref_thin.energy.square);
    // sum |r| <= sqrt(3 n sum r^2) (Cauchy-Schwarz): the sums' bound from the samples' own.
    const double abs_bound = std::sqrt(3.0 * static_cast<double>(ref_thin.energy.samples) * ref_thin.energy.square);
    EXPECT_NEAR(vk_thin.energy.sum, ref_thin.energy.sum, 1e-4 * abs_bound);
}

TEST_F(ResidualsConformance, BatchedAndChunkedUnderASmallBindingLimit) {
    const LambertInputs in = scene().inputs();
    const ResidualSamples ref = residual_samples_cpu(in, diffuse(), {});
    ResidualsVk kernel(ctx());
    // One view's images and surface map (7 x 96^2 x 16 bytes = 1008 KiB) per batch, ~20k slots per chunk.
    const ResidualSamples vk = kernel.run(in, diffuse(), {.max_binding_bytes = 1u << 20});
    EXPECT_GE(vk.view_batches, 6u);
    EXPECT_GT(vk.chunks, vk.view_batches);
    expect_same_counts(ref.counts, vk.counts);
    expect_same_samples(ref, vk);
    // Two frames and a surface map per batch: every view's frames span several batches, and
    // the samples still come out in the reference's order.
    const ResidualSamples split = kernel.run(in, diffuse(), {.max_binding_bytes = 448u << 10});
    EXPECT_GT(split.view_batches, 2 * in.views.size());
    expect_same_counts(ref.counts, split.counts);
    expect_same_samples(ref, split);
}

} // namespace
} // namespace specula
