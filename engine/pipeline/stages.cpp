#include "pipeline/stages.h"

#include "core/error.h"
#include "core/file_util.h"
#include "core/format.h"
#include "core/log.h"
#include "core/parallel.h"
#include "core/timer.h"
#include "evaluate/indirect_light.h"
#include "gpu/context.h"
#include "export/normal_map.h"
#include "material/core_material.h"
#include "metrics/display_values.h"
#include "pipeline/planner.h"
#include "specula/version.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <utility>

namespace specula {

namespace fs = std::filesystem;

namespace {

// Seconds per occlusion ray, timed on up to `max_rays` (particle, view) rays of the pairs the
// views see (a deterministic stride over the particles): the planner's cheap measurement of
// what the rays a convex mesh makes unnecessary would have cost.
std::optional<double> probe_ray_seconds(const RayScene& scene, std::span<const Particle> particles, const Visibility& vis,
                                        std::span<const VisibilityView> views, std::size_t max_rays) {
    std::vector<Ray> rays;
    const std::size_t per_particle = std::max<std::size_t>(1, views.size() / 4);
    const std::size_t stride = std::max<std::size_t>(1, particles.size() * per_particle / std::max<std::size_t>(1, max_rays));
    for (std::size_t p = 0; p < particles.size() && rays.size() < max_rays; p += stride)
        for (std::size_t v = 0; v < views.size() && rays.size() < max_rays; ++v)
            if (vis.sees(p, v))
                rays.push_back(scene.ray_toward(particles[p].p(), particles[p].n(), glm::vec3(views[v].camera.center())));
    if (rays.size() < 16) return std::nullopt;
    std::vector<std::uint8_t> hit(rays.size());
    const Stopwatch watch;
    scene.occluded(rays, hit);
    return watch.seconds() / static_cast<double>(rays.size());
}

// The occlusion-ray decision's detail and cost, once visibility has run.
void record_occlusion_cost(PipelineRun& run, const GeometryStage& geometry, const VisibilityStage& vis, bool cast_rays) {
    const VisibilityStats& stats = vis.visibility.stats;
    PlanDecision& d = *run.plan().find("occlusion_rays");
    d.detail["rays_cast"] = stats.rays_cast;
    d.detail["rays_avoided"] = stats.rays_avoided;
    if (cast_rays) {
        d.measured_seconds = run.seconds("visibility");
        d.cost_basis = "measured: the visibility stage with " + std::to_string(stats.rays_cast) + " occlusion rays" +
                       (stats.rays_answered > 0 ? " (" + std::to_string(stats.rays_answered) + " light rays answered by the shadow maps)"
                                                : std::string()) +
                       ", " + std::to_string(stats.depth_rays) + " depth-map rays and " + std::to_string(stats.shadow_map_rays) +
                       " shadow-map rays";
        return;
    }
    run.leave_out("occlusion rays (visibility and shadows)", d.reason);
    if (!run.config.cost_probes || stats.rays_avoided == 0) return;
    const auto per_ray = run.stage("probe: occlusion rays", [&] {
        return probe_ray_seconds(*vis.scene, geometry.particles.particles, vis.visibility, vis.inputs.views, 20000);
    });
    if (!per_ray) return;
    PlanDecision& again = *run.plan().find("occlusion_rays"); // the probe added no decision, but stay safe
    again.avoided_seconds = *per_ray * static_cast<double>(stats.rays_avoided);
    again.cost_basis = "estimate: " + std::to_string(stats.rays_avoided) + " rays avoided x " + std::to_string(*per_ray * 1e9) +
                       " ns per ray (timed on up to 20000 particle-to-camera rays); the footprint test's depth and shadow "
                       "maps, skipped too, are not included";
}

// The residual pass's options for a solve made with `options` (whose material it subtracted).
ResidualOptions residual_options(const LambertOptions& options, std::size_t fit_samples) {
    return {.min_light_cos = options.min_light_cos,
            .material = options.material,
            .tap_irradiance = options.tap_irradiance,
            .max_binding_bytes = 0,
            .max_albedo_spread = 0.02f,
            .fit_samples = fit_samples,
            .threads = options.threads};
}

// The residual samples of `solve` (solved with `options`) on the run's per-particle backend,
// timed as `name`; with fit_samples, only those a fit of that many takes.
ResidualSamples run_residuals(PipelineRun& run, const LambertInputs& inputs, const LambertOutputs& solve,
                              const LambertOptions& options, const std::string& name, std::size_t fit_samples = 0) {
    const ResidualOptions ro = residual_options(options, fit_samples);
    ResidualSamples rs = run.stage(name, [&] {
        return run.on_particle_backend("residual samples", [&](Backend b) {
            return residual_samples(inputs, solve, ro, b, run.compute_context());
        });
    });
    if (rs.gpu_ms) run.add_gpu_dispatch(name, "residuals (" + std::to_string(rs.chunks) + " dispatches)", *rs.gpu_ms);
    return rs;
}

// The validation error of `model` over the residual samples of `solve` (solved with `options`)
// on `inputs`, timed as `name`: on the C++ backend without holding the samples.
double run_validation(PipelineRun& run, const LambertInputs& inputs, const LambertOutputs& solve, const LambertOptions& options,
                      const SpecularModel& model, const std::string& name) {
    const ResidualOptions ro = residual_options(options, 0);
    return run.stage(name, [&] {
        return run.on_particle_backend("residual samples", [&](Backend b) {
            return residual_mean_square_error(inputs, solve, ro, model, b, run.compute_context());
        });
    }).mean_square;
}

// The diffuse solve with `options` on the run's per-particle backend, timed as `name`.
LambertOutputs run_solve(PipelineRun& run, const LambertInputs& inputs, const LambertOptions& options, const std::string& name) {
    LambertOutputs solve = run.stage(name, [&] {
        return run.on_particle_backend("diffuse solve",
                                       [&](Backend b) { return lambert_solve(inputs, options, b, run.compute_context()); });
    });
    for (const auto& [label, ms] : solve.summary.gpu_dispatch_ms) run.add_gpu_dispatch(name, label, ms);
    return solve;
}

// The auto decision left the fit out: time it on a small subsample so the report can say what it would have cost.
void probe_fit_cost(PipelineRun& run, const std::vector<LafortuneSample>& all, const LafortuneFitOptions& fo, std::size_t would_fit) {
    if (!run.config.cost_probes || all.size() < 100) return;
    constexpr std::size_t kProbe = 4000;
    std::optional<double> probe;
    std::size_t probe_n = 0;
    run.stage("probe: lafortune fit", [&] {
        const std::vector<LafortuneSample> sub = stride_subsample(all, kProbe);
        probe_n = sub.size();
        const Stopwatch w;
        (void)fit_lafortune(sub, fo);
        probe = w.seconds();
    });
    set_specular_cost(*run.plan().find("specular_stages"), probe, probe_n, would_fit, std::nullopt);
}

} // namespace

const Capture& load_stage(PipelineRun& run, const Capture* preloaded, std::optional<Capture>& storage) {
    if (preloaded == nullptr)
        storage = run.stage("load", [&] {
            return load_capture(run.config.capture, CaptureLoadOptions{.threads = static_cast<int>(run.config.threads)});
        });
    const Capture& capture = preloaded != nullptr ? *preloaded : *storage;
    if (capture.images.empty()) throw Error("reconstruct: the capture was loaded without its images");
    for (const std::string& w : capture.warnings) run.warn(w);
    if (capture.frame_count(Split::Train) == 0)
        throw InputError(capture_json_path(run.config.capture), "frames", "no train frames: nothing to reconstruct from");
    return capture;
}

LambertOptions plan_stage(PipelineRun& run, const Capture& capture) {
    LambertOptions lambert = run.config.lambert;
    lambert.threads = run.config.threads;
    Plan& plan = run.plan();
    run.stage("plan", [&] {
        plan.add(decide_occlusion_rays(analyze_convexity(capture.mesh), run.config.occlusion_rays));
        const LightConditioning lc = light_conditioning(capture, static_cast<double>(lambert.min_rcond));
        const PlanDecision& mode = plan.add(decide_diffuse_mode(lc, run.config.diffuse_mode, run.config.specular != SpecularMode::Off));
        lambert.mode = decided_photometric(mode) ? LambertMode::Photometric : LambertMode::Albedo;
        plan.add(decide_normal_map(lc, run.config.normal_map));
        plan.add(PlanDecision{.name = "atlas"}); // filled once the particle stages are timed
    });
    for (const PlanDecision& d : plan.decisions)
        if (!d.value.empty()) log::info("plan: " + d.name + " = " + d.value + " (" + (d.forced ? "forced" : "auto") + ")");
    const PlanDecision& mode = *plan.find("diffuse_mode");
    if (mode.value == "albedo" && !mode.forced) run.leave_out("photometric solve (refined normals)", mode.reason);
    return lambert;
}

GeometryStage geometry_stage(PipelineRun& run, const Capture& capture) {
    // Cameras of the views that have train frames size the atlas (test views must not).
    std::vector<Camera> train_cameras;
    for (const View& view : capture.views)
        for (std::size_t f : view.frames)
            if (capture.desc.frames[f].split == Split::Train) {
                train_cameras.push_back(view.camera);
                break;
            }
    GeometryStage g{.atlas = run.stage("atlas", [&] { return build_atlas(capture.mesh, train_cameras, run.config.atlas); }),
                    .particles = {}};
    log::info(describe(g.atlas.summary));
    g.particles = run.stage("particles", [&] { return build_particles(capture.mesh, g.atlas); });
    return g;
}

VisibilityStage visibility_stage(PipelineRun& run, const Capture& capture, const GeometryStage& geometry) {
    const bool cast_rays = run.plan().find("occlusion_rays")->value == "cast";
    VisibilityStage v{.inputs = visibility_inputs(capture), .scene = std::nullopt, .visibility = {}};
    v.visibility = run.stage("visibility", [&] {
        v.scene.emplace(capture.mesh);
        return compute_visibility(geometry.particles.particles, capture.mesh, *v.scene, v.inputs.views, v.inputs.lights,
                                  VisibilityOptions{.threads = run.config.threads,
                                                    .force_rays = cast_rays,
                                                    .skip_rays = !cast_rays,
                                                    .frame_view = v.inputs.frame_view,
                                                    .surface_maps = run.config.lambert.tap_irradiance,
                                                    .keep_pixel_hits = true, // the indirect measure's and the pixel fit's
                                                    .lit_seen_only = true,
                                                    .shadow_maps_answer_lights = run.config.light_rays_from_shadow_maps});
    });
    // Legal but useless input (issue 21 cases 15, 17): most of the surface unseen or unlit is
    // warned; nothing seen, or nothing lit by a train frame of a view that sees it, is refused
    // here, naming the capture, rather than solved into an all-inpainted texture.
    for (const std::string& w : visibility_warnings(v.visibility.stats)) run.warn(w);
    std::vector<std::size_t> train_frames;
    for (std::size_t f = 0; f < capture.desc.frames.size(); ++f)
        if (capture.desc.frames[f].split == Split::Train) train_frames.push_back(f);
    require_usable_visibility(v.visibility, v.inputs.frame_view, capture_json_path(run.config.capture), train_frames);
    if (!run.config.lambert.tap_irradiance)
        run.leave_out("per-tap irradiance (surface maps)",
                      "--tap-irradiance off: each sample mixes its 4 pixels as they are (the thesis's sampling), "
                      "biased where the normal turns within a pixel");
    record_occlusion_cost(run, geometry, v, cast_rays);
    return v;
}

DiffuseStage diffuse_stage(PipelineRun& run, const Capture& capture, const GeometryStage& geometry,
                           const VisibilityStage& visibility, const LambertOptions& options) {
    (void)run.compute_context(); // "vulkan init", timed on its own before the first solve
    DiffuseStage d{.inputs = lambert_inputs(capture, geometry.particles.particles, visibility.visibility),
                   .options = options,
                   .solve = {}};
    // Where the specular stage holds validation frames out for its candidates' joint rounds, the
    // first solve is theirs (the train frames less those frames): the residual energy test and
    // the indirect stage's measure take it too, and every train frame is solved again once the
    // material is known. A solve of all the train frames here was used for those two alone
    // (the demo can: 0.9 s and its residual samples 0.8 s).
    const ReconstructConfig& config = run.config;
    std::optional<ValidationSplit> split;
    if (config.specular != SpecularMode::Off && config.joint_rounds > 0)
        if (ValidationSplit sp = split_validation_frames(d.inputs); sp.held_out > 0) split = std::move(sp);
    d.solve = run_solve(run, split ? split->fit : d.inputs, d.options, "diffuse solve");
    d.on_fit_split = split.has_value();
    if (split) log::info("first diffuse solve: the train frames less " + std::to_string(split->held_out) + " validation frames");
    log::info(describe(d.solve.summary, d.options.mode));
    PlanDecision& mode = *run.plan().find("diffuse_mode");
    if (mode.forced) {
        mode.measured_seconds = run.seconds("diffuse solve");
        mode.cost_basis = std::string("measured: the diffuse solve in ") + to_string(d.options.mode) + " mode";
    } else {
        mode.cost_basis = "no estimate: both modes read the same samples; photometric solves a 3x3 system where albedo "
                          "mode divides two sums (force a mode to measure it)";
    }
    if (d.solve.summary.fallback > 0)
        run.leave_out("photometric solve for " + std::to_string(d.solve.summary.fallback) + " particles",
                      "fewer than three usable, non-coplanar light directions in their best view: "
                      "albedo mode (known normals) used instead");
    return d;
}

namespace {

// The albedo of the particles as a solve gives it, inpainted where the solve has none: the
// texture stage inpaints what no view saw (a source the cameras never see still reflects).
std::vector<glm::vec3> solved_albedo(const GeometryStage& g, const LambertOutputs& solve) {
    return evaluate::particle_albedo(g.particles.particles, make_albedo_texture(g.atlas, g.particles.particles, solve).image);
}

IndirectScene indirect_scene(const IndirectStage& s, const GeometryStage& g, const VisibilityStage& v) {
    return IndirectScene{.particles = g.particles.particles,
                         .visibility = &v.visibility,
                         .lights = v.inputs.lights,
                         .frame_view = v.inputs.frame_view,
                         .atlas = &g.atlas,
                         .transfer = &*s.transfer,
                         .view_maps = s.view_maps};
}

// The frames the indirect light is removed from: the train frames, or for the planner's measure
// kIndirectMeasureFrames of them, evenly spaced.
std::vector<std::size_t> indirect_frames(const Capture& capture, bool measure) {
    std::vector<std::size_t> frames;
    for (std::size_t f = 0; f < capture.desc.frames.size(); ++f)
        if (capture.desc.frames[f].split == Split::Train) frames.push_back(f);
    if (measure && frames.size() > kIndirectMeasureFrames) {
        std::vector<std::size_t> sample;
        for (std::size_t k = 0; k < kIndirectMeasureFrames; ++k) sample.push_back(frames[k * frames.size() / kIndirectMeasureFrames]);
        frames = std::move(sample);
    }
    return frames;
}

// The light rays of `frames` that the visibility stage left out (lit_seen_only: toward the
// particles the frames' views do not see), cast into its bits: one a row of `transfer` and frame
// (a row sends its particles' mean light).
void complete_visibility(PipelineRun& run, const Capture& capture, const GeometryStage& geometry, VisibilityStage& v,
                         std::span<const std::size_t> frames, const IndirectTransfer& transfer) {
    complete_lit(v.visibility, geometry.particles.particles, capture.mesh, *v.scene, v.inputs.views, v.inputs.lights,
                 v.inputs.frame_view, frames, run.config.threads, row_stand_ins(transfer));
}

// The train frames less the indirect light that `albedo` sends (the other frames stay empty:
// the solves read train frames only). An object pixel whose added light is over
// kIndirectMaxShare of what it shows is flagged missing; returns how many were. With `measure`,
// the planner's figures (IndirectMeasure) over every 4th object pixel of kIndirectMeasureFrames
// train frames (the unlit ones found with the views' surface maps), and only those frames are
// corrected; with `ratio`, indirect_images' R per particle.
std::size_t remove_indirect_light(const IndirectStage& s, const IndirectScene& scene, const Capture& capture,
                                  std::span<const glm::vec3> albedo, const std::optional<SpecularModel>& material,
                                  std::vector<FrameImage>& corrected, const Visibility& visibility, const RayScene& rays,
                                  IndirectMeasure* measure, std::vector<float>* ratio) {
    const std::vector<std::size_t> frames = indirect_frames(capture, measure != nullptr);
    corrected.resize(capture.images.size());
    std::vector<float> codes;
    double captured_dot_predicted = 0.0, predicted_square = 0.0;
    std::size_t shadow_pixels = 0, dropped = 0;
    const auto code = [](float v) { return 255.0f * linear_to_srgb(std::clamp(v, 0.0f, 1.0f)); };
    // No light reaches the surface a pixel's centre ray hits (the view's surface map): it faces
    // away from the frame's light, or a shadow ray toward the light is blocked.
    const auto unlit = [&](std::size_t f, std::size_t p) {
        const std::uint32_t v = scene.frame_view[f];
        const SurfaceMap& surface = visibility.surfaces[v];
        glm::vec3 position, normal;
        if (!surface.at(static_cast<int>(p % static_cast<std::size_t>(surface.width)),
                        static_cast<int>(p / static_cast<std::size_t>(surface.width)), position, normal))
            return false;
        const glm::vec3 light(scene.lights[f].position);
        if (glm::dot(normal, light - position) <= 0.0f) return true;
        const Ray ray = rays.ray_toward(position, normal, light);
        return rays.occluded(ray.origin, ray.dir, ray.tmin, ray.tmax);
    };
    const bool can_check = measure != nullptr && visibility.surfaces.size() == s.view_maps.size();
    indirect_images(scene, frames, albedo, material, s.options, [&](std::size_t f, const Image& light) {
        const FrameImage& captured = capture.images[f];
        const ViewAtlasMap& map = s.view_maps[scene.frame_view[f]];
        FrameImage& out = corrected[f];
        out.flags = captured.flags;
        out.saturation = captured.saturation;
        out.missing_pixels = captured.missing_pixels;
        out.file_info = captured.file_info;
        out.color = captured.color;
        const std::size_t n = static_cast<std::size_t>(light.width) * static_cast<std::size_t>(light.height);
        // Pixel p less its light; true where it is left out of the solves.
        const auto step = [&](std::size_t p) {
            const float* add = &light.pixels[3 * p];
            float* v = &out.color.pixels[3 * p];
            // The object's pixels: the mask where there is one, else where the surface is seen.
            const bool object = map.texel[p].x >= 0.0f && (captured.flags.empty() || (captured.flags[p] & kOutsideMask) == 0);
            if (measure != nullptr && p % 4 == 0 && object) {
                float largest = 0.0f;
                for (int c = 0; c < 3; ++c)
                    if (add[c] != 0.0f) largest = std::max(largest, code(v[c]) - code(v[c] - add[c]));
                codes.push_back(largest);
                // What the light alone would show (a shadowed pixel of a capture without it is black).
                const float alone = code(std::max({add[0], add[1], add[2]}));
                if (can_check && alone >= 1.0f && (captured.flags.empty() || (captured.flags[p] & (kMissing | kClippedAny)) == 0) &&
                    unlit(f, p)) {
                    const double seen = double(v[0]) + v[1] + v[2], predicted = double(add[0]) + add[1] + add[2];
                    captured_dot_predicted += seen * predicted;
                    predicted_square += predicted * predicted;
                    ++shadow_pixels;
                }
            }
            // Where the light added outweighs the direct light left, the subtraction amplifies any
            // error of the predicted light, and the rounds, which alternate about their fixed point
            // by that ratio, would not settle there: the sample is not used.
            const float added = add[0] + add[1] + add[2], seen = v[0] + v[1] + v[2];
            for (int c = 0; c < 3; ++c) v[c] -= add[c];
            return object && added > kIndirectMaxShare * seen;
        };
        std::vector<std::uint8_t> left_out(n, 0);
        if (measure != nullptr) {
            for (std::size_t p = 0; p < n; ++p) left_out[p] = step(p) ? 1 : 0;
        } else { // side by side: the pixels are independent
            parallel_for_chunks(n, std::max(s.options.threads, 1u), 16384, [&](unsigned, std::size_t begin, std::size_t end) {
                for (std::size_t p = begin; p < end; ++p) left_out[p] = step(p) ? 1 : 0;
            });
        }
        const std::size_t count = static_cast<std::size_t>(std::count(left_out.begin(), left_out.end(), std::uint8_t{1}));
        if (count == 0) return;
        if (out.flags.empty()) out.flags.assign(n, 0);
        for (std::size_t p = 0; p < n; ++p)
            if (left_out[p] != 0) out.flags[p] |= kMissing;
        dropped += count;
    }, ratio);
    if (measure == nullptr) {
        log::info(format_text("indirect light: %.0f object pixels of the train frames left out (the light added is over %.0f%% of "
                              "what they show)", double(dropped), 100.0 * kIndirectMaxShare));
        return dropped;
    }
    *measure = IndirectMeasure{};
    measure->shadow_pixels = shadow_pixels;
    if (shadow_pixels >= kIndirectMinShadowPixels && predicted_square > 0.0) measure->shadow_ratio = captured_dot_predicted / predicted_square;
    if (codes.empty()) return dropped;
    const auto k = codes.begin() + static_cast<std::ptrdiff_t>(0.99 * static_cast<double>(codes.size() - 1));
    std::nth_element(codes.begin(), k, codes.end());
    measure->p99_codes = *k;
    return dropped;
}

// One round: the diffuse solve on the corrected frames, damped (planner.h kIndirectRounds: each
// particle's albedo becomes (solved + R rho_k) / (1 + R), R its `ratio`, rho_k `albedo`), and how
// far the albedo moved from `albedo` (which becomes the new one).
IndirectRound solve_round(PipelineRun& run, const GeometryStage& geometry, DiffuseStage& diffuse, std::vector<glm::vec3>& albedo,
                          std::span<const float> ratio, const std::string& tag) {
    diffuse.solve = run_solve(run, diffuse.inputs, diffuse.options, "diffuse solve" + tag);
    diffuse.on_fit_split = false;
    for (std::size_t p = 0; p < diffuse.solve.particles.size() && p < ratio.size(); ++p) {
        LambertParticleResult& r = diffuse.solve.particles[p];
        if (!(r.status & shared::kLambertOk) || !(ratio[p] > 0.0f)) continue;
        const float w = 1.0f / (1.0f + ratio[p]);
        r.albedo_best = glm::vec4(w * glm::vec3(r.albedo_best) + (1.0f - w) * albedo[p], r.albedo_best.w);
        r.albedo_robust = glm::vec4(w * glm::vec3(r.albedo_robust) + (1.0f - w) * albedo[p], r.albedo_robust.w);
    }
    std::vector<glm::vec3> next = solved_albedo(geometry, diffuse.solve);
    double moved = 0.0, size = 0.0;
    for (std::size_t p = 0; p < next.size(); ++p) {
        if (!(diffuse.solve.particles[p].status & shared::kLambertOk)) continue;
        moved += glm::dot(next[p] - albedo[p], next[p] - albedo[p]);
        size += glm::dot(next[p], next[p]);
    }
    IndirectRound r{.albedo_change = size > 0.0 ? std::sqrt(moved / size) : 0.0, .seconds = 0.0, .material = false};
    albedo = std::move(next);
    log::info("indirect" + tag + format_text(": the albedo changed by %.3f%% (RMS, relative)", 100.0 * r.albedo_change));
    return r;
}

} // namespace

IndirectStage indirect_stage(PipelineRun& run, const Capture& capture, const GeometryStage& geometry,
                             VisibilityStage& visibility, DiffuseStage& diffuse) {
    const ReconstructConfig& config = run.config;
    IndirectStage s;
    const ConvexityReport& convexity = visibility.visibility.stats.convexity;
    // The estimate of what it costs: the transfer's rays at the visibility stage's rate (its
    // occlusion rays; none on a convex mesh, then its depth rays), the rounds at the first solve's time.
    const VisibilityStats& vs = visibility.visibility.stats;
    const double rays_done = static_cast<double>(vs.rays_cast + vs.depth_rays + vs.shadow_map_rays);
    const double ray_seconds = rays_done > 0.0 ? vs.seconds / rays_done : 0.0;
    PlanDecision block_decision = decide_indirect_block(geometry.particles.particles.size(), config.indirect_block);
    const std::uint32_t block = decided_indirect_block(block_decision);
    const double blocks = static_cast<double>(geometry.particles.particles.size()) / (static_cast<double>(block) * block);
    const double estimate = ray_seconds * blocks * config.indirect_rays +
                            config.indirect_rounds * run.seconds("diffuse solve");
    if (config.indirect == Toggle::Off || (config.indirect == Toggle::Auto && convexity.convex)) {
        const PlanDecision& d = run.plan().add(decide_indirect(convexity, config.indirect, std::nullopt, estimate));
        run.leave_out("indirect light (light that bounced off the object)", d.reason);
        return s;
    }
    const Stopwatch clock;
    // As for the factorization: a CPU Vulkan driver runs the gather slower than C++ (bench/
    // indirect_bench, 200k particles x 16 frames: 0.67 s on lavapipe, 0.34 s for the reference),
    // a GPU runs the kernels. The directed lobe's kernel alone beats the C++ path on lavapipe
    // (0.95 s against 1.44 s, 200k rows x 32 entries x 16 frames), but not in the pipeline, where
    // each batch of 8 frames uploads the transfer's entries and directions again: the knot at
    // 256 px with 2 bounces, the pass with the material 2.60 s against 1.37 s, the same figures.
    // On the CPU the float paths (the kernels' arithmetic) run.
    s.backend_reason = "C++ (gather_indirect_float): --backend cpu";
    if (config.backend == Backend::Vulkan) {
        gpu::Context* ctx = run.compute_context();
        if (ctx == nullptr) {
            s.backend_reason = "C++ (gather_indirect_float): no Vulkan device";
        } else if (ctx->info().kind == gpu::DeviceKind::Cpu) {
            s.backend_reason = "C++ (gather_indirect_float, add_directed_lobe_float): the device is a CPU Vulkan driver, where "
                               "the kernels run slower";
        } else {
            s.gather = std::make_shared<IndirectGatherVk>(*ctx);
            s.lobe = std::make_shared<IndirectLobeVk>(*ctx);
            s.backend_reason = "the Vulkan kernels";
        }
    }
    s.options = IndirectOptions{.bounces = config.indirect_bounces, .kernel = s.gather.get(), .lobe_kernel = s.lobe.get(),
                                .threads = config.threads, .lobe_directions = config.indirect_lobe_directions};
    // The planner's measure goes through a transfer of fewer rays (kIndirectMeasureRays) and wider
    // blocks (kIndirectMeasureBlockScale) unless the stage is forced on; the rounds get one of
    // --indirect-rays on the decided blocks.
    const bool forced_on = config.indirect == Toggle::On;
    const std::uint32_t measure_rays = forced_on ? config.indirect_rays : std::min(config.indirect_rays, kIndirectMeasureRays);
    const std::uint32_t measure_block = forced_on ? block : block * kIndirectMeasureBlockScale;
    const bool measure_transfer = measure_rays != config.indirect_rays || measure_block != block;
    (void)run.plan().add(std::move(block_decision));
    const auto build = [&](std::uint32_t rays, std::uint32_t b) {
        s.transfer = build_transfer(geometry.particles.particles, capture.mesh, *visibility.scene, geometry.atlas,
                                    TransferOptions{.rays = rays, .block = b, .threads = config.threads},
                                    &s.transfer_stats);
        log::info(format_text("indirect transfer: %.0f rows (blocks of %.0f x %.0f texels), %.0f rays each, %.0f entries "
                              "(%.1f a row), %.1f%% of the rays reached the object",
                              double(s.transfer->rows), double(b), double(b),
                              double(s.transfer->rays_per_row), double(s.transfer->entry_count()),
                              double(s.transfer->entry_count()) / std::max<double>(1.0, s.transfer->rows),
                              100.0 * double(s.transfer_stats.hits) / std::max<double>(1.0, double(s.transfer_stats.rays))));
    };
    // The frames whose light rays the measure casts, toward its blocks' stand-ins only.
    std::vector<std::size_t> measure_completed;
    run.stage(measure_transfer ? "indirect transfer (measure)" : "indirect transfer", [&] {
        build(measure_rays, measure_block);
        const std::vector<std::size_t> frames = indirect_frames(capture, true);
        for (const std::size_t f : frames)
            if (!visibility.visibility.lit_complete[f]) measure_completed.push_back(f);
        complete_visibility(run, capture, geometry, visibility, frames, *s.transfer);
        const std::vector<PixelHits>& hits = visibility.visibility.pixel_hits; // empty where not kept: cast here
        for (std::size_t v = 0; v < capture.views.size(); ++v)
            s.view_maps.push_back(build_view_atlas_map(capture.views[v].camera, capture.mesh, *visibility.scene, geometry.atlas,
                                                         geometry.particles.particles, config.threads,
                                                         v < hits.size() ? &hits[v] : nullptr));
    });
    std::vector<glm::vec3> albedo = solved_albedo(geometry, diffuse.solve);
    std::size_t left_out = 0;  // by the last pass: the next solve's
    std::vector<float> ratio;  // of the last pass
    s.measure = run.stage("indirect light (measure)", [&] {
        IndirectMeasure m;
        std::vector<FrameImage> sample;
        (void)remove_indirect_light(s, indirect_scene(s, geometry, visibility), capture, albedo, diffuse.options.material, sample,
                                    visibility.visibility, *visibility.scene, &m, nullptr);
        return m;
    });
    const PlanDecision& d = run.plan().add(decide_indirect(convexity, config.indirect, s.measure, estimate));
    if (!decided_indirect(d)) {
        run.leave_out("indirect light (light that bounced off the object)", d.reason);
        s.transfer.reset();
        decltype(s.view_maps)().swap(s.view_maps); // 42 MB on the knot at 384 px, held to the end otherwise
        s.seconds = clock.seconds();
        return s;
    }
    run.stage("indirect transfer", [&] {
        // Every frame: the rounds read the train frames, the evaluation adds the light to the test frames too.
        if (measure_transfer) build(config.indirect_rays, block);
        // The measure's frames were completed for its wider blocks' stand-ins: cast again for these rows'.
        if (measure_block != block) uncomplete_lit(visibility.visibility, visibility.inputs.frame_view, measure_completed);
        std::vector<std::size_t> all(capture.desc.frames.size());
        for (std::size_t f = 0; f < all.size(); ++f) all[f] = f;
        complete_visibility(run, capture, geometry, visibility, all, *s.transfer);
    });
    const IndirectScene scene = indirect_scene(s, geometry, visibility);
    run.stage("indirect light", [&] {
        left_out = remove_indirect_light(s, scene, capture, albedo, diffuse.options.material, s.corrected, visibility.visibility,
                                         *visibility.scene, nullptr, &ratio);
    });
    diffuse.inputs.images = s.corrected;
    for (std::uint32_t round = 1; round <= std::max(config.indirect_rounds, 1u); ++round) {
        const Stopwatch round_clock;
        const std::string tag = " (indirect round " + std::to_string(round) + ")";
        IndirectRound r = solve_round(run, geometry, diffuse, albedo, ratio, tag);
        r.pixels_left_out = left_out;
        // The estimate alternates about its fixed point, each move smaller than the last; one that
        // grows does not settle: the capture's indirect light is not what the model predicts.
        const bool growing = !s.rounds.empty() && r.albedo_change > s.rounds.back().albedo_change;
        if (growing)
            run.warn(format_text("indirect light: the rounds do not settle (the albedo moved by %.1f%%, then %.1f%%)",
                                 100.0 * s.rounds.back().albedo_change, 100.0 * r.albedo_change) +
                     ": the light the object sends itself is not what the transfer predicts there (a glossy lobe's later "
                     "bounces, which it spreads diffusely?); compare --indirect off");
        const bool last = growing || r.albedo_change < kIndirectTolerance || round >= config.indirect_rounds;
        if (!last) {
            // The next round's images: the captures less the light this round's albedo sends.
            run.stage("indirect light" + tag, [&] {
                left_out = remove_indirect_light(s, scene, capture, albedo, diffuse.options.material, s.corrected,
                                                 visibility.visibility, *visibility.scene, nullptr, &ratio);
            });
        }
        r.seconds = round_clock.seconds();
        s.rounds.push_back(r);
        if (last) break;
    }
    s.seconds = clock.seconds();
    return s;
}

void indirect_update_stage(PipelineRun& run, const Capture& capture, const GeometryStage& geometry,
                           const VisibilityStage& visibility, const SpecularStage& specular, IndirectStage& indirect,
                           DiffuseStage& diffuse) {
    // The fitted material, whether or not a joint round kept it in the solve's options (a
    // validated estimate that undid its first round keeps none).
    const std::optional<SpecularModel> material = specular.fit ? std::optional(specular.fit->model()) : std::nullopt;
    if (!indirect.on() || !material || is_zero(*material)) return;
    const Stopwatch clock;
    std::vector<glm::vec3> albedo = solved_albedo(geometry, diffuse.solve);
    const std::string tag = " (indirect round with the material)";
    std::size_t left_out = 0;
    std::vector<float> ratio;
    run.stage("indirect light" + tag, [&] {
        left_out = remove_indirect_light(indirect, indirect_scene(indirect, geometry, visibility), capture, albedo,
                                         material, indirect.corrected, visibility.visibility,
                                         *visibility.scene, nullptr, &ratio);
    });
    IndirectRound r = solve_round(run, geometry, diffuse, albedo, ratio, tag);
    r.pixels_left_out = left_out;
    r.seconds = clock.seconds();
    r.material = true;
    indirect.rounds.push_back(r);
    indirect.seconds += r.seconds;
}

namespace {

// The steps of the joint estimate of one family on `inputs` (labels end in `label`), with a
// validation step when `validation` is given. The fits' time and samples add up in `s`.
JointSteps material_steps(PipelineRun& run, SpecularStage& s, const LambertInputs& inputs, const LambertInputs* validation,
                          MaterialFamily family, const MaterialFitOptions& fo, const std::string& label) {
    JointSteps steps;
    steps.solve = [&run, &inputs, label](const LambertOptions& o, const std::string& tag) {
        return run_solve(run, inputs, o, "diffuse solve" + label + tag);
    };
    // The rounds' samples go to the fit only: those it takes are made (ResidualOptions::fit_samples).
    steps.residuals = [&run, &inputs, label, max = fo.max_samples](const LambertOutputs& solve, const LambertOptions& o,
                                                                   const std::string& tag) {
        return run_residuals(run, inputs, solve, o, "residual samples" + label + tag, max);
    };
    steps.fit = [&run, &s, family, fo, label](const ResidualSamples& rs, const std::string& tag) {
        return run.stage(std::string(to_string(family)) + " fit" + (label.empty() ? "" : " (validation split)") + tag, [&] {
            MaterialFit f = fit_material(family, rs.samples, fo);
            s.fit_seconds += f.seconds;
            s.fit_samples = f.samples;
            return f;
        });
    };
    if (validation != nullptr)
        steps.validate = [&run, validation, label, base = run.config.lambert](const LambertOutputs& solve, const SpecularModel& m,
                                                                             const std::string& tag) {
            LambertOptions o = base;
            o.material = m;
            return run_validation(run, *validation, solve, o, m, "validation" + label + tag);
        };
    return steps;
}

// PSNR of a mean square error in image units (images in [0, 1]), for the logs and the report.
double psnr_of(double mse) { return mse > 0.0 ? -10.0 * std::log10(mse) : 99.0; }

// Which family wins: the least validation error, or the forced one; the sentence says why.
std::size_t choose_material(const PipelineRun& run, SpecularStage& s, const std::vector<MaterialFamily>& families,
                            std::span<const ResidualSample> train) {
    std::vector<double> error(s.candidates.size());
    for (std::size_t k = 0; k < s.candidates.size(); ++k) {
        const std::optional<SpecularModel> m = s.candidates[k].fit.model();
        // No usable fit: scored as the diffuse term alone (a zero lobe).
        const SpecularModel scored = m ? *m : SpecularModel(LafortuneRgb{});
        // With validation frames, a candidate without a validation error (no usable fit) loses:
        // its train error would not compare with the others' held-out error.
        error[k] = s.candidates[k].validation_mse ? *s.candidates[k].validation_mse
                   : s.validation_frames > 0      ? std::numeric_limits<double>::infinity()
                                                  : material_mean_square_error(scored, train);
    }
    std::size_t best = static_cast<std::size_t>(std::min_element(error.begin(), error.end()) - error.begin());
    // "Diffuse only" (its index: families.size()) when it competes (decide_specular "validate"):
    // it wins unless the best family beats it by more than kDiffuseOnlyMarginDb.
    if (s.diffuse_only_mse) {
        error.push_back(*s.diffuse_only_mse);
        if (!(psnr_of(error[best]) > psnr_of(*s.diffuse_only_mse) + kDiffuseOnlyMarginDb)) best = families.size();
    }
    std::string scores;
    for (std::size_t k = 0; k < error.size(); ++k) {
        if (k > 0) scores += ", ";
        scores += k < families.size() ? to_string(families[k]) : "diffuse only";
        if (!std::isfinite(error[k])) {
            scores += " no usable fit";
            continue;
        }
        scores += ' ';
        scores += std::to_string(error[k]);
        scores += " (";
        scores += std::to_string(psnr_of(error[k])).substr(0, 5);
        scores += " dB)";
    }
    const std::string basis = s.validation_frames > 0
                                  ? "mean square error on " + std::to_string(s.validation_frames) + " validation frames (one light of each view, held out): "
                                  : "no validation frames (every view has fewer than 4 train frames): mean square error on the "
                                    "train residuals, which favours the more flexible model: ";
    if (run.config.material) s.choice = std::string("forced (--material ") + to_string(*run.config.material) + "); " + basis + scores;
    else if (best < families.size()) s.choice = std::string(to_string(families[best])) + " has the least " + basis + scores;
    else s.choice = "diffuse only: no family beats it by more than " + format_text("%.2g", kDiffuseOnlyMarginDb) + " dB on the " + basis + scores;
    return best;
}

} // namespace

bool display_is_srgb(const Capture& capture) {
    for (const FrameImage& f : capture.images)
        if (metrics::display_encoding_of(f.file_info, capture.desc.color_space).transfer != ColorSpace::Srgb) return false;
    return true;
}

SpecularStage specular_stage(PipelineRun& run, DiffuseStage& diffuse, bool srgb_display) {
    const ReconstructConfig& config = run.config;
    SpecularStage s;
    if (config.specular == SpecularMode::Off) {
        PlanDecision d = decide_specular(ResidualEnergy{}, Toggle::Off);
        d.detail = nullptr;
        run.plan().add(std::move(d));
        run.leave_out("specular fit, factorization and specular pass (residual samples too)", "--specular off");
        return s;
    }
    s.residuals_ran = true;
    const ValidationSplit split = split_validation_frames(diffuse.inputs);
    // The first solve read the train frames less the validation frames (diffuse_stage): it is
    // the candidates' first solve, and its residual samples theirs.
    const bool first_on_split = diffuse.on_fit_split;
    // Every train frame solved, where the first solve left the validation frames out.
    const auto solve_all = [&](const LambertOptions& o) {
        diffuse.on_fit_split = false;
        return run_solve(run, diffuse.inputs, o, "diffuse solve (every train frame)");
    };
    // With validation frames the first pass's samples go to the energy test, which reads the
    // pass's sums, and to the fits: only those the fits take are made (ResidualOptions::fit_samples).
    // Without, the material choice reads every one (the train residuals' error).
    ResidualSamples rs = run_residuals(run, first_on_split ? split.fit : diffuse.inputs, diffuse.solve, diffuse.options,
                                       "residual samples", split.held_out > 0 ? config.max_fit_samples : 0);
    s.energy = residual_energy(rs.energy, static_cast<double>(diffuse.options.noise_sigma), config.specular_energy_threshold);
    const Toggle toggle = config.specular == SpecularMode::On ? Toggle::On : Toggle::Auto;
    const PlanDecision& decision = run.plan().add(decide_specular(s.energy, toggle, split.held_out));
    // Little energy, but validation frames: "diffuse only" competes with the families.
    const bool diffuse_only_competes = decision.value == "validate";
    log::info("residual samples: " + std::to_string(rs.counts.used) + " used; " + decision.reason);
    MaterialFitOptions fo{.lafortune = config.lafortune, .coated = config.coated, .max_samples = config.max_fit_samples};
    fo.lafortune.noise_sigma = static_cast<double>(diffuse.options.noise_sigma);
    fo.lafortune.threads = fo.coated.threads = config.threads;
    if (decision.skipped) {
        run.leave_out("specular fit, factorization and specular pass", decision.reason);
        s.decision = "skipped: no specular energy (--specular auto)";
        const std::vector<LafortuneSample> all = to_lafortune_samples(rs.samples);
        const std::size_t would_fit =
            config.max_fit_samples != 0 ? std::min<std::size_t>(all.size(), config.max_fit_samples) : all.size();
        probe_fit_cost(run, all, fo.lafortune, would_fit);
        if (first_on_split) diffuse.solve = solve_all(diffuse.options);
        s.backend = run.particle_backend();
        std::vector<ResidualSample>().swap(rs.samples); // memory back (`= {}` keeps the capacity)
        s.residuals = std::move(rs);
        return s;
    }

    const Stopwatch watch;
    const JointOptions jo{.rounds = config.joint_rounds, .tolerance = config.joint_tolerance,
                          .restart_low_index = !fo.coated.fixed_eta.has_value()};
    std::vector<MaterialFamily> families;
    if (config.material) families = {*config.material};
    else for (std::size_t f = 0; f < kMaterialFamilyCount; ++f) families.push_back(static_cast<MaterialFamily>(f));

    // 1. Each family on the train frames less the validation frames, scored on those.
    s.validation_frames = split.held_out;
    // With validation frames and joint rounds the final estimate starts from the winner's
    // validated state (step 2), so the first solve's samples are no longer needed: only their
    // counts are kept (peak memory: the knot at 384 px held 200 MB of them through the candidates).
    const bool warm_start = split.held_out > 0 && jo.rounds > 0;
    ResidualSamples rs0; // the first solve's on the split, when it is the diffuse stage's
    if (first_on_split) {
        rs0.samples.swap(rs.samples);
        rs0.counts = rs.counts;
    }
    if (warm_start) std::vector<ResidualSample>().swap(rs.samples);
    if (split.held_out > 0) {
        const LambertOutputs solve0 =
            first_on_split ? diffuse.solve : run_solve(run, split.fit, diffuse.options, "diffuse solve (validation split)");
        if (!first_on_split)
            rs0 = run_residuals(run, split.fit, solve0, diffuse.options, "residual samples (validation split)", config.max_fit_samples);
        if (diffuse_only_competes) {
            // The first solve's albedo with no specular at all, scored as every family is.
            s.diffuse_only_mse = run_validation(run, split.validation, solve0, diffuse.options, SpecularModel(LafortuneRgb{}),
                                                "validation (diffuse only)");
            log::info("material candidate diffuse only: validation PSNR " + std::to_string(psnr_of(*s.diffuse_only_mse)) + " dB");
        }
        // Every family's first fit, then the samples go (peak memory: they would be held through
        // every candidate's rounds beside each round's own); until then only those the fits take
        // (the knot at 384 px: 13 MB of 200 MB; both first passes above make no others) are held
        // beside the validation passes. Each first fit is validated as it is made. A family fitted
        // after another's validation error is known is first fitted on kScreenSamples of them
        // (joint.h): where that fit is more than kScreenFactor behind, it is the candidate's first
        // fit and the full one is left out.
        std::vector<JointSteps> steps;
        std::vector<MaterialFit> first_fits;
        std::vector<double> first_seconds;
        std::vector<std::optional<double>> first_mse(families.size());
        std::vector<std::size_t> screened(families.size(), 0); // the screen's samples, where it stood in for the fit
        std::vector<std::string> screen_stop(families.size());
        std::optional<double> least_first;
        const auto validated = [&](const MaterialFit& f, const JointSteps& st, const std::string& tag) {
            const std::optional<SpecularModel> m = f.model();
            return m && st.validate ? std::optional(st.validate(solve0, *m, tag)) : std::nullopt;
        };
        for (std::size_t k = 0; k < families.size(); ++k) {
            const Stopwatch w;
            const std::string label = std::string(" (") + to_string(families[k]) + ", validation split)";
            steps.push_back(material_steps(run, s, split.fit, &split.validation, families[k], fo, label));
            if (least_first && rs0.counts.used > kScreenSamples && (fo.max_samples == 0 || fo.max_samples > kScreenSamples)) {
                MaterialFitOptions so = fo;
                so.max_samples = kScreenSamples;
                const JointSteps screen = material_steps(run, s, split.fit, &split.validation, families[k], so, label);
                MaterialFit f = screen.fit(rs0, " (screen)");
                const std::optional<double> mse = validated(f, screen, " (screen)");
                if (mse)
                    log::info(std::string(to_string(families[k])) +
                              format_text(" screen: validation mean square %.6g on %.0f samples, %.3g times the least first fit's",
                                          *mse, static_cast<double>(f.samples), *mse / *least_first));
                if (mse && *mse > kScreenFactor * *least_first) {
                    screened[k] = f.samples;
                    screen_stop[k] = format_text("screened, no full fit and no rounds: fitted to %.0f samples, its validation "
                                                 "error is %.3g times another candidate's first fit's, more than %g (a full "
                                                 "fit and rounds could not make it win)",
                                                 static_cast<double>(f.samples), *mse / *least_first, kScreenFactor);
                    first_mse[k] = mse;
                    first_fits.push_back(std::move(f));
                    first_seconds.push_back(w.seconds());
                    continue;
                }
            }
            first_fits.push_back(steps.back().fit(rs0, ""));
            first_mse[k] = validated(first_fits.back(), steps.back(), "");
            if (first_mse[k] && (!least_first || *first_mse[k] < *least_first)) least_first = first_mse[k];
            first_seconds.push_back(w.seconds());
        }
        std::vector<ResidualSample>().swap(rs0.samples);
        // The candidates' rounds in the order of their first fits' validation errors, the least
        // first; a candidate whose first fit is more than kNoRoundsFactor behind the least error
        // the rounds before it reached runs none: they could not make it win (joint.h).
        std::vector<std::size_t> order(families.size());
        for (std::size_t k = 0; k < order.size(); ++k) order[k] = k;
        std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
            return first_mse[a] && (!first_mse[b] || *first_mse[a] < *first_mse[b]);
        });
        s.candidates.resize(families.size());
        std::optional<double> rival; // the least validation error a candidate's rounds reached so far
        for (const std::size_t k : order) {
            const Stopwatch w;
            JointState state{.solve_options = diffuse.options, .solve = solve0, .residuals = {}, .fit = std::move(first_fits[k]),
                             .validation_mse = first_mse[k]};
            state.residuals.counts = rs0.counts;
            MaterialCandidate& c = s.candidates[k];
            JointOptions candidate_rounds = jo;
            candidate_rounds.rival_mse = rival;
            c.screen_samples = screened[k];
            if (screened[k] != 0) {
                c.joint.first_validation_mse = first_mse[k];
                c.joint.stop = screen_stop[k];
                log::info(std::string(to_string(families[k])) + " candidate: " + c.joint.stop);
            } else if (rival && first_mse[k] && *first_mse[k] > kNoRoundsFactor * *rival) {
                c.joint.first_validation_mse = first_mse[k];
                c.joint.stop = format_text("no rounds: its first fit's validation error is %.3g times the least another "
                                           "candidate reached, more than %g (rounds could not make it win)",
                                           *first_mse[k] / *rival, kNoRoundsFactor);
                log::info(std::string(to_string(families[k])) + " candidate: " + c.joint.stop);
            } else {
                c.joint = joint_estimate(state, candidate_rounds, steps[k]);
                (void)name_unsettled(state.fit, c.joint, fo.coated.max_relative_error);
            }
            c.fit = std::move(state.fit);
            c.validation_mse = state.validation_mse;
            c.seconds = first_seconds[k] + w.seconds();
            if (c.validation_mse && (!rival || *c.validation_mse < *rival)) rival = c.validation_mse;
            log::info("material candidate " + c.fit.describe() +
                      (c.validation_mse ? "; validation PSNR " + std::to_string(psnr_of(*c.validation_mse)) + " dB" : std::string()));
        }
    } else {
        for (const MaterialFamily family : families) {
            const Stopwatch w;
            MaterialCandidate c;
            c.fit = fit_material(family, rs.samples, fo);
            s.fit_seconds += c.fit.seconds;
            c.seconds = w.seconds();
            s.candidates.push_back(std::move(c));
        }
    }
    const std::size_t best = choose_material(run, s, families, rs.samples);
    log::info("material: " + s.choice);
    if (best == families.size()) {
        // Diffuse only has the least validation error: the specular is left out, measured.
        PlanDecision& d = *run.plan().find("specular_stages");
        d.value = "skip";
        d.skipped = true;
        d.reason += "; diffuse only won: " + s.choice;
        d.measured_seconds = watch.seconds();
        d.cost_basis = "measured: the candidates' estimates on the validation split, which diffuse only beat";
        PlanDecision m{.name = "material", .value = "diffuse only", .forced = false, .reason = s.choice};
        m.measured_seconds = watch.seconds();
        m.cost_basis = "measured: each candidate's joint estimate on the train frames less the validation frames";
        run.plan().add(std::move(m));
        run.leave_out("specular fit, factorization and specular pass", "diffuse only has the least validation error: " + s.choice);
        s.decision = "skipped: diffuse only has the least validation error (--specular auto)";
        if (first_on_split) diffuse.solve = solve_all(diffuse.options);
        s.seconds = watch.seconds();
        s.backend = run.particle_backend();
        std::vector<ResidualSample>().swap(rs.samples); // memory back (`= {}` keeps the capacity)
        s.residuals = std::move(rs);
        return s;
    }
    const MaterialFamily winner = families[best];
    {
        PlanDecision d{.name = "material", .value = to_string(winner), .forced = config.material.has_value(), .reason = s.choice};
        double seconds = 0.0;
        for (std::size_t k = 0; k < s.candidates.size(); ++k) {
            seconds += s.candidates[k].seconds;
            d.detail[to_string(families[k])] = {{"seconds", s.candidates[k].seconds},
                                                {"validation_mse", s.candidates[k].validation_mse ? nlohmann::json(*s.candidates[k].validation_mse)
                                                                                                  : nlohmann::json(nullptr)}};
        }
        d.measured_seconds = seconds;
        d.cost_basis = "measured: each candidate's joint estimate on the train frames less the validation frames";
        run.plan().add(std::move(d));
        for (std::size_t k = 0; k < families.size(); ++k)
            if (k != best) run.leave_out(std::string("the ") + to_string(families[k]) + " material", s.choice);
    }

    // 2. The winner on all the train frames, as many rounds as its validated estimate kept. The
    //    rounds start from the winner's validated material: the fixed point they iterate toward
    //    is the same, and the validated state is already near it (knot, 384 px: the first round
    //    moves the material by 0.12% from there, against 0.62% from a fit to the first solve's
    //    residuals), so one round fewer settles it. Without validation frames the candidates
    //    were fitted to the first solve's samples: the winner's fit is that fit.
    // Each fit's samples are kept (bounded, as total BRDF samples: the last two rounds') for the
    // core material's fit to the state the rounds end in (a rejected round is the last one).
    std::vector<std::pair<std::string, std::vector<MaterialSample>>> kept;
    JointSteps steps = material_steps(run, s, diffuse.inputs, nullptr, winner, fo, "");
    steps.fit = [&kept, fit = steps.fit, max = config.max_fit_samples](const ResidualSamples& r, const std::string& tag) {
        if (kept.size() == 2) kept.erase(kept.begin());
        kept.emplace_back(tag, to_material_samples(r.samples, max));
        return fit(r, tag);
    };
    const bool start_validated = split.held_out == 0 || (warm_start && s.candidates[best].fit.model());
    if (!start_validated && rs.samples.empty()) // the winner has no usable validated fit: fit the first solve's samples
        rs = run_residuals(run, diffuse.inputs, diffuse.solve, diffuse.options, "residual samples");
    JointState state{.solve_options = diffuse.options, .solve = std::move(diffuse.solve), .residuals = {},
                     .fit = start_validated ? s.candidates[best].fit : steps.fit(rs, ""), .validation_mse = std::nullopt};
    state.residuals = std::move(rs);
    JointOptions final_rounds = jo;
    // Without a validation step the final rounds cannot undo a round that makes things worse:
    // where the validated estimate undid one (an oscillation), at most its kept rounds run;
    // where it settled or ran out of rounds, the same limit (a settled estimate stops early).
    const JointResult& validated = s.candidates[best].joint;
    const bool undid_a_round = !validated.rounds.empty() && validated.rounds.back().rejected;
    if (split.held_out > 0 && undid_a_round) final_rounds.rounds = validated.accepted;
    s.joint = joint_estimate(state, final_rounds, steps);
    if (name_unsettled(state.fit, s.joint, fo.coated.max_relative_error))
        run.warn("the joint estimate had not settled after " + rounds_text(s.joint) +
                 ": the material may be off by more than its standard errors say (report.json specular)");
    if (config.joint_rounds == 0) run.leave_out("joint albedo and material estimate", "--joint-rounds 0: the thesis's one-pass estimate");
    // The state's albedo was solved with the material before its fit. Where the rounds ended
    // with the material still moving (out of rounds, or capped where the validated estimate
    // undid one), that albedo belongs to another material than the bundle's: solve it once more
    // with the final one, so the albedo, its refinement and the renders take the pair that goes
    // together (coated can, thesis rig, 512 px: the last round moved the material by 82%, and
    // the test frames scored 21.2 dB with the albedo of the material before it).
    if (config.joint_rounds > 0)
        if (const std::optional<SpecularModel> final_model = state.fit.model();
            final_model && (!state.solve_options.material ||
                            max_relative_change(*final_model, *state.solve_options.material) >= jo.tolerance)) {
            LambertOptions lo = state.solve_options;
            lo.material = *final_model;
            state.solve = run_solve(run, diffuse.inputs, lo, "diffuse solve (final material)");
            state.solve_options = std::move(lo);
            s.final_solve = true;
        }
    // No round kept and no final solve: the state still holds the first solve, which left the
    // validation frames out.
    if (first_on_split && s.joint.accepted == 0 && !s.final_solve) state.solve = solve_all(state.solve_options);
    s.seconds = watch.seconds();
    diffuse.solve = std::move(state.solve);
    diffuse.on_fit_split = false;
    diffuse.options = state.solve_options;
    log::info("material " + state.fit.describe());
    s.fit = std::move(state.fit);
    s.decision = config.specular == SpecularMode::On ? "fitted (--specular on)" : "fitted: residuals above the noise (--specular auto)";
    s.backend = run.particle_backend();
    // The core material for ordinary viewers, from the same samples (total BRDF, image-space weights).
    std::string kept_tag; // the round whose fit the state holds: the last accepted one ("": the first fit)
    for (const JointRound& r : s.joint.rounds)
        if (!r.rejected) kept_tag = " (joint round " + std::to_string(r.round) + ")";
    const auto samples_of_state = std::find_if(kept.begin(), kept.end(), [&](const auto& k) { return k.first == kept_tag; });
    s.core = run.stage("core material fit", [&] {
        const CoreFitOptions co{.srgb_display = srgb_display, .threads = config.threads};
        if (samples_of_state != kept.end()) return fit_core_material(samples_of_state->second, co);
        // The validated estimate's fit with no final round accepted: its samples are gone; the
        // final solve's residuals stand in (computed with the material that solve assumed).
        const ResidualSamples r = steps.residuals(diffuse.solve, diffuse.options, " (core material)");
        return fit_core_material(to_material_samples(r.samples, config.max_fit_samples), co);
    });
    std::vector<std::pair<std::string, std::vector<MaterialSample>>>().swap(kept);
    const CoreMaterial& cm = s.core->material;
    log::info(!s.core->fitted ? "core material for ordinary viewers: " + s.core->note
              : cm.clearcoat > 0.0
                  ? format_text("core material for ordinary viewers: a clearcoat of weight %.3f, roughness %.3f (pixel rms %.4g, "
                                "diffuse only %.4g)",
                                cm.clearcoat, cm.clearcoat_roughness, s.core->rms, s.core->diffuse_only_rms)
                  : format_text("core material for ordinary viewers: roughness %.3f, F0 %.4f, F90 %.3f (pixel rms %.4g, diffuse "
                                "only %.4g)",
                                cm.roughness, cm.f0, cm.f90, s.core->rms, s.core->diffuse_only_rms));
    std::vector<ResidualSample>().swap(state.residuals.samples); // memory back (`= {}` keeps the capacity)
    s.residuals = std::move(state.residuals);
    return s;
}

