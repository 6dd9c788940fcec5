#include "pipeline/joint.h"

#include "core/log.h"

#include <algorithm>
#include <cmath>

namespace specula {

double max_relative_change(const LafortuneRgb& next, const LafortuneRgb& previous) noexcept {
    const auto rel = [](float a, float b) { return std::abs(double(a) - double(b)) / std::max(1e-6, std::abs(double(b))); };
    double change = 0.0;
    for (int k = 0; k < 3; ++k)
        change = std::max({change, rel(next.cx[k], previous.cx[k]), rel(next.cz[k], previous.cz[k]), rel(next.n[k], previous.n[k])});
    return change;
}

JointResult joint_estimate(JointState& state, const JointOptions& options, const JointSteps& steps) {
    JointResult out;
    out.stop = "joint rounds: " + std::to_string(options.rounds) + " allowed";
    for (std::uint32_t round = 1; round <= options.rounds; ++round) {
        const LafortuneRgb previous = state.fit.converged_lobe();
        if (previous.is_zero()) {
            out.stop = "no channel converged: nothing to subtract";
            break;
        }
        const std::string tag = " (joint round " + std::to_string(round) + ")";
        LambertOptions lo = state.solve_options;
        lo.lobe = previous;
        state.solve = steps.solve(lo, tag);
        state.solve_options = lo;
        state.residuals = steps.residuals(state.solve, tag);
        state.fit = steps.fit(to_lafortune_samples(state.residuals.samples), tag);
        const double change = max_relative_change(state.fit.converged_lobe(), previous);
        out.rounds.push_back({round, change, state.residuals.counts.used});
        log::info("joint round " + std::to_string(round) + ": lobe changed by " + std::to_string(100.0 * change) + "%");
        if (change < options.tolerance) {
            out.stop = "converged: the lobe changed by less than " + std::to_string(100.0 * options.tolerance) + "%";
            break;
        }
    }
    return out;
}

} // namespace specula
