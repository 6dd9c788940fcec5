#include "pipeline/joint.h"

#include "core/format.h"
#include "core/log.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <utility>

namespace specula {

ValidationSplit split_validation_frames(const LambertInputs& in, std::size_t min_frames) {
    ValidationSplit split{.fit = in, .validation = in, .held_out = 0};
    for (std::size_t v = 0; v < in.views.size(); ++v) {
        const std::vector<std::uint32_t>& frames = in.views[v].frames;
        split.validation.views[v].frames.clear();
        if (frames.size() < std::max<std::size_t>(min_frames, 2)) continue;
        const std::size_t k = v % frames.size();
        split.validation.views[v].frames = {frames[k]};
        split.fit.views[v].frames.erase(split.fit.views[v].frames.begin() + static_cast<std::ptrdiff_t>(k));
        ++split.held_out;
    }
    return split;
}

namespace {

// The rounds from `state` (joint_estimate without the restart).
JointResult run_rounds(JointState& state, const JointOptions& options, const JointSteps& steps) {
    JointResult out;
    out.stop = "joint rounds: " + std::to_string(options.rounds) + " allowed";
    std::optional<SpecularModel> previous = state.fit.model();
    if (steps.validate && previous && !state.validation_mse)
        state.validation_mse = steps.validate(state.solve, *previous, "");
    out.first_validation_mse = state.validation_mse;
    for (std::uint32_t round = 1; round <= options.rounds; ++round) {
        if (!previous) {
            out.stop = "no usable fit: nothing to subtract";
            break;
        }
        const std::string tag = " (joint round " + std::to_string(round) + ")";
        std::vector<ResidualSample>().swap(state.residuals.samples); // fitted: only the counts are kept (peak memory)
        LambertOptions lo = state.solve_options;
        lo.material = *previous;
        // A round kept with its own albedo left the state solved with *previous already: that
        // solve is this round's, not made again.
        const bool solved = !out.rounds.empty() && out.rounds.back().own_albedo;
        LambertOutputs solve = solved ? state.solve : steps.solve(lo, tag);
        ResidualSamples residuals = steps.residuals(solve, lo, tag);
        MaterialFit fit = steps.fit(residuals, tag);
        std::vector<ResidualSample>().swap(residuals.samples); // fitted: only the counts are kept (peak memory)
        const std::optional<SpecularModel> next = fit.model();
        JointRound r{round, next ? max_relative_change(*next, *previous) : 1.0, residuals.counts.used, std::nullopt, false};
        if (steps.validate && next) r.validation_mse = steps.validate(solve, *next, tag);
        const auto rose = [&] { return r.validation_mse && state.validation_mse && *r.validation_mse > *state.validation_mse; };
        // The round's albedo was solved with the material before its fit: a large move can raise
        // the validation error through that mismatch alone (coated can, thesis rig, 512 px: round 2
        // undone, the estimate stuck at eta 2.45, alpha 0.72 for the truth's 1.5, 0.12). Before a
        // rise undoes the round, the new material is scored once more with its own albedo, and
        // kept, with that albedo, where that does not rise; unless another candidate is more than
        // kRivalFactor ahead (this one cannot win the choice).
        if (rose() && (!options.rival_mse || *state.validation_mse < kRivalFactor * *options.rival_mse)) {
            LambertOptions own = lo;
            own.material = *next;
            LambertOutputs own_solve = steps.solve(own, tag + " (its own albedo)");
            const double own_mse = steps.validate(own_solve, *next, tag + " (its own albedo)");
            if (own_mse <= *state.validation_mse) {
                r.validation_mse = own_mse;
                r.own_albedo = true;
                lo = std::move(own);
                solve = std::move(own_solve);
            }
        }
        // A round is rejected when its fit is unusable or the validation error rose.
        const bool worse = !next || rose();
        if (worse) {
            r.rejected = true;
            out.rounds.push_back(r);
            out.stop = !next ? "rejected round " + std::to_string(round) + ": its fit is not usable; the previous round is kept"
                             : "rejected round " + std::to_string(round) + ": the validation error rose from " +
                                   std::to_string(*state.validation_mse) + " to " + std::to_string(*r.validation_mse) +
                                   " (mean square, image units); the previous round is kept";
            log::info(out.stop);
            break;
        }
        state.solve_options = std::move(lo);
        state.solve = std::move(solve);
        state.residuals = std::move(residuals);
        state.fit = std::move(fit);
        state.validation_mse = r.validation_mse;
        out.rounds.push_back(r);
        ++out.accepted;
        log::info("joint round " + std::to_string(round) + ": material changed by " + std::to_string(100.0 * r.max_relative_change) +
                  "%" + (r.validation_mse ? ", validation mean square " + std::to_string(*r.validation_mse) : std::string()));
        previous = next;
        if (r.max_relative_change < options.tolerance) {
            out.stop = "converged: the material changed by less than " + std::to_string(100.0 * options.tolerance) + "%";
            break;
        }
    }
    // Ended unsettled: out of rounds while still moving, or a round undone (by the validation
    // error) while the kept state had itself just moved. Say how far from settled (the caller
    // names the parameters underdetermined; the fit's standard errors hold the albedo fixed
    // and miss it).
    if (!out.rounds.empty() && out.rounds.back().rejected) {
        // The kept state's own last move, or the undone round's step from it: whichever is larger
        // (no tail: the rounds did not go on). Vase, coated, thesis rig: kept round 2 had moved
        // by 20%, the undone round 3 by 1.3%, and alpha was 11% low.
        double moved = out.rounds.back().max_relative_change;
        if (out.rounds.size() >= 2) moved = std::max(moved, out.rounds[out.rounds.size() - 2].max_relative_change);
        if (moved >= options.tolerance) {
            out.unsettled_change = moved;
            out.unsettled_remaining = 0.0;
        }
    } else if (options.rounds > 0 && out.rounds.size() == options.rounds &&
               out.rounds.back().max_relative_change >= options.tolerance) {
        const double last = out.rounds.back().max_relative_change;
        out.unsettled_change = last;
        // The rate: the slowest of the last (up to) three ratios of successive changes, since the
        // rate drifts from round to round (woodenpot, coated, thesis rig, 128 px: 0.82, 0.75,
        // 0.67; the last ratio alone promised 2.9% more where alpha was still 7.5% off).
        const std::size_t n = out.rounds.size();
        double q = 0.0;
        for (std::size_t k = n - 1; k >= 1 && k + 3 >= n; --k)
            q = std::max(q, out.rounds[k].max_relative_change / std::max(1e-12, out.rounds[k - 1].max_relative_change));
        if (n >= 2 && q < 1.0) out.unsettled_remaining = last * q / (1.0 - q);
    }
    return out;
}

} // namespace

JointResult joint_estimate(JointState& state, const JointOptions& options, const JointSteps& steps) {
    JointResult first = run_rounds(state, options, steps);
    const bool low = options.restart_low_index && steps.validate && state.fit.coated && state.fit.coated->usable() &&
                     state.fit.coated->params.eta < kCoatedLowEta;
    // Not where another candidate is more than kRivalFactor ahead: this one cannot win the choice
    // (the Lafortune vase's coated candidate ends at eta 1.01, 130 times behind).
    const bool behind = options.rival_mse && (!state.validation_mse || *state.validation_mse >= kRivalFactor * *options.rival_mse);
    if (!low || behind) return first;
    // The rounds ended near eta = 1: once more from a common dielectric, the same alpha and albedo.
    JointState common = state;
    common.fit.coated->params.eta = kCoatedCommonEta;
    common.validation_mse.reset();
    JointRestart restart{.first_eta = state.fit.coated->params.eta, .common_eta = kCoatedCommonEta};
    JointResult second = run_rounds(common, options, steps);
    restart.first_mse = state.validation_mse;
    restart.common_mse = common.validation_mse;
    restart.common_kept = common.validation_mse && (!state.validation_mse || *common.validation_mse < *state.validation_mse);
    log::info(format_text("coated candidate: its rounds ended at eta %.3f, validation mean square %.6g; from eta %.2f: %.6g; ",
                          restart.first_eta, restart.first_mse.value_or(-1.0), restart.common_eta, restart.common_mse.value_or(-1.0)) +
              (restart.common_kept ? "the second kept" : "the first kept"));
    JointResult& kept = restart.common_kept ? second : first;
    if (restart.common_kept) state = std::move(common);
    kept.restart = restart;
    return std::move(kept);
}

// The joint rounds ran out while the material still moved (JointResult::unsettled_change):
// the fit's standard errors hold the albedo fixed, so they cannot see that the albedo still
// holds part of the specular. The distance to the fixed point is about the last change plus
// its geometric tail (unknown when the changes do not shrink); where that exceeds the bound a
// parameter must meet to count as determined (the coated fit's max_relative_error, 5%), the
// coated parameters are named underdetermined with the reason, and a Lafortune fit keeps its
// status (its lobe stays usable) with the reason appended. Returns whether it was named.
std::string rounds_text(const JointResult& joint) {
    const std::size_t n = joint.rounds.size();
    return std::to_string(n) + (n == 1 ? " round" : " rounds");
}

bool name_unsettled(MaterialFit& fit, const JointResult& joint, double bound) {
    if (!joint.unsettled_change) return false;
    const double last = *joint.unsettled_change;
    const double distance = joint.unsettled_remaining ? last + *joint.unsettled_remaining : std::numeric_limits<double>::infinity();
    if (distance <= bound) return false;
    std::string reason = "the joint estimate of albedo and material had not settled after " + rounds_text(joint) +
                         ": the material last moved by " + format_text("%.2g", 100.0 * last) + "%";
    const bool undone = !joint.rounds.empty() && joint.rounds.back().rejected;
    reason += undone ? " (round " + std::to_string(joint.rounds.back().round) + " was undone: it raised the validation error)"
              : joint.unsettled_remaining
                  ? " (" + format_text("%.2g", 100.0 * *joint.unsettled_remaining) + "% more if the rounds keep converging at that rate)"
                  : " (and the changes are not shrinking)";
    reason += ", so the parameters may be off by more than " + format_text("%.3g", 100.0 * bound) +
              "%, whatever their standard errors (which hold the albedo fixed) say: the albedo still holds part of the "
              "specular (lights near the camera put the highlight in every frame of a particle's best view); the "
              "rounds stop at --joint-rounds, or at as many as the validated estimate kept where it undid one";
    if (fit.coated && fit.coated->usable()) {
        fit.coated->status = CoatedFitStatus::Underdetermined;
        fit.coated->alpha_determined = fit.coated->eta_determined = false;
        fit.coated->reason = fit.coated->reason == "converged" ? reason : fit.coated->reason + "; " + reason;
    }
    if (fit.lafortune)
        for (LafortuneChannelFit& c : fit.lafortune->channel) c.reason += (c.reason.empty() ? "" : "; ") + reason;
    return true;
}

} // namespace specula
