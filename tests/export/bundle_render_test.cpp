// The bundle carries what the renderer needs exactly: a frame rendered from the
// pipeline's in-memory pieces (mesh, atlas corner coordinates, float albedo, lobe,
// cube-maps) and one rendered from the bundle read back from disk are identical, in
// every mode (lavapipe + validation; VulkanTest fails on any validation message).
#include "bundle_fixtures.h"
#include "capture/camera.h"
#include "render/renderer.h"
#include "test_dirs.h"
#include "vulkan_env.h"

#include <gtest/gtest.h>

namespace specula {
namespace {

using test::VulkanTest;

render::CubeMapRgb to_render(const BundleCubeMap& c) { return {c.resolution, c.rgb}; }

TEST_F(VulkanTest, BundleRendersLikeTheInMemoryPieces) {
    for (const FactorParam param : {FactorParam::Gshd, FactorParam::Mirrored, FactorParam::Warped}) {
        const test::BundlePieces p = test::make_pieces(12, 20);
        const BundleCubeMap g = test::random_cube(8, 11), h = test::random_cube(16, 12);
        Bundle b = make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, p.lobe);
        b.cube_g = g;
        b.cube_h = h;
        b.factor_param = param;
        const glm::vec4 warp = param == FactorParam::Warped ? warp_for_lobe(p.lobe).value() : glm::vec4(1.0f);
        b.factor_warp = warp;
        test::TempDir dir("bundle-render");
        write_bundle(dir / "r.glb", b);
        const Bundle r = read_bundle(dir / "r.glb");
        ASSERT_TRUE(r.lobe && r.cube_g && r.cube_h);
        EXPECT_EQ(r.factor_param, param);
        const std::vector<glm::vec2> uv = corner_uvs(r.mesh);

        render::Renderer mem(ctx(), {.mesh = &p.mesh, .corner_uv = p.atlas.corner_uv, .albedo = &p.albedo, .lobe = p.lobe});
        mem.set_factorization(to_render(g), to_render(h), param, warp);
        render::Renderer disk(ctx(), {.mesh = &r.mesh, .corner_uv = uv, .albedo = &r.albedo, .lobe = *r.lobe});
        disk.set_factorization(to_render(*r.cube_g), to_render(*r.cube_h), r.factor_param, r.factor_warp);

        const Camera cam(Intrinsics{96, 80, 110.0, 110.0, 47.0, 41.0},
                         look_at_camera_to_world({0.4, 0.9, 2.6}, {0, 0, 0}, {0, 1, 0}));
        const PointLight light{{1.2, 1.6, 2.0}, {5.0, 5.0, 5.0}};
        for (const render::SpecularModel model : {render::SpecularModel::Analytic, render::SpecularModel::Factorized}) {
            const render::Settings s{.mode = render::Mode::Both, .specular = model};
            const render::Frame a = mem.render(cam, light, s), c = disk.render(cam, light, s);
            ASSERT_GT(a.info.covered_pixels, 1000u);
            EXPECT_TRUE(a.info.specular_pass);
            EXPECT_EQ(a.mask, c.mask);
            EXPECT_EQ(a.color.pixels, c.color.pixels) << render::specular_model_name(model) << " " << to_string(param);
        }
    }
}

} // namespace
} // namespace specula
