#include "pipeline/planner.h"

#include "core/error.h"
#include "core/format.h"
#include "indirect/indirect.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace specula {

using nlohmann::json;

namespace {

} // namespace

const char* to_string(Toggle t) noexcept {
    switch (t) {
    case Toggle::Auto: return "auto";
    case Toggle::On: return "on";
    case Toggle::Off: return "off";
    }
    return "?";
}

const char* to_string(DiffuseModeChoice m) noexcept {
    switch (m) {
    case DiffuseModeChoice::Auto: return "auto";
    case DiffuseModeChoice::Albedo: return "albedo";
    case DiffuseModeChoice::Photometric: return "photometric";
    }
    return "?";
}

PlanDecision* Plan::find(const std::string& name) {
    for (PlanDecision& d : decisions)
        if (d.name == name) return &d;
    return nullptr;
}

const PlanDecision* Plan::find(const std::string& name) const {
    for (const PlanDecision& d : decisions)
        if (d.name == name) return &d;
    return nullptr;
}

PlanDecision& Plan::add(PlanDecision d) {
    if (PlanDecision* existing = find(d.name)) {
        *existing = std::move(d);
        return *existing;
    }
    decisions.push_back(std::move(d));
    return decisions.back();
}

json Plan::to_json() const {
    json out = json::array();
    for (const PlanDecision& d : decisions) {
        const auto num = [](const std::optional<double>& v) { return v && std::isfinite(*v) ? json(*v) : json(nullptr); };
        out.push_back({{"name", d.name},
                       {"value", d.value},
                       {"mode", d.forced ? "forced" : "auto"},
                       {"skipped", d.skipped},
                       {"reason", d.reason},
                       {"avoided_seconds", num(d.avoided_seconds)},
                       {"measured_seconds", num(d.measured_seconds)},
                       {"cost_basis", d.cost_basis},
                       {"detail", d.detail}});
    }
    return out;
}

// ---- occlusion rays ---------------------------------------------------------------------

PlanDecision decide_occlusion_rays(const ConvexityReport& c, Toggle toggle) {
    PlanDecision d;
    d.name = "occlusion_rays";
    d.forced = toggle != Toggle::Auto;
    d.detail = {{"convex", c.convex},
                {"closed", c.closed},
                {"connected", c.connected},
                {"boundary_edges", c.boundary_edges},
                {"nonmanifold_edges", c.nonmanifold_edges},
                {"reflex_edges", c.reflex_edges},
                {"components", c.components}};
    const bool cast = toggle == Toggle::On || (toggle == Toggle::Auto && !c.convex);
    d.value = cast ? "cast" : "skip";
    d.skipped = !cast;
    if (toggle == Toggle::Auto)
        d.reason = c.convex ? "the mesh is convex (closed, connected, no reflex edge): it cannot shadow or hide itself, "
                              "the facing test is exact"
                            : "the mesh can occlude itself: " + c.reason;
    else if (toggle == Toggle::On)
        d.reason = c.convex ? "--occlusion-rays on: cast although the mesh is convex (they cannot hit anything)"
                            : "--occlusion-rays on (the planner would cast them too: " + c.reason + ")";
    else
        d.reason = c.convex ? "--occlusion-rays off (the planner would skip them too: the mesh is convex)"
                            : "--occlusion-rays off on a mesh that can occlude itself (" + c.reason +
                                  "): shadowed and hidden samples are taken as seen and lit, the result is biased there";
    return d;
}

// ---- diffuse mode -----------------------------------------------------------------------

