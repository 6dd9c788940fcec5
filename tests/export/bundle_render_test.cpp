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

TEST_F(VulkanTest, BundleRendersLikeTheInMemoryPieces) {
    for (const FactorParam param : {FactorParam::Gshd, FactorParam::Mirrored, FactorParam::Warped}) {
        const test::BundlePieces p = test::make_pieces(12, 20);
        const CubeMap g = test::random_cube(8, 11), h = test::random_cube(16, 12);
        const glm::vec4 warp = param == FactorParam::Warped ? warp_for_lobe(p.lobe).value() : glm::vec4(1.0f);
        const FactorizedSpecular cubes{.param = param, .warp = warp, .terms = {{g, h}}};
        Bundle b = make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, Material{.specular = p.lobe, .factorized = cubes});
        test::TempDir dir("bundle-render");
        write_bundle(dir / "r.glb", b);
        const Bundle r = read_bundle(dir / "r.glb");
        ASSERT_TRUE(r.material.specular && r.material.factorized);
        EXPECT_EQ(r.material.factorized->param, param);
        const std::vector<glm::vec2> uv = corner_uvs(r.mesh);

        // In memory: the lobe in the scene, the cube-maps set after; from disk: the whole material
        // in the scene (as evaluate::BundleRenderer does).
        render::Renderer mem(ctx(), {.mesh = &p.mesh, .corner_uv = p.atlas.corner_uv, .albedo = &p.albedo,
                                     .material = {.specular = p.lobe}});
        mem.set_factorization(cubes);
        render::Renderer disk(ctx(), {.mesh = &r.mesh, .corner_uv = uv, .albedo = &r.albedo, .material = r.material});

        const Camera cam(Intrinsics{96, 80, 110.0, 110.0, 47.0, 41.0},
                         look_at_camera_to_world({0.4, 0.9, 2.6}, {0, 0, 0}, {0, 1, 0}));
        const PointLight light{{1.2, 1.6, 2.0}, {5.0, 5.0, 5.0}};
        for (const render::SpecularPath model : {render::SpecularPath::Analytic, render::SpecularPath::Factorized}) {
            const render::Settings s{.mode = render::Mode::Both, .specular = model};
            const render::Frame a = mem.render(cam, light, s), c = disk.render(cam, light, s);
            ASSERT_GT(a.info.covered_pixels, 1000u);
            EXPECT_TRUE(a.info.specular_pass);
            EXPECT_EQ(a.mask, c.mask);
            EXPECT_EQ(a.color.pixels, c.color.pixels) << render::specular_path_name(model) << " " << to_string(param);
        }
    }
}

} // namespace
} // namespace specula
