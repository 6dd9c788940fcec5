// Light that bounced off the object (issue 16) through the whole pipeline: left out, byte for
// byte, on a convex mesh; left out on a concave capture that does not hold it (rendered with
// direct light only); on, and closer to the truth, on one path-traced with two bounces.
#include "concave_albedo.h"
#include "core/file_util.h"
#include "core/image.h"
#include "evaluate/evaluate.h"
#include "evaluate/indirect_light.h"
#include "export/bundle.h"
#include "pipeline/reconstruct.h"
#include "synth/presets.h"
#include "synth/synth.h"
#include "test_dirs.h"
#include "vulkan_env.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>

namespace specula {
namespace {

namespace fs = std::filesystem;

fs::path make_capture(const test::TempDir& dir, const std::string& preset, int size, int bounces, bool lambertian) {
    synth::SynthOptions o;
    o.size = size;
    o.views = 8;
    o.lights = 4;
    o.test_views = 2;
    o.test_lights = 1;
    o.format = synth::ImageFormat::Png16;
    o.lambertian = lambertian;
    o.bounces = bounces;
    o.bounce_samples = 256;
    const fs::path out = dir / (preset + "_" + std::to_string(bounces));
    (void)synth::write_synthetic_capture(synth::to_object(synth::make_preset(preset, lambertian)), out, o);
    return out;
}

const nlohmann::json& decision(const nlohmann::json& report, const std::string& name) {
    for (const auto& d : report["planner"])
        if (d["name"] == name) return d;
    throw std::runtime_error("no decision " + name);
}

bool left_out_mentions(const nlohmann::json& report, const std::string& what) {
    for (const auto& item : report["left_out"])
        if (item["what"].get<std::string>().find(what) != std::string::npos) return true;
    return false;
}

ReconstructResult run(const fs::path& capture, const fs::path& out, Toggle indirect) {
    ReconstructConfig c;
    c.capture = capture;
    c.out_dir = out;
    c.backend = Backend::Cpu;
    c.indirect = indirect;
    c.write_html = false;
    return reconstruct(c);
}

TEST(IndirectPipeline, ConvexSphereLeavesItOutAndChangesNoByte) {
    SPECULA_REQUIRE_VULKAN();
    test::TempDir dir("indirect");
    const fs::path capture = make_capture(dir, "sphere", 96, 0, false);
    const ReconstructResult a = run(capture, dir / "auto", Toggle::Auto);
    const ReconstructResult off = run(capture, dir / "off", Toggle::Off);
    const nlohmann::json& d = decision(a.report, "indirect");
    EXPECT_EQ(d["value"], "none");
    EXPECT_EQ(d["mode"], "auto");
    EXPECT_NE(d["reason"].get<std::string>().find("convex"), std::string::npos);
    ASSERT_TRUE(d["avoided_seconds"].is_number());
    EXPECT_GT(d["avoided_seconds"].get<double>(), 0.0);
    EXPECT_TRUE(left_out_mentions(a.report, "indirect light"));
    EXPECT_TRUE(a.report["indirect"].is_null());
    for (const char* file : {"object.glb", "albedo.png"})
        EXPECT_TRUE(read_text_file(dir / "auto" / file) == read_text_file(dir / "off" / file)) << file << " differs";
    // The EXR header holds the time it was written: its pixels, bit for bit.
    EXPECT_TRUE(read_image(dir / "auto" / "albedo.exr", ColorSpace::Linear).pixels ==
                read_image(dir / "off" / "albedo.exr", ColorSpace::Linear).pixels);
    EXPECT_FALSE(a.report["evaluation"].contains("without_added_light"));
}

// The knot at 96 px, Lambertian (so the light it sends itself is all diffuse, as the model's
// sources are), path-traced with 2 bounces, and the same knot with direct light only.
TEST(IndirectPipeline, KnotWithBouncesIsSolvedWithItAndWithoutBouncesWithout) {
    SPECULA_REQUIRE_VULKAN();
    test::TempDir dir("indirect");
    const fs::path bounced = make_capture(dir, "knot", 96, 2, true);
    const ReconstructResult on = run(bounced, dir / "on", Toggle::Auto);
    const ReconstructResult off = run(bounced, dir / "off", Toggle::Off);
    const nlohmann::json& d = decision(on.report, "indirect");
    EXPECT_EQ(d["value"], "inverse global illumination") << d["reason"];
    // The unlit pixels hold about the light the first solve's albedo predicts (that albedo is
    // too bright in the hollows, so the prediction is, if anything, high).
    const double ratio = d["detail"]["shadow_ratio"].get<double>();
    EXPECT_GT(ratio, 0.7);
    EXPECT_LT(ratio, 1.3);

    const nlohmann::json& e = on.report["indirect"]["evaluation"];
    const double with = e["test_masked"]["with"]["psnr_display"].get<double>();
    const double without = e["test_masked"]["without"]["psnr_display"].get<double>();
    const double off_psnr = off.report["evaluation"]["test"]["masked"]["psnr_display"].get<double>();
    const test::AlbedoComparison a_on = test::compare_albedo(bounced, dir / "on" / "object.glb");
    const test::AlbedoComparison a_off = test::compare_albedo(bounced, dir / "off" / "object.glb");
    std::printf("test masked display PSNR: with %.2f dB, its render without %.2f dB, --indirect off %.2f dB; concave albedo "
                "RMSE %.2f%% (bias %+.2f%%) vs off %.2f%% (%+.2f%%)\n",
                with, without, off_psnr, 100 * a_on.rmse_concave, 100 * a_on.bias_concave, 100 * a_off.rmse_concave,
                100 * a_off.bias_concave);
    // At 96 px much of the albedo's error is resolution (measured: 8.3% RMSE in the hollows
    // without, 6.0% with); the light the hollows get from the rest is a bias: +3.6% without,
    // -0.2% with.
    EXPECT_GT(with - off_psnr, 2.0);
    EXPECT_GT(with - without, 2.0);
    EXPECT_GT(a_off.bias_concave, 0.025);
    EXPECT_LT(std::abs(a_on.bias_concave), 0.01);
    EXPECT_LT(a_on.rmse_concave, 0.85 * a_off.rmse_concave);
    // Pixels whose added light outweighs the direct light left are left out of the solves.
    const nlohmann::json& rounds = on.report["indirect"]["rounds"];
    ASSERT_FALSE(rounds.empty());
    EXPECT_GT(rounds[0]["pixels_left_out"].get<std::size_t>(), 0u);

    // `specula evaluate --indirect`: the same light from the bundle alone (particles on its own
    // texture coordinates, visibility, transfer) scores what the reconstruction's own evaluation did.
    {
        const Capture capture = load_capture(bounced, {.load_images = true});
        const Bundle bundle = read_bundle(dir / "on" / "object.glb");
        ASSERT_TRUE(evaluate::indirect_removed_from_albedo(bundle));
        EXPECT_EQ(evaluate::indirect_bounces_of(bundle), 2u);
        // The transfer the reconstruction built, which the renders rebuild: the planner's blocks
        // for the 96 px knot's particles (2: well under 100k rows) and the default rays.
        const nlohmann::json& block = decision(on.report, "indirect_block");
        EXPECT_EQ(block["mode"], "auto");
        const evaluate::BundleTransfer transfer = evaluate::indirect_transfer_of(bundle);
        EXPECT_EQ(transfer.block, block["detail"]["block"].get<std::uint32_t>());
        EXPECT_EQ(transfer.block, 2u);
        EXPECT_EQ(transfer.rays, kTransferRays);
        const VisibilityInputs in = visibility_inputs(capture);
        evaluate::BundleIndirectLight light(bundle, in.views, in.lights, in.frame_view,
                                            {.rays = transfer.rays, .block = transfer.block});
        evaluate::EvaluateOptions eo;
        eo.metrics_backend = Backend::Cpu;
        eo.progress = false;
        eo.add_light = [&](std::size_t frame, Image& rendered) { light.add(frame, rendered); };
        const evaluate::EvaluationResult r = evaluate::evaluate(*test::vulkan_context(), bundle, capture, eo);
        const double again = r.display_metrics.test_masked.psnr, again_without = r.direct_display_metrics->test_masked.psnr;
        std::printf("evaluated from the bundle: with %.2f dB (the reconstruction's %.2f), without %.2f dB (%.2f); %zu particles, "
                    "set up in %.1f s\n",
                    again, with, again_without, without, light.stats().particles, light.stats().setup_s());
        EXPECT_NEAR(again_without, without, 0.01);
        EXPECT_NEAR(again, with, 0.05);
    }

    // The same knot without bounces: the unlit pixels are black, so the planner leaves it out.
    const fs::path direct = make_capture(dir, "knot", 96, 0, true);
    const ReconstructResult plain = run(direct, dir / "plain", Toggle::Auto);
    const nlohmann::json& dp = decision(plain.report, "indirect");
    EXPECT_EQ(dp["value"], "none");
    EXPECT_LT(dp["detail"]["shadow_ratio"].get<double>(), 0.1);
    EXPECT_NE(dp["reason"].get<std::string>().find("does not hold"), std::string::npos);
    EXPECT_TRUE(left_out_mentions(plain.report, "indirect light"));
}

} // namespace
} // namespace specula
