// The pipeline end to end on small synthetic captures: outputs exist, the report is
// complete and honest about what it left out, and both backends agree.
#include "core/error.h"
#include "core/file_util.h"
#include "core/image.h"
#include "export/bundle.h"
#include "pipeline/reconstruct.h"
#include "synth/presets.h"
#include "synth/synth.h"
#include "test_dirs.h"
#include "vulkan_env.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>

namespace specula {
namespace {

namespace fs = std::filesystem;

fs::path make_capture(const test::TempDir& dir, const std::string& preset, bool lambertian = false) {
    synth::SynthOptions o;
    o.size = 96;
    o.views = 6;
    o.lights = 4;
    o.test_views = 1;
    o.test_lights = 1;
    o.format = synth::ImageFormat::Png16;
    o.lambertian = lambertian;
    const fs::path out = dir / preset;
    (void)synth::write_synthetic_capture(synth::to_object(synth::make_preset(preset, lambertian)), out, o);
    return out;
}

bool left_out_mentions(const nlohmann::json& report, const std::string& what) {
    for (const auto& item : report["left_out"])
        if (item["what"].get<std::string>().find(what) != std::string::npos) return true;
    return false;
}

TEST(Reconstruct, ConvexSphereSkipsOcclusionRaysAndSaysWhy) {
    test::TempDir dir("pipe");
    ReconstructConfig c;
    c.capture = make_capture(dir, "sphere");
    c.out_dir = dir / "out";
    c.backend = Backend::Cpu;
    const ReconstructResult r = reconstruct(c);
    EXPECT_TRUE(left_out_mentions(r.report, "occlusion rays"));
    EXPECT_TRUE(r.report["visibility"]["convex"].get<bool>());
    EXPECT_EQ(r.report["visibility"]["rays_cast"].get<std::uint64_t>(), 0u);
    EXPECT_GT(r.report["visibility"]["rays_avoided"].get<std::uint64_t>(), 0u);
}

TEST(Reconstruct, WritesOutputsAndACompleteReport) {
    test::TempDir dir("pipe");
    ReconstructConfig c;
    c.capture = make_capture(dir, "can");
    c.out_dir = dir / "out";
    c.backend = Backend::Cpu;
    const ReconstructResult r = reconstruct(c);
    ASSERT_TRUE(fs::exists(c.out_dir / "albedo.exr"));
    ASSERT_TRUE(fs::exists(c.out_dir / "albedo.png"));
    ASSERT_TRUE(fs::exists(c.out_dir / "report.json"));
    const nlohmann::json saved = nlohmann::json::parse(std::ifstream(c.out_dir / "report.json"));
    EXPECT_EQ(saved, r.report);
    // The can is not convex: rays are cast, and the report does not claim otherwise.
    EXPECT_FALSE(left_out_mentions(saved, "occlusion rays"));
    EXPECT_GT(saved["visibility"]["rays_cast"].get<std::uint64_t>(), 0u);
    EXPECT_GT(saved["visibility"]["shadow_map_rays"].get<std::uint64_t>(), 0u); // the shadow-edge test's
    EXPECT_EQ(saved["visibility"]["light_rays_answered_by_shadow_maps"].get<std::uint64_t>(), 0u); // off by default
    // Every stage is timed; the texture has the atlas's size.
    for (const char* stage : {"load", "atlas", "particles", "visibility", "diffuse solve", "albedo texture", "bundle",
                              "evaluation"}) {
        bool found = false;
        for (const auto& s : saved["stages"])
            if (s["name"] == stage) {
                found = true;
                EXPECT_GE(s["seconds"].get<double>(), 0.0);
            }
        EXPECT_TRUE(found) << stage;
    }
    // The bundle reads back with the same albedo; the self-evaluation scored train and test.
    ASSERT_TRUE(fs::exists(c.out_dir / "object.glb"));
    ASSERT_TRUE(fs::exists(c.out_dir / "evaluation.json"));
    const Bundle bundle = read_bundle(c.out_dir / "object.glb");
    for (const char* split : {"train", "test"})
        for (const char* set : {"masked", "full"}) {
            const auto& m = saved["evaluation"][split][set];
            ASSERT_TRUE(m.is_object()) << split << "." << set;
            EXPECT_GT(m["q1"].get<double>(), 90.0) << split << "." << set; // diffuse-only of a glossy can at 96 px
            EXPECT_LE(m["q1"].get<double>(), 100.0);
            EXPECT_GT(m["psnr"].get<double>(), 20.0);
        }
    // No machine path in what travels with the result (issue 20): the capture is named
    // relative to the output folder, and by its folder's name alone in the bundle.
    EXPECT_EQ(saved["capture"]["path"], "../" + c.capture.filename().string());
    EXPECT_EQ(bundle.info["capture"], c.capture.filename().string());
    for (const char* file : {"object.glb", "report.json", "evaluation.json", "report.html"}) {
        if (fs::exists(c.out_dir / file)) {
            EXPECT_EQ(read_text_file(c.out_dir / file).find(dir.path().string()), std::string::npos) << file;
        }
    }
    const Image albedo = read_image(c.out_dir / "albedo.exr", ColorSpace::Linear);
    ASSERT_EQ(bundle.albedo.pixels.size(), albedo.pixels.size());
    for (std::size_t i = 0; i < albedo.pixels.size(); ++i) ASSERT_EQ(bundle.albedo.pixels[i], albedo.pixels[i]);
    EXPECT_EQ(albedo.width, saved["atlas"]["width"].get<int>());
    EXPECT_EQ(albedo.height, saved["atlas"]["height"].get<int>());
    for (float v : albedo.pixels) ASSERT_TRUE(std::isfinite(v));
    // At 96 px most particles are gutters of tiny patches; the footprint test drops the
    // (particle, view) pairs whose taps straddle an occluding edge, and those are counted.
    EXPECT_GT(saved["diffuse"]["ok"].get<std::size_t>(), saved["particles"]["count"].get<std::size_t>() * 85 / 100);
    EXPECT_GT(saved["visibility"]["footprint_rejected_pairs"].get<std::uint64_t>(), 0u);
}

TEST(Reconstruct, VulkanAndCpuBackendsAgree) {
    SPECULA_REQUIRE_VULKAN();
    test::TempDir dir("pipe");
    const fs::path capture = make_capture(dir, "can");
    ReconstructConfig c;
    c.capture = capture;
    c.out_dir = dir / "cpu";
    c.backend = Backend::Cpu;
    // One pass: the joint rounds subtract each backend's own fitted lobe, and a fit moves with
    // float-level changes of its samples, so later rounds compare two lobes, not two solvers.
    c.joint_rounds = 0;
    (void)reconstruct(c);
    c.out_dir = dir / "vk";
    c.backend = Backend::Vulkan;
    const ReconstructResult vk = reconstruct(c);
    EXPECT_EQ(vk.report["device"]["validation_messages"].get<std::size_t>(), 0u);
    const Image a = read_image(dir / "cpu" / "albedo.exr", ColorSpace::Linear);
    const Image b = read_image(dir / "vk" / "albedo.exr", ColorSpace::Linear);
    ASSERT_EQ(a.pixels.size(), b.pixels.size());
    // fp32 on the GPU against the double reference; a texel may differ where a sample sits
    // at a rejection threshold, so bound the mean and count the large differences.
    double sum = 0.0;
    std::size_t large = 0;
    for (std::size_t i = 0; i < a.pixels.size(); ++i) {
        const double d = std::abs(static_cast<double>(a.pixels[i]) - b.pixels[i]);
        sum += d;
        if (d > 1e-3) ++large;
    }
    EXPECT_LT(sum / static_cast<double>(a.pixels.size()), 1e-4);
    EXPECT_LT(static_cast<double>(large), 1e-3 * static_cast<double>(a.pixels.size()));
}

// Specular stage (pipeline.md sections 4, 5, 9) on the can at 96 px, 6 views x 4 lights, png16.
// Checks the report's shape only (too few pixels and lights for the accuracy targets); the
// recovery of ground_truth.lobe is tested end to end in tests/specular/lobe_recovery_test.cpp.
TEST(Reconstruct, SpecularStageReportsLobeInGroundTruthShape) {
    test::TempDir dir("pipe");
    ReconstructConfig c;
    c.capture = make_capture(dir, "can");
    c.out_dir = dir / "out";
    c.backend = Backend::Cpu;
    c.specular = SpecularMode::On;
    c.max_fit_samples = 20000;
    const ReconstructResult r = reconstruct(c);
    const nlohmann::json& s = r.report["specular"];
    ASSERT_TRUE(s.is_object());
    for (const char* key : {"cx", "cz", "n", "status"}) ASSERT_EQ(s["lobe"][key].size(), 3u) << key;
    EXPECT_GT(s["samples"]["used"].get<std::uint64_t>(), 0u);
    EXPECT_GT(s["samples"]["dropped"]["shadow"].get<std::uint64_t>(), 0u);
    EXPECT_TRUE(s["seconds"].contains("residuals"));
    EXPECT_TRUE(s["seconds"].contains("fit"));
    EXPECT_FALSE(left_out_mentions(r.report, "specular fit"));
    const nlohmann::json truth = nlohmann::json::parse(std::ifstream(c.capture / "capture.json"))["ground_truth"]["lobe"];
    for (int k = 0; k < 3; ++k)
        std::printf("channel %d: Cx %.4f (truth %.4f)  Cz %.4f (truth %.4f)  N %.3f (truth %.3f)  %s\n", k,
                    s["lobe"]["cx"][k].get<double>(), truth["cx"][k].get<double>(), s["lobe"]["cz"][k].get<double>(),
                    truth["cz"][k].get<double>(), s["lobe"]["n"][k].get<double>(), truth["n"][k].get<double>(),
                    s["lobe"]["status"][k].get<std::string>().c_str());
    std::printf("energy ratio %.3f\n", s["energy"]["ratio_to_noise_variance"].get<double>());
}

TEST(Reconstruct, SpecularOffIsLeftOutAndSaysWhy) {
    test::TempDir dir("pipe");
    ReconstructConfig c;
    c.capture = make_capture(dir, "sphere", /*lambertian=*/true);
    c.out_dir = dir / "out";
    c.backend = Backend::Cpu;
    c.specular = SpecularMode::Off;
    const ReconstructResult r = reconstruct(c);
    EXPECT_TRUE(r.report["specular"].is_null());
    EXPECT_TRUE(left_out_mentions(r.report, "specular fit"));
}

TEST(Reconstruct, LambertianSkipsTheSpecularFitWithAutoAndSaysWhy) {
    test::TempDir dir("pipe");
    ReconstructConfig c;
    c.capture = make_capture(dir, "sphere", /*lambertian=*/true);
    c.out_dir = dir / "out";
    c.backend = Backend::Cpu;
    const ReconstructResult r = reconstruct(c);
    const nlohmann::json& s = r.report["specular"];
    EXPECT_FALSE(s["energy"]["has_specular"].get<bool>());
    EXPECT_TRUE(s["lobe"].is_null());
    EXPECT_TRUE(left_out_mentions(r.report, "specular fit"));
    EXPECT_GT(s["samples"]["used"].get<std::uint64_t>(), 0u);
}

const nlohmann::json& decision(const nlohmann::json& report, const std::string& name) {
    for (const auto& d : report["planner"])
        if (d["name"] == name) return d;
    static const nlohmann::json kNull;
    ADD_FAILURE() << "no planner decision " << name;
    return kNull;
}

std::string read_all(const fs::path& p) {
    std::ifstream in(p);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

double mean_abs_difference(const fs::path& a_path, const fs::path& b_path) {
    const Image a = read_image(a_path, ColorSpace::Linear);
    const Image b = read_image(b_path, ColorSpace::Linear);
    EXPECT_EQ(a.pixels.size(), b.pixels.size());
    double sum = 0.0;
    for (std::size_t i = 0; i < std::min(a.pixels.size(), b.pixels.size()); ++i)
        sum += std::abs(static_cast<double>(a.pixels[i]) - b.pixels[i]);
    return a.pixels.empty() ? 0.0 : sum / static_cast<double>(a.pixels.size());
}

// Issue 6's quality target (noise-free captures: masked test Q1 >= 99, PSNR >= 40 dB) in
// small. The sphere's checker has sharp albedo edges; the solve reads each particle
// bilinearly from its best view and the renderer reads the atlas bilinearly again, so the
// edges come back as ramps that the held-out views see at another phase. The refinement
// corrects them with every view's sampling: by default the pixel fit (refine/pixel_fit.h),
// or back-projection through renders (refine/albedo_refine.h).
// 128 px, 12 views x 4 lights, 2 test views x 2 lights, png16. Measured (lavapipe): test
// masked PSNR 41.26 dB, Q1 99.13 without the refinement, 42.93 dB, Q1 99.28 with 2 rounds of
// back-projection, 44.19 dB, Q1 99.38 with the pixel fit's 8 iterations (44.57, 99.41 before its
// bounds). Back-projection's
// thresholds lie between it and no refinement, the pixel fit's between it and back-projection.
TEST(Reconstruct, AlbedoRefinementSharpensEdgesForHeldOutViews) {
    SPECULA_REQUIRE_VULKAN(); // the evaluation renders the test frames (and back-projection the train frames)
    test::TempDir dir("pipe");
    synth::SynthOptions o;
    o.size = 128;
    o.views = 12;
    o.lights = 4;
    o.test_views = 2;
    o.test_lights = 2;
    o.format = synth::ImageFormat::Png16;
    (void)synth::write_synthetic_capture(synth::to_object(synth::make_preset("sphere")), dir / "sphere", o);
    ReconstructConfig c;
    c.capture = dir / "sphere";
    c.backend = Backend::Cpu; // on lavapipe the reference is the faster solve
    c.evaluate_train = false;
    c.write_sheets = false;
    c.write_html = false;
    c.cost_probes = false;
    const auto test_masked = [&](RefineMethod method, std::optional<std::uint32_t> rounds, const char* out, const char* value) {
        c.refine_method = method;
        c.refine_rounds = rounds;
        c.out_dir = dir / out;
        const ReconstructResult r = reconstruct(c);
        EXPECT_EQ(decision(r.report, "albedo_refinement")["value"], value);
        return r.report["evaluation"]["test"]["masked"];
    };
    const nlohmann::json pixels = test_masked(RefineMethod::Pixels, std::nullopt, "auto", "8 iterations (pixels)");
    const nlohmann::json back = test_masked(RefineMethod::BackProjection, std::nullopt, "back", "2 rounds (back-projection)");
    const nlohmann::json plain = test_masked(RefineMethod::Pixels, 0u, "plain", "skip");
    const auto psnr = [](const nlohmann::json& m) { return m["psnr"].get<double>(); };
    const auto q1 = [](const nlohmann::json& m) { return m["q1"].get<double>(); };
    std::printf("test masked PSNR (Q1): pixel fit %.2f dB (%.3f), back-projection %.2f dB (%.3f), without %.2f dB (%.3f)\n",
                psnr(pixels), q1(pixels), psnr(back), q1(back), psnr(plain), q1(plain));
    EXPECT_GE(psnr(back), 42.7);
    EXPECT_GE(q1(back), 99.26);
    EXPECT_GE(psnr(back) - psnr(plain), 1.0);
    EXPECT_GE(psnr(pixels), 43.8);
    EXPECT_GE(q1(pixels), 99.35);
    EXPECT_GE(psnr(pixels) - psnr(back), 0.8);
}

// Planner (pipeline.md section 9), convex preset: auto skips the occlusion rays and
// estimates what they would have cost; forcing them on changes the albedo by less than
// kRaysTolerance (mean absolute difference, albedo units: on a convex mesh the rays
// cannot hit anything, so only float rounding at the facing test may differ) and the
// report says they were cast, what they cost, and no longer lists them as left out.
TEST(Planner, ConvexSphereSkipsRaysAndForcingThemChangesNothing) {
    constexpr double kRaysTolerance = 1e-4;
    test::TempDir dir("plan");
    const fs::path capture = make_capture(dir, "sphere");
    ReconstructConfig c;
    c.capture = capture;
    c.backend = Backend::Cpu;
    c.out_dir = dir / "auto";
    const ReconstructResult a = reconstruct(c);
    c.out_dir = dir / "forced";
    c.occlusion_rays = Toggle::On;
    const ReconstructResult f = reconstruct(c);

    const auto& da = decision(a.report, "occlusion_rays");
    EXPECT_EQ(da["value"], "skip");
    EXPECT_EQ(da["mode"], "auto");
    ASSERT_TRUE(da["avoided_seconds"].is_number());
    EXPECT_GT(da["avoided_seconds"].get<double>(), 0.0);
    EXPECT_NE(da["cost_basis"].get<std::string>().find("estimate"), std::string::npos);
    EXPECT_TRUE(left_out_mentions(a.report, "occlusion rays"));

    const auto& df = decision(f.report, "occlusion_rays");
    EXPECT_EQ(df["value"], "cast");
    EXPECT_EQ(df["mode"], "forced");
    ASSERT_TRUE(df["measured_seconds"].is_number());
    EXPECT_GT(f.report["visibility"]["rays_cast"].get<std::uint64_t>(), 0u);
    EXPECT_EQ(f.report["visibility"]["rays_occluded"].get<std::uint64_t>(), 0u); // nothing to hit on a convex mesh
    EXPECT_FALSE(left_out_mentions(f.report, "occlusion rays"));

    EXPECT_LT(mean_abs_difference(dir / "auto" / "albedo.exr", dir / "forced" / "albedo.exr"), kRaysTolerance);
    const double qa = a.report["evaluation"]["test"]["masked"]["q1"].get<double>();
    const double qf = f.report["evaluation"]["test"]["masked"]["q1"].get<double>();
    EXPECT_NEAR(qa, qf, 0.01);

    // The page shows the decision and both pixel sets.
    const std::string html = read_all(dir / "auto" / "report.html");
    EXPECT_NE(html.find("occlusion_rays"), std::string::npos);
    EXPECT_NE(html.find("avoided &asymp;"), std::string::npos);
    EXPECT_NE(html.find("<td>masked</td>"), std::string::npos);
    EXPECT_NE(html.find("<td>full</td>"), std::string::npos);
    EXPECT_NE(html.find("data:image/png;base64,"), std::string::npos); // the sheets, embedded
}

// Planner, Lambertian variant: auto leaves the specular stages out with an estimate of
// their cost; --specular on runs them, reports the measured cost, and changes the
// test-frame quality by less than kSpecularTolerance (Q1 points): there is no lobe to find.
TEST(Planner, LambertianLeavesSpecularOutAndForcingItChangesLittle) {
    constexpr double kSpecularTolerance = 0.5;
    test::TempDir dir("plan");
    const fs::path capture = make_capture(dir, "sphere", /*lambertian=*/true);
    ReconstructConfig c;
    c.capture = capture;
    c.backend = Backend::Cpu;
    c.out_dir = dir / "auto";
    const ReconstructResult a = reconstruct(c);
    c.out_dir = dir / "forced";
    c.specular = SpecularMode::On;
    const ReconstructResult f = reconstruct(c);

    const auto& da = decision(a.report, "specular_stages");
    EXPECT_EQ(da["value"], "skip");
    EXPECT_EQ(da["mode"], "auto");
    // With validation frames the families compete with diffuse only (docs/pipeline.md 5.8),
    // which must win on a Lambertian truth: the decision then gives the candidates' measured
    // time; without them, the estimated time of the fit it avoided.
    if (da.contains("measured_seconds") && da["measured_seconds"].is_number()) {
        EXPECT_GT(da["measured_seconds"].get<double>(), 0.0);
        EXPECT_EQ(decision(a.report, "material")["value"], "diffuse only");
    } else {
        ASSERT_TRUE(da["avoided_seconds"].is_number()) << da.dump();
        EXPECT_GT(da["avoided_seconds"].get<double>(), 0.0);
    }
    EXPECT_EQ(decision(a.report, "factorization_grid")["value"], "none");
    EXPECT_TRUE(left_out_mentions(a.report, "specular fit"));
    EXPECT_FALSE(a.report["bundle"]["has_lobe"].get<bool>());

    const auto& df = decision(f.report, "specular_stages");
    EXPECT_EQ(df["value"], "fit");
    EXPECT_EQ(df["mode"], "forced");
    ASSERT_TRUE(df["measured_seconds"].is_number());
    EXPECT_FALSE(left_out_mentions(f.report, "specular fit, factorization"));

    const double qa = a.report["evaluation"]["test"]["masked"]["q1"].get<double>();
    const double qf = f.report["evaluation"]["test"]["masked"]["q1"].get<double>();
    EXPECT_NEAR(qa, qf, kSpecularTolerance);
    // The albedo goes with the bundle's material (docs/pipeline.md 5.5): where the forced estimate
    // ended with the material still moving, it was solved once more with that material, nearly no
    // reflection on a Lambertian truth (eta near 1), so it moves little (0.0020 when measured);
    // otherwise the specular stages leave it as the auto run has it, bit for bit.
    const double moved = mean_abs_difference(dir / "auto" / "albedo.exr", dir / "forced" / "albedo.exr");
    if (f.report["specular"]["joint"]["final_solve"].get<bool>()) EXPECT_LT(moved, 0.005);
    else EXPECT_EQ(moved, 0.0);
}

// Planner, near-mirror lobe: the factorization grid follows the fitted lobe's width
// (factorization/resolution.h: R = ceil(k sqrt(N)), clamped to [16, 128], along h in the plain
// GSHD (k = 2), along d in the mirrored one (k = 16) and the warped one (k = 28), which the
// automatic choice keeps for this lobe), so a lobe of N ~ 300 gets a finer grid than the 16 a
// broad lobe gets. --specular on: at 128 px the
// energy test alone does not see so small a highlight (about 3 noise variances).
TEST(Planner, NearMirrorLobeGetsAFinerFactorizationGrid) {
    test::TempDir dir("plan");
    synth::SynthOptions o;
    o.size = 128;
    o.views = 8;
    o.lights = 6;
    o.test_views = 1;
    o.test_lights = 1;
    o.format = synth::ImageFormat::Png16;
    synth::SynthObject object = synth::to_object(synth::make_preset("sphere"));
    object.material.lobe = {glm::vec3(-1.0f), glm::vec3(1.0f), glm::vec3(300.0f)};
    (void)synth::write_synthetic_capture(object, dir / "mirror", o);
    ReconstructConfig c;
    c.capture = dir / "mirror";
    c.out_dir = dir / "out";
    c.backend = Backend::Cpu;
    c.specular = SpecularMode::On;
    c.evaluate = false;
    const ReconstructResult r = reconstruct(c);
    ASSERT_TRUE(r.report["bundle"]["has_lobe"].get<bool>()) << r.report["specular"].dump();
    const auto& d = decision(r.report, "factorization_grid");
    EXPECT_EQ(d["mode"], "auto");
    const double n = d["detail"]["max_exponent"].get<double>();
    EXPECT_GT(n, 100.0); // a narrow lobe was fitted (truth 300)
    const nlohmann::json& f = r.report["factorization"];
    const double k = f["parametrization"] == "warped"     ? factorization::kWarpedPeakCellsPerHalfWidth
                     : f["parametrization"] == "mirrored" ? factorization::kMirroredPeakCellsPerHalfWidth
                                                          : factorization::kCellsPerHalfWidth;
    const int expected = std::clamp(static_cast<int>(std::ceil(k * std::sqrt(n))), 16, 128);
    const int expected_plain = std::clamp(static_cast<int>(std::ceil(2.0 * std::sqrt(n))), 16, 128);
    EXPECT_EQ(f["parametrization"], "warped") << f["parametrization_reason"];
    EXPECT_FALSE(f["parametrization_forced"].get<bool>());
    EXPECT_TRUE(f["parametrization_candidates"].contains("warped"));
    EXPECT_EQ(f["warp"].size(), 4u);
    const char* peak = f["parametrization"] == "gshd" ? "grid_h" : "grid_d";
    EXPECT_EQ(d["detail"][peak].get<int>(), expected);
    EXPECT_GT(d["detail"][peak].get<int>(), 16);
    EXPECT_EQ(f[peak].get<int>(), expected); // the grid the factorization used
    if (f["parametrization_candidates"].contains("gshd")) { // computed when the warped error is above 1%
        EXPECT_EQ(f["parametrization_candidates"]["gshd"]["grid_h"].get<int>(), expected_plain);
    }
    EXPECT_EQ(d["detail"]["auto_grid_h"].get<int>(), expected_plain); // the planner's rule is the plain one's
    ASSERT_TRUE(d["avoided_seconds"].is_number());
    EXPECT_GT(d["avoided_seconds"].get<double>(), 0.0);
}

TEST(Planner, EveryDecisionIsInTheReport) {
    test::TempDir dir("plan");
    ReconstructConfig c;
    c.capture = make_capture(dir, "can");
    c.out_dir = dir / "out";
    c.backend = Backend::Cpu;
    c.evaluate = false;
    const ReconstructResult r = reconstruct(c);
    for (const char* name : {"occlusion_rays", "diffuse_mode", "atlas", "specular_stages", "factorization_grid"}) {
        const auto& d = decision(r.report, name);
        EXPECT_FALSE(d["value"].get<std::string>().empty()) << name;
        EXPECT_FALSE(d["reason"].get<std::string>().empty()) << name;
    }
    EXPECT_EQ(decision(r.report, "occlusion_rays")["value"], "cast"); // the can is not convex
    EXPECT_TRUE(decision(r.report, "atlas")["avoided_seconds"].is_number());
}

TEST(Reconstruct, MissingCaptureFailsWithoutWritingOutputs) {
    test::TempDir dir("pipe");
    ReconstructConfig c;
    c.capture = dir / "nothing-here";
    c.out_dir = dir / "out";
    EXPECT_THROW((void)reconstruct(c), InputError);
    EXPECT_FALSE(fs::exists(c.out_dir / "report.json"));
}

} // namespace
} // namespace specula
