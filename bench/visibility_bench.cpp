// Measures the particle and visibility stages on a procedural torus (not
// convex: every occlusion ray is cast) and on a sphere (convex: rays skipped).
//   visibility_bench [triangles=100000] [views=20] [lights=120] [image size=512] [threads=2]
#include "visibility/visibility.h"

#include "core/timer.h"
#include "test_meshes.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace {

using namespace specula;

void run(const char* name, const Mesh& mesh, int views, int lights, int size, unsigned threads) {
    std::vector<Camera> cams;
    std::vector<VisibilityView> vviews;
    for (int i = 0; i < views; ++i) {
        // Cameras spread over a sphere (golden-angle spiral), all looking at the origin.
        const double y = 1.0 - 2.0 * (i + 0.5) / views, r = std::sqrt(1.0 - y * y), phi = 2.39996322972865332 * i;
        const glm::dvec3 eye = 4.0 * glm::dvec3(r * std::cos(phi), 0.8 * y, r * std::sin(phi));
        const Camera cam(Intrinsics{size, size, 1.4 * size, 1.4 * size, size / 2.0, size / 2.0},
                         look_at_camera_to_world(eye, {0, 0, 0}, {0, 1, 0}));
        cams.push_back(cam);
        vviews.push_back({cam, {}});
    }
    std::vector<PointLight> pls;
    for (int i = 0; i < lights; ++i) {
        const double y = 1.0 - 2.0 * (i + 0.5) / lights, r = std::sqrt(1.0 - y * y), phi = 2.39996322972865332 * i + 0.5;
        pls.push_back({5.0 * glm::dvec3(r * std::cos(phi), y, r * std::sin(phi)), glm::dvec3(20.0)});
    }

    Stopwatch clock;
    const Atlas atlas = build_atlas(mesh, cams);
    const double t_atlas = clock.seconds();
    clock.restart();
    const ParticleSet particles = build_particles(mesh, atlas);
    const double t_particles = clock.seconds();
    clock.restart();
    RaySceneOptions ro;
    ro.build_threads = threads;
    const RayScene scene(mesh, ro);
    const double t_scene = clock.seconds();
    VisibilityOptions vo;
    vo.threads = threads;
    const Visibility vis = compute_visibility(particles.particles, mesh, scene, vviews, pls, vo);

    std::printf("== %s: %zu triangles, %d views at %dx%d, %d lights, %u threads\n", name, mesh.triangles.size(), views, size, size,
                lights, threads);
    std::printf("%s", describe(atlas.summary).c_str());
    std::printf("atlas %.3f s, particles %.3f s (%zu particles: %zu interior, %zu gutter), Embree build %.3f s\n", t_atlas,
                t_particles, particles.particles.size(), particles.interior, particles.gutter, t_scene);
    std::printf("%s", describe(vis.stats).c_str());
    if (vis.stats.rays_cast > 0)
        std::printf("  %.2f M rays/s\n", double(vis.stats.rays_cast) / vis.stats.seconds * 1e-6);
}

} // namespace

int main(int argc, char** argv) try {
    const int triangles = argc > 1 ? std::atoi(argv[1]) : 100000;
    const int views = argc > 2 ? std::atoi(argv[2]) : 20;
    const int lights = argc > 3 ? std::atoi(argv[3]) : 120;
    const int size = argc > 4 ? std::atoi(argv[4]) : 512;
    const unsigned threads = argc > 5 ? unsigned(std::atoi(argv[5])) : 2u;
    // Torus with nu = 2 nv: 2 nu nv = 4 nv^2 triangles.
    const int nv = std::max(3, int(std::lround(std::sqrt(triangles / 4.0))));
    run("torus", specula::test::torus(1.0f, 0.4f, 2 * nv, nv), views, lights, size, threads);
    // UV sphere with segments = 2 rings: about 4 rings^2 triangles.
    const int rings = std::max(3, int(std::lround(std::sqrt(triangles / 4.0))));
    run("sphere", specula::test::sphere(1.0f, rings, 2 * rings), views, lights, size, threads);
    return 0;
} catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
}