void atlas_decision(PipelineRun& run, const GeometryStage& geometry) {
    const double particle_seconds = run.seconds("visibility") + run.seconds("diffuse solve") + run.seconds("residual samples");
    run.plan().add(decide_atlas(geometry.atlas.summary, run.config.atlas, geometry.particles.particles.size(), particle_seconds));
}

RefineStage refine_stage(PipelineRun& run, const Capture& capture, const GeometryStage& geometry, const VisibilityStage& visibility,
                         const DiffuseStage& diffuse) {
    RefineStage r;
    r.method = run.config.refine_method;
    PlanDecision& decision =
        run.plan().add(decide_albedo_refinement(r.method, run.config.refine_rounds, run.seconds("diffuse solve")));
    r.rounds = decided_refine_rounds(decision);
    if (r.rounds == 0) {
        run.leave_out("albedo refinement", decision.reason);
        return r;
    }
    if (r.method == RefineMethod::Pixels) {
        if (!visibility.scene) {
            run.leave_out("albedo refinement", "the pixel fit casts the train pixels' rays and the visibility stage built no ray scene");
            return r;
        }
        r.refined = run.stage("albedo refinement", [&] {
            PixelFitStats stats;
            AlbedoRefineResult fit =
                fit_albedo_to_pixels(capture.mesh, *visibility.scene, geometry.atlas, geometry.particles.particles, diffuse.inputs,
                                     diffuse.solve, diffuse.options,
                                     PixelFitOptions{.iterations = r.rounds, .threads = run.config.threads,
                                                     .view_hits = visibility.visibility.pixel_hits},
                                     &stats);
            r.pixel_fit = std::move(stats);
            return fit;
        });
        log::info(format_text("albedo pixel fit: %.0f train pixels (%.0f samples), weighted RMS residual %.5f -> %.5f in %.0f iterations",
                              r.pixel_fit->pixels_used, r.pixel_fit->samples_used, r.pixel_fit->rms.front(),
                              r.pixel_fit->rms.back(), r.rounds));
    } else {
        gpu::Context* rc = run.render_context();
        if (rc == nullptr) {
            run.leave_out("albedo refinement", "back-projection renders the train frames, which needs a Vulkan device, and none "
                                               "could be had: " + run.no_device());
            return r;
        }
        r.refined = run.stage("albedo refinement", [&] {
            return refine_albedo(*rc, capture, geometry.atlas, geometry.particles.particles, diffuse.inputs, diffuse.solve,
                                 diffuse.options.material, r.rounds, [&](const LambertInputs& in) {
                                     return run.on_particle_backend("diffuse solve", [&](Backend b) {
                                         return lambert_solve(in, diffuse.options, b, run.compute_context());
                                     });
                                 });
        });
        for (std::size_t i = 0; i < r.refined->rounds.size(); ++i)
            log::info("albedo refinement round " + std::to_string(i + 1) + ": mean |change| " +
                      std::to_string(r.refined->rounds[i].mean_abs_change) + " over " +
                      std::to_string(r.refined->rounds[i].corrected) + " particles");
    }
    set_refinement_cost(*run.plan().find("albedo_refinement"), run.seconds("albedo refinement"));
    return r;
}

