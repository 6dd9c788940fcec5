// Stage driver and error measurement of the factorization (factorization.h).
#include "factorization/factorization.h"

#include "core/error.h"
#include "core/timer.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <utility>
#include <iterator>
#include <random>
#include <thread>

namespace specula::factorization {

std::optional<double> FactorizationTimings::gpu_total_ns() const {
    if (!matrix_gpu_ns || !decomposition_g_gpu_ns || !decomposition_h_gpu_ns || !cube_g_gpu_ns || !cube_h_gpu_ns)
        return std::nullopt;
    return *matrix_gpu_ns + *decomposition_g_gpu_ns + *decomposition_h_gpu_ns + first_refine_gpu_ns.value_or(0.0) +
           *cube_g_gpu_ns + *cube_h_gpu_ns;
}

namespace {

/// An upper bound of the specular model's value (F's largest entry in the plain and mirrored
/// parametrizations, where F is the model itself). Lafortune: max(|Cx|, |Cz|)^N. Coated
/// (shared/coated.h): F <= 1, D <= D(1) = 1 / (pi alpha^2), and G1(c) / (2 c) <= 1 / alpha (its
/// denominator c + sqrt(c^2 + alpha^2 (1 - c^2)) is at least alpha), so f_s <= tint / (pi alpha^4).
double model_height(const SpecularModel& model) {
    double height = 0.0;
    if (const auto* lobe = std::get_if<LafortuneRgb>(&model)) {
        for (int c = 0; c < 3; ++c)
            height = std::max(height, std::pow(std::max(std::abs(static_cast<double>(lobe->cx[c])),
                                                        std::abs(static_cast<double>(lobe->cz[c]))),
                                               static_cast<double>(lobe->n[c])));
        return height;
    }
    const auto& coated = std::get<CoatedParams>(model);
    const double a2 = static_cast<double>(coated.alpha) * coated.alpha;
    for (int c = 0; c < 3; ++c) height = std::max(height, static_cast<double>(coated.tint[c]));
    return height / (kPi * a2 * a2);
}

/// Whether the residual kernels' float sums of products of F with G and H stay finite: the
/// model's height (model_height) is at most kResidualMaxValue (the warped F is in [0, 1] and
/// always fits).
bool residual_sums_fit(const SpecularModel& model, FactorParam param) {
    if (param == FactorParam::Warped) return true;
    return model_height(model) <= kResidualMaxValue;
}

/// K_max of the run: the forced K, or max_terms; 1 when the lobe is too high for the
/// residual kernels' float sums, or unforced in the warped parametrization (note says why).
uint32_t terms_to_compute(const SpecularModel& model, const FactorizationOptions& o, FactorParam param, std::string& note) {
    if (o.terms > kMaxFactorTerms)
        throw Error("factorize: terms must be 0 (automatic) or 1.." + std::to_string(kMaxFactorTerms) + " (got " +
                    std::to_string(o.terms) + ")");
    if (o.max_terms < 1 || o.max_terms > kMaxFactorTerms)
        throw Error("factorize: max_terms must be in [1, " + std::to_string(kMaxFactorTerms) + "]");
    if (!(o.term_target >= 0.0)) throw Error("factorize: term_target must be >= 0");
    const uint32_t k = o.terms != 0 ? o.terms : o.max_terms;
    if (k == 1) return 1;
    if (param == FactorParam::Warped && o.terms == 0) {
        note = "the warped F is rank 1 per channel: one term";
        return 1;
    }
    if (!residual_sums_fit(model, param)) {
        note = "the model's height (max(|Cx|, |Cz|)^N for a lobe) exceeds " + std::to_string(kResidualMaxValue) +
               " (float sums of the residual kernels could overflow): one term only";
        return 1;
    }
    return k;
}

std::string percent(double x) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.1f%%", 100.0 * x);
    return buf;
}

/// ALS iterations refining term 1 (FactorizationOptions::first_iterations); 0 when the lobe is
/// too high for the residual kernels' float sums (as terms_to_compute).
uint32_t first_term_iterations(const SpecularModel& model, const FactorizationOptions& o, FactorParam param) {
    const uint32_t it = o.first_iterations.value_or(param == FactorParam::Warped ? kResidualIterations : 0u);
    if (it > 1000) throw Error("factorize: first_iterations must be in [0, 1000]");
    return residual_sums_fit(model, param) ? it : 0u;
}

/// Matrix errors of the first k terms for every k, then K by the rule of FactorizationOptions::terms.
/// m may be null only when there is one term (the Vulkan path without keep_matrix): no errors then.
TermChoice choose_terms(const BrdfMatrix* m, const Decomposition& first, const std::vector<Decomposition>& rest,
                        const FactorizationOptions& o, const std::string& note) {
    TermChoice t;
    t.target = o.term_target;
    t.forced = o.terms != 0;
    if (m == nullptr) {
        t.count = 1;
        t.reason = (t.forced ? std::string("forced K = 1") : "max_terms = 1") + (note.empty() ? "" : "; " + note);
        if (!t.forced && !note.empty()) t.reason = "automatic: " + note;
        return t;
    }
    std::vector<const Decomposition*> terms{&first};
    t.matrix_rms.push_back(matrix_relative_rms(*m, terms));
    for (const Decomposition& d : rest) {
        terms.push_back(&d);
        t.matrix_rms.push_back(matrix_relative_rms(*m, terms));
    }
    std::string errors;
    for (std::size_t k = 0; k < t.matrix_rms.size(); ++k)
        errors += std::string(k ? ", " : "") + "K=" + std::to_string(k + 1) + " " + percent(t.matrix_rms[k]);
    if (t.forced) {
        t.count = static_cast<uint32_t>(t.matrix_rms.size());
        t.reason = "forced K = " + std::to_string(o.terms) + (note.empty() ? "" : "; " + note) +
                   " (matrix relative RMS " + errors + ")";
        return t;
    }
    const auto hit = std::find_if(t.matrix_rms.begin(), t.matrix_rms.end(), [&](double e) { return e <= o.term_target; });
    if (hit != t.matrix_rms.end()) {
        t.count = static_cast<uint32_t>(hit - t.matrix_rms.begin()) + 1;
        t.reason = "automatic: K = " + std::to_string(t.count) + ", the fewest terms whose matrix relative RMS is <= " +
                   percent(o.term_target) + " (" + errors + ")";
    } else {
        t.count = static_cast<uint32_t>(std::min_element(t.matrix_rms.begin(), t.matrix_rms.end()) - t.matrix_rms.begin()) + 1;
        t.reason = "automatic: the target " + percent(o.term_target) + " is not reached within " +
                   std::to_string(t.matrix_rms.size()) + " term(s); K = " + std::to_string(t.count) +
                   " has the least matrix relative RMS (" + errors + ")";
    }
    if (!note.empty()) t.reason += "; " + note;
    return t;
}

} // namespace