LightConditioning light_conditioning(const Capture& capture, double min_rcond) {
    LightConditioning lc;
    lc.min_rcond = min_rcond;
    glm::dvec3 lo(1e300), hi(-1e300);
    for (const glm::vec3& p : capture.mesh.positions) {
        lo = glm::min(lo, glm::dvec3(p));
        hi = glm::max(hi, glm::dvec3(p));
    }
    const glm::dvec3 center = capture.mesh.positions.empty() ? glm::dvec3(0.0) : 0.5 * (lo + hi);
    std::vector<double> rconds;
    lc.min_lights = static_cast<std::size_t>(-1);
    for (const View& view : capture.views) {
        Eigen::Matrix3d c = Eigen::Matrix3d::Zero();
        std::size_t lights = 0;
        for (const std::size_t f : view.frames) {
            const FrameDesc& fd = capture.desc.frames[f];
            if (fd.split != Split::Train) continue;
            const glm::dvec3 d = fd.light.position - center;
            const double len = glm::length(d);
            if (!(len > 0.0)) continue;
            const Eigen::Vector3d u(d.x / len, d.y / len, d.z / len);
            c += u * u.transpose();
            ++lights;
        }
        if (lights == 0) continue; // a test-only view
        ++lc.views;
        lc.min_lights = std::min(lc.min_lights, lights);
        double rcond = 0.0;
        if (lights >= 3) {
            const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(c, Eigen::EigenvaluesOnly);
            const Eigen::Vector3d ev = es.eigenvalues(); // ascending
            rcond = ev(2) > 0.0 ? std::max(0.0, ev(0)) / ev(2) : 0.0;
        }
        rconds.push_back(rcond);
        if (lights >= 3 && rcond >= min_rcond) ++lc.capable_views;
        lc.max_lights = std::max(lc.max_lights, lights);
        if (lights >= kNormalMapMinLights && rcond >= kNormalMapMinRcond) ++lc.rich_views;
    }
    if (lc.views == 0) lc.min_lights = 0;
    if (!rconds.empty()) {
        std::sort(rconds.begin(), rconds.end());
        lc.median_rcond = rconds[rconds.size() / 2];
    }
    return lc;
}

PlanDecision decide_diffuse_mode(const LightConditioning& lc, DiffuseModeChoice choice, bool specular_may_run) {
    PlanDecision d;
    d.name = "diffuse_mode";
    d.forced = choice != DiffuseModeChoice::Auto;
    d.detail = {{"train_views", lc.views},
                {"photometric_capable_views", lc.capable_views},
                {"fewest_lights_per_view", lc.min_lights},
                {"median_rcond", lc.median_rcond},
                {"min_rcond", lc.min_rcond},
                {"required_fraction", kPhotometricViewFraction}};
    const bool allowed = lc.views > 0 &&
                         static_cast<double>(lc.capable_views) >= kPhotometricViewFraction * static_cast<double>(lc.views);
    const std::string why = std::to_string(lc.capable_views) + " of " + std::to_string(lc.views) +
                            " train views have >= 3 light directions with rcond >= " + format_text("%.3g", lc.min_rcond) +
                            " (median rcond " + format_text("%.3g", lc.median_rcond) + ", fewest lights in a view " +
                            std::to_string(lc.min_lights) + ")";
    const bool photometric = allowed && !specular_may_run;
    const std::string highlight =
        "the specular stages may run, and the photometric solve would fit a tilted normal to part of each highlight, "
        "hiding specular energy from the energy test: albedo mode (known mesh normals)";
    d.detail["specular_may_run"] = specular_may_run;
    if (choice == DiffuseModeChoice::Auto) {
        d.value = photometric ? "photometric" : "albedo";
        d.skipped = !photometric;
        d.reason = !allowed ? why + ": the lights do not constrain a normal, albedo mode (known normals) everywhere"
                   : specular_may_run ? why + ", but " + highlight
                                      : why + "; --specular off: photometric solve (eq. 3.1, refines normals), albedo mode "
                                              "per particle where its view's lights are coplanar";
    } else {
        d.value = to_string(choice);
        d.reason = std::string("--mode ") + to_string(choice) + " (the planner would choose " +
                   (photometric ? "photometric" : "albedo") + ": " + why + (allowed && specular_may_run ? "; " + highlight : "") +
                   ")";
    }
    return d;
}

bool decided_photometric(const PlanDecision& d) { return d.value == "photometric"; }

// ---- normal map -------------------------------------------------------------------------