AlbedoTexture texture_stage(PipelineRun& run, const GeometryStage& geometry, const DiffuseStage& diffuse, const RefineStage& refine) {
    return run.stage("albedo texture", [&] {
        AlbedoTexture t = refine.refined ? make_albedo_texture(geometry.atlas, geometry.particles.particles, refine.refined->albedo,
                                                               refine.refined->valid)
                                         : make_albedo_texture(geometry.atlas, geometry.particles.particles, diffuse.solve);
        // albedo.exr: the bundle stage writes it beside object.glb (the same texels) unless the
        // bundle embeds the float albedo; one zip-compressed encode of 8 MB is 0.1 s.
        write_albedo_texture(t, run.config.out_dir / "albedo", run.config.embed_float_albedo);
        return t;
    });
}

namespace {

// Angles between refined and mesh normals over the refined interior particles.
void normal_angle_stats(std::vector<double> angles, NormalMapStats& s) {
    if (angles.empty()) return;
    std::sort(angles.begin(), angles.end());
    double sum = 0.0;
    for (double a : angles) sum += a;
    s.mean_angle_deg = sum / static_cast<double>(angles.size());
    s.median_angle_deg = angles[angles.size() / 2];
    s.p95_angle_deg = angles[angles.size() * 95 / 100];
    s.max_angle_deg = angles.back();
}

} // namespace

