// The indirect-light model against a path tracer's, with the true albedo and material, so that
// no solve is involved: indirect_model CAPTURE_BOUNCES CAPTURE_DIRECT [EVERY_NTH_FRAME (6)]
// CAPTURE_BOUNCES and CAPTURE_DIRECT are `specula synth` captures of one preset, rig and seed,
// with --bounces N and without: their difference is the true indirect light of every pixel (up
// to the path tracer's noise). The model's (indirect/indirect.h) is computed from the capture's
// truth (albedo texture, material) with the lobe's first bounce directed and spread, and without the
// lobe; printed: predicted / true over the object's pixels, by how much direct light they show.
#include "capture/capture.h"
#include "indirect/indirect.h"
#include "pipeline/run.h"
#include "pipeline/stages.h"
#include "synth/render.h"
#include "synth/synth.h"

#include <cstdio>
#include <exception>
#include <string>
#include <vector>

int main(int argc, char** argv) try {
    using namespace specula;
    if (argc < 3) {
        std::fprintf(stderr, "usage: indirect_model CAPTURE_BOUNCES CAPTURE_DIRECT [EVERY_NTH_FRAME (6)]\n");
        return 2;
    }
    const std::size_t every = argc > 3 ? std::stoul(argv[3]) : 6;
    const Capture bounced = load_capture(argv[1], {.load_mesh = true, .load_images = true});
    const Capture direct = load_capture(argv[2], {.load_mesh = false, .load_images = true});
    ReconstructConfig config;
    ReconstructResult result;
    PipelineRun run(config, result);
    (void)plan_stage(run, bounced); // the decisions the stages read (occlusion rays)
    const GeometryStage geometry = geometry_stage(run, bounced);
    const VisibilityStage visibility = visibility_stage(run, bounced, geometry);
    const std::span<const Particle> particles = geometry.particles.particles;
    // The truth's albedo at each particle (the capture's mesh keeps the preset's texture coordinates).
    const Image truth = read_image(bounced.desc.dir / "truth" / "albedo.exr", ColorSpace::Linear);
    std::vector<glm::vec3> albedo(particles.size());
    for (std::size_t i = 0; i < particles.size(); ++i) {
        const glm::uvec3 t = bounced.mesh.triangles[particles[i].triangle];
        const glm::vec2 st = particles[i].bary;
        const glm::vec2 uv = (1.0f - st.x - st.y) * bounced.mesh.texcoords[t.x] + st.x * bounced.mesh.texcoords[t.y] +
                             st.y * bounced.mesh.texcoords[t.z];
        albedo[i] = synth::sample_albedo(truth, uv);
    }
    std::vector<std::size_t> frames;
    for (std::size_t f = 0; f < bounced.desc.frames.size(); f += every)
        if (bounced.desc.frames[f].split == Split::Train) frames.push_back(f);
    // The truth's material, any family (ground_truth.material, as synth writes it).
    const SpecularModel material = synth::material_from_json(bounced.desc.ground_truth.at("material"));
    std::vector<ViewAtlasMap> maps;
    for (const View& v : bounced.views) maps.push_back(build_view_atlas_map(v.camera, bounced.mesh, *visibility.scene, geometry.atlas, geometry.particles.particles));
    for (const std::uint32_t block : {1u, 2u}) {
        const IndirectTransfer transfer = build_transfer(particles, bounced.mesh, *visibility.scene, geometry.atlas, {.block = block});
        const IndirectScene scene{.particles = particles, .visibility = &visibility.visibility, .lights = visibility.inputs.lights,
                                  .frame_view = visibility.inputs.frame_view, .atlas = &geometry.atlas, .transfer = &transfer,
                                  .view_maps = maps};
        struct Variant {
            const char* name;
            std::optional<SpecularModel> material;
            bool directions;
        };
        for (const Variant& v : {Variant{"lobe directed", material, true},
                                 Variant{"lobe spread", material, false}, Variant{"no lobe", std::nullopt, false}}) {
            // Bins by the direct light of the pixel (the direct capture's, r + g + b, linear), which
            // the indirect light's noise does not move: sums of predicted and true.
            constexpr int kBins = 5;
            const double edges[kBins + 1] = {0.0, 1e-6, 0.03, 0.1, 0.3, 1e9};
            double predicted[kBins] = {}, actual[kBins] = {}, square[kBins] = {};
            std::size_t count[kBins] = {};
            indirect_images(scene, frames, albedo, v.material, {.bounces = static_cast<std::uint32_t>(
                                                                     bounced.desc.ground_truth.value("bounces", 2)),
                                                                 .lobe_directions = v.directions},
                            [&](std::size_t f, const Image& light) {
                                const Image& b = bounced.images[f].color;
                                const Image& d = direct.images[f].color;
                                const std::vector<std::uint8_t>& flags = bounced.images[f].flags;
                                for (std::size_t p = 0; p < light.pixels.size() / 3; ++p) {
                                    if (!flags.empty() && (flags[p] & (kOutsideMask | kClippedAny)) != 0) continue;
                                    double pr = 0.0, tr = 0.0, lit = 0.0;
                                    for (int c = 0; c < 3; ++c) {
                                        pr += light.pixels[3 * p + c];
                                        tr += b.pixels[3 * p + c] - d.pixels[3 * p + c];
                                        lit += d.pixels[3 * p + c];
                                    }
                                    if (!(b.pixels[3 * p] + b.pixels[3 * p + 1] + b.pixels[3 * p + 2] > 0.0f)) continue;
                                    int k = 0;
                                    while (k + 1 < kBins && lit >= edges[k + 1]) ++k;
                                    predicted[k] += pr;
                                    actual[k] += tr;
                                    square[k] += (pr - tr) * (pr - tr);
                                    ++count[k];
                                }
                            });
            std::printf("block %u, %-14s", block, v.name);
            for (int k = 0; k < kBins; ++k)
                std::printf(" | direct %g-%g: %7zu px, pred/true %.3f, rms %.4f", edges[k], edges[k + 1], count[k],
                            actual[k] > 0.0 ? predicted[k] / actual[k] : 0.0, count[k] ? std::sqrt(square[k] / count[k]) : 0.0);
            std::printf("\n");
        }
    }
    return 0;
} catch (const std::exception& e) {
    std::fprintf(stderr, "indirect_model: %s\n", e.what());
    return 1;
}
