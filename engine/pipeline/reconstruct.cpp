#include "pipeline/reconstruct.h"

#include "capture/capture.h"
#include "core/error.h"
#include "core/file_util.h"
#include "core/log.h"
#include "core/timer.h"
#include "diffuse/albedo_texture.h"
#include "evaluate/evaluate.h"
#include "export/bundle.h"
#include "factorization/factorization.h"
#include "geometry/particles.h"
#include "geometry/ray_scene.h"
#include "gpu/context.h"
#include "refine/albedo_refine.h"
#include "report/report_html.h"
#include "specula/version.h"
#include "visibility/visibility.h"

#include <algorithm>
#include <memory>
#include <optional>
#include <utility>

namespace specula {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// Times one stage, logs it, and records it in the result.
// On a terminal, a stage that runs longer than a second shows its elapsed time (log::Ticker).
template <class Fn>
auto run_stage(ReconstructResult& result, const std::string& name, Fn&& fn) {
    log::info("[" + name + "] ...");
    log::Ticker ticker(name);
    Stopwatch watch;
    if constexpr (std::is_void_v<decltype(fn())>) {
        fn();
        result.stages.push_back({name, watch.seconds()});
        log::info("[" + name + "] " + std::to_string(result.stages.back().seconds) + " s");
    } else {
        auto value = fn();
        result.stages.push_back({name, watch.seconds()});
        log::info("[" + name + "] " + std::to_string(result.stages.back().seconds) + " s");
        return value;
    }
}

json atlas_json(const AtlasSummary& s, const AtlasOptions& o) {
    return {{"mode", s.mode},
            {"charts", s.charts},
            {"seam_edges", s.seam_edges},
            {"vertices", {{"mesh", s.mesh_vertices}, {"atlas", s.atlas_vertices}}},
            {"width", s.width},
            {"height", s.height},
            {"size_source", s.size_source},
            {"texels_per_pixel", o.texels_per_pixel},
            {"budget", {o.max_width, o.max_height}},
            {"budget_clipped", s.budget_clipped},
            {"budget_scale", s.budget_scale},
            {"patch_leg", {{"min", s.patch_min}, {"median", s.patch_median}, {"mean", s.patch_mean}, {"max", s.patch_max}}},
            {"interior_texels", s.interior_texels},
            {"gutter_texels", s.gutter_texels},
            {"fill_ratio", s.fill_ratio},
            {"triangles_seen_by_no_camera", s.triangles_seen_by_no_camera},
            {"notes", s.notes}};
}

json visibility_json(const VisibilityStats& s) {
    return {{"particles", s.particles},
            {"views", s.views},
            {"frames", s.frames},
            {"seen_by_no_view", s.seen_by_no_view},
            {"lit_by_no_frame", s.lit_by_no_frame},
            {"rays_cast", s.rays_cast},
            {"rays_occluded", s.rays_occluded},
            {"rays_avoided", s.rays_avoided},
            {"depth_rays", s.depth_rays},
            {"surface_maps", s.surface_maps},
            {"footprint_rejected_pairs", s.footprint_rejected},
            {"shadow_map_rays", s.shadow_map_rays},
            {"shadow_edge_rejected_pairs", s.shadow_edge_rejected},
            {"convex", s.convexity.convex},
            {"convexity_reason", s.convexity.reason},
            {"occlusion_rays_skipped", s.skipped},
            {"seconds", s.seconds}};
}

json lambert_json(const LambertOutputs& out, const LambertOptions& o, LambertBackend backend) {
    const LambertSummary& s = out.summary;
    json j = {{"backend", to_string(backend)},
              {"mode", to_string(o.mode)},
              {"view_choice", o.choice == ViewChoice::BestView ? "best_view" : "robust"},
              {"tap_irradiance", s.tap_irradiance},
              {"particles", s.particles},
              {"pairs", s.pairs},
              {"ok", s.ok},
              {"fallback_to_albedo_mode", s.fallback},
              {"no_valid_sample", s.no_sample},
              {"not_seen", s.not_seen},
              {"particles_with_outlier_views", s.views_rejected},
              {"samples",
               {{"used", s.used},
                {"rejected_shadow", s.rejected_shadow},
                {"rejected_clipped", s.rejected_clipped},
                {"rejected_missing", s.rejected_missing},
                {"rejected_grazing", s.rejected_grazing},
                {"rejected_highlight", s.rejected_highlight},
                {"rejected_outlier_view", s.rejected_view}}},
              {"thresholds",
               {{"min_light_cos", o.min_light_cos},
                {"highlight_tau", o.highlight_tau},
                {"highlight_k_sigma", o.highlight_k},
                {"noise_sigma", o.noise_sigma},
                {"min_rcond", o.min_rcond},
                {"view_tau", o.view_tau},
                {"view_abs", o.view_abs}}},
              {"view_batches", s.view_batches},
              {"seconds", s.seconds}};
    if (o.mode == LambertMode::Photometric) j["mean_normal_angle_deg"] = s.mean_normal_angle_deg;
    if (s.gpu_ms) {
        j["gpu_ms"] = *s.gpu_ms;
        json d = json::array();
        for (const auto& [label, ms] : s.gpu_dispatch_ms) d.push_back({{"label", label}, {"ms", ms}});
        j["gpu_dispatches"] = d;
    }
    return j;
}

json rgb(const double (&v)[3]) { return json::array({v[0], v[1], v[2]}); }

/// Every parametrization's factorization as the choice saw it (only the forced one when forced).
json param_candidates_json(const factorization::ParamChoice& c) {
    json out = json::object();
    for (const FactorParam p : {FactorParam::Gshd, FactorParam::Mirrored, FactorParam::Warped}) {
        const factorization::ParamCandidate& k = c.of(p);
        if (!k.computed) continue;
        out[to_string(p)] = {{"grid_h", k.resolution.grid_h},
                             {"grid_d", k.resolution.grid_d},
                             {"terms", k.terms.count},
                             {"matrix_relative_rms", k.terms.matrix_rms},
                             {"relative_rms_vs_lobe_cubemaps", k.direct_rms}};
    }
    return out;
}

json specular_json(const ResidualSamples& rs, const ResidualEnergy& energy, const LafortuneFitRgb* fit, double fit_seconds,
                   LambertBackend backend, const std::string& decision) {
    const ResidualCounts& c = rs.counts;
    json j = {{"decision", decision},
              {"backend", to_string(backend)},
              {"samples",
               {{"candidates", c.candidates},
                {"used", c.used},
                {"dropped",
                 {{"shadow", c.dropped_shadow},
                  {"grazing", c.dropped_grazing},
                  {"missing", c.dropped_missing},
                  {"clipped", c.dropped_clipped},
                  {"no_diffuse_solution", c.dropped_no_diffuse}}},
                {"weight", "Ebar^2 (image-space residual; shared/residuals.h)"}}},
              {"energy",
               {{"mean_square_residual", energy.mean_square},
                {"mean_residual", energy.mean},
                {"noise_sigma", energy.noise_sigma},
                {"ratio_to_noise_variance", energy.ratio},
                {"threshold", energy.threshold},
                {"has_specular", energy.has_specular}}},
              {"view_batches", rs.view_batches},
              {"dispatches", rs.chunks}};
    json seconds = {{"residuals", rs.seconds}};
    if (rs.gpu_ms) seconds["residuals_gpu_ms"] = *rs.gpu_ms;
    if (fit != nullptr) {
        seconds["fit"] = fit_seconds;
        double cx[3], cz[3], n[3], ecx[3], ecz[3], en[3], cond[3], cost[3], rms[3];
        json status = json::array(), reason = json::array(), iterations = json::array();
        for (int k = 0; k < 3; ++k) {
            const LafortuneChannelFit& f = fit->channel[k];
            cx[k] = f.cx, cz[k] = f.cz, n[k] = f.n;
            ecx[k] = f.std_error_cx, ecz[k] = f.std_error_cz, en[k] = f.std_error_n;
            cond[k] = f.condition, cost[k] = f.cost, rms[k] = f.rms;
            status.push_back(to_string(f.status));
            reason.push_back(f.reason);
            iterations.push_back(f.iterations);
        }
        j["lobe"] = {{"cx", rgb(cx)}, {"cz", rgb(cz)}, {"n", rgb(n)}, {"status", status}};
        j["reason"] = reason;
        j["standard_errors"] = {{"cx", rgb(ecx)}, {"cz", rgb(ecz)}, {"n", rgb(en)}};
        j["condition"] = rgb(cond);
        j["cost"] = rgb(cost);
        j["rms"] = rgb(rms);
        j["iterations"] = iterations;
    } else {
        j["lobe"] = nullptr;
    }
    j["seconds"] = seconds;
    return j;
}

} // namespace