NormalMapStage normal_map_stage(PipelineRun& run, const GeometryStage& geometry, const DiffuseStage& diffuse) {
    NormalMapStage out;
    const PlanDecision& decision = *run.plan().find("normal_map");
    if (!decided_normal_map(decision)) {
        if (!decision.forced) run.leave_out("normal map (refined normals)", decision.reason);
        return out;
    }
    LambertOptions o = diffuse.options; // the final material known: its specular light subtracted
    o.mode = LambertMode::Photometric;
    const LambertOutputs solve = run_solve(run, diffuse.inputs, o, "photometric solve (normal map)");
    const std::span<const Particle> particles = geometry.particles.particles;
    out.normals.emplace(particles.size());
    std::vector<double> angles;
    for (std::size_t p = 0; p < particles.size(); ++p) {
        const LambertParticleResult& r = solve.particles[p];
        const bool refined = (r.status & shared::kLambertOk) && !(r.status & shared::kLambertFallback);
        (*out.normals)[p] = refined ? glm::vec3(r.normal) : particles[p].n();
        if (!refined) continue;
        ++out.stats.refined;
        if (!particles[p].is_gutter()) angles.push_back(r.normal.w);
    }
    out.stats.particles = particles.size();
    normal_angle_stats(std::move(angles), out.stats);
    log::info(format_text("normal map: %.0f of %.0f particles refined; angle to the mesh normal mean %.3f, median %.3f, "
                          "95%% %.3f deg",
                          out.stats.refined, out.stats.particles, out.stats.mean_angle_deg, out.stats.median_angle_deg,
                          out.stats.p95_angle_deg));
    return out;
}

