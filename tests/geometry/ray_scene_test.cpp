// RayScene (engine/geometry/ray_scene.h): known hits, occlusion limits,
// batched and concurrent use, moves, the scale-relative offset.
#include "geometry/ray_scene.h"

#include "core/error.h"
#include "test_meshes.h"

#include <gtest/gtest.h>

#include <limits>
#include <random>
#include <thread>

namespace specula {
namespace {

Mesh unit_quad_at_z0() {
    Mesh m;
    test::add_quad(m, {0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}); // triangles (0,1,2) and (0,2,3)
    return m;
}

TEST(RayScene, HitsAKnownTriangleAtAKnownDistance) {
    const Mesh mesh = unit_quad_at_z0();
    const RayScene scene(mesh);
    // (0.75, 0.25) lies in triangle 0 = (0,0,0), (1,0,0), (1,1,0).
    const auto hit = scene.intersect({0.75f, 0.25f, 5.0f}, {0, 0, -1}, 0.0f, 100.0f);
    ASSERT_TRUE(hit.has_value());
    EXPECT_NEAR(hit->t, 5.0f, 1e-5f);
    EXPECT_EQ(hit->triangle, 0u);
    const glm::uvec3 t = mesh.triangles[hit->triangle];
    const glm::vec3 p = (1.0f - hit->u - hit->v) * mesh.positions[t.x] + hit->u * mesh.positions[t.y] + hit->v * mesh.positions[t.z];
    EXPECT_LT(glm::length(p - glm::vec3(0.75f, 0.25f, 0.0f)), 1e-5f);
    // (0.25, 0.75) lies in triangle 1; t scales with |dir|.
    const auto hit2 = scene.intersect({0.25f, 0.75f, 3.0f}, {0, 0, -2}, 0.0f, 100.0f);
    ASSERT_TRUE(hit2.has_value());
    EXPECT_EQ(hit2->triangle, 1u);
    EXPECT_NEAR(hit2->t, 1.5f, 1e-5f);
    EXPECT_FALSE(scene.intersect({2.0f, 2.0f, 3.0f}, {0, 0, -1}, 0.0f, 100.0f).has_value());
}

TEST(RayScene, OcclusionRespectsTheRayInterval) {
    const RayScene scene(unit_quad_at_z0());
    EXPECT_TRUE(scene.occluded({0.5f, 0.3f, 5.0f}, {0, 0, -1}, 0.0f, 6.0f));
    EXPECT_FALSE(scene.occluded({0.5f, 0.3f, 5.0f}, {0, 0, -1}, 0.0f, 4.9f));
    EXPECT_FALSE(scene.occluded({0.5f, 0.3f, 5.0f}, {0, 0, -1}, 5.1f, 9.0f));
    EXPECT_FALSE(scene.occluded({0.5f, 0.3f, 5.0f}, {0, 0, 1}, 0.0f, 100.0f));
    // Back faces occlude too.
    EXPECT_TRUE(scene.occluded({0.5f, 0.3f, -5.0f}, {0, 0, 1}, 0.0f, 100.0f));
}

TEST(RayScene, BatchesMatchSingleRaysFromSeveralThreads) {
    const Mesh mesh = test::torus(1.0f, 0.35f, 40, 20);
    const RayScene scene(mesh);
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    std::vector<Ray> rays(3000);
    for (Ray& r : rays) {
        r.origin = glm::vec3(u(rng), u(rng), u(rng)) * 2.0f;
        r.dir = glm::normalize(glm::vec3(u(rng), u(rng), u(rng)) + glm::vec3(0.0f, 0.0f, 0.01f));
        r.tmin = 0.0f;
        r.tmax = 0.5f + 3.0f * (u(rng) + 1.0f);
    }
    std::vector<std::uint8_t> occluded_single(rays.size());
    std::vector<std::optional<RayHit>> hit_single(rays.size());
    std::size_t hits = 0;
    for (std::size_t i = 0; i < rays.size(); ++i) {
        occluded_single[i] = scene.occluded(rays[i].origin, rays[i].dir, rays[i].tmin, rays[i].tmax) ? 1 : 0;
        hit_single[i] = scene.intersect(rays[i].origin, rays[i].dir, rays[i].tmin, rays[i].tmax);
        hits += hit_single[i].has_value();
        EXPECT_EQ(bool(occluded_single[i]), hit_single[i].has_value());
    }
    EXPECT_GT(hits, 300u);
    EXPECT_LT(hits, rays.size());

    std::vector<std::uint8_t> occ[2];
    std::vector<std::optional<RayHit>> hit[2];
    std::thread workers[2];
    for (int w = 0; w < 2; ++w) {
        occ[w].resize(rays.size());
        hit[w].resize(rays.size());
        workers[w] = std::thread([&, w] {
            for (int rep = 0; rep < 3; ++rep) {
                scene.occluded(rays, occ[w]);
                scene.intersect(rays, hit[w]);
            }
        });
    }
    for (std::thread& t : workers) t.join();
    for (int w = 0; w < 2; ++w)
        for (std::size_t i = 0; i < rays.size(); ++i) {
            EXPECT_EQ(occ[w][i], occluded_single[i]);
            ASSERT_EQ(hit[w][i].has_value(), hit_single[i].has_value());
            if (hit_single[i]) {
                EXPECT_EQ(hit[w][i]->triangle, hit_single[i]->triangle);
                EXPECT_FLOAT_EQ(hit[w][i]->t, hit_single[i]->t);
            }
        }
    std::vector<std::uint8_t> wrong(3);
    EXPECT_THROW(scene.occluded(rays, wrong), Error);
}

TEST(RayScene, BatchesAgreeWithSingleRaysOnNearlyAxisAlignedRays) {
    // A floor particle's shadow ray through a box, with a 5e-18 x component:
    // Embree's stream API (rtcOccluded1M) once missed the box here.
    const RayScene scene(test::merge(test::plane(2.0f, 16), test::box({-0.5f, 0.0f, -0.5f}, {0.5f, 1.0f, 0.5f})));
    // As a batch of three, the middle ray came back unoccluded from rtcOccluded1M (alone it was right).
    const glm::vec3 p(5.20417e-18f, 0.0f, -0.75f);
    const std::vector<Ray> rays = {scene.ray_toward(p, {0, 1, 0}, {0.0f, 4.0f, 4.0f}), scene.ray_toward(p, {0, 1, 0}, {0.0f, 1.5f, 3.0f}),
                                   scene.ray_toward(p, {0, 1, 0}, {0.0f, 5.0f, 0.0f})};
    std::vector<std::uint8_t> batch(rays.size());
    scene.occluded(rays, batch);
    EXPECT_EQ(batch, (std::vector<std::uint8_t>{1, 1, 0}));
    for (std::size_t i = 0; i < rays.size(); ++i)
        EXPECT_EQ(bool(batch[i]), scene.occluded(rays[i].origin, rays[i].dir, rays[i].tmin, rays[i].tmax));
}

TEST(RayScene, MovedSceneStillAnswers) {
    RayScene a(unit_quad_at_z0());
    RayScene b(std::move(a));
    EXPECT_TRUE(b.occluded({0.5f, 0.5f, 1.0f}, {0, 0, -1}, 0.0f, 2.0f));
    RayScene c(test::box({5, 5, 5}, {6, 6, 6}));
    c = std::move(b);
    EXPECT_TRUE(c.occluded({0.5f, 0.5f, 1.0f}, {0, 0, -1}, 0.0f, 2.0f));
    EXPECT_EQ(c.triangle_count(), 2u);
}

TEST(RayScene, RayOffsetIsRelativeToTheMeshSize) {
    const RayScene small(test::sphere(1.0f, 8, 8));
    const RayScene large(test::sphere(1000.0f, 8, 8));
    EXPECT_NEAR(large.ray_offset() / small.ray_offset(), 1000.0f, 1.0f);
    EXPECT_NEAR(small.ray_offset(), RayScene::kRayOffsetRelative * std::sqrt(12.0f), 1e-6f);
    // A ray leaving the surface along the normal toward an outside point does not hit its own triangle.
    const Ray r = large.ray_toward({0.0f, 1000.0f, 0.0f}, {0, 1, 0}, {300.0f, 3000.0f, 0.0f});
    EXPECT_FALSE(large.occluded(r.origin, r.dir, r.tmin, r.tmax));
    EXPECT_NEAR(glm::length(r.dir), 1.0f, 1e-6f);
}

TEST(RayScene, RefusesAnEmptyMesh) {
    EXPECT_THROW(RayScene(Mesh{}), Error);
    Mesh bad = unit_quad_at_z0();
    bad.triangles.push_back({0, 1, 99});
    EXPECT_THROW(RayScene{bad}, Error);
}

// The second line of defence (issue 21 cases 1-3): rays Embree cannot trace (it aborts on an
// assertion in Debian's build) are refused with an Error naming them, whatever the caller checked.
TEST(RayScene, RaysOutsideEmbreesRangeAreRefusedNotTraced) {
    const RayScene scene(unit_quad_at_z0());
    const float inf = std::numeric_limits<float>::infinity(), nan = std::numeric_limits<float>::quiet_NaN();
    const glm::vec3 o(0.5f, 0.5f, 1.0f), down(0.0f, 0.0f, -1.0f);
    auto refused = [&](const Ray& r) {
        try {
            (void)scene.intersect(r.origin, r.dir, r.tmin, r.tmax);
        } catch (const Error& e) {
            EXPECT_NE(std::string(e.what()).find("outside what the ray tracer accepts"), std::string::npos) << e.what();
            EXPECT_THROW((void)scene.occluded(r.origin, r.dir, r.tmin, r.tmax), Error);
            return true;
        }
        return false;
    };
    EXPECT_TRUE(refused({glm::vec3(float(1e39), 0.0f, 0.0f), 0.0f, down, 10.0f})); // a light at 1e39: infinity as a float
    EXPECT_TRUE(refused({glm::vec3(1e20f, 0.5f, 1.0f), 0.0f, down, 10.0f}));        // finite, beyond Embree's 1.8e18
    EXPECT_TRUE(refused({o, 0.0f, glm::vec3(nan, 0.0f, -1.0f), 10.0f}));           // fl_x = 5e-324: a NaN direction
    EXPECT_TRUE(refused({o, 0.0f, glm::vec3(inf, 0.0f, -1.0f), 10.0f}));
    EXPECT_TRUE(refused({o, -1.0f, down, 10.0f}));                                  // a segment before the origin
    EXPECT_TRUE(refused({o, nan, down, 10.0f}));
    EXPECT_TRUE(refused({o, 0.0f, down, nan}));
    // In range: traced as before, up to the limit and with an infinite tmax.
    EXPECT_FALSE(refused({o, 0.0f, down, inf}));
    EXPECT_TRUE(scene.intersect(o, down, 0.0f, inf).has_value());
    EXPECT_FALSE(refused({glm::vec3(0.5f, 0.5f, 1e18f), 0.0f, down, inf}));
    // Batches name the ray.
    std::vector<Ray> rays(3, Ray{o, 0.0f, down, 10.0f});
    rays[2].origin.x = nan;
    std::vector<std::uint8_t> occluded(3);
    try {
        scene.occluded(rays, occluded);
        ADD_FAILURE() << "not refused";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("ray 2 is outside"), std::string::npos) << e.what();
    }
    std::vector<std::optional<RayHit>> hits(3);
    EXPECT_THROW(scene.intersect(rays, hits), Error);
}

TEST(RayScene, RefusesVerticesItCannotTrace) {
    Mesh bad = unit_quad_at_z0();
    bad.positions[2].x = 1e19f;
    EXPECT_THROW(RayScene{bad}, Error);
    bad.positions[2].x = std::numeric_limits<float>::infinity();
    EXPECT_THROW(RayScene{bad}, Error);
}

} // namespace
} // namespace specula
