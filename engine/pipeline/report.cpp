#include "pipeline/report.h"

#include "core/file_util.h"
#include "report/report_html.h"
#include "specula/version.h"

#include <cmath>
#include <filesystem>

namespace specula {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

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
            {"rays_completed", s.rays_completed},
            {"depth_rays", s.depth_rays},
            {"surface_maps", s.surface_maps},
            {"footprint_rejected_pairs", s.footprint_rejected},
            {"shadow_map_rays", s.shadow_map_rays},
            {"shadow_edge_rejected_pairs", s.shadow_edge_rejected},
            {"light_rays_answered_by_shadow_maps", s.rays_answered},
            {"convex", s.convexity.convex},
            {"convexity_reason", s.convexity.reason},
            {"occlusion_rays_skipped", s.skipped},
            {"seconds", s.seconds}};
}

json lambert_json(const LambertOutputs& out, const LambertOptions& o, Backend backend) {
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
                {"rejected_shadow_edge", s.rejected_low},
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
              {"pair_chunks", s.pair_chunks},
              {"record_groups", s.record_groups},
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

json coated_json(const CoatedFit& c) {
    return {{"eta", c.params.eta},
            {"alpha", c.params.alpha},
            {"tint", json::array({c.params.tint.x, c.params.tint.y, c.params.tint.z})},
            {"status", to_string(c.status)},
            {"reason", c.reason},
            {"standard_errors", {{"eta", c.std_error_eta}, {"alpha", c.std_error_alpha}}},
            {"diffuse_scale", c.diffuse_scale},
            {"determined", {{"eta", c.eta_determined}, {"alpha", c.alpha_determined}}},
            {"condition", std::isfinite(c.condition) ? json(c.condition) : json(nullptr)},
            {"cost", c.cost},
            {"rms", c.rms},
            {"iterations", c.iterations},
            {"samples", c.samples},
            {"seconds", c.seconds}};
}

json joint_json(const JointResult& joint) {
    json rounds = json::array();
    for (const JointRound& r : joint.rounds) {
        json round = {{"round", r.round}, {"max_relative_change", r.max_relative_change}, {"residual_samples", r.residual_samples}};
        if (r.validation_mse) round["validation_mse"] = *r.validation_mse;
        if (r.rejected) round["rejected"] = true;
        if (r.own_albedo) round["own_albedo"] = true;
        rounds.push_back(std::move(round));
    }
    json j = {{"rounds", rounds}, {"accepted", joint.accepted}, {"stop", joint.stop}};
    if (joint.first_validation_mse) j["first_validation_mse"] = *joint.first_validation_mse;
    if (joint.restart) {
        const JointRestart& r = *joint.restart;
        const auto mse = [](const std::optional<double>& v) { return v ? json(*v) : json(nullptr); };
        j["restart"] = {{"why", "the rounds ended at an index near 1: estimated again from a common dielectric's"},
                        {"first_eta", r.first_eta},
                        {"first_validation_mse", mse(r.first_mse)},
                        {"common_eta", r.common_eta},
                        {"common_validation_mse", mse(r.common_mse)},
                        {"kept", r.common_kept ? "common" : "first"}};
    }
    return j;
}

// The model choice (pipeline.md section 5.6): every candidate's parameters, validation error and time.
json material_choice_json(const SpecularStage& s) {
    json candidates = json::array();
    for (const MaterialCandidate& c : s.candidates) {
        json m = {{"family", to_string(c.fit.family)},
                  {"status", c.fit.status()},
                  {"summary", c.fit.describe()},
                  {"validation_mse", c.validation_mse ? json(*c.validation_mse) : json(nullptr)},
                  {"validation_psnr_linear_db",
                   c.validation_mse && *c.validation_mse > 0.0 ? json(-10.0 * std::log10(*c.validation_mse)) : json(nullptr)},
                  {"seconds", c.seconds},
                  {"screen_samples", c.screen_samples},
                  {"joint", joint_json(c.joint)}};
        if (c.fit.coated) m["coated"] = coated_json(*c.fit.coated);
        candidates.push_back(std::move(m));
    }
    json j = {{"family", s.fit ? to_string(s.fit->family) : "diffuse_only"},
              {"choice", s.choice},
              {"validation_frames", s.validation_frames},
              {"candidates", candidates}};
    if (s.diffuse_only_mse)
        j["diffuse_only"] = {{"validation_mse", *s.diffuse_only_mse},
                             {"validation_psnr_linear_db", *s.diffuse_only_mse > 0.0 ? json(-10.0 * std::log10(*s.diffuse_only_mse)) : json(nullptr)}};
    return j;
}

json specular_json(const SpecularStage& s, double joint_tolerance) {
    if (!s.residuals_ran) return nullptr;
    const ResidualSamples& rs = s.residuals;
    const ResidualCounts& c = rs.counts;
    const ResidualEnergy& energy = s.energy;
    json j = {{"decision", s.decision},
              {"backend", to_string(s.backend)},
              {"samples",
               {{"candidates", c.candidates},
                {"used", c.used},
                {"kept_stride", rs.keep_stride}, // every k-th used sample kept (memory bound, residuals.h)
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
    if (!s.fit) {
        j["lobe"] = nullptr;
        // Diffuse only may have beaten the families on the validation frames (decide_specular "validate").
        j["material"] = s.candidates.empty() ? json(nullptr) : material_choice_json(s);
        j["seconds"] = seconds;
        return j;
    }
    seconds["fit"] = s.fit_seconds;
    j["material"] = material_choice_json(s);
    if (s.fit->lafortune) {
        const LafortuneFitRgb& fit = *s.fit->lafortune;
        double cx[3], cz[3], n[3], ecx[3], ecz[3], en[3], cond[3], cost[3], rms[3];
        json status = json::array(), reason = json::array(), iterations = json::array();
        for (int k = 0; k < 3; ++k) {
            const LafortuneChannelFit& f = fit.channel[k];
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
        j["coated"] = coated_json(*s.fit->coated);
    }
    j["seconds"] = seconds;
    j["samples"]["fitted"] = s.fit_samples; // stride subsample (max_fit_samples)
    j["joint"] = joint_json(s.joint);
    j["joint"]["tolerance"] = joint_tolerance;
    // Out of rounds while still moving (the fit's status and reason say what it means).
    j["joint"]["settled"] = !s.joint.unsettled_change.has_value();
    if (s.joint.unsettled_change) j["joint"]["unsettled_change"] = *s.joint.unsettled_change;
    if (s.joint.unsettled_remaining) j["joint"]["unsettled_remaining"] = *s.joint.unsettled_remaining;
    // The albedo solved once more with the final material (the rounds ended with it still moving).
    j["joint"]["final_solve"] = s.final_solve;
    j["joint"]["seconds"] = s.seconds; // the candidates, the final fit and its joint rounds
    return j;
}

json refinement_json(const PipelineRun& run, const RefineStage& r) {
    if (!r.refined) return nullptr;
    json rounds = json::array();
    for (std::size_t i = 0; i < r.refined->rounds.size(); ++i) {
        const AlbedoRefineRound& round = r.refined->rounds[i];
        json j = {{"round", i + 1}, {"mean_abs_change", round.mean_abs_change}, {"corrected_particles", round.corrected}};
        if (r.pixel_fit) {
            j["rms_residual_before"] = r.pixel_fit->rms[i];
            j["rms_residual_after"] = r.pixel_fit->rms[i + 1];
        } else {
            j["render_seconds"] = round.render_seconds;
            j["solve_seconds"] = round.solve_seconds;
        }
        rounds.push_back(j);
    }
    json out = {{"method", to_string(r.method)}, {"rounds", rounds}, {"seconds", run.seconds("albedo refinement")}};
    if (r.pixel_fit) {
        const PixelFitStats& p = *r.pixel_fit;
        out["formula"] = "min over the atlas A of sum_i w_i (bilinear_A(t_i) - a_i)^2 + mu sum_p d_p (A_p - A0_p)^2: t_i the "
                         "atlas point of train pixel i's centre ray, a_i the albedo its lit frames show (the solve's "
                         "material and band test), w_i = sum of its kept frames' E^2, A0 the solve's albedo; Jacobi "
                         "iterations, each texel kept within the least and largest albedo of the pixels that read it "
                         "(refine/pixel_fit.h)";
        out["pixels"] = p.pixels;
        out["pixels_used"] = p.pixels_used;
        out["samples_used"] = p.samples_used;
        out["ray_seconds"] = p.ray_seconds;
        out["sample_seconds"] = p.sample_seconds;
        out["fit_seconds"] = p.fit_seconds;
    } else {
        out["formula"] = "A <- A + s [w (S(captured) - S(render(A))) - lambda (A - A_0)]: S the diffuse solve's robust "
                         "combination over views, render without cast shadows with the solve's lobe, w the best view's n.v "
                         "ramp, lambda a prior toward the solve's albedo A_0, s the step (refine/albedo_refine.h)";
    }
    return out;
}

/// Every parametrization's factorization as the choice saw it (only the forced one when forced).
json param_candidates_json(const factorization::ParamChoice& c) {
    const auto candidate = [](const factorization::ParamCandidate& k) {
        return json{{"grid_h", k.resolution.grid_h},
                    {"grid_d", k.resolution.grid_d},
                    {"terms", k.terms.count},
                    {"matrix_relative_rms", k.terms.matrix_rms},
                    {"relative_rms_vs_lobe_cubemaps", k.direct_rms}};
    };
    json out = json::object();
    for (const FactorParam p : {FactorParam::Gshd, FactorParam::Mirrored, FactorParam::Warped})
        if (c.of(p).computed) out[to_string(p)] = candidate(c.of(p));
    // The warped candidate is then the one with the warp shared by the channels (the kept one).
    if (c.warped_per_channel) out["warped_per_channel"] = candidate(*c.warped_per_channel);
    return out;
}

json factorization_json(const PipelineRun& run, const FactorizationStage& f) {
    if (!f.cubes) return nullptr;
    const factorization::Factorization& cubes = *f.cubes;
    json per_term = json::array();
    for (std::size_t i = 0; i < f.per_term.size(); ++i) {
        json t = {{"terms", i + 1}, {"relative_rms_vs_lobe_grid", f.per_term[i].grid}, {"relative_rms_vs_lobe_cubemaps", f.per_term[i].cube}};
        if (i < cubes.terms.matrix_rms.size()) t["matrix_relative_rms"] = cubes.terms.matrix_rms[i];
        per_term.push_back(std::move(t));
    }
    const factorization::DirectError& err = f.per_term.back();
    json j = {{"grid_h", cubes.resolution.grid_h},
              {"grid_d", cubes.resolution.grid_d},
              {"cube_g", cubes.resolution.cube_g},
              {"cube_h", cubes.resolution.cube_h},
              {"resolution_reason", run.result.plan.find("factorization_grid")->reason},
              {"relative_rms_vs_lobe_grid", err.grid},
              {"relative_rms_vs_lobe_cubemaps", err.cube},
              {"terms", cubes.term_count()},
              {"terms_reason", cubes.terms.reason},
              {"terms_target", cubes.terms.target},
              {"per_term", std::move(per_term)},
              {"parametrization", to_string(cubes.cubes.param)},
              {"parametrization_forced", cubes.param_choice.forced},
              {"parametrization_reason", cubes.param_choice.reason},
              {"parametrization_candidates", param_candidates_json(cubes.param_choice)},
              {"seconds", cubes.timings.total_s}};
    if (cubes.cubes.param == FactorParam::Warped) j["warp"] = {cubes.cubes.warp.x, cubes.cubes.warp.y, cubes.cubes.warp.z, cubes.cubes.warp.w};
    if (const auto ns = cubes.timings.gpu_total_ns()) j["gpu_ms"] = *ns * 1e-6;
    return j;
}

json evaluation_json(const PipelineRun& run, const std::optional<evaluate::EvaluationResult>& ev) {
    if (!ev) return nullptr;
    json j = evaluate::to_json(*ev, run.config.out_dir);
    j.erase("frames"); // per frame: evaluation.json
    j["file"] = "evaluation.json";
    // Sheets as paths relative to the output folder (the report may move with it).
    json sheets = json::array();
    for (const fs::path& sp : ev->sheets) sheets.push_back(fs::relative(sp, run.config.out_dir).generic_string());
    j["sheets"] = sheets;
    return j;
}

// What ordinary viewers show (null without an evaluation): the core material in the bundle, its
// fit, and its masked figures beside Specula's own renderer's on the same frames.
json viewer_json(const SpecularStage& specular, const Bundle& bundle, const std::optional<evaluate::EvaluationResult>& viewer,
                 const std::optional<evaluate::EvaluationResult>& evaluation) {
    json j = {{"what", "the bundle's glTF core material (roughnessFactor, KHR_materials_ior, KHR_materials_specular, "
                       "KHR_materials_clearcoat, the base colour texture) rendered with glTF's BRDF as three.js r187 draws a point "
                       "light, direct light only: what ordinary viewers show"},
              {"material", to_json(bundle.core.value_or(CoreMaterial{}))},
              {"fit", specular.core ? to_json(*specular.core) : json(nullptr)}};
    if (!viewer || !evaluation) return j;
    for (const Split split : {Split::Train, Split::Test}) {
        double core_d = 0, core_l = 0, own_d = 0, own_l = 0;
        std::size_t n = 0;
        for (const evaluate::FrameEvaluation& v : viewer->frames) {
            if (v.split != split) continue;
            const auto it = std::find_if(evaluation->frames.begin(), evaluation->frames.end(),
                                         [&](const evaluate::FrameEvaluation& e) { return e.frame == v.frame; });
            if (it == evaluation->frames.end() || v.masked.pixels == 0) continue;
            core_d += v.masked_display.psnr, core_l += v.masked.psnr;
            own_d += it->masked_display.psnr, own_l += it->masked.psnr;
            ++n;
        }
        if (n == 0) continue;
        const double k = 1.0 / static_cast<double>(n);
        j[split == Split::Train ? "train" : "test"] = {{"frames", n},
                                                       {"psnr_display", core_d * k},
                                                       {"psnr_linear", core_l * k},
                                                       {"specula_psnr_display", own_d * k},
                                                       {"specula_psnr_linear", own_l * k}};
    }
    j["seconds"] = viewer->timings.total_s;
    return j;
}

// The refined normals (null when left out): how many particles, their angle to the mesh normals.
json normal_map_json(const PipelineRun& run, const NormalMapStage& n, const Bundle& bundle) {
    if (!n.normals || !bundle.normal_map) return nullptr;
    const NormalMapStats& s = n.stats;
    return {{"in", "object.glb (material.normalTexture, tangent space, with the TANGENT attribute)"},
            {"width", bundle.normal_map->width},
            {"height", bundle.normal_map->height},
            {"particles", s.particles},
            {"refined", s.refined},
            {"angle_to_mesh_normal_deg",
             {{"mean", s.mean_angle_deg}, {"median", s.median_angle_deg}, {"p95", s.p95_angle_deg}, {"max", s.max_angle_deg}}},
            {"seconds", run.seconds("photometric solve (normal map)")}}; // the encoding is part of the bundle stage
}

// The indirect light (null when left out): the method, the transfer, the rounds, and the
// evaluation's figures with and without it.
json indirect_json(const IndirectStage& s, const std::optional<evaluate::EvaluationResult>& ev) {
    if (!s.on()) return nullptr;
    json rounds = json::array();
    for (const IndirectRound& r : s.rounds)
        rounds.push_back({{"albedo_change", r.albedo_change},
                          {"seconds", r.seconds},
                          {"with_material", r.material},
                          {"pixels_left_out", r.pixels_left_out}});
    json j = {{"method", "inverse global illumination (Yu, Debevec, Malik and Hawkins 1999): the light that the albedo "
                         "estimate sends from particle to particle through a transfer of stratified cosine-weighted rays, "
                         "removed from the train frames before each solve and added to the evaluation's renders"},
              {"sources", s.options.lobe_directions
                              ? "diffuse; the fitted lobe's first bounce sent along each transfer ray (f_s toward it), its "
                                "later bounces spread diffusely"
                              : "diffuse, with the fitted lobe's directional albedo spread diffusely (--indirect-lobe spread)"},
              {"viewer", "specula-view shows direct light only; specula render and specula evaluate add this light from the bundle "
                         "alone (--indirect, on by default for this bundle)"},
              {"bounces", s.options.bounces},
              {"gather", s.backend_reason},
              {"transfer_rows", s.transfer->rows},
              {"transfer_block_texels", s.transfer_stats.block},
              {"rays_per_row", s.transfer->rays_per_row},
              {"transfer_entries", s.transfer->entry_count()},
              {"rays_cast", s.transfer_stats.rays},
              {"rays_reaching_the_object", s.transfer_stats.hits},
              {"transfer_seconds", s.transfer_stats.seconds},
              {"p99_codes_first_solve", s.measure ? json(s.measure->p99_codes) : json(nullptr)},
              {"shadow_ratio", s.measure && s.measure->shadow_ratio ? json(*s.measure->shadow_ratio) : json(nullptr)},
              {"rounds", rounds},
              {"seconds", s.seconds}};
    if (ev && ev->direct_metrics) {
        const auto split = [&](const metrics::MetricsSummary& with, const metrics::MetricsSummary& with_d,
                               const metrics::MetricsSummary& without, const metrics::MetricsSummary& without_d) {
            return json{{"with", {{"psnr_linear", with.psnr}, {"psnr_display", with_d.psnr}, {"q1_linear", with.q1}, {"q1_display", with_d.q1}}},
                        {"without", {{"psnr_linear", without.psnr}, {"psnr_display", without_d.psnr}, {"q1_linear", without.q1},
                                     {"q1_display", without_d.q1}}}};
        };
        json e = json::object();
        if (ev->train_frames > 0)
            e["train_masked"] = split(ev->metrics.train_masked, ev->display_metrics.train_masked, ev->direct_metrics->train_masked,
                                      ev->direct_display_metrics->train_masked);
        if (ev->test_frames > 0)
            e["test_masked"] = split(ev->metrics.test_masked, ev->display_metrics.test_masked, ev->direct_metrics->test_masked,
                                     ev->direct_display_metrics->test_masked);
        j["evaluation"] = e;
    }
    return j;
}

} // namespace

json report_json(PipelineRun& run, const ReportInputs& in) {
    const ReconstructResult& result = run.result;
    json stages = json::array();
    for (const StageRecord& s : result.stages) stages.push_back({{"name", s.name}, {"seconds", s.seconds}});
    json left_out = json::array();
    for (const LeftOut& l : result.left_out) left_out.push_back({{"what", l.what}, {"why", l.why}});
    const AlbedoTextureStats& ts = in.texture.stats;
    return {{"specula_version", kVersion},
            {"capture",
             {{"path", path_relative_to(in.capture.desc.dir, run.config.out_dir)}, // no machine path
              {"views", in.capture.views.size()},
              {"train_frames", in.capture.frame_count(Split::Train)},
              {"test_frames", in.capture.frame_count(Split::Test)},
              {"mesh_triangles", in.capture.mesh.triangle_count()},
              {"load_seconds", in.capture.load_seconds},
              {"preloaded", in.preloaded}}},
            {"device", run.device_json()},
            {"planner", result.plan.to_json()},
            {"stages", stages},
            {"total_seconds", result.total_seconds},
            {"gpu_dispatches", run.gpu_dispatches()},
            {"atlas", atlas_json(in.geometry.atlas.summary, run.config.atlas)},
            {"particles",
             {{"count", in.geometry.particles.particles.size()},
              {"interior", in.geometry.particles.interior},
              {"gutter", in.geometry.particles.gutter}}},
            {"visibility", visibility_json(in.visibility.visibility.stats)},
            {"diffuse", lambert_json(in.diffuse.solve, in.diffuse.options, run.particle_backend())},
            {"indirect", indirect_json(in.indirect, in.evaluation)},
            {"albedo_refinement", refinement_json(run, in.refine)},
            {"specular", specular_json(in.specular, run.config.joint_tolerance)},
            {"factorization", factorization_json(run, in.factorization)},
            {"bundle",
             {{"file", "object.glb"},
              {"has_lobe", in.bundle.material.specular.has_value()},
              {"has_cubemaps", in.bundle.material.factorized.has_value()},
              {"has_normal_map", in.bundle.normal_map.has_value()}}},
            {"normal_map", normal_map_json(run, in.normals, in.bundle)},
            {"evaluation", evaluation_json(run, in.evaluation)},
            {"viewer", viewer_json(in.specular, in.bundle, in.viewer, in.evaluation)},
            {"albedo_texture",
             {{"files", {"albedo.exr", "albedo.png"}},
              {"width", in.texture.image.width},
              {"height", in.texture.image.height},
              {"texels", ts.texels},
              {"solved", ts.solved},
              {"filled_same_patch", ts.filled_same_patch},
              {"filled_across_patches", ts.filled_across},
              {"filled_global_mean", ts.filled_global},
              {"filled_gutter_dilation", ts.filled_dilation},
              {"filled_pull_push", ts.filled_pull_push}}},
            {"left_out", left_out},
            {"warnings", result.warnings}};
}

void write_reports(const PipelineRun& run, const json& report) {
    if (run.config.write_html)
        write_text_file(run.config.out_dir / "report.html", report::report_html(report, {.out_dir = run.config.out_dir}));
    write_text_file(run.config.out_dir / "report.json", report.dump(2) + "\n");
}

} // namespace specula