PlanDecision decide_normal_map(const LightConditioning& lc, Toggle choice) {
    PlanDecision d;
    d.name = "normal_map";
    d.forced = choice != Toggle::Auto;
    d.detail = {{"train_views", lc.views},
                {"rich_views", lc.rich_views},
                {"most_lights_per_view", lc.max_lights},
                {"min_lights", kNormalMapMinLights},
                {"min_rcond", kNormalMapMinRcond}};
    const bool rich = lc.rich_views > 0;
    const bool on = choice == Toggle::On || (choice == Toggle::Auto && rich);
    d.value = on ? "refined normals" : "none";
    d.skipped = !on;
    const std::string why = std::to_string(lc.rich_views) + " of " + std::to_string(lc.views) + " train views have >= " +
                            std::to_string(kNormalMapMinLights) + " lights with rcond >= " +
                            format_text("%.3g", kNormalMapMinRcond) + " (most lights in a view " +
                            std::to_string(lc.max_lights) + ")";
    if (choice == Toggle::Auto)
        d.reason = rich ? why + ": a photometric rig, the photometric solve refines the normals (the bundle's normal map)"
                        : why + ": too few lights to refine a normal beside the highlights, the mesh normals stay";
    else
        d.reason = std::string("--normal-map ") + (on ? "on" : "off") + " (the planner would " + (rich ? "" : "not ") +
                   "make one: " + why + ")";
    return d;
}

bool decided_normal_map(const PlanDecision& d) { return d.value == "refined normals"; }

// ---- indirect light ---------------------------------------------------------------------

PlanDecision decide_indirect(const ConvexityReport& c, Toggle toggle, const std::optional<IndirectMeasure>& m,
                             double estimated_seconds) {
    PlanDecision d;
    d.name = "indirect";
    d.forced = toggle != Toggle::Auto;
    d.detail = {{"convex", c.convex}, {"min_codes", kIndirectMinCodes}, {"min_shadow_ratio", kIndirectMinShadowRatio}};
    std::string measured;
    bool weak = false, absent = false;
    if (m) {
        d.detail["p99_codes"] = m->p99_codes;
        d.detail["shadow_pixels"] = m->shadow_pixels;
        d.detail["shadow_ratio"] = m->shadow_ratio ? nlohmann::json(*m->shadow_ratio) : nlohmann::json(nullptr);
        weak = m->p99_codes < kIndirectMinCodes;
        absent = m->shadow_ratio && *m->shadow_ratio < kIndirectMinShadowRatio;
        measured = "the first solve's albedo sends " + format_text("%.2f", m->p99_codes) +
                   " 8-bit codes of indirect light to the 99th percentile of the train frames' object pixels (threshold " +
                   format_text("%.2g", kIndirectMinCodes) + "); " +
                   (m->shadow_ratio ? "the " + std::to_string(m->shadow_pixels) + " unlit object pixels show " +
                                          format_text("%.2f", *m->shadow_ratio) + " times the light it predicts there (threshold " +
                                          format_text("%.2g", kIndirectMinShadowRatio) + ")"
                                    : std::to_string(m->shadow_pixels) + " unlit object pixels with a prediction of a code or more: "
                                                                         "too few to check the capture holds it (" +
                                          std::to_string(kIndirectMinShadowPixels) + " needed)");
    }
    const bool on = toggle == Toggle::On || (toggle == Toggle::Auto && !c.convex && !weak && !absent);
    d.value = on ? "inverse global illumination" : "none";
    d.skipped = !on;
    if (toggle == Toggle::Auto) {
        if (c.convex) {
            d.reason = "the mesh is convex (closed, connected, no reflex edge): no point of it sees another, so no light "
                       "bounces off it onto itself";
            d.avoided_seconds = estimated_seconds;
            d.cost_basis = "estimate: the transfer's rays at the visibility stage's ray rate, and the rounds' solves at the "
                           "first solve's time";
        } else if (weak || absent) {
            d.reason = "the mesh can see itself, but " + measured +
                       (weak ? ": below what the images hold" : ": the capture does not hold that light, or not where the model puts it");
            d.avoided_seconds = estimated_seconds;
            d.cost_basis = "estimate: the rounds' solves at the first solve's time (the transfer was built to measure)";
        } else {
            d.reason = "the mesh can see itself (" + c.reason + ")" + (m ? "; " + measured : std::string());
        }
    } else {
        d.reason = std::string("--indirect ") + (on ? "on" : "off") +
                   (c.convex ? " (the planner would leave it out: the mesh is convex)"
                    : m      ? " (" + measured + ")"
                             : " (the planner would measure the indirect light: the mesh can see itself)");
    }
    return d;
}

