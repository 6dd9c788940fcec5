// The pipeline end to end on small synthetic captures: outputs exist, the report is
// complete and honest about what it left out, and both backends agree.
#include "core/error.h"
#include "core/image.h"
#include "export/bundle.h"
#include "pipeline/reconstruct.h"
#include "synth/presets.h"
#include "synth/synth.h"
#include "test_dirs.h"
#include "vulkan_env.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

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
    c.backend = LambertBackend::Cpu;
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
    c.backend = LambertBackend::Cpu;
    const ReconstructResult r = reconstruct(c);
    ASSERT_TRUE(fs::exists(c.out_dir / "albedo.exr"));
    ASSERT_TRUE(fs::exists(c.out_dir / "albedo.png"));
    ASSERT_TRUE(fs::exists(c.out_dir / "report.json"));
    const nlohmann::json saved = nlohmann::json::parse(std::ifstream(c.out_dir / "report.json"));
    EXPECT_EQ(saved, r.report);
    // The can is not convex: rays are cast, and the report does not claim otherwise.
    EXPECT_FALSE(left_out_mentions(saved, "occlusion rays"));
    EXPECT_GT(saved["visibility"]["rays_cast"].get<std::uint64_t>(), 0u);
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
    c.backend = LambertBackend::Cpu;
    // One pass: the joint rounds subtract each backend's own fitted lobe, and a fit moves with
    // float-level changes of its samples, so later rounds compare two lobes, not two solvers.
    c.joint_rounds = 0;
    (void)reconstruct(c);
    c.out_dir = dir / "vk";
    c.backend = LambertBackend::Vulkan;
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
// Checks the report's shape only: the recovered lobe does NOT yet match ground_truth.lobe
// (at this size the fit ends near Cx ~ -0.04, Cz ~ 0.90, N ~ 25, not converged, against
// truth -0.90, 0.76, 10.1); the accuracy target (Cx, Cz 2%, N 5%) is open, see the stage note.
TEST(Reconstruct, SpecularStageReportsLobeInGroundTruthShape) {
    test::TempDir dir("pipe");
    ReconstructConfig c;
    c.capture = make_capture(dir, "can");
    c.out_dir = dir / "out";
    c.backend = LambertBackend::Cpu;
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
    c.backend = LambertBackend::Cpu;
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
    c.backend = LambertBackend::Cpu;
    const ReconstructResult r = reconstruct(c);
    const nlohmann::json& s = r.report["specular"];
    EXPECT_FALSE(s["energy"]["has_specular"].get<bool>());
    EXPECT_TRUE(s["lobe"].is_null());
    EXPECT_TRUE(left_out_mentions(r.report, "specular fit"));
    EXPECT_GT(s["samples"]["used"].get<std::uint64_t>(), 0u);
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
