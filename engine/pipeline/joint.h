#pragma once
// The joint estimate of albedo and lobe (an addition to the thesis; docs/pipeline.md 5.5).
// The diffuse solve absorbs the part of a broad lobe that its highlight test cannot separate,
// which biases the residuals low. Each round subtracts the fitted lobe's light from the
// samples (LambertOptions::lobe), re-solves the albedo, recomputes the residuals and refits,
// until no lobe parameter changes by more than `tolerance` (relative) or `rounds` is reached.
//
// The loop is separate from the stages that run its steps (pipeline/stages.cpp gives them the
// pipeline's backend, timing and report), so it can be tested with any steps.
#include "diffuse/lambert_solve.h"
#include "specular/lafortune_fit.h"
#include "specular/residuals.h"

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace specula {

struct JointOptions {
    std::uint32_t rounds = 3;  ///< at most this many rounds after the first fit; 0: the thesis's one pass
    double tolerance = 0.005;  ///< stop when no parameter changes by more than this (relative)
};

/// What the estimate advances: the last solve with its options (their lobe is the one that
/// solve subtracted), the residual samples of that solve, and the fit to them.
struct JointState {
    LambertOptions solve_options;
    LambertOutputs solve;
    ResidualSamples residuals;
    LafortuneFitRgb fit;
};

/// The three steps of a round; `tag` names the round (" (joint round 2)") for stage labels.
struct JointSteps {
    std::function<LambertOutputs(const LambertOptions&, const std::string& tag)> solve;
    std::function<ResidualSamples(const LambertOutputs&, const std::string& tag)> residuals;
    std::function<LafortuneFitRgb(std::vector<LafortuneSample>, const std::string& tag)> fit;
};

struct JointRound {
    std::uint32_t round = 0;
    double max_relative_change = 0.0; ///< largest relative change of Cx, Cz or N over the channels
    std::size_t residual_samples = 0; ///< samples the round's fit used
};

struct JointResult {
    std::vector<JointRound> rounds;
    std::string stop; ///< why the loop ended
};

/// The largest relative change |next - previous| / max(1e-6, |previous|) of Cx, Cz and N over
/// the three channels.
[[nodiscard]] double max_relative_change(const LafortuneRgb& next, const LafortuneRgb& previous) noexcept;

/// Runs the rounds on `state` (which holds the first solve, residuals and fit on entry and the
/// last ones on return).
JointResult joint_estimate(JointState& state, const JointOptions& options, const JointSteps& steps);

} // namespace specula