bool decided_indirect(const PlanDecision& d) { return d.value == "inverse global illumination"; }

// ---- atlas ------------------------------------------------------------------------------

PlanDecision decide_atlas(const AtlasSummary& s, const AtlasOptions& o, std::size_t particles, double particle_stage_seconds) {
    const AtlasOptions defaults;
    const bool charts = s.mode == to_string(AtlasMode::Charts);
    PlanDecision d;
    d.name = "atlas";
    const bool mode_forced = o.mode != defaults.mode;
    const bool size_forced = o.texels_per_pixel != defaults.texels_per_pixel || o.max_width != defaults.max_width ||
                             o.max_height != defaults.max_height;
    d.forced = mode_forced || size_forced;
    d.value = std::string(to_string(o.mode)) + " " + std::to_string(s.width) + "x" + std::to_string(s.height) +
              (charts ? " (" + std::to_string(s.charts) + " charts, " + std::to_string(s.seam_edges) + " seam edges)" : "") + ", " +
              format_text("%.3g", o.texels_per_pixel) + " texel(s) per pixel";
    d.detail = {{"mode", s.mode},
                {"charts", s.charts},
                {"seam_edges", s.seam_edges},
                {"vertices", {{"mesh", s.mesh_vertices}, {"atlas", s.atlas_vertices}}},
                {"fill_ratio", s.fill_ratio},
                {"width", s.width},
                {"height", s.height},
                {"texels_per_pixel", o.texels_per_pixel},
                {"budget", {o.max_width, o.max_height}},
                {"budget_clipped", s.budget_clipped},
                {"particles", particles},
                {"size_source", s.size_source}};
    std::string base =
        charts ? std::to_string(s.charts) + " connected charts (least-squares conformal maps, " + std::to_string(s.seam_edges) +
                     " seam edges): " + std::to_string(s.mesh_vertices) + " mesh vertices become " + std::to_string(s.atlas_vertices) +
                     " in the bundle"
               : "the thesis's patchwork (every triangle its own patch): " + std::to_string(s.mesh_vertices) + " mesh vertices become " +
                     std::to_string(s.atlas_vertices) + " in the bundle";
    base += s.size_source == "cameras" ? "; texel density follows each triangle's pixel footprint in its best train view"
                                       : "; no camera sees the mesh: texel density follows surface area";
    if (s.budget_clipped) base += "; the " + std::to_string(o.max_width) + "x" + std::to_string(o.max_height) +
                                  " budget clipped it (scale " + format_text("%.3g", s.budget_scale) + ")";
    if (!d.forced) {
        // Not "no information": views sample an edge at different sub-pixel phases, and the albedo
        // refinement combines them. Measured on the can (512 px, refinement on): 2 texels per pixel
        // gave +1.4 dB masked test PSNR for 1.6x the particles and about twice the particle stages' time.
        d.reason = base + ", one texel per pixel: a finer atlas sharpens albedo edges a little for held-out views "
                          "(the can at 2 texels per pixel: +1.4 dB masked test PSNR) for several times the particle stages' time";
        // Twice the linear resolution: 4x the particles; the particle-proportional stages scale with them.
        d.avoided_seconds = 3.0 * particle_stage_seconds;
        d.cost_basis = "estimate: at 2 texels per pixel (4x the particles) the particle stages (visibility, diffuse "
                       "solve, residual samples; measured " + format_text("%.3g", particle_stage_seconds) +
                       " s) would take about 4x as long";
    } else {
        std::string flags;
        if (mode_forced) flags += "--atlas " + std::string(to_string(o.mode));
        if (size_forced)
            flags += std::string(flags.empty() ? "" : ", ") + "--texels-per-pixel " + format_text("%.3g", o.texels_per_pixel) +
                     " / --texture-size " + std::to_string(o.max_width);
        d.reason = base + "; forced by " + flags + " (the planner uses charts, 1 texel per pixel, 4096 budget)";
        d.measured_seconds = particle_stage_seconds;
        d.cost_basis = "measured: visibility, diffuse solve and residual samples at this atlas (" + std::to_string(particles) +
                       " particles)";
    }
    return d;
}

