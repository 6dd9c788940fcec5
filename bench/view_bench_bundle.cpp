// Writes a bundle of a synth preset built from its truth, for `specula-view --bench`
// without a full reconstruction (knot_hd takes minutes: its 2.8 M particles exceed one
// storage binding on lavapipe, so the per-particle passes run on the CPU reference).
// Run by hand, not a ctest:
//   build/bench/view_bench_bundle knot_hd /tmp/knot_hd.glb
// The atlas is a real one (build_atlas, default budget) filled with the true albedo,
// as bench/render_bench builds it, so the renderer's load (mesh split at
// patches, atlas size) is what a reconstruction would give; the lobe is the truth's.
#include "core/timer.h"
#include "export/bundle.h"
#include "geometry/atlas.h"
#include "geometry/particles.h"
#include "synth/presets.h"
#include "synth/render.h"

#include <cstdio>
#include <string>

using namespace specula;

int main(int argc, char** argv) try {
    if (argc != 3) {
        std::fprintf(stderr, "usage: view_bench_bundle PRESET OUT.glb\n");
        return 2;
    }
    const Stopwatch sw;
    const synth::Preset preset = synth::make_preset(argv[1]);
    const Atlas atlas = build_atlas(preset.mesh, {});
    const ParticleSet particles = build_particles(preset.mesh, atlas);
    Image albedo(static_cast<int>(atlas.width), static_cast<int>(atlas.height), 3, 0.0f);
    for (const Particle& p : particles.particles) {
        const glm::uvec3 t = preset.mesh.triangles[p.triangle];
        glm::vec3 rho = preset.material.albedo_value;
        if (!preset.material.albedo_texture.empty()) {
            const glm::vec2 uv = (1.0f - p.bary.x - p.bary.y) * preset.mesh.texcoords[t.x] +
                                 p.bary.x * preset.mesh.texcoords[t.y] + p.bary.y * preset.mesh.texcoords[t.z];
            rho = synth::sample_albedo(preset.material.albedo_texture, uv);
        }
        for (int c = 0; c < 3; ++c) albedo.at(static_cast<int>(p.texel_x()), static_cast<int>(p.texel_y()), c) = rho[c];
    }
    const Bundle bundle = make_bundle(preset.mesh, atlas.corner_uv, std::move(albedo), Material{.specular = preset.material.lobe});
    write_bundle(argv[2], bundle);
    std::printf("%s: %zu triangles, %zu vertices, atlas %ux%u -> %s (%.1f s)\n", argv[1], bundle.mesh.triangles.size(),
                bundle.mesh.positions.size(), atlas.width, atlas.height, argv[2], sw.seconds());
    return 0;
} catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
}