float default_weight_exponent(const SpecularModel& model) {
    const auto* coated = std::get_if<CoatedParams>(&model);
    if (coated == nullptr || !std::isfinite(coated->alpha)) return 0.0f;
    const float t = (coated->alpha - kCoatedWeightAlphaLow) / (kCoatedWeightAlphaHigh - kCoatedWeightAlphaLow);
    return kCoatedWeightExponent * std::clamp(t, 0.0f, 1.0f);
}

namespace {

/// The run's weight exponent (FactorizationOptions::weight_q), checked, and what the reason says of it.
float weight_exponent(const SpecularModel& model, const FactorizationOptions& o, FactorizationResolution& r) {
    const float q = o.weight_q.value_or(default_weight_exponent(model));
    if (!(q >= 0.0f && q <= 8.0f)) throw Error("factorize: weight_q must be in [0, 8]");
    if (q != 0.0f) {
        char buf[224];
        std::snprintf(buf, sizeof buf,
                      "; entries weighted by (n.h u.h)^%.3g (%s): a weighted least-squares fit that does not spend the terms "
                      "on grazing pairs",
                      static_cast<double>(q), o.weight_q ? "forced" : "default_weight_exponent");
        r.reason += buf;
    }
    return q;
}

} // namespace

std::optional<glm::vec4> warp_for_model(const SpecularModel& model, std::string* why) {
    if (const auto* lobe = std::get_if<LafortuneRgb>(&model)) return warp_for_lobe(*lobe, why);
    if (why)
        *why = std::string("the ") + to_string(family_of(model)) +
               " family has no Lafortune radial factor |C u|^N for the warped F to divide by";
    return std::nullopt;
}

FactorizationResolution resolve_resolution(const SpecularModel& model, const FactorizationOptions& o, FactorParam param) {
    FactorizationResolution r = default_resolution(model, param);
    std::string forced;
    const auto force = [&](uint32_t value, uint32_t& field, const char* name) {
        if (value == 0) return;
        field = value;
        forced += std::string(forced.empty() ? "" : ", ") + name + " = " + std::to_string(value);
    };
    force(o.grid_h, r.grid_h, "h grid");
    force(o.grid_d, r.grid_d, "d grid");
    if (o.cube_g == 0 && o.grid_h != 0) r.cube_g = cube_res_for_grid(r.grid_h);
    if (o.cube_h == 0 && o.grid_d != 0) r.cube_h = cube_res_for_grid(r.grid_d);
    force(o.cube_g, r.cube_g, "G cube");
    force(o.cube_h, r.cube_h, "H cube");
    if (!forced.empty()) r.reason = "forced: " + forced + "; default rule: " + r.reason;
    return r;
}