PlanDecision decide_indirect_block(std::size_t particles, std::uint32_t forced) {
    PlanDecision d;
    d.name = "indirect_block";
    d.forced = forced != 0;
    const std::uint32_t chosen = transfer_block_for(particles);
    const std::uint32_t block = d.forced ? forced : chosen;
    const double rows = static_cast<double>(particles) / (static_cast<double>(block) * block);
    d.value = std::to_string(block) + " x " + std::to_string(block) + " texels";
    d.detail = {{"block", block}, {"auto_block", chosen}, {"particles", particles}, {"rows_about", std::lround(rows)}};
    const std::string why =
        "the light a surface sends itself varies over the object's features, not its texels, so a denser atlas takes wider "
        "blocks: the nearest to " + short_number(kTransferBlockRows / 1000.0) + "k rows, at least " +
        std::to_string(kTransferBlock) + " texels (the knot at 512 px: 1.92% albedo RMSE in its hollows with 3, 2.00% with "
        "2, 2.06% with 4, and a fifth less time than with 2; at 256 px 2 does best)";
    const std::string rows_text = "about " + std::to_string(std::lround(rows)) + " rows";
    if (!d.forced) d.reason = why + ": " + std::to_string(particles) + " particles, " + rows_text;
    else d.reason = "--indirect-block " + std::to_string(forced) + ": " + rows_text + " (auto: " + std::to_string(chosen) + "; " + why + ")";
    return d;
}

std::uint32_t decided_indirect_block(const PlanDecision& d) { return d.detail.at("block").get<std::uint32_t>(); }

// ---- albedo refinement ------------------------------------------------------------------

const char* to_string(RefineMethod m) noexcept {
    switch (m) {
    case RefineMethod::Pixels: return "pixels";
    case RefineMethod::BackProjection: return "back-projection";
    }
    return "?";
}

PlanDecision decide_albedo_refinement(RefineMethod method, std::optional<std::uint32_t> forced_rounds, double solve_seconds) {
    PlanDecision d;
    d.name = "albedo_refinement";
    d.forced = forced_rounds.has_value();
    const bool pixels = method == RefineMethod::Pixels;
    const std::uint32_t auto_rounds = pixels ? kPixelFitIterations : kAlbedoRefineRounds;
    const std::uint32_t rounds = forced_rounds.value_or(auto_rounds);
    const char* unit = pixels ? (rounds == 1 ? " iteration" : " iterations") : (rounds == 1 ? " round" : " rounds");
    d.value = rounds == 0 ? "skip" : std::to_string(rounds) + unit + " (" + to_string(method) + ")";
    d.skipped = rounds == 0;
    d.detail = {{"method", to_string(method)}, {"rounds", rounds}, {"auto_rounds", auto_rounds}};
    const std::string edge =
        "the solve reads each particle bilinearly from its best view and the renderer reads the atlas bilinearly again, "
        "so a sharp albedo edge comes back as a ramp that held-out views and lights see at another sub-pixel phase; ";
    const std::string why =
        edge + (pixels ? "the pixel fit finds the albedo whose bilinear atlas read best reproduces every train pixel's albedo "
                         "(least squares through the atlas point each pixel's centre ray hits; no renders)"
                       : "each round renders the train frames from the albedo, solves them, and adds the difference to "
                         "the captured frames' solve (the robust combination over all views that see a particle)");
    const std::string named = std::to_string(auto_rounds) + (pixels ? " iterations" : " rounds");
    if (!d.forced) {
        d.reason = why + ": " + named +
                   (pixels ? " (the last one lowers the train pixels' residual by 0.3%; the coated can at 512 px: test "
                             "PSNR 41.25 dB, 38.36 by 2 rounds of back-projection)"
                           : " (a third changes the can's test PSNR by < 0.01 dB)");
    } else if (rounds == 0) {
        d.reason = "--refine-rounds 0: the solve's bilinear reading of the best view (the planner runs " + named + ": " +
                   why + ")";
        if (!pixels) {
            d.avoided_seconds = static_cast<double>(kAlbedoRefineRounds) * solve_seconds;
            d.cost_basis = "estimate: " + std::to_string(kAlbedoRefineRounds) + " diffuse solves (the first took " +
                           format_text("%.3g", solve_seconds) + " s); the renders of the train frames are not included";
        }
    } else {
        d.reason = "--refine-rounds " + std::to_string(rounds) + " (the planner runs " + named + ")";
    }
    return d;
}