namespace {

// Each particle's world normal in the tangent frame a viewer interpolates on the bundle's
// mesh at its point, and the atlas filled as the albedo texture is (every particle has a value).
Image encode_normal_map(const Mesh& bundle_mesh, const GeometryStage& geometry, std::span<const glm::vec3> world) {
    const std::span<const Particle> particles = geometry.particles.particles;
    const std::vector<glm::vec3> normals = gltf_unit_normals(bundle_mesh);
    const std::vector<glm::vec4> tangents = vertex_tangents(bundle_mesh);
    std::vector<glm::vec3> encoded(particles.size());
    for (std::size_t p = 0; p < particles.size(); ++p)
        encoded[p] = encode_tangent_normal(tangent_frame_at(bundle_mesh, normals, tangents, particles[p].triangle, particles[p].bary),
                                           world[p]);
    return make_albedo_texture(geometry.atlas, particles, encoded, std::vector<std::uint8_t>(particles.size(), 1)).image;
}

} // namespace

FactorizationStage factorization_stage(PipelineRun& run, const SpecularStage& specular) {
    const ReconstructConfig& config = run.config;
    FactorizationStage f;
    // Lafortune channels whose fit did not converge carry no lobe (they render diffuse only, and say so).
    if (specular.fit) {
        f.status = specular.fit->status();
        f.material = specular.fit->model();
        if (!f.material)
            run.leave_out("specular term in the bundle", "the " + std::string(to_string(specular.fit->family)) +
                                                             " fit gave no usable model: the bundle is diffuse only");
    }
    if (!f.material) {
        run.plan().add(PlanDecision{.name = "factorization_grid",
                                    .value = "none",
                                    .forced = false,
                                    .skipped = true,
                                    .reason = specular.fit ? "no usable fit: no specular to factorize"
                                                           : "no specular: the specular stages were left out"});
        return f;
    }
    const SpecularModel& model = *f.material;
    run.plan().add(decide_factorization_grid(model, config.factorization_grid_h, config.factorization_grid_d));
    const factorization::FactorizationResolution res = decided_grid(model, config.factorization_grid_h, config.factorization_grid_d);
    // On a CPU Vulkan driver (lavapipe) the factorization's kernels run slower than their C++
    // reference (the coated cologne at 512 px: residual terms 35 s on lavapipe, the whole plain
    // factorization 11 s of CPU in C++), as the metric kernels do (evaluation_stage): the
    // reference runs there, and the decision says so. A GPU runs the kernels.
    Backend backend = config.backend;
    std::string backend_reason = backend == Backend::Cpu ? "--backend cpu" : "a Vulkan device";
    if (backend == Backend::Vulkan) {
        gpu::Context* ctx = run.compute_context();
        if (ctx != nullptr && ctx->info().kind == gpu::DeviceKind::Cpu) {
            backend = Backend::Cpu;
            backend_reason = "the C++ reference: the device is a CPU Vulkan driver, where the kernels run slower";
        }
    }
    run.plan().find("factorization_grid")->detail["backend"] = std::string(to_string(backend)) + " (" + backend_reason + ")";
    f.cubes = run.stage("factorization", [&] {
        factorization::FactorizationOptions fo;
        // The planner's grid is the plain GSHD's; the mirrored and warped ones put the peak
        // along d (factorization/resolution.h), so unforced axes are left to each parametrization.
        fo.grid_h = config.factorization_grid_h;
        fo.grid_d = config.factorization_grid_d;
        fo.param = config.factor_param;
        fo.shared_warp = config.shared_warp;
        fo.threads = config.threads;
        return factorization::factorize(model, fo, backend, backend == Backend::Vulkan ? run.compute_context() : nullptr);
    });
    const factorization::Factorization& cubes = *f.cubes;
    PlanDecision& grid = *run.plan().find("factorization_grid");
    if (cubes.resolution.grid_h != res.grid_h || cubes.resolution.grid_d != res.grid_d) {
        grid.value = "h " + std::to_string(cubes.resolution.grid_h) + " x d " + std::to_string(cubes.resolution.grid_d) +
                     " (cube faces " + std::to_string(cubes.resolution.cube_g) + ", " + std::to_string(cubes.resolution.cube_h) + ")";
        grid.detail["grid_h"] = cubes.resolution.grid_h;
        grid.detail["grid_d"] = cubes.resolution.grid_d;
        grid.detail["cube_g"] = cubes.resolution.cube_g;
        grid.detail["cube_h"] = cubes.resolution.cube_h;
        grid.reason = cubes.resolution.reason;
    }
    // The CPU path times each step; the Vulkan path records the three kernels in one submission
    // (no per-step wall time), so its dispatches' GPU time stands in.
    const factorization::FactorizationTimings& t = cubes.timings;
    double seconds = t.matrix_s + t.decomposition_s;
    std::string what = "matrix and decomposition wall time";
    if (!(seconds > 0.0)) {
        if (t.matrix_gpu_ns && t.decomposition_g_gpu_ns && t.decomposition_h_gpu_ns) {
            seconds = (*t.matrix_gpu_ns + *t.decomposition_g_gpu_ns + *t.decomposition_h_gpu_ns) * 1e-9;
            what = "GPU time of the matrix and decomposition dispatches";
        } else {
            seconds = t.total_s;
            what = "factorization wall time";
        }
    }
    set_factorization_cost(grid, seconds, what);
    // Error of the first k terms for k = 1..K (the last one is what the bundle renders).
    for (uint32_t k = 1; k <= cubes.term_count(); ++k) f.per_term.push_back(factorization::direct_relative_rms(model, cubes, k, 1u << 16));
    grid.detail["relative_rms_vs_lobe_cubemaps"] =
        std::isfinite(f.per_term.back().cube) ? nlohmann::json(f.per_term.back().cube) : nlohmann::json(nullptr);
    grid.detail["terms"] = cubes.term_count();
    const auto add_gpu = [&](const char* label, const std::optional<double>& ns) {
        if (ns) run.add_gpu_dispatch("factorization", label, *ns * 1e-6);
    };
    add_gpu("brdf_matrix", t.matrix_gpu_ns);
    add_gpu("decomposition G", t.decomposition_g_gpu_ns);
    add_gpu("decomposition H", t.decomposition_h_gpu_ns);
    add_gpu("cube-map G", t.cube_g_gpu_ns);
    add_gpu("cube-map H", t.cube_h_gpu_ns);
    add_gpu("residual terms", t.residual_gpu_ns);
    return f;
}