namespace {

std::string param_errors(const ParamCandidate& c) {
    const TermChoice& t = c.terms;
    char buf[96];
    std::snprintf(buf, sizeof buf, "K=%u: %.1f%% vs the lobe, matrix %s", t.count, 100.0 * c.direct_rms,
                  t.matrix_rms.empty() ? "n/a" : percent(t.matrix_rms[t.count - 1]).c_str());
    return buf;
}

ParamCandidate candidate_of(const SpecularModel& model, const Factorization& f) {
    return ParamCandidate{.computed = true,
                          .resolution = f.resolution,
                          .terms = f.terms,
                          .direct_rms = direct_relative_rms(model, f, 0, kParamChoicePairs).cube};
}

/// The warp of the warped parametrization for `model`, shared by the channels when `o` says so
/// (automatic: not here, with_param_choice decides); throws Error naming why it has none.
glm::vec4 required_warp(const SpecularModel& model, const FactorizationOptions& o) {
    std::string why;
    const std::optional<glm::vec4> w = warp_for_model(model, &why);
    if (!w) throw Error("factorize: the warped parametrization does not fit this model: " + why);
    return o.shared_warp.value_or(false) ? shared_warp_of(*w) : *w;
}

/// Where the warped factorization with a warp per channel is kept (not forced either way, the
/// channels' k differ), the one with a shared warp: kept instead when its error against the lobe
/// through the cube-maps is within kSharedWarpGoodEnough and it makes no more lookups a pixel (2 K
/// against 6 K). `run(options)` factorizes in the warped parametrization.
template <class Run>
Factorization with_shared_warp_choice(const SpecularModel& model, const FactorizationOptions& o, Factorization per_channel,
                                      Run&& run) {
    if (o.shared_warp.has_value() || is_shared_warp(per_channel.cubes.warp)) return per_channel;
    FactorizationOptions shared_options = o;
    shared_options.shared_warp = true;
    Factorization shared = run(shared_options);
    ParamCandidate per = per_channel.param_choice.of(FactorParam::Warped);
    ParamCandidate one = candidate_of(model, shared);
    const uint32_t lookups_per = 6 * per.terms.count, lookups_one = 2 * one.terms.count;
    char buf[256];
    std::snprintf(buf, sizeof buf, "; one warp shared by the channels (k %.3f): K=%u, %.2f%% vs the lobe, %u lookups a pixel against %u",
                  static_cast<double>(shared.cubes.warp.y), one.terms.count, 100.0 * one.direct_rms, lookups_one, lookups_per);
    if (one.direct_rms > kSharedWarpGoodEnough || lookups_one > lookups_per) {
        per_channel.param_choice.reason +=
            std::string(buf) + (one.direct_rms > kSharedWarpGoodEnough ? ": over " + percent(kSharedWarpGoodEnough) : "") +
            ", so a warp per channel";
        return per_channel;
    }
    ParamChoice c = std::move(per_channel.param_choice);
    c.reason += std::string(buf) + ": kept";
    c.candidates[static_cast<std::size_t>(FactorParam::Warped)] = one;
    c.warped_per_channel = per;
    shared.param_choice = std::move(c);
    shared.timings.total_s += per_channel.timings.total_s;
    return shared;
}

/// ParamChoice's rule with the options' warp (a warp per channel unless forced shared).
template <class Run>
Factorization with_param_choice_per_channel(const SpecularModel& model, const FactorizationOptions& o, Run&& run) {
    if (o.param) {
        Factorization f = run(*o.param, false, o);
        ParamChoice& c = f.param_choice;
        c.param = *o.param;
        c.forced = true;
        c.candidates[static_cast<std::size_t>(*o.param)] = candidate_of(model, f);
        c.reason = std::string("forced ") + to_string(*o.param) + " (" + param_errors(c.of(*o.param)) + ")";
        return f;
    }
    Stopwatch all;
    std::string no_warp;
    ParamChoice c;
    std::vector<Factorization> runs;
    std::vector<FactorParam> params;
    std::string errors;
    const auto add = [&](FactorParam p) {
        params.push_back(p);
        runs.push_back(run(p, true, o));
        c.candidates[static_cast<std::size_t>(p)] = candidate_of(model, runs.back());
        errors += std::string(errors.empty() ? " (" : "; ") + to_string(p) + " " + param_errors(c.of(p));
    };
    // The warped parametrization first, where it fits the lobe: good enough, it is kept and the
    // others are left out (their residual terms on the larger grids cost seconds).
    if (warp_for_model(model, &no_warp)) {
        add(FactorParam::Warped);
        if (c.of(FactorParam::Warped).direct_rms <= kWarpedGoodEnough) {
            c.param = FactorParam::Warped;
            c.reason = "automatic: warped, its relative RMS against the lobe through the cube-maps within " +
                       percent(kWarpedGoodEnough) + errors + "); the thesis's GSHD and the mirrored one left out";
            Factorization f = std::move(runs.back());
            f.param_choice = std::move(c);
            f.timings.total_s = all.seconds();
            return f;
        }
    }
    add(FactorParam::Gshd);
    // The coated family: the mirrored GSHD is left out. Its GGX peak lies along d and the Fresnel
    // factor and the masking along both axes, so it never came near the plain one: against the
    // model through the cube-maps, plain / mirrored, alpha 0.25 2.9% / 67.5%; on the coated
    // presets' fits at 512 px, can 9.3% / 74.7%, cologne 34.3% / 155.5%, vase 23.3% / 77.7%; and
    // its residual terms cost as much as the plain ones (on lavapipe about 35 s for the cologne).
    // `--factor-param mirrored` still forces it.
    const bool coated = std::holds_alternative<CoatedParams>(model);
    if (!coated) add(FactorParam::Mirrored);
    errors += no_warp.empty() ? "" : "; warped not offered: " + no_warp;
    if (coated) errors += "; mirrored not offered: for the coated family its error was 2.5 to 23 times the plain GSHD's";
    errors += ")";
    // The least error; within the tie margin of it, the fewest terms, then the thesis's GSHD,
    // the mirrored one, the warped one.
    double best = std::numeric_limits<double>::infinity();
    for (const FactorParam p : params) best = std::min(best, c.of(p).direct_rms);
    std::optional<FactorParam> pick;
    bool tie = false;
    std::sort(params.begin(), params.end());
    for (const FactorParam p : params) {
        const ParamCandidate& x = c.of(p);
        if (x.direct_rms > best + kParamTieMargin * best) continue;
        if (pick) tie = true;
        if (!pick || x.terms.count < c.of(*pick).terms.count) pick = p;
    }
    c.param = pick.value_or(FactorParam::Gshd);
    c.reason = std::string("automatic: ") + to_string(c.param) +
               (params.size() == 1 ? std::string(", the only parametrization offered")
                : tie ? ", the fewest terms then the thesis's order among those within " + percent(kParamTieMargin) +
                            " of the least relative RMS against the lobe through the cube-maps"
                      : std::string(", the lower relative RMS against the lobe through the cube-maps")) +
               errors;
    const auto kept = std::find_if(runs.begin(), runs.end(), [&](const Factorization& r) { return r.cubes.param == c.param; });
    Factorization f = std::move(*kept);
    f.param_choice = std::move(c);
    f.timings.total_s = all.seconds(); // every factorization and its errors
    return f;
}

/// ParamChoice's rule: `run(param, errors, options)` factorizes in one parametrization (errors: F's
/// matrix errors are needed even where the path would skip them), then with_shared_warp_choice.
template <class Run>
Factorization with_param_choice(const SpecularModel& model, const FactorizationOptions& o, Run&& run) {
    Factorization f = with_param_choice_per_channel(model, o, run);
    if (f.cubes.param != FactorParam::Warped) return f;
    return with_shared_warp_choice(model, o, std::move(f),
                                   [&](const FactorizationOptions& so) { return run(FactorParam::Warped, true, so); });
}

Factorization factorize_cpu_param(const SpecularModel& model, const FactorizationOptions& options, FactorParam param) {
    Factorization f;
    f.cubes.param = param;
    if (param == FactorParam::Warped) f.cubes.warp = required_warp(model, options);
    f.resolution = resolve_resolution(model, options, param);
    f.weight_q = weight_exponent(model, options, f.resolution);
    f.p = options.p;
    f.weighting = options.weighting;
    Stopwatch total;
    Stopwatch step;
    const unsigned threads = options.threads != 0 ? options.threads : std::max(1u, std::thread::hardware_concurrency());
    BrdfMatrix m = brdf_matrix_cpu({.model = model, .res_h = f.resolution.grid_h, .res_d = f.resolution.grid_d,
                                    .param = param, .warp = f.cubes.warp, .weight_q = f.weight_q, .threads = threads});
    f.timings.matrix_s = step.seconds();
    step.restart();
    Decomposition first = normalized_decomposition_cpu({.matrix = &m, .p = options.p, .weighting = options.weighting});
    if (const uint32_t it = first_term_iterations(model, options, param); it > 0) first = refine_first_term_cpu(m, first, it, threads);
    f.timings.decomposition_s = step.seconds();
    step.restart();
    const auto term_cubes = [&](const Decomposition& d) {
        return FactorTerm{.g = cubemaps_cpu({.grid = d.g, .grid_res = f.resolution.grid_h, .cube_res = f.resolution.cube_g}),
                          .h = cubemaps_cpu({.grid = d.h, .grid_res = f.resolution.grid_d, .cube_res = f.resolution.cube_h})};
    };
    std::string note;
    const uint32_t kmax = terms_to_compute(model, options, param, note);
    std::vector<Decomposition> rest;
    if (kmax > 1)
        rest = residual_terms_cpu(
            {.matrix = &m, .first = &first, .terms = kmax, .iterations = options.iterations, .threads = threads});
    f.terms = choose_terms(&m, first, rest, options, note); // on the (weighted) matrix the terms were fitted to
    rest.resize(f.terms.count - 1);
    f.timings.residual_s = step.seconds();
    step.restart();
    unweight_decomposition(first, f.weight_q);
    for (Decomposition& d : rest) unweight_decomposition(d, f.weight_q);
    f.cubes.terms.push_back(term_cubes(first));
    f.grids.push_back(std::move(first));
    for (Decomposition& d : rest) {
        f.cubes.terms.push_back(term_cubes(d));
        f.grids.push_back(std::move(d));
    }
    f.timings.cubemaps_s = step.seconds();
    f.timings.total_s = total.seconds();
    if (options.keep_matrix) f.matrix = std::move(m);
    return f;
}

} // namespace