std::uint32_t decided_refine_rounds(const PlanDecision& d) { return d.detail.value("rounds", 0u); }

void set_refinement_cost(PlanDecision& d, double seconds) {
    d.measured_seconds = seconds;
    d.cost_basis = "measured: " + std::to_string(decided_refine_rounds(d)) +
                   (d.detail.value("method", std::string()) == to_string(RefineMethod::Pixels)
                        ? " iterations over the train pixels, and one ray per train-view pixel"
                        : " rounds, each one render of every train frame and one diffuse solve");
}

// ---- specular stages --------------------------------------------------------------------

PlanDecision decide_specular(const ResidualEnergy& e, Toggle toggle, std::size_t validation_frames) {
    PlanDecision d;
    d.name = "specular_stages";
    d.forced = toggle != Toggle::Auto;
    const bool validate = toggle == Toggle::Auto && !e.has_specular && validation_frames > 0;
    const bool fit = toggle == Toggle::On || (toggle == Toggle::Auto && e.has_specular) || validate;
    d.value = validate ? "validate" : fit ? "fit" : "skip";
    d.skipped = !fit;
    const std::string energy = "mean squared residual " + format_text("%.3g", e.mean_square) + " = " + format_text("%.3g", e.ratio) +
                               " noise variances (noise sigma " + format_text("%.3g", e.noise_sigma) + ", threshold " +
                               format_text("%.3g", e.threshold) + ")";
    d.detail = {{"mean_square_residual", e.mean_square},
                {"ratio_to_noise_variance", e.ratio},
                {"threshold", e.threshold},
                {"diffuse_only_margin_db", kDiffuseOnlyMarginDb},
                {"noise_sigma", e.noise_sigma},
                {"has_specular", e.has_specular}};
    if (validate)
        d.reason = "the residuals hold little energy: " + energy + ", but " + std::to_string(validation_frames) +
                   " validation frames can tell: the families are estimated and 'diffuse only' competes with them on the "
                   "validation frames, a family kept only if it beats it by more than " + format_text("%.2g", kDiffuseOnlyMarginDb) +
                   " dB (near-camera lights leave a real lobe mostly in the albedo of the first solve)";
    else if (toggle == Toggle::Auto)
        d.reason = e.has_specular ? "the residuals hold specular energy: " + energy + "; fit, factorization and specular pass run"
                                  : "the residuals hold no more energy than the noise: " + energy +
                                        "; no Lafortune fit, factorization or specular pass";
    else if (toggle == Toggle::On)
        d.reason = "--specular on (the planner would " + std::string(e.has_specular ? "fit too" : "skip: ") +
                   (e.has_specular ? "" : energy) + ")";
    else
        d.reason = "--specular off: no residual samples, fit, factorization or specular pass";
    return d;
}

void set_specular_cost(PlanDecision& d, std::optional<double> probe_seconds, std::size_t probe_samples, std::size_t fit_samples,
                       std::optional<double> measured_seconds) {
    if (measured_seconds) {
        d.measured_seconds = measured_seconds;
        d.cost_basis = "measured: Lafortune fit on " + std::to_string(fit_samples) + " samples plus the factorization";
    } else if (probe_seconds && probe_samples > 0) {
        const double scale = static_cast<double>(std::max(fit_samples, probe_samples)) / static_cast<double>(probe_samples);
        d.avoided_seconds = *probe_seconds * scale;
        d.cost_basis = "estimate: the fit timed on a " + std::to_string(probe_samples) + "-sample subsample (" +
                       format_text("%.3g", *probe_seconds) + " s), scaled linearly to the " + std::to_string(fit_samples) +
                       " samples it would use; the factorization and specular pass are not included";
    }
}