void record_specular_cost(PipelineRun& run, const SpecularStage& specular, const FactorizationStage& factorization) {
    PlanDecision* spec = run.plan().find("specular_stages");
    if (spec == nullptr || spec->skipped || !spec->forced) return;
    set_specular_cost(*spec, std::nullopt, 0, specular.fit_samples,
                      specular.seconds + (factorization.cubes ? run.seconds("factorization") : 0.0));
}

Bundle bundle_stage(PipelineRun& run, const Capture& capture, const GeometryStage& geometry, const AlbedoTexture& texture,
                    const FactorizationStage& factorization, const NormalMapStage& normals, const IndirectStage& indirect,
                    const SpecularStage& specular) {
    return run.stage("bundle", [&] {
        Material material;
        material.specular = factorization.material;
        material.status = factorization.status;
        if (factorization.cubes) material.factorized = factorization.cubes->cubes;
        Bundle b = make_bundle(capture.mesh, geometry.atlas.corner_uv, texture.image, std::move(material));
        if (normals.normals) b.normal_map = encode_normal_map(b.mesh, geometry, *normals.normals);
        // What ordinary viewers draw: the fit, or without one (no specular) no specular term and
        // the albedo as the base colour, not glTF's default F0 of 0.04 dimming it.
        b.core = specular.core && specular.core->fitted ? specular.core->material : CoreMaterial{};
        b.info = {{"generator", std::string("specula ") + kVersion}, {"capture", folder_name(capture.desc.dir)}}; // no machine path
        // What an engine needs to know: this albedo is the surface's own, with the light that
        // bounced off the object removed; an engine that renders global illumination adds it back.
        if (indirect.on())
            b.info["indirect_light"] = {{"removed_from_albedo", true},
                                        {"method", "inverse global illumination (Yu et al. 1999), diffuse transfer between "
                                                   "surface particles"},
                                        {"bounces", indirect.options.bounces},
                                        {"transfer", {{"rays", indirect.transfer->rays_per_row},
                                                      {"block", indirect.transfer_stats.block}}},
                                        {"baked", false}};
        // The float albedo beside the bundle by default: albedo.exr (the albedo texture stage
        // writes it only when the bundle embeds it instead).
        write_bundle(run.config.out_dir / "object.glb", b,
                     {.float_albedo_file = run.config.embed_float_albedo ? std::string() : std::string("albedo.exr")});
        return b;
    });
}