Factorization factorize_cpu(const SpecularModel& model, const FactorizationOptions& options) {
    return with_param_choice(model, options, [&](FactorParam param, bool, const FactorizationOptions& o) {
        return factorize_cpu_param(model, o, param);
    });
}

FactorizeVk::FactorizeVk(gpu::Context& ctx)
    : m_ctx(&ctx), m_matrix(ctx), m_decomposition(ctx), m_residual(ctx), m_cubemaps(ctx) {}

Factorization FactorizeVk::run(const SpecularModel& model, const FactorizationOptions& options) {
    return with_param_choice(model, options, [&](FactorParam param, bool errors, const FactorizationOptions& o) {
        return run_param(model, o, param, errors);
    });
}

Factorization FactorizeVk::run_param(const SpecularModel& model, const FactorizationOptions& options, FactorParam param,
                                     bool errors) {
    Factorization f;
    f.cubes.param = param;
    if (param == FactorParam::Warped) f.cubes.warp = required_warp(model, options);
    f.resolution = resolve_resolution(model, options, param);
    f.weight_q = weight_exponent(model, options, f.resolution);
    f.p = options.p;
    f.weighting = options.weighting;
    const FactorizationResolution& r = f.resolution;
    const BrdfMatrixInputs min{.model = model, .res_h = r.grid_h, .res_d = r.grid_d, .param = param, .warp = f.cubes.warp,
                               .weight_q = f.weight_q};
    // Weighted: the grids are unweighted on the host before any cube-map is made (second submit).
    const bool weighted = f.weight_q != 0.0f;
    brdf_matrix_validate(min);
    if (!(options.p >= 1.0f && options.p <= 64.0f)) throw Error("factorize: p must be in [1, 64]");
    std::string note;
    const uint32_t kmax = terms_to_compute(model, options, param, note);
    if (kmax > 1 && (options.iterations < 1 || options.iterations > 1000))
        throw Error("factorize: iterations must be in [1, 1000]");
    Stopwatch total;
    const std::size_t rows = std::size_t{r.grid_h} * r.grid_h;
    const std::size_t cols = std::size_t{r.grid_d} * r.grid_d;
    const std::size_t texels_g = std::size_t{6} * r.cube_g * r.cube_g;
    const std::size_t texels_h = std::size_t{6} * r.cube_h * r.cube_h;
    gpu::Buffer matrix = gpu::Buffer::of<float>(*m_ctx, 3 * rows * cols, "factorization F");
    gpu::Buffer g = gpu::Buffer::of<glm::vec3>(*m_ctx, kmax * rows, "factorization G grids"); // term-major
    gpu::Buffer h = gpu::Buffer::of<glm::vec3>(*m_ctx, kmax * cols, "factorization H grids");
    gpu::Buffer cube_g = gpu::Buffer::of<glm::vec3>(*m_ctx, texels_g, "factorization G cube-map");
    gpu::Buffer cube_h = gpu::Buffer::of<glm::vec3>(*m_ctx, texels_h, "factorization H cube-map");

    gpu::Sequence seq(*m_ctx, 8 + kMaxFactorTerms);
    m_matrix.record(seq, matrix, min);
    seq.barrier(gpu::Barrier::ComputeToCompute);
    m_decomposition.record(seq, matrix, g, h, r.grid_h, r.grid_d, options.p, options.weighting);
    seq.barrier(gpu::Barrier::ComputeToCompute);
    if (const uint32_t it = first_term_iterations(model, options, param); it > 0) {
        m_residual.record_refine_first(seq, matrix, g, h, r.grid_h, r.grid_d, it);
        seq.barrier(gpu::Barrier::ComputeToCompute);
    }
    if (!weighted) {
        m_cubemaps.record(seq, g, cube_g, r.grid_h, r.cube_g, "cube_g");
        m_cubemaps.record(seq, h, cube_h, r.grid_d, r.cube_h, "cube_h");
    }
    // Terms 2..K_max read term 1's G and H and write their own parts of g and h, which the
    // cube-map dispatches above read: the validator tracks whole buffers, so a barrier first.
    if (kmax > 1) {
        seq.barrier(gpu::Barrier::ComputeToCompute);
        m_residual.record(seq, matrix, g, h, r.grid_h, r.grid_d, kmax, options.iterations);
    }
    seq.barrier(gpu::Barrier::ComputeToHost).submit_and_wait();

    Decomposition first{.res_h = r.grid_h, .res_d = r.grid_d, .g = g.download<glm::vec3>(rows),
                        .h = h.download<glm::vec3>(cols), .param = param, .warp = f.cubes.warp};
    std::optional<BrdfMatrix> m;
    if (options.keep_matrix || errors || kmax > 1)
        m = BrdfMatrix{.res_h = r.grid_h, .res_d = r.grid_d, .param = param, .warp = f.cubes.warp, .weight_q = f.weight_q,
                       .values = matrix.download<float>(3 * rows * cols)};
    std::vector<Decomposition> rest;
    if (kmax > 1) {
        const std::vector<glm::vec3> ga = g.download<glm::vec3>(kmax * rows);
        const std::vector<glm::vec3> ha = h.download<glm::vec3>(kmax * cols);
        for (uint32_t k = 1; k < kmax; ++k)
            rest.push_back(Decomposition{.res_h = r.grid_h, .res_d = r.grid_d,
                                         .g = {ga.begin() + k * rows, ga.begin() + (k + 1) * rows},
                                         .h = {ha.begin() + k * cols, ha.begin() + (k + 1) * cols},
                                         .param = param,
                                         .warp = f.cubes.warp});
    }
    f.terms = choose_terms(m ? &*m : nullptr, first, rest, options, note); // on the (weighted) matrix the terms were fitted to
    rest.resize(f.terms.count - 1);
    // Terms whose cube-maps the second submit makes: the chosen residual terms, and term 1 too
    // when weighted (its grids unweighted first).
    std::vector<Decomposition> later;
    if (weighted) {
        unweight_decomposition(first, f.weight_q);
        later.push_back(first);
    } else {
        f.cubes.terms.push_back(FactorTerm{.g = CubeMap{.resolution = r.cube_g, .texels = cube_g.download<glm::vec3>(texels_g)},
                                           .h = CubeMap{.resolution = r.cube_h, .texels = cube_h.download<glm::vec3>(texels_h)}});
    }
    f.grids.push_back(std::move(first));
    for (Decomposition& d : rest) {
        unweight_decomposition(d, f.weight_q);
        later.push_back(std::move(d));
    }
    std::optional<gpu::Sequence> cubes_seq;
    if (!later.empty()) { // a second submit
        std::vector<gpu::Buffer> grids, cubes;
        cubes_seq.emplace(*m_ctx, 2 + 2 * kMaxFactorTerms);
        for (std::size_t k = 0; k < later.size(); ++k) {
            const Decomposition& d = later[k];
            const bool term1 = weighted && k == 0; // timed as the first submit's cube-maps would be
            grids.push_back(gpu::Buffer::of<glm::vec3>(*m_ctx, rows, "factorization G grid"));
            grids.back().upload(d.g);
            grids.push_back(gpu::Buffer::of<glm::vec3>(*m_ctx, cols, "factorization H grid"));
            grids.back().upload(d.h);
            cubes.push_back(gpu::Buffer::of<glm::vec3>(*m_ctx, texels_g, "factorization G cube-map"));
            cubes.push_back(gpu::Buffer::of<glm::vec3>(*m_ctx, texels_h, "factorization H cube-map"));
            m_cubemaps.record(*cubes_seq, grids[grids.size() - 2], cubes[cubes.size() - 2], r.grid_h, r.cube_g,
                              term1 ? "cube_g" : "");
            m_cubemaps.record(*cubes_seq, grids.back(), cubes.back(), r.grid_d, r.cube_h, term1 ? "cube_h" : "");
        }
        cubes_seq->barrier(gpu::Barrier::ComputeToHost).submit_and_wait();
        for (std::size_t k = 0; k < later.size(); ++k) {
            f.cubes.terms.push_back(FactorTerm{.g = CubeMap{.resolution = r.cube_g, .texels = cubes[2 * k].download<glm::vec3>(texels_g)},
                                               .h = CubeMap{.resolution = r.cube_h, .texels = cubes[2 * k + 1].download<glm::vec3>(texels_h)}});
            if (!(weighted && k == 0)) f.grids.push_back(std::move(later[k]));
        }
    }
    if (options.keep_matrix) f.matrix = std::move(m);
    f.timings.total_s = total.seconds();
    std::vector<gpu::GpuTiming> timings = seq.timings();
    if (cubes_seq) std::ranges::copy(cubes_seq->timings(), std::back_inserter(timings));
    for (const auto& t : timings) {
        if (t.label == "brdf_matrix") f.timings.matrix_gpu_ns = t.ns;
        else if (t.label == "decomposition_g") f.timings.decomposition_g_gpu_ns = t.ns;
        else if (t.label == "decomposition_h") f.timings.decomposition_h_gpu_ns = t.ns;
        else if (t.label == "cube_g") f.timings.cube_g_gpu_ns = t.ns;
        else if (t.label == "cube_h") f.timings.cube_h_gpu_ns = t.ns;
        else if (t.label == "first_term_als") f.timings.first_refine_gpu_ns = t.ns;
        else if (t.label.starts_with("residual_term_") && t.ns)
            f.timings.residual_gpu_ns = f.timings.residual_gpu_ns.value_or(0.0) + *t.ns;
    }
    return f;
}