// ---- factorization grid -----------------------------------------------------------------

factorization::FactorizationResolution decided_grid(const SpecularModel& model, std::uint32_t forced_h, std::uint32_t forced_d) {
    factorization::FactorizationResolution r = factorization::default_resolution(model);
    if (forced_h != 0) r.grid_h = forced_h;
    if (forced_d != 0) r.grid_d = forced_d;
    if (r.grid_h * r.grid_d > factorization::kMaxGridProduct)
        throw UsageError("factorization grid h " + std::to_string(r.grid_h) + " x d " + std::to_string(r.grid_d) +
                         ": R_h R_d must be at most " + std::to_string(factorization::kMaxGridProduct) +
                         " (the matrix F, 3 R_h^2 R_d^2 floats, must fit one 128 MiB storage binding)");
    r.cube_g = factorization::cube_res_for_grid(r.grid_h);
    r.cube_h = factorization::cube_res_for_grid(r.grid_d);
    return r;
}

PlanDecision decide_factorization_grid(const SpecularModel& model, std::uint32_t forced_h, std::uint32_t forced_d) {
    const factorization::FactorizationResolution def = factorization::default_resolution(model);
    const factorization::FactorizationResolution r = decided_grid(model, forced_h, forced_d);
    PlanDecision d;
    d.name = "factorization_grid";
    d.forced = forced_h != 0 || forced_d != 0;
    d.value = "h " + std::to_string(r.grid_h) + " x d " + std::to_string(r.grid_d) + " (cube faces " + std::to_string(r.cube_g) +
              ", " + std::to_string(r.cube_h) + ")";
    d.detail = {{"grid_h", r.grid_h},
                {"grid_d", r.grid_d},
                {"cube_g", r.cube_g},
                {"cube_h", r.cube_h},
                {"auto_grid_h", def.grid_h},
                {"auto_grid_d", def.grid_d}};
    // The figure the rule reads: the sharpest lobe's exponent, or the coated family's roughness.
    if (const auto* lobe = std::get_if<LafortuneRgb>(&model)) {
        double n_max = 1.0;
        for (int c = 0; c < 3; ++c)
            if (std::isfinite(lobe->n[c])) n_max = std::max(n_max, static_cast<double>(lobe->n[c]));
        d.detail["max_exponent"] = n_max;
    } else {
        d.detail["alpha"] = std::get<CoatedParams>(model).alpha;
    }
    d.reason = d.forced ? "--factorization-grid " + std::to_string(r.grid_h) + "," + std::to_string(r.grid_d) +
                              " (the planner would use h " + std::to_string(def.grid_h) + " x d " + std::to_string(def.grid_d) +
                              ": " + def.reason + ")"
                        : def.reason;
    return d;
}

void set_factorization_cost(PlanDecision& d, double seconds, const std::string& what) {
    if (d.forced) {
        d.measured_seconds = seconds;
        d.cost_basis = "measured: " + what + " at the forced grid";
        return;
    }
    // The finest grid the rule allows: R_h R_d at kMaxGridProduct (h 128 x d 24).
    const double h = d.detail["grid_h"].get<double>(), g = d.detail["grid_d"].get<double>();
    const double max_product = static_cast<double>(factorization::kMaxGridProduct);
    const double ratio = (max_product * max_product) / ((h * g) * (h * g));
    if (ratio <= 1.0) return;
    d.avoided_seconds = seconds * (ratio - 1.0);
    d.cost_basis = "estimate: the " + what + " (" + format_text("%.3g", seconds) +
                   " s) scales with the matrix size 3 R_h^2 R_d^2; the finest grid the rule allows (R_h R_d = " +
                   std::to_string(factorization::kMaxGridProduct) + ") has " + format_text("%.3g", ratio) + "x the entries";
}

} // namespace specula
