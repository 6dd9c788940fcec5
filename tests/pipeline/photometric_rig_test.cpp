// A photometric rig end to end (issue 17): one view lit by 48 directional lights (capture
// format 1.1, rendered exactly by synth), 4 held-out lights of the same view as test frames,
// the can with its Lafortune lobe, png16. reconstruct() must
//  - run (no limit on frames per view);
//  - recover the lobe within the 20 x 6 rig's bounds (tests/specular/lobe_recovery_test.cpp:
//    Cx, Cz within 2%, N within 5% of the truth) and the albedo of resolved seen texels within
//    the diffuse tests' 0.5% RMSE;
//  - choose the normal map (a view with >= 12 well-spread lights) and put it in the bundle,
//    with refined normals within 1 degree of the mesh's (noise-free: the mesh is the truth);
//  - and on the 20 x 6 rig's few lights per view, leave the normal map out.
#include "diffuse_scene.h"

#include "core/image.h"
#include "export/bundle.h"
#include "pipeline/planner.h"
#include "pipeline/reconstruct.h"
#include "synth/presets.h"
#include "synth/synth.h"
#include "lobe_truth.h"
#include "test_dirs.h"
#include "vulkan_env.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>

namespace specula {
namespace {

namespace fs = std::filesystem;

TEST(PhotometricRig, OneViewOfDirectionalLightsReconstructsWithANormalMap) {
    SPECULA_REQUIRE_VULKAN();
    test::TempDir dir("photometric_rig");
    synth::SynthOptions so;
    so.size = 128;
    so.views = 1;
    so.lights = 48;
    so.held_out_lights = 4;
    so.test_views = 0;
    so.directional = true;
    so.format = synth::ImageFormat::Png16;
    so.light_angles_deg = {10.0, 25.0, 40.0, 55.0};
    const fs::path capture = dir / "can";
    (void)synth::write_synthetic_capture(synth::to_object(synth::make_preset("can", false)), capture, so);

    ReconstructConfig c;
    c.capture = capture;
    c.out_dir = dir / "out";
    c.evaluate = false;
    const ReconstructResult r = reconstruct(c);

    // The lobe, within the 20 x 6 rig's noise-free bounds.
    test::expect_lobe_near_truth(r.report, capture, 0.02, 0.05, "one view x 48 directional lights");

    // The albedo of resolved seen texels: reconstruct's albedo.exr at the texels of the same
    // atlas (build_scene_stages sizes it as reconstruct does) against the preset's texture.
    test::DiffuseScene s;
    s.preset = synth::make_preset("can", false);
    s.capture = load_capture(capture);
    test::build_scene_stages(s);
    const Image albedo = read_image(c.out_dir / "albedo.exr", ColorSpace::Linear);
    ASSERT_EQ(albedo.width, static_cast<int>(s.atlas.width));
    const LambertOutputs seen = lambert_solve_cpu(s.inputs(), {}); // which particles a view saw
    std::vector<glm::vec3> estimate(s.truth.size());
    std::vector<std::uint8_t> select = test::flat_truth(s, 1.5, 0.004f);
    for (std::size_t p = 0; p < estimate.size(); ++p) {
        const Particle& q = s.particles.particles[p];
        for (int ch = 0; ch < 3; ++ch)
            estimate[p][ch] = albedo.at(static_cast<int>(q.texel_x()), static_cast<int>(q.texel_y()), ch);
        select[p] = select[p] && (seen.particles[p].status & shared::kLambertOk);
    }
    const test::AlbedoError e = test::albedo_error(estimate, s.truth, select);
    std::printf("albedo of resolved seen texels: RMSE %.4f%%, max %.4f (n %zu)\n", 100 * e.rmse, e.max_abs, e.count);
    EXPECT_GT(e.count, 1000u);
    EXPECT_LT(e.rmse, 0.005);

    // The normal map.
    const nlohmann::json& plan = r.report["planner"];
    const auto decision = std::find_if(plan.begin(), plan.end(), [](const nlohmann::json& d) { return d["name"] == "normal_map"; });
    ASSERT_NE(decision, plan.end());
    EXPECT_EQ((*decision)["value"], "refined normals") << decision->dump();
    const nlohmann::json& nm = r.report["normal_map"];
    ASSERT_TRUE(nm.is_object()) << r.report.dump();
    std::printf("normal map: %s\n", nm.dump().c_str());
    EXPECT_LT(nm["angle_to_mesh_normal_deg"]["mean"].get<double>(), 1.0);
    EXPECT_LT(nm["angle_to_mesh_normal_deg"]["median"].get<double>(), 1.0);
    EXPECT_LT(nm["angle_to_mesh_normal_deg"]["p95"].get<double>(), 1.0); // the rest: silhouettes and rims
    EXPECT_GT(nm["refined"].get<double>(), 0.3 * nm["particles"].get<double>());
    const Bundle b = read_bundle(c.out_dir / "object.glb");
    ASSERT_TRUE(b.normal_map.has_value());
    EXPECT_EQ(b.normal_map->width, b.albedo.width);
}

TEST(PhotometricRig, FewLightsPerViewLeaveTheNormalMapOut) {
    LightConditioning lc{.views = 20, .capable_views = 20, .median_rcond = 0.3, .min_rcond = 1e-3, .min_lights = 6,
                         .max_lights = 6, .rich_views = 0};
    const PlanDecision d = decide_normal_map(lc, Toggle::Auto);
    EXPECT_EQ(d.value, "none");
    EXPECT_TRUE(d.skipped);
    EXPECT_NE(d.reason.find("too few lights"), std::string::npos) << d.reason;
    lc.rich_views = 1;
    lc.max_lights = 96;
    EXPECT_EQ(decide_normal_map(lc, Toggle::Auto).value, "refined normals");
    EXPECT_EQ(decide_normal_map(lc, Toggle::Off).value, "none");
    lc.rich_views = 0;
    EXPECT_EQ(decide_normal_map(lc, Toggle::On).value, "refined normals");
}

} // namespace
} // namespace specula