Factorization factorize(const SpecularModel& model, const FactorizationOptions& options, Backend backend,
                        gpu::Context* ctx) {
    if (backend == Backend::Cpu) return factorize_cpu(model, options);
    if (ctx == nullptr) throw Error("factorize: the Vulkan backend needs a gpu::Context");
    return FactorizeVk(*ctx).run(model, options);
}

double matrix_relative_rms(const BrdfMatrix& m, std::span<const Decomposition* const> terms) {
    if (terms.empty()) throw Error("matrix_relative_rms: no terms");
    for (const Decomposition* d : terms)
        if (d == nullptr || d->res_h != m.res_h || d->res_d != m.res_d || d->g.size() != m.rows() || d->h.size() != m.cols())
            throw Error("matrix_relative_rms: resolutions differ");
        else if (d->param != m.param || d->warp != m.warp)
            throw Error("matrix_relative_rms: the terms and the matrix have different parametrizations");
    const std::size_t rows = m.rows();
    const std::size_t cols = m.cols();
    double err = 0.0;
    double ref = 0.0;
    for (uint32_t c = 0; c < 3; ++c) {
        const int ci = static_cast<int>(c);
        for (std::size_t row = 0; row < rows; ++row) {
            const float* f = &m.values[(c * rows + row) * cols];
            for (std::size_t col = 0; col < cols; ++col) {
                if (f[col] < 0.0f) continue;
                double sum = 0.0;
                for (const Decomposition* d : terms) sum += static_cast<double>(d->g[row][ci]) * d->h[col][ci];
                const double e = std::max(sum, 0.0) - f[col];
                err += e * e;
                ref += static_cast<double>(f[col]) * f[col];
            }
        }
    }
    return ref > 0.0 ? std::sqrt(err / ref) : 0.0;
}