namespace {

// The viewer evaluation's options (the metrics backend is the evaluation's).
evaluate::EvaluateOptions viewer_options(const ReconstructConfig& config) {
    evaluate::EvaluateOptions eo;
    eo.metrics.hausdorff = false;
    eo.max_frames_per_split = config.evaluate_max_frames;
    eo.max_train_frames = kViewerTrainFrames;
    eo.include_train = config.evaluate_train;
    eo.threads = config.threads;
    eo.bundle_name = "object.glb (core material)";
    eo.progress = false;
    eo.core_material = true;
    return eo;
}

} // namespace

std::optional<evaluate::EvaluationResult> viewer_stage(PipelineRun& run, const Capture& capture, const Bundle& bundle,
                                                       const std::optional<evaluate::EvaluationResult>& evaluation,
                                                       std::map<std::size_t, render::Frame>* core_renders) {
    if (!evaluation) return std::nullopt; // left out with the evaluation (it said why)
    gpu::Context* ctx = run.render_context();
    if (ctx == nullptr) return std::nullopt;
    return run.stage("viewer evaluation", [&] {
        evaluate::EvaluateOptions eo = viewer_options(run.config);
        eo.metrics_backend = evaluation->metrics_backend;
        eo.rendered = core_renders;
        return evaluate::evaluate(*ctx, bundle, capture, eo);
    });
}

