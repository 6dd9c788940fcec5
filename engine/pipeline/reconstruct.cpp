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
#include "visibility/visibility.h"

#include <memory>
#include <optional>
#include <utility>

namespace specula {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// Times one stage, logs it, and records it in the result.
template <class Fn>
auto run_stage(ReconstructResult& result, const std::string& name, Fn&& fn) {
    log::info("[" + name + "] ...");
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
    return {{"width", s.width},
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

ReconstructResult reconstruct(const ReconstructConfig& config) {
    ReconstructResult result;
    Stopwatch total;
    if (config.out_dir.empty()) throw UsageError("no output folder given");

    // 1. Capture: description, mesh, train and test images (test frames are only counted here).
    const Capture capture = run_stage(result, "load", [&] {
        return load_capture(config.capture, CaptureLoadOptions{.threads = static_cast<int>(config.threads)});
    });
    result.warnings = capture.warnings;
    for (const std::string& w : capture.warnings) log::warn(w);
    if (capture.frame_count(Split::Train) == 0)
        throw InputError(capture_json_path(config.capture), "frames", "no train frames: nothing to reconstruct from");

    // Cameras of the views that have train frames size the atlas (test views must not).
    std::vector<Camera> train_cameras;
    for (const View& view : capture.views)
        for (std::size_t f : view.frames)
            if (capture.desc.frames[f].split == Split::Train) {
                train_cameras.push_back(view.camera);
                break;
            }

    // 2. Atlas and particles.
    const Atlas atlas = run_stage(result, "atlas", [&] { return build_atlas(capture.mesh, train_cameras, config.atlas); });
    log::info(describe(atlas.summary));
    const ParticleSet particles = run_stage(result, "particles", [&] { return build_particles(capture.mesh, atlas); });

    // 3. Visibility: Embree occlusion rays unless the mesh is convex.
    const Visibility visibility = run_stage(result, "visibility", [&] {
        const RayScene scene(capture.mesh);
        const VisibilityInputs inputs = visibility_inputs(capture);
        return compute_visibility(particles.particles, capture.mesh, scene, inputs.views, inputs.lights,
                                  VisibilityOptions{.threads = config.threads,
                                                    .force_rays = config.force_occlusion_rays,
                                                    .frame_view = inputs.frame_view});
    });
    if (!visibility.stats.skipped.empty())
        result.left_out.push_back({"occlusion rays (visibility and shadows)", visibility.stats.skipped});

    // 4. Diffuse solve on the chosen backend.
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
    const LambertInputs lambert_in = lambert_inputs(capture, particles.particles, visibility);
    LambertOutputs solve = run_stage(result, "diffuse solve", [&] {
        return lambert_solve(lambert_in, config.lambert, config.backend, ctx.get());
    });
    log::info(describe(solve.summary, config.lambert.mode));
    if (ctx) device["validation_messages"] = ctx->validation_message_count();
    if (solve.summary.fallback > 0)
        result.left_out.push_back({"photometric solve for " + std::to_string(solve.summary.fallback) + " particles",
                                   "fewer than three usable, non-coplanar light directions in their best view: "
                                   "albedo mode (known normals) used instead"});

    // 5. Specular: residual samples, then the Lafortune fit when the residuals hold energy
    //    above the noise (pipeline.md sections 4, 5 and 9) or when forced.
    json specular = nullptr;
    std::optional<LafortuneFitRgb> fitted_lobe;
    if (config.specular == SpecularMode::Off) {
        result.left_out.push_back({"specular fit (residual samples and Lafortune lobe)", "--specular off"});
    } else {
        const ResidualOptions residual_options{.min_light_cos = config.lambert.min_light_cos, .max_binding_bytes = 0,
                                               .max_albedo_spread = 0.02f};
        ResidualSamples rs = run_stage(result, "residual samples", [&] {
            return residual_samples(lambert_in, solve, residual_options, config.backend, ctx.get());
        });
        const ResidualEnergy energy =
            residual_energy(rs.samples, static_cast<double>(config.lambert.noise_sigma), config.specular_energy_threshold);
        const std::string energy_text = "mean squared residual " + std::to_string(energy.mean_square) + " = " +
                                        std::to_string(energy.ratio) + " noise variances (threshold " +
                                        std::to_string(energy.threshold) + ")";
        log::info("residual samples: " + std::to_string(rs.counts.used) + " used; " + energy_text);
        if (config.specular == SpecularMode::Auto && !energy.has_specular) {
            result.left_out.push_back({"specular fit, factorization and specular pass",
                                       "the residuals hold no more energy than the noise: " + energy_text});
            specular = specular_json(rs, energy, nullptr, 0.0, config.backend, "skipped: no specular energy (--specular auto)");
        } else {
            Stopwatch fit_watch;
            std::size_t fit_samples = 0;
            const auto run_fit = [&](const char* stage) {
                return run_stage(result, stage, [&] {
                    LafortuneFitOptions fo = config.lafortune;
                    fo.noise_sigma = static_cast<double>(config.lambert.noise_sigma);
                    std::vector<LafortuneSample> all = to_lafortune_samples(rs.samples);
                    if (config.max_fit_samples != 0 && all.size() > config.max_fit_samples) {
                        const std::size_t stride = (all.size() + config.max_fit_samples - 1) / config.max_fit_samples;
                        std::size_t k = 0;
                        for (std::size_t i = 0; i < all.size(); i += stride) all[k++] = all[i];
                        all.resize(k);
                    }
                    fit_samples = all.size();
                    return fit_lafortune(all, fo);
                });
            };
            LafortuneFitRgb fit = run_fit("lafortune fit");
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
                LambertOptions lo = config.lambert;
                lo.lobe = previous;
                solve = run_stage(result, "diffuse solve" + tag, [&] { return lambert_solve(lambert_in, lo, config.backend, ctx.get()); });
                rs = run_stage(result, "residual samples" + tag, [&] {
                    return residual_samples(lambert_in, solve, residual_options, config.backend, ctx.get());
                });
                fit = run_fit(("lafortune fit" + tag).c_str());
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
            const double fit_seconds = fit_watch.seconds();
            fitted_lobe = fit;
            for (int k = 0; k < 3; ++k)
                log::info(std::string("lafortune ") + "rgb"[k] + ": Cx " + std::to_string(fit.channel[k].cx) + " Cz " +
                          std::to_string(fit.channel[k].cz) + " N " + std::to_string(fit.channel[k].n) + " (" +
                          to_string(fit.channel[k].status) + ")");
            specular = specular_json(rs, energy, &fit, fit_seconds, config.backend,
                                     config.specular == SpecularMode::On ? "fitted (--specular on)"
                                                                         : "fitted: residuals above the noise (--specular auto)");
            specular["samples"]["fitted"] = fit_samples; // stride subsample (max_fit_samples)
            specular["joint"] = {{"rounds", rounds}, {"stop", joint_stop}, {"tolerance", config.joint_tolerance}};
        }
    }

    // 6. Albedo texture: inpaint what no view saw, write linear EXR and sRGB PNG.
    const AlbedoTexture texture = run_stage(result, "albedo texture", [&] {
        AlbedoTexture t = make_albedo_texture(atlas, particles.particles, solve);
        write_albedo_texture(t, config.out_dir / "albedo");
        return t;
    });

    // 7. Factorization of the lobe into the two cube-maps (Kautz and McCool), channels
    //    whose fit did not converge carry no lobe (they render diffuse only, and say so).
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
        cubes = run_stage(result, "factorization", [&] {
            const auto backend = config.backend == LambertBackend::Vulkan ? factorization::FactorizationBackend::Vulkan
                                                                          : factorization::FactorizationBackend::Cpu;
            return factorization::factorize(*lobe, {}, backend, ctx.get());
        });
        const factorization::DirectError err =
            factorization::direct_relative_rms(*lobe, cubes->decomposition, &cubes->cube_g, &cubes->cube_h, 1u << 16);
        factorization_report = {{"grid_h", cubes->resolution.grid_h},
                                {"grid_d", cubes->resolution.grid_d},
                                {"cube_g", cubes->resolution.cube_g},
                                {"cube_h", cubes->resolution.cube_h},
                                {"resolution_reason", cubes->resolution.reason},
                                {"relative_rms_vs_lobe_grid", err.grid},
                                {"relative_rms_vs_lobe_cubemaps", err.cube},
                                {"seconds", cubes->timings.total_s}};
        if (const auto ns = cubes->timings.gpu_total_ns()) factorization_report["gpu_ms"] = *ns * 1e-6;
    } // else: the entries above already say why there is no lobe

    // 8. The bundle: mesh with atlas coordinates, albedo, lobe, cube-maps (object.glb).
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
        }
        b.info = {{"generator", "specula 0.1.0"}, {"capture", fs::absolute(capture.desc.dir).string()}};
        write_bundle(config.out_dir / "object.glb", b);
        return b;
    });

    // 9. Self-evaluation: every frame re-rendered from the bundle, train and test, masked and full.
    json evaluation_report = nullptr;
    if (!config.evaluate) {
        result.left_out.push_back({"evaluation", "--no-evaluate"});
    } else {
        std::unique_ptr<gpu::Context> eval_ctx;
        std::string no_device;
        if (!ctx) {
            try {
                eval_ctx = std::make_unique<gpu::Context>(gpu::ContextOptions{.device = config.device});
            } catch (const std::exception& e) {
                no_device = e.what();
            }
        }
        gpu::Context* render_ctx = ctx ? ctx.get() : eval_ctx.get();
        if (render_ctx == nullptr) {
            result.left_out.push_back({"evaluation", "rendering needs a Vulkan device and none could be had: " + no_device});
        } else {
            const evaluate::EvaluationResult ev = run_stage(result, "evaluation", [&] {
                evaluate::EvaluateOptions eo;
                // A CPU Vulkan driver (lavapipe) runs the metric kernels ~9x slower than the C++ reference.
                eo.metrics_backend = render_ctx->info().kind == gpu::DeviceKind::Cpu ? evaluate::MetricsBackend::Cpu : evaluate::MetricsBackend::Vulkan;
                eo.max_frames_per_split = config.evaluate_max_frames;
                eo.sheet_dir = config.out_dir / "sheets";
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
        }
    }

    // report.json, written last: its presence means the outputs above are complete.
    result.total_seconds = total.seconds();
    json stages = json::array();
    for (const StageRecord& s : result.stages) stages.push_back({{"name", s.name}, {"seconds", s.seconds}});
    json left_out = json::array();
    for (const LeftOut& l : result.left_out) left_out.push_back({{"what", l.what}, {"why", l.why}});
    result.report = {
        {"specula_version", "0.1.0"},
        {"capture",
         {{"path", fs::absolute(capture.desc.dir).string()},
          {"views", capture.views.size()},
          {"train_frames", capture.frame_count(Split::Train)},
          {"test_frames", capture.frame_count(Split::Test)},
          {"mesh_triangles", capture.mesh.triangle_count()}}},
        {"device", device},
        {"stages", stages},
        {"total_seconds", result.total_seconds},
        {"atlas", atlas_json(atlas.summary, config.atlas)},
        {"particles", {{"count", particles.particles.size()}, {"interior", particles.interior}, {"gutter", particles.gutter}}},
        {"visibility", visibility_json(visibility.stats)},
        {"diffuse", lambert_json(solve, config.lambert, config.backend)},
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
          {"filled_global_mean", texture.stats.filled_global}}},
        {"left_out", left_out},
        {"warnings", result.warnings}};
    write_text_file(config.out_dir / "report.json", result.report.dump(2) + "\n");
    return result;
}

} // namespace specula