double matrix_relative_rms(const BrdfMatrix& m, const Decomposition& dec) {
    if (dec.res_h != m.res_h || dec.res_d != m.res_d) throw Error("matrix_relative_rms: resolutions differ");
    if (dec.param != m.param || dec.warp != m.warp) throw Error("matrix_relative_rms: the terms and the matrix have different parametrizations");
    const std::size_t rows = m.rows();
    const std::size_t cols = m.cols();
    double err = 0.0;
    double ref = 0.0;
    for (uint32_t c = 0; c < 3; ++c)
        for (std::size_t row = 0; row < rows; ++row) {
            const double g = dec.g[row][static_cast<int>(c)];
            const float* f = &m.values[(c * rows + row) * cols];
            for (std::size_t col = 0; col < cols; ++col) {
                if (f[col] < 0.0f) continue;
                const double e = g * dec.h[col][static_cast<int>(c)] - f[col];
                err += e * e;
                ref += static_cast<double>(f[col]) * f[col];
            }
        }
    return ref > 0.0 ? std::sqrt(err / ref) : 0.0;
}

namespace {

/// Relative RMS against the specular model (material_specular, any family) over `pairs` random
/// (u, v) pairs, both uniform in solid angle on the upper hemisphere; `model(c)` gives the (grid,
/// cube-map) approximations at the coordinates c of a pair in parametrization `param` (warp:
/// FactorParam::Warped's), which the lobe's radial factor multiplies in the warped parametrization.
template <class Model>
DirectError sample_direct_error(const SpecularModel& specular, FactorParam param, glm::vec4 warp, uint32_t pairs,
                                uint32_t seed, Model&& model) {
    if (param == FactorParam::Warped && family_of(specular) != MaterialFamily::Lafortune)
        throw Error("direct_relative_rms: the warped parametrization needs a model of the lafortune family");
    const shared::MaterialGpu material = material_gpu(specular);
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    const double two_pi = 6.283185307179586;
    const auto hemisphere = [&] { // uniform in solid angle: z ~ U(0, 1)
        const double z = uni(rng);
        const double phi = two_pi * uni(rng);
        const double s = std::sqrt(std::max(0.0, 1.0 - z * z));
        return glm::dvec3(s * std::cos(phi), s * std::sin(phi), z);
    };
    double err_grid = 0.0, err_cube = 0.0, ref = 0.0;
    for (uint32_t i = 0; i < pairs; ++i) {
        const glm::dvec3 u = hemisphere();
        const glm::dvec3 v = hemisphere();
        const auto coords = [&](int k) {
            return shared::f64::gshd_from_uv_warped(u, v, static_cast<uint32_t>(param), glm::dvec2(channel_warp(warp, k)));
        };
        auto [gg, gc] = model(coords(0));
        if (param == FactorParam::Warped) // each channel at its own coordinates
            for (int k = 1; k < 3; ++k) {
                const auto [g2, c2] = model(coords(k));
                gg[k] = g2[k];
                gc[k] = c2[k];
            }
        const glm::dvec3 fs = shared::f64::material_specular(material, u.z, v.z, glm::dot(u, v));
        for (int k = 0; k < 3; ++k) {
            const double f = std::min<double>(fs[k], shared::kGshdMaxValue);
            const double radial = param == FactorParam::Warped
                                      ? std::min<double>(shared::f64::lafortune_radial(material.a[k], material.b[k], material.c[k], u),
                                                         shared::kGshdMaxValue)
                                      : 1.0;
            ref += f * f;
            err_grid += (radial * gg[k] - f) * (radial * gg[k] - f);
            err_cube += (radial * gc[k] - f) * (radial * gc[k] - f);
        }
    }
    DirectError out;
    out.pairs = pairs;
    out.grid = ref > 0.0 ? std::sqrt(err_grid / ref) : 0.0;
    out.cube = ref > 0.0 ? std::sqrt(err_cube / ref) : 0.0;
    return out;
}

} // namespace