std::unique_ptr<evaluate::IndirectLightAdder> indirect_light_of(const IndirectStage& indirect, const GeometryStage& geometry,
                                                                const VisibilityStage& visibility, const AlbedoTexture& texture,
                                                                const FactorizationStage& factorization) {
    if (!indirect.on()) return nullptr;
    // The final albedo (refined, inpainted) and material: what the bundle renders.
    return std::make_unique<evaluate::IndirectLightAdder>(indirect_scene(indirect, geometry, visibility),
                                                          evaluate::particle_albedo(geometry.particles.particles, texture.image),
                                                          factorization.material, indirect.options);
}

std::optional<evaluate::EvaluationResult> evaluation_stage(PipelineRun& run, const Capture& capture, const Bundle& bundle,
                                                           evaluate::IndirectLightAdder* add_light,
                                                           std::map<std::size_t, render::Frame>* core_renders) {
    const ReconstructConfig& config = run.config;
    if (!config.evaluate) {
        run.leave_out("evaluation", "--no-evaluate");
        return std::nullopt;
    }
    gpu::Context* ctx = run.render_context();
    if (ctx == nullptr) {
        run.leave_out("evaluation", "rendering needs a Vulkan device and none could be had: " + run.no_device());
        return std::nullopt;
    }
    evaluate::EvaluationResult ev = run.stage("evaluation", [&] {
        evaluate::EvaluateOptions eo;
        eo.metrics_backend = evaluate::metrics_backend_for(*ctx);
        eo.max_frames_per_split = config.evaluate_max_frames;
        eo.max_train_frames = config.evaluate_train_frames;
        eo.include_train = config.evaluate_train;
        eo.threads = config.threads;
        if (config.evaluate_factorized && bundle.material.factorized) eo.render.specular = render::SpecularPath::Factorized;
        if (config.write_sheets) eo.sheet_dir = config.out_dir / "sheets";
        eo.bundle_name = "object.glb";
        eo.progress = true;
        if (core_renders != nullptr) {
            core_renders->clear();
            for (const std::size_t f : evaluate::evaluated_frames(capture.desc, viewer_options(config))) core_renders->try_emplace(f);
            eo.core_renders = core_renders;
        }
        if (add_light != nullptr) {
            add_light->expect(evaluate::evaluated_frames(capture.desc, eo)); // its batches: the frames scored
            eo.add_light = [add_light](std::size_t frame, Image& rendered) { add_light->add(frame, rendered); };
        }
        return evaluate::evaluate(*ctx, bundle, capture, eo);
    });
    log::info(evaluate::format_summary(ev));
    // Sheets relative to the output folder, as in report.json: the run writes into a staging
    // folder that is renamed into place at the end (core/output_dir.h).
    nlohmann::json ej = evaluate::to_json(ev, config.out_dir);
    nlohmann::json sheets = nlohmann::json::array();
    for (const fs::path& sp : ev.sheets) sheets.push_back(fs::relative(sp, config.out_dir).generic_string());
    ej["sheets"] = std::move(sheets);
    write_text_file(config.out_dir / "evaluation.json", ej.dump(2) + "\n");
    if (!config.evaluate_train) {
        run.leave_out("evaluation of the train frames", "test frames only (evaluate_train off)");
    } else {
        std::size_t train = 0;
        for (const FrameDesc& f : capture.desc.frames) train += f.split == Split::Train ? 1 : 0;
        if (ev.train_frames < train)
            run.leave_out(std::to_string(train - ev.train_frames) + " of the " + std::to_string(train) + " train frames in the evaluation",
                          "the train figures are those of " + std::to_string(ev.train_frames) +
                              " frames evenly spaced over the split (every test frame is scored); --eval-train-frames 0 "
                              "scores them all, as `specula evaluate` does");
    }
    return ev;
}

} // namespace specula