const char* to_string(SpecularMode mode) noexcept {
    switch (mode) {
    case SpecularMode::Auto: return "auto";
    case SpecularMode::On: return "on";
    case SpecularMode::Off: return "off";
    }
    return "?";
}

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

std::vector<LafortuneSample> stride_subsample(std::vector<LafortuneSample> all, std::size_t max_samples) {
    if (max_samples != 0 && all.size() > max_samples) {
        const std::size_t stride = (all.size() + max_samples - 1) / max_samples;
        std::size_t k = 0;
        for (std::size_t i = 0; i < all.size(); i += stride) all[k++] = all[i];
        all.resize(k);
    }
    return all;
}

double stage_seconds(const ReconstructResult& r, const std::string& name) {
    double s = 0.0;
    for (const StageRecord& st : r.stages)
        if (st.name == name) s += st.seconds;
    return s;
}

} // namespace

ReconstructResult reconstruct(const ReconstructConfig& config, const Capture* preloaded) {
    ReconstructResult result;
    Stopwatch total;
    if (config.out_dir.empty()) throw UsageError("no output folder given");
    Plan& plan = result.plan;

    // 1. Capture: description, mesh, train and test images (test frames are only counted here).
    std::optional<Capture> loaded;
    if (preloaded == nullptr)
        loaded = run_stage(result, "load", [&] {
            return load_capture(config.capture, CaptureLoadOptions{.threads = static_cast<int>(config.threads)});
        });
    const Capture& capture = preloaded != nullptr ? *preloaded : *loaded;
    if (capture.images.empty()) throw Error("reconstruct: the capture was loaded without its images");
    result.warnings = capture.warnings;
    for (const std::string& w : capture.warnings) log::warn(w);
    if (capture.frame_count(Split::Train) == 0)
        throw InputError(capture_json_path(config.capture), "frames", "no train frames: nothing to reconstruct from");

    // 2. The plan from the capture alone: can the mesh occlude itself, do the lights allow
    //    the photometric solve (the atlas, specular and factorization decisions follow
    //    from later measurements).
    LambertOptions lambert = config.lambert;
    run_stage(result, "plan", [&] {
        plan.add(decide_occlusion_rays(analyze_convexity(capture.mesh), config.occlusion_rays));
        const PlanDecision& mode =
            plan.add(decide_diffuse_mode(light_conditioning(capture, static_cast<double>(lambert.min_rcond)), config.diffuse_mode,
                                        config.specular != SpecularMode::Off));
        lambert.mode = decided_photometric(mode) ? LambertMode::Photometric : LambertMode::Albedo;
        plan.add(PlanDecision{.name = "atlas"}); // filled once the particle stages are timed
    });
    for (const PlanDecision& d : plan.decisions)
        if (!d.value.empty()) log::info("plan: " + d.name + " = " + d.value + " (" + (d.forced ? "forced" : "auto") + ")");
    if (plan.find("diffuse_mode")->value == "albedo" && !plan.find("diffuse_mode")->forced)
        result.left_out.push_back({"photometric solve (refined normals)", plan.find("diffuse_mode")->reason});

    // Cameras of the views that have train frames size the atlas (test views must not).
    std::vector<Camera> train_cameras;
    for (const View& view : capture.views)
        for (std::size_t f : view.frames)
            if (capture.desc.frames[f].split == Split::Train) {
                train_cameras.push_back(view.camera);
                break;
            }

    // 3. Atlas and particles.
    const Atlas atlas = run_stage(result, "atlas", [&] { return build_atlas(capture.mesh, train_cameras, config.atlas); });
    log::info(describe(atlas.summary));
    const ParticleSet particles = run_stage(result, "particles", [&] { return build_particles(capture.mesh, atlas); });

    // 4. Visibility: Embree occlusion rays unless the planner (or a flag) leaves them out.
    const bool cast_rays = plan.find("occlusion_rays")->value == "cast";
    std::optional<RayScene> scene; // built inside the stage (its BVH is part of its cost), kept for the probe
    const VisibilityInputs vis_inputs = visibility_inputs(capture);
    const Visibility visibility = run_stage(result, "visibility", [&] {
        scene.emplace(capture.mesh);
        return compute_visibility(particles.particles, capture.mesh, *scene, vis_inputs.views, vis_inputs.lights,
                                  VisibilityOptions{.threads = config.threads,
                                                    .force_rays = cast_rays,
                                                    .skip_rays = !cast_rays,
                                                    .frame_view = vis_inputs.frame_view,
                                                    .surface_maps = config.lambert.tap_irradiance});
    });
    if (!config.lambert.tap_irradiance)
        result.left_out.push_back({"per-tap irradiance (surface maps)",
                                   "--tap-irradiance off: each sample mixes its 4 pixels as they are (the thesis's sampling), "
                                   "biased where the normal turns within a pixel"});
    {
        PlanDecision& d = *plan.find("occlusion_rays");
        d.detail["rays_cast"] = visibility.stats.rays_cast;
        d.detail["rays_avoided"] = visibility.stats.rays_avoided;
        if (!cast_rays) {
            result.left_out.push_back({"occlusion rays (visibility and shadows)", d.reason});
            if (config.cost_probes && visibility.stats.rays_avoided > 0) {
                const auto per_ray = run_stage(result, "probe: occlusion rays", [&] {
                    return probe_ray_seconds(*scene, particles.particles, visibility, vis_inputs.views, 20000);
                });
                if (per_ray) {
                    d.avoided_seconds = *per_ray * static_cast<double>(visibility.stats.rays_avoided);
                    d.cost_basis = "estimate: " + std::to_string(visibility.stats.rays_avoided) + " rays avoided x " +
                                   std::to_string(*per_ray * 1e9) + " ns per ray (timed on up to 20000 particle-to-camera "
                                   "rays); the footprint test's depth and shadow maps, skipped too, are not included";
                }
            }
        } else {
            d.measured_seconds = stage_seconds(result, "visibility");
            d.cost_basis = "measured: the visibility stage with " + std::to_string(visibility.stats.rays_cast) +
                           " occlusion rays, " + std::to_string(visibility.stats.depth_rays) + " depth-map rays and " +
                           std::to_string(visibility.stats.shadow_map_rays) + " shadow-map rays";
        }
    }

    // 5. Diffuse solve on the chosen backend.
    std::unique_ptr<gpu::Context> ctx;
    json device = nullptr;
    if (config.backend == LambertBackend::Vulkan) {
        ctx = run_stage(result, "vulkan init", [&] { return std::make_unique<gpu::Context>(gpu::ContextOptions{.device = config.device}); });
        device = {{"name", ctx->info().name},
                  {"kind", gpu::device_kind_name(ctx->info().kind)},
                  {"api_version", gpu::version_string(ctx->info().api_version)},
                  {"validation", ctx->validation_enabled()}};
        log::info("Vulkan device: " + ctx->info().name);
    }
    json gpu_dispatches = json::array();
    const LambertInputs lambert_in = lambert_inputs(capture, particles.particles, visibility);
    // The per-particle passes (diffuse solve, residual samples) run on the chosen backend;
    // when one of their buffers would exceed a storage binding of this device (gpu::LimitError:
    // knot_hd's 2.8 M particles need 134 MB, lavapipe allows 128 MiB), the C++ reference runs
    // them instead, and the report says so.
    LambertBackend particle_backend = config.backend;
    const auto on_backend = [&](const std::string& what, auto&& fn) {
        if (particle_backend == LambertBackend::Vulkan) {
            try {
                return fn(LambertBackend::Vulkan);
            } catch (const gpu::LimitError& e) {
                particle_backend = LambertBackend::Cpu;
                const std::string why = std::string(e.what()) + ": the C++ reference ran instead";
                result.left_out.push_back({"Vulkan " + what + " and the later per-particle passes", why});
                log::warn("Vulkan " + what + ": " + why);
            }
        }
        return fn(LambertBackend::Cpu);
    };
    LambertOptions solve_options = lambert; // the options of the last solve (its lobe, after joint rounds)
    LambertOutputs solve = run_stage(result, "diffuse solve", [&] {
        return on_backend("diffuse solve", [&](LambertBackend b) { return lambert_solve(lambert_in, lambert, b, ctx.get()); });
    });
    log::info(describe(solve.summary, lambert.mode));
    {
        PlanDecision& d = *plan.find("diffuse_mode");
        if (d.forced) {
            d.measured_seconds = stage_seconds(result, "diffuse solve");
            d.cost_basis = std::string("measured: the diffuse solve in ") + to_string(lambert.mode) + " mode";
        } else {
            d.cost_basis = "no estimate: both modes read the same samples; photometric solves a 3x3 system where albedo "
                           "mode divides two sums (force a mode to measure it)";
        }
    }
    for (const auto& [label, ms] : solve.summary.gpu_dispatch_ms)
        gpu_dispatches.push_back({{"stage", "diffuse solve"}, {"dispatch", label}, {"ms", ms}});
    if (ctx) device["validation_messages"] = ctx->validation_message_count();
    if (solve.summary.fallback > 0)
        result.left_out.push_back({"photometric solve for " + std::to_string(solve.summary.fallback) + " particles",
                                   "fewer than three usable, non-coplanar light directions in their best view: "
                                   "albedo mode (known normals) used instead"});

    // 6. Specular: residual samples, then the Lafortune fit when the residuals hold energy
    //    above the noise (pipeline.md sections 4, 5 and 9) or when forced.
    json specular = nullptr;
    std::optional<LafortuneFitRgb> fitted_lobe;
    double fit_seconds = 0.0;      // the Lafortune fits
    double specular_seconds = 0.0; // the fits and the joint rounds (diffuse solve, residuals, fit)
    std::size_t fit_samples = 0;
    if (config.specular == SpecularMode::Off) {
        PlanDecision d = decide_specular(ResidualEnergy{}, Toggle::Off);
        d.detail = nullptr;
        plan.add(std::move(d));
        result.left_out.push_back({"specular fit, factorization and specular pass (residual samples too)", "--specular off"});
    } else {
        const ResidualOptions residual_options{.min_light_cos = lambert.min_light_cos, .tap_irradiance = lambert.tap_irradiance, .max_binding_bytes = 0,
                                               .max_albedo_spread = 0.02f};
        ResidualSamples rs = run_stage(result, "residual samples", [&] {
            return on_backend("residual samples",
                              [&](LambertBackend b) { return residual_samples(lambert_in, solve, residual_options, b, ctx.get()); });
        });
        if (rs.gpu_ms) gpu_dispatches.push_back({{"stage", "residual samples"}, {"dispatch", "residuals (" + std::to_string(rs.chunks) + " dispatches)"}, {"ms", *rs.gpu_ms}});
        const ResidualEnergy energy =
            residual_energy(rs.samples, static_cast<double>(lambert.noise_sigma), config.specular_energy_threshold);
        const Toggle toggle = config.specular == SpecularMode::On ? Toggle::On : Toggle::Auto;
        PlanDecision& decision = plan.add(decide_specular(energy, toggle));
        log::info("residual samples: " + std::to_string(rs.counts.used) + " used; " + decision.reason);
        LafortuneFitOptions fo = config.lafortune;
        fo.noise_sigma = static_cast<double>(lambert.noise_sigma);
        std::vector<LafortuneSample> all = to_lafortune_samples(rs.samples);
        const std::size_t would_fit = config.max_fit_samples != 0 ? std::min<std::size_t>(all.size(), config.max_fit_samples) : all.size();
        if (decision.skipped) {
            result.left_out.push_back({"specular fit, factorization and specular pass", decision.reason});
            specular = specular_json(rs, energy, nullptr, 0.0, particle_backend, "skipped: no specular energy (--specular auto)");
            if (config.cost_probes && all.size() >= 100) {
                constexpr std::size_t kProbe = 4000;
                std::optional<double> probe;
                std::size_t probe_n = 0;
                run_stage(result, "probe: lafortune fit", [&] {
                    const std::vector<LafortuneSample> sub = stride_subsample(all, kProbe);
                    probe_n = sub.size();
                    const Stopwatch w;
                    (void)fit_lafortune(sub, fo);
                    probe = w.seconds();
                });
                set_specular_cost(decision, probe, probe_n, would_fit, std::nullopt);
            }
        } else {
            Stopwatch fit_watch;
            const auto run_fit = [&](const std::string& stage, std::vector<LafortuneSample> samples) {
                return run_stage(result, stage, [&] {
                    const std::vector<LafortuneSample> sub = stride_subsample(std::move(samples), config.max_fit_samples);
                    fit_samples = sub.size();
                    const Stopwatch w;
                    LafortuneFitRgb f = fit_lafortune(sub, fo);
                    fit_seconds += w.seconds(); // the fits alone (specular.joint.seconds: all rounds)
                    return f;
                });
            };
            LafortuneFitRgb fit = run_fit("lafortune fit", std::move(all)); // converted above for the energy decision
            // Joint estimate (an addition to the thesis): the diffuse solve absorbs the part of a
            // broad lobe that its highlight test cannot separate, which biases the residuals low.
            // Each round subtracts the fitted lobe's light from the samples, re-solves the albedo,
            // recomputes the residuals and refits, until the lobe changes by less than
            // joint_tolerance (relative, per parameter) or joint_rounds is reached.
            json rounds = json::array();
            const auto lobe_of = [](const LafortuneFitRgb& f) {
                LafortuneRgb l;
                for (int k = 0; k < 3; ++k)
                    if (f.channel[k].status == LafortuneFitStatus::Converged) {
                        l.cx[k] = static_cast<float>(f.channel[k].cx);
                        l.cz[k] = static_cast<float>(f.channel[k].cz);
                        l.n[k] = static_cast<float>(f.channel[k].n);
                    }
                return l;
            };
            std::string joint_stop = "joint rounds: " + std::to_string(config.joint_rounds) + " allowed";
            for (std::uint32_t round = 1; round <= config.joint_rounds; ++round) {
                const LafortuneRgb previous = lobe_of(fit);
                if (previous.is_zero()) {
                    joint_stop = "no channel converged: nothing to subtract";
                    break;
                }
                const std::string tag = " (joint round " + std::to_string(round) + ")";
                LambertOptions lo = lambert;
                lo.lobe = previous;
                solve = run_stage(result, "diffuse solve" + tag, [&] {
                    return on_backend("diffuse solve", [&](LambertBackend b) { return lambert_solve(lambert_in, lo, b, ctx.get()); });
                });
                solve_options = lo;
                rs = run_stage(result, "residual samples" + tag, [&] {
                    return on_backend("residual samples", [&](LambertBackend b) {
                        return residual_samples(lambert_in, solve, residual_options, b, ctx.get());
                    });
                });
                for (const auto& [label, ms] : solve.summary.gpu_dispatch_ms)
                    gpu_dispatches.push_back({{"stage", "diffuse solve" + tag}, {"dispatch", label}, {"ms", ms}});
                if (rs.gpu_ms)
                    gpu_dispatches.push_back({{"stage", "residual samples" + tag},
                                              {"dispatch", "residuals (" + std::to_string(rs.chunks) + " dispatches)"},
                                              {"ms", *rs.gpu_ms}});
                fit = run_fit("lafortune fit" + tag, to_lafortune_samples(rs.samples));
                const LafortuneRgb next = lobe_of(fit);
                double change = 0.0;
                for (int k = 0; k < 3; ++k) {
                    const auto rel = [](float a, float b) { return std::abs(double(a) - double(b)) / std::max(1e-6, std::abs(double(b))); };
                    change = std::max({change, rel(next.cx[k], previous.cx[k]), rel(next.cz[k], previous.cz[k]), rel(next.n[k], previous.n[k])});
                }
                rounds.push_back({{"round", round}, {"max_relative_change", change}, {"residual_samples", rs.counts.used}});
                log::info("joint round " + std::to_string(round) + ": lobe changed by " + std::to_string(100.0 * change) + "%");
                if (change < config.joint_tolerance) {
                    joint_stop = "converged: the lobe changed by less than " + std::to_string(100.0 * config.joint_tolerance) + "%";
                    break;
                }
            }
            if (config.joint_rounds == 0)
                result.left_out.push_back({"joint albedo and lobe estimate", "--joint-rounds 0: the thesis's one-pass estimate"});
            specular_seconds = fit_watch.seconds();
            fitted_lobe = fit;
            for (int k = 0; k < 3; ++k)
                log::info(std::string("lafortune ") + "rgb"[k] + ": Cx " + std::to_string(fit.channel[k].cx) + " Cz " +
                          std::to_string(fit.channel[k].cz) + " N " + std::to_string(fit.channel[k].n) + " (" +
                          to_string(fit.channel[k].status) + ")");
            specular = specular_json(rs, energy, &fit, fit_seconds, particle_backend,
                                     config.specular == SpecularMode::On ? "fitted (--specular on)"
                                                                         : "fitted: residuals above the noise (--specular auto)");
            specular["samples"]["fitted"] = fit_samples; // stride subsample (max_fit_samples)
            specular["joint"] = {{"rounds", rounds},
                                 {"stop", joint_stop},
                                 {"tolerance", config.joint_tolerance},
                                 {"seconds", specular_seconds}}; // fits and joint rounds
        }
    }
    {
        const double particle_seconds = stage_seconds(result, "visibility") + stage_seconds(result, "diffuse solve") +
                                        stage_seconds(result, "residual samples");
        plan.add(decide_atlas(atlas.summary, config.atlas, particles.particles.size(), particle_seconds));
    }

    // A Vulkan device for rendering (refinement, evaluation): the solve's, else one made now.
    std::unique_ptr<gpu::Context> render_only_ctx;
    std::string no_device;
    const auto render_context = [&]() -> gpu::Context* {
        if (ctx) return ctx.get();
        if (!render_only_ctx && no_device.empty()) {
            try {
                render_only_ctx = std::make_unique<gpu::Context>(gpu::ContextOptions{.device = config.device});
            } catch (const std::exception& e) {
                no_device = e.what();
            }
        }
        return render_only_ctx.get();
    };

    // 6b. Albedo refinement by back-projection (albedo_refine.h): the albedo whose renders,
    //     read back by the solve, reproduce the solve's reading of the captured images.
    std::optional<AlbedoRefineResult> refined;
    json refinement = nullptr;
    PlanDecision& refine_decision = plan.add(decide_albedo_refinement(config.refine_rounds, stage_seconds(result, "diffuse solve")));
    const std::uint32_t refine_rounds = decided_refine_rounds(refine_decision);
    if (refine_rounds == 0) {
        result.left_out.push_back({"albedo refinement", refine_decision.reason});
    } else if (gpu::Context* rc = render_context(); rc == nullptr) {
        result.left_out.push_back({"albedo refinement", "rendering needs a Vulkan device and none could be had: " + no_device});
    } else {
        refined = run_stage(result, "albedo refinement", [&] {
            return refine_albedo(*rc, capture, atlas, particles.particles, lambert_in, solve, solve_options.lobe,
                                 refine_rounds, [&](const LambertInputs& in) {
                                     return on_backend("diffuse solve", [&](LambertBackend b) {
                                         return lambert_solve(in, solve_options, b, ctx.get());
                                     });
                                 });
        });
        json rounds = json::array();
        for (std::size_t i = 0; i < refined->rounds.size(); ++i) {
            const AlbedoRefineRound& r = refined->rounds[i];
            rounds.push_back({{"round", i + 1},
                              {"mean_abs_change", r.mean_abs_change},
                              {"corrected_particles", r.corrected},
                              {"render_seconds", r.render_seconds},
                              {"solve_seconds", r.solve_seconds}});
            log::info("albedo refinement round " + std::to_string(i + 1) + ": mean |change| " + std::to_string(r.mean_abs_change) +
                      " over " + std::to_string(r.corrected) + " particles");
        }
        set_refinement_cost(refine_decision, stage_seconds(result, "albedo refinement"));
        refinement = {{"rounds", rounds},
                      {"method", "A <- A + S(captured) - S(render(A)): S the diffuse solve's robust combination over views, "
                                 "render without cast shadows with the solve's lobe (refine/albedo_refine.h)"},
                      {"seconds", stage_seconds(result, "albedo refinement")}};
    }

    // 7. Albedo texture: inpaint what no view saw, write linear EXR and sRGB PNG.
    const AlbedoTexture texture = run_stage(result, "albedo texture", [&] {
        AlbedoTexture t = refined ? make_albedo_texture(atlas, particles.particles, refined->albedo, refined->valid)
                                  : make_albedo_texture(atlas, particles.particles, solve);
        write_albedo_texture(t, config.out_dir / "albedo");
        return t;
    });

    // 8. Factorization of the lobe into the two cube-maps (Kautz and McCool), on the grid
    //    the planner chose from the lobe's width, in the parametrization (plain, mirrored or
    //    warped GSHD) whose error against the lobe is lowest. Channels whose fit did not converge carry
    //    no lobe (they render diffuse only, and say so).
    std::optional<LafortuneRgb> lobe;
    std::vector<std::string> lobe_status;
    if (fitted_lobe) {
        LafortuneRgb l;
        for (int k = 0; k < 3; ++k) {
            lobe_status.push_back(to_string(fitted_lobe->channel[k].status));
            if (fitted_lobe->channel[k].status != LafortuneFitStatus::Converged) continue;
            l.cx[k] = static_cast<float>(fitted_lobe->channel[k].cx);
            l.cz[k] = static_cast<float>(fitted_lobe->channel[k].cz);
            l.n[k] = static_cast<float>(fitted_lobe->channel[k].n);
        }
        if (!l.is_zero()) lobe = l;
        else result.left_out.push_back({"specular lobe in the bundle", "no channel's fit converged: the bundle is diffuse only"});
    }
    json factorization_report = nullptr;
    std::optional<factorization::Factorization> cubes;
    if (lobe) {
        PlanDecision& grid = plan.add(decide_factorization_grid(*lobe, config.factorization_grid_h, config.factorization_grid_d));
        const factorization::FactorizationResolution res =
            decided_grid(*lobe, config.factorization_grid_h, config.factorization_grid_d);
        cubes = run_stage(result, "factorization", [&] {
            const auto backend = config.backend == LambertBackend::Vulkan ? factorization::FactorizationBackend::Vulkan
                                                                          : factorization::FactorizationBackend::Cpu;
            factorization::FactorizationOptions fo;
            // The planner's grid is the plain GSHD's; the mirrored and warped ones put the peak
            // along d (factorization/resolution.h), so unforced axes are left to each parametrization.
            fo.grid_h = config.factorization_grid_h;
            fo.grid_d = config.factorization_grid_d;
            fo.param = config.factor_param;
            return factorization::factorize(*lobe, fo, backend, ctx.get());
        });
        if (cubes->resolution.grid_h != res.grid_h || cubes->resolution.grid_d != res.grid_d) {
            grid.value = "h " + std::to_string(cubes->resolution.grid_h) + " x d " + std::to_string(cubes->resolution.grid_d) +
                         " (cube faces " + std::to_string(cubes->resolution.cube_g) + ", " +
                         std::to_string(cubes->resolution.cube_h) + ")";
            grid.detail["grid_h"] = cubes->resolution.grid_h;
            grid.detail["grid_d"] = cubes->resolution.grid_d;
            grid.detail["cube_g"] = cubes->resolution.cube_g;
            grid.detail["cube_h"] = cubes->resolution.cube_h;
            grid.reason = cubes->resolution.reason;
        }
        {
            // The CPU path times each step; the Vulkan path records the three kernels in one
            // submission (no per-step wall time), so its dispatches' GPU time stands in.
            const factorization::FactorizationTimings& t = cubes->timings;
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
        }
        // Error of the first k terms for k = 1..K (the last one is what the bundle renders).
        json per_term = json::array();
        factorization::DirectError err;
        for (uint32_t k = 1; k <= cubes->term_count(); ++k) {
            err = factorization::direct_relative_rms(*lobe, *cubes, k, 1u << 16);
            json t = {{"terms", k}, {"relative_rms_vs_lobe_grid", err.grid}, {"relative_rms_vs_lobe_cubemaps", err.cube}};
            if (k <= cubes->terms.matrix_rms.size()) t["matrix_relative_rms"] = cubes->terms.matrix_rms[k - 1];
            per_term.push_back(std::move(t));
        }
        grid.detail["relative_rms_vs_lobe_cubemaps"] = std::isfinite(err.cube) ? json(err.cube) : json(nullptr);
        grid.detail["terms"] = cubes->term_count();
        factorization_report = {{"grid_h", cubes->resolution.grid_h},
                                {"grid_d", cubes->resolution.grid_d},
                                {"cube_g", cubes->resolution.cube_g},
                                {"cube_h", cubes->resolution.cube_h},
                                {"resolution_reason", grid.reason},
                                {"relative_rms_vs_lobe_grid", err.grid},
                                {"relative_rms_vs_lobe_cubemaps", err.cube},
                                {"terms", cubes->term_count()},
                                {"terms_reason", cubes->terms.reason},
                                {"terms_target", cubes->terms.target},
                                {"per_term", std::move(per_term)},
                                {"parametrization", to_string(cubes->param)},
                                {"parametrization_forced", cubes->param_choice.forced},
                                {"parametrization_reason", cubes->param_choice.reason},
                                {"parametrization_candidates", param_candidates_json(cubes->param_choice)},
                                {"seconds", cubes->timings.total_s}};
        if (cubes->param == FactorParam::Warped) factorization_report["warp"] = {cubes->warp.x, cubes->warp.y, cubes->warp.z, cubes->warp.w};
        if (const auto ns = cubes->timings.gpu_total_ns()) factorization_report["gpu_ms"] = *ns * 1e-6;
        const auto add_gpu = [&](const char* label, const std::optional<double>& ns) {
            if (ns) gpu_dispatches.push_back({{"stage", "factorization"}, {"dispatch", label}, {"ms", *ns * 1e-6}});
        };
        add_gpu("brdf_matrix", cubes->timings.matrix_gpu_ns);
        add_gpu("decomposition G", cubes->timings.decomposition_g_gpu_ns);
        add_gpu("decomposition H", cubes->timings.decomposition_h_gpu_ns);
        add_gpu("cube-map G", cubes->timings.cube_g_gpu_ns);
        add_gpu("cube-map H", cubes->timings.cube_h_gpu_ns);
        add_gpu("residual terms", cubes->timings.residual_gpu_ns);
    } else {
        plan.add(PlanDecision{.name = "factorization_grid",
                              .value = "none",
                              .forced = false,
                              .skipped = true,
                              .reason = fitted_lobe ? "no channel's fit converged: no lobe to factorize"
                                                    : "no lobe: the specular stages were left out"});
    }
    if (PlanDecision* spec = plan.find("specular_stages"); spec != nullptr && !spec->skipped && spec->forced)
        set_specular_cost(*spec, std::nullopt, 0, fit_samples,
                          specular_seconds + (cubes ? stage_seconds(result, "factorization") : 0.0));

    // 9. The bundle: mesh with atlas coordinates, albedo, lobe, cube-maps (object.glb).
    Bundle bundle = run_stage(result, "bundle", [&] {
        Bundle b = make_bundle(capture.mesh, atlas.corner_uv, texture.image, lobe);
        b.lobe_status = lobe_status;
        if (cubes) {
            const auto to_cube = [](const factorization::Cubemap& c) {
                BundleCubeMap out{c.res, {}};
                out.rgb.reserve(c.texels.size() * 3);
                for (const glm::vec3& t : c.texels) out.rgb.insert(out.rgb.end(), {t.x, t.y, t.z});
                return out;
            };
            b.cube_g = to_cube(cubes->cube_g);
            b.cube_h = to_cube(cubes->cube_h);
            for (const factorization::FactorTerm& t : cubes->extra)
                b.extra_terms.push_back({to_cube(t.cube_g), to_cube(t.cube_h)});
            b.factor_param = cubes->param;
            b.factor_warp = cubes->warp;
        }
        b.info = {{"generator", std::string("specula ") + kVersion}, {"capture", fs::absolute(capture.desc.dir).string()}};
        write_bundle(config.out_dir / "object.glb", b);
        return b;
    });

    // 10. Self-evaluation: every frame re-rendered from the bundle, train and test, masked and full.
    json evaluation_report = nullptr;
    if (!config.evaluate) {
        result.left_out.push_back({"evaluation", "--no-evaluate"});
    } else {
        gpu::Context* render_ctx = render_context();
        if (render_ctx == nullptr) {
            result.left_out.push_back({"evaluation", "rendering needs a Vulkan device and none could be had: " + no_device});
        } else {
            const evaluate::EvaluationResult ev = run_stage(result, "evaluation", [&] {
                evaluate::EvaluateOptions eo;
                // A CPU Vulkan driver (lavapipe) runs the metric kernels ~9x slower than the C++ reference.
                eo.metrics_backend = render_ctx->info().kind == gpu::DeviceKind::Cpu ? evaluate::MetricsBackend::Cpu : evaluate::MetricsBackend::Vulkan;
                eo.max_frames_per_split = config.evaluate_max_frames;
                eo.include_train = config.evaluate_train;
                if (config.evaluate_factorized && bundle.cube_g) eo.render.specular = render::SpecularModel::Factorized;
                if (config.write_sheets) eo.sheet_dir = config.out_dir / "sheets";
                eo.bundle_name = "object.glb";
                eo.progress = true;
                return evaluate::evaluate(*render_ctx, bundle, capture, eo);
            });
            log::info(evaluate::format_summary(ev));
            json full = evaluate::to_json(ev);
            write_text_file(config.out_dir / "evaluation.json", full.dump(2) + "\n");
            evaluation_report = full;
            evaluation_report.erase("frames"); // per frame: evaluation.json
            evaluation_report["file"] = "evaluation.json";
            // Sheets as paths relative to the output folder (the report may move with it).
            json sheets = json::array();
            for (const fs::path& sp : ev.sheets) sheets.push_back(fs::relative(sp, config.out_dir).generic_string());
            evaluation_report["sheets"] = sheets;
            if (!config.evaluate_train) result.left_out.push_back({"evaluation of the train frames", "test frames only (evaluate_train off)"});
        }
    }

    // report.html, then report.json last: its presence means the outputs above are complete.
    result.total_seconds = total.seconds();
    json stages = json::array();
    for (const StageRecord& s : result.stages) stages.push_back({{"name", s.name}, {"seconds", s.seconds}});
    json left_out = json::array();
    for (const LeftOut& l : result.left_out) left_out.push_back({{"what", l.what}, {"why", l.why}});
    result.report = {
        {"specula_version", kVersion},
        {"capture",
         {{"path", fs::absolute(capture.desc.dir).string()},
          {"views", capture.views.size()},
          {"train_frames", capture.frame_count(Split::Train)},
          {"test_frames", capture.frame_count(Split::Test)},
          {"mesh_triangles", capture.mesh.triangle_count()},
          {"load_seconds", capture.load_seconds},
          {"preloaded", preloaded != nullptr}}},
        {"device", device},
        {"planner", plan.to_json()},
        {"stages", stages},
        {"total_seconds", result.total_seconds},
        {"gpu_dispatches", gpu_dispatches},
        {"atlas", atlas_json(atlas.summary, config.atlas)},
        {"particles", {{"count", particles.particles.size()}, {"interior", particles.interior}, {"gutter", particles.gutter}}},
        {"visibility", visibility_json(visibility.stats)},
        {"diffuse", lambert_json(solve, lambert, particle_backend)},
        {"albedo_refinement", refinement},
        {"specular", specular},
        {"factorization", factorization_report},
        {"bundle", {{"file", "object.glb"}, {"has_lobe", bundle.lobe.has_value()}, {"has_cubemaps", bundle.cube_g.has_value()}}},
        {"evaluation", evaluation_report},
        {"albedo_texture",
         {{"files", {"albedo.exr", "albedo.png"}},
          {"width", texture.image.width},
          {"height", texture.image.height},
          {"texels", texture.stats.texels},
          {"solved", texture.stats.solved},
          {"filled_same_patch", texture.stats.filled_same_patch},
          {"filled_across_patches", texture.stats.filled_across},
          {"filled_global_mean", texture.stats.filled_global},
          {"filled_gutter_dilation", texture.stats.filled_dilation},
          {"filled_pull_push", texture.stats.filled_pull_push}}},
        {"left_out", left_out},
        {"warnings", result.warnings}};
    if (config.write_html)
        write_text_file(config.out_dir / "report.html", report::report_html(result.report, {.out_dir = config.out_dir}));
    write_text_file(config.out_dir / "report.json", result.report.dump(2) + "\n");
    return result;
}

} // namespace specula