DirectError direct_relative_rms(const SpecularModel& model, const Decomposition& dec, const CubeMap* cube_g,
                                const CubeMap* cube_h, uint32_t pairs, uint32_t seed) {
    const bool cubes = cube_g != nullptr && cube_h != nullptr;
    DirectError out = sample_direct_error(model, dec.param, dec.warp, pairs, seed, [&](const shared::f64::GshdCoords& c) {
        const glm::dvec3 gg = grid_sample(dec.g, dec.res_h, c.h) * grid_sample(dec.h, dec.res_d, c.d);
        const glm::dvec3 gc = cubes ? cubemap_sample(*cube_g, c.h) * cubemap_sample(*cube_h, c.d) : glm::dvec3(0.0);
        return std::pair{gg, gc};
    });
    if (!cubes) out.cube = std::numeric_limits<double>::quiet_NaN();
    return out;
}

DirectError direct_relative_rms(const SpecularModel& model, const Factorization& fac, uint32_t terms, uint32_t pairs,
                                uint32_t seed) {
    const uint32_t k_count = terms == 0 ? fac.term_count() : terms;
    if (k_count > fac.term_count())
        throw Error("direct_relative_rms: " + std::to_string(k_count) + " terms asked, the factorization has " +
                    std::to_string(fac.term_count()));
    // The same draws as the one-term overload; the sum of the terms is clamped at 0 as the renderer does.
    return sample_direct_error(model, fac.cubes.param, fac.cubes.warp, pairs, seed, [&](const shared::f64::GshdCoords& c) {
        glm::dvec3 gg(0.0), gc(0.0);
        for (uint32_t k = 0; k < k_count; ++k) {
            const Decomposition& d = fac.grids[k];
            gg += grid_sample(d.g, d.res_h, c.h) * grid_sample(d.h, d.res_d, c.d);
            gc += cubemap_sample(fac.cubes.terms[k].g, c.h) * cubemap_sample(fac.cubes.terms[k].h, c.d);
        }
        return std::pair{glm::max(gg, glm::dvec3(0.0)), glm::max(gc, glm::dvec3(0.0))};
    });
}

} // namespace specula::factorization
