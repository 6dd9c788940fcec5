// The joint estimate's loop (pipeline/joint.h) with scripted steps: no capture, no device.
// Each fit the script returns is the next model; the test checks which model each solve
// subtracted, when the loop stops, what it records, and that a round whose validation error
// rises is undone (both families), and the validation split.
#include "pipeline/joint.h"

#include <gtest/gtest.h>

#include <algorithm>

#include <string>
#include <vector>

namespace specula {
namespace {

MaterialFit fit_of(float cx, float cz, float n, LafortuneFitStatus status = LafortuneFitStatus::Converged) {
    LafortuneFitRgb f;
    for (LafortuneChannelFit& c : f.channel) {
        c.cx = cx;
        c.cz = cz;
        c.n = n;
        c.status = status;
    }
    return MaterialFit{.family = MaterialFamily::Lafortune, .lafortune = f};
}

MaterialFit coated_of(float eta, float alpha) {
    CoatedFit c;
    c.status = CoatedFitStatus::Converged;
    c.params = CoatedParams{.eta = eta, .alpha = alpha};
    return MaterialFit{.family = MaterialFamily::Coated, .coated = c};
}

struct Script {
    std::vector<MaterialFit> fits;        // returned by the fit step, in order
    std::vector<double> validation;       // returned by the validation step, in order (empty: no validation step)
    std::vector<SpecularModel> subtracted; // the model each solve was given
    std::vector<std::string> tags;
    std::size_t next = 0, next_validation = 0;
    JointSteps steps() {
        JointSteps s{.solve =
                         [this](const LambertOptions& o, const std::string& tag) {
                             subtracted.push_back(*o.material);
                             tags.push_back(tag);
                             LambertOutputs out;
                             out.particles.resize(subtracted.size()); // tells the solves apart
                             return out;
                         },
                     .residuals = [](const LambertOutputs&, const LambertOptions&, const std::string&) { return ResidualSamples{}; },
                     .fit = [this](const ResidualSamples&, const std::string&) { return fits.at(next++); },
                     .validate = {}};
        if (!validation.empty())
            s.validate = [this](const LambertOutputs&, const SpecularModel&, const std::string&) {
                return validation.at(next_validation++);
            };
        return s;
    }
};

TEST(JointEstimate, StopsWhenTheLobeSettlesAndSubtractsThePreviousFit) {
    Script s{.fits = {fit_of(-0.9f, 0.8f, 20.0f), fit_of(-0.901f, 0.8f, 20.0f), fit_of(-0.5f, 0.5f, 5.0f)}};
    JointState state{.fit = fit_of(-1.0f, 1.0f, 10.0f)};
    const JointResult r = joint_estimate(state, {.rounds = 3, .tolerance = 0.005}, s.steps());
    ASSERT_EQ(r.rounds.size(), 2u); // -0.9 -> -0.901 is 0.11% < 0.5%: the third fit is never asked for
    EXPECT_EQ(r.accepted, 2u);
    EXPECT_EQ(s.next, 2u);
    ASSERT_EQ(s.subtracted.size(), 2u);
    EXPECT_FLOAT_EQ(std::get<LafortuneRgb>(s.subtracted[0]).cx.x, -1.0f); // round 1 subtracts the first fit
    EXPECT_FLOAT_EQ(std::get<LafortuneRgb>(s.subtracted[1]).cx.x, -0.9f); // round 2 the fit of round 1
    EXPECT_EQ(s.tags[1], " (joint round 2)");
    EXPECT_NEAR(r.rounds[0].max_relative_change, 1.0, 1e-6); // N: 10 -> 20
    EXPECT_LT(r.rounds[1].max_relative_change, 0.005);
    EXPECT_NE(r.stop.find("converged"), std::string::npos) << r.stop;
    EXPECT_FLOAT_EQ(state.fit.lafortune->channel[0].cx, -0.901f);
    EXPECT_FLOAT_EQ(std::get<LafortuneRgb>(*state.solve_options.material).cx.x, -0.9f); // the last solve's options carry its model
}

TEST(JointEstimate, StopsAtTheRoundLimit) {
    Script s{.fits = {fit_of(-0.5f, 0.5f, 5.0f), fit_of(-1.0f, 1.0f, 10.0f), fit_of(-0.5f, 0.5f, 5.0f)}};
    JointState state{.fit = fit_of(-1.0f, 1.0f, 10.0f)};
    const JointResult r = joint_estimate(state, {.rounds = 2, .tolerance = 0.005}, s.steps());
    EXPECT_EQ(r.rounds.size(), 2u);
    EXPECT_EQ(r.stop, "joint rounds: 2 allowed");
}

TEST(JointEstimate, NothingToSubtractWithoutAConvergedChannel) {
    Script s{.fits = {fit_of(-0.9f, 0.8f, 20.0f)}};
    JointState state{.fit = fit_of(-1.0f, 1.0f, 10.0f, LafortuneFitStatus::Underdetermined)};
    const JointResult r = joint_estimate(state, {.rounds = 3, .tolerance = 0.005}, s.steps());
    EXPECT_TRUE(r.rounds.empty());
    EXPECT_TRUE(s.subtracted.empty());
    EXPECT_NE(r.stop.find("no usable fit"), std::string::npos) << r.stop;
}

TEST(JointEstimate, ZeroRoundsIsTheThesissOnePass) {
    Script s;
    JointState state{.fit = fit_of(-1.0f, 1.0f, 10.0f)};
    const JointResult r = joint_estimate(state, {.rounds = 0, .tolerance = 0.005}, s.steps());
    EXPECT_TRUE(r.rounds.empty());
    EXPECT_TRUE(s.subtracted.empty());
}

// The oscillation the issue measured (the lobe changing by 250%, 158%, 37%): the second round
// raises the validation error, so it is undone and the loop stops.
TEST(JointEstimate, ARoundThatRaisesTheValidationErrorIsUndoneLafortune) {
    Script s{.fits = {fit_of(-0.9f, 0.8f, 20.0f), fit_of(-2.3f, 0.67f, 7.6f), fit_of(-0.9f, 0.8f, 21.0f)},
             .validation = {4e-4, 3e-4, 9e-4, 8e-4}}; // round 2: 9e-4, and 8e-4 with its own albedo
    JointState state{.fit = fit_of(-1.0f, 1.0f, 10.0f)};
    const JointResult r = joint_estimate(state, {.rounds = 3, .tolerance = 0.005}, s.steps());
    ASSERT_EQ(r.rounds.size(), 2u);
    EXPECT_EQ(r.accepted, 1u);
    EXPECT_FALSE(r.rounds[0].rejected);
    EXPECT_TRUE(r.rounds[1].rejected);
    EXPECT_NE(r.stop.find("rejected round 2"), std::string::npos) << r.stop;
    ASSERT_TRUE(r.first_validation_mse);
    EXPECT_DOUBLE_EQ(*r.first_validation_mse, 4e-4);
    // The state is round 1's: its fit, its solve (one particle: the first solve), its error.
    EXPECT_FLOAT_EQ(state.fit.lafortune->channel[0].cx, -0.9f);
    EXPECT_EQ(state.solve.particles.size(), 1u);
    EXPECT_DOUBLE_EQ(*state.validation_mse, 3e-4);
    EXPECT_FLOAT_EQ(std::get<LafortuneRgb>(*state.solve_options.material).cx.x, -1.0f);
}

TEST(JointEstimate, ValidationErrorNeverIncreasesFromRoundToRoundCoated) {
    Script s{.fits = {coated_of(1.45f, 0.2f), coated_of(1.48f, 0.16f), coated_of(1.6f, 0.3f), coated_of(1.49f, 0.15f)},
             .validation = {5e-4, 4e-4, 3.5e-4, 6e-4, 7e-4, 1e-4}}; // round 3: 6e-4, and 7e-4 with its own albedo
    JointState state{.fit = coated_of(1.4f, 0.25f)};
    const JointResult r = joint_estimate(state, {.rounds = 4, .tolerance = 0.005}, s.steps());
    double last = *r.first_validation_mse;
    std::uint32_t accepted = 0;
    for (const JointRound& round : r.rounds) {
        ASSERT_TRUE(round.validation_mse);
        if (round.rejected) continue;
        EXPECT_LE(*round.validation_mse, last) << round.round;
        last = *round.validation_mse;
        ++accepted;
    }
    EXPECT_EQ(accepted, r.accepted);
    EXPECT_EQ(r.accepted, 2u); // round 3 (eta 1.6) raised the error: stopped before round 4
    EXPECT_FLOAT_EQ(state.fit.coated->params.eta, 1.48f);
    EXPECT_EQ(std::get<CoatedParams>(s.subtracted[0]).eta, 1.4f);
    EXPECT_FALSE(r.restart); // eta 1.4 is not near 1: one start
}

// The thesis rig's slow fixed point (issue 15; can, coated, 128 px: alpha 0.0765 -> 0.0972 ->
// 0.1031 -> 0.1107 at 3 rounds, 7.6% low): out of rounds while the material still moves, the
// result says so and how far it may still be from the fixed point.
TEST(JointEstimate, OutOfRoundsWhileStillMovingIsUnsettled) {
    Script s{.fits = {coated_of(1.45f, 0.09f), coated_of(1.47f, 0.099f), coated_of(1.48f, 0.104f)}};
    JointState state{.fit = coated_of(1.40f, 0.08f)};
    const JointResult r = joint_estimate(state, {.rounds = 3, .tolerance = 0.005}, s.steps());
    ASSERT_EQ(r.rounds.size(), 3u);
    EXPECT_EQ(r.stop, "joint rounds: 3 allowed");
    ASSERT_TRUE(r.unsettled_change);
    const double first = (0.09 - 0.08) / 0.08, previous = (0.099 - 0.09) / 0.09, last = (0.104 - 0.099) / 0.099;
    EXPECT_NEAR(*r.unsettled_change, last, 1e-5);
    ASSERT_TRUE(r.unsettled_remaining); // the changes shrink: a geometric tail at the slowest recent rate
    const double q = std::max(previous / first, last / previous);
    EXPECT_NEAR(q, 0.8, 1e-5);
    EXPECT_NEAR(*r.unsettled_remaining, last * q / (1.0 - q), 1e-5);
}

// What the pipeline reports then: the coated fit's parameters are named underdetermined with
// the reason where the distance to the fixed point (last change + geometric tail) exceeds 5%,
// whatever their standard errors say; close enough, the status stands. A Lafortune fit keeps
// its status (and its lobe) and the reason says it.
TEST(JointEstimate, AnUnsettledEstimateNamesTheParametersUnderdetermined) {
    Script s{.fits = {coated_of(1.45f, 0.09f), coated_of(1.47f, 0.099f), coated_of(1.48f, 0.104f)}};
    JointState state{.fit = coated_of(1.40f, 0.08f)};
    const JointResult r = joint_estimate(state, {.rounds = 3, .tolerance = 0.005}, s.steps());
    MaterialFit fit = state.fit;
    fit.coated->alpha_determined = fit.coated->eta_determined = true;
    fit.coated->reason = "converged";
    ASSERT_TRUE(name_unsettled(fit, r, 0.05)); // 5.1% + 20% tail > 5%
    EXPECT_EQ(fit.coated->status, CoatedFitStatus::Underdetermined);
    EXPECT_FALSE(fit.coated->alpha_determined);
    EXPECT_FALSE(fit.coated->eta_determined);
    EXPECT_NE(fit.coated->reason.find("had not settled after 3 rounds"), std::string::npos) << fit.coated->reason;
    ASSERT_TRUE(fit.model()); // still the best estimate: rendered and factorized
    EXPECT_FLOAT_EQ(std::get<CoatedParams>(*fit.model()).alpha, 0.104f);

    MaterialFit close = state.fit;
    EXPECT_FALSE(name_unsettled(close, r, 0.3)); // within a looser bound: the status stands
    EXPECT_EQ(close.coated->status, CoatedFitStatus::Converged);

    MaterialFit lobe = fit_of(-0.9f, 0.8f, 20.0f, LafortuneFitStatus::Constrained);
    ASSERT_TRUE(name_unsettled(lobe, r, 0.05));
    EXPECT_EQ(lobe.lafortune->channel[0].status, LafortuneFitStatus::Constrained);
    EXPECT_NE(lobe.lafortune->channel[2].reason.find("had not settled"), std::string::npos);
    EXPECT_TRUE(lobe.model());

    JointResult settled = r;
    settled.unsettled_change.reset();
    settled.unsettled_remaining.reset();
    MaterialFit untouched = state.fit;
    EXPECT_FALSE(name_unsettled(untouched, settled, 0.05));
}

TEST(JointEstimate, SettledRoundsAreNotUnsettledAndSmallMovesAreNotNamed) {
    {   // settled below the tolerance before the limit
        Script s{.fits = {fit_of(-0.9f, 0.8f, 20.0f), fit_of(-0.901f, 0.8f, 20.0f)}};
        JointState state{.fit = fit_of(-1.0f, 1.0f, 10.0f)};
        const JointResult r = joint_estimate(state, {.rounds = 3, .tolerance = 0.005}, s.steps());
        EXPECT_FALSE(r.unsettled_change);
        EXPECT_FALSE(r.unsettled_remaining);
    }
    {   // settled exactly at the limit
        Script s{.fits = {fit_of(-0.9f, 0.8f, 20.0f), fit_of(-0.901f, 0.8f, 20.0f)}};
        JointState state{.fit = fit_of(-1.0f, 1.0f, 10.0f)};
        const JointResult r = joint_estimate(state, {.rounds = 2, .tolerance = 0.005}, s.steps());
        EXPECT_FALSE(r.unsettled_change);
    }
    {   // a round undone after a kept round that moved 1%: unsettled, but within the 5% bound
        Script s{.fits = {fit_of(-0.99f, 0.99f, 10.0f), fit_of(-0.98f, 0.98f, 10.0f)}, .validation = {4e-4, 3e-4, 5e-4, 6e-4}};
        JointState state{.fit = fit_of(-1.0f, 1.0f, 10.0f)};
        const JointResult r = joint_estimate(state, {.rounds = 5, .tolerance = 0.005}, s.steps());
        ASSERT_EQ(r.rounds.size(), 2u);
        EXPECT_TRUE(r.rounds[1].rejected);
        ASSERT_TRUE(r.unsettled_change);
        EXPECT_NEAR(*r.unsettled_change, 0.0101, 1e-4);
        MaterialFit fit = state.fit;
        EXPECT_FALSE(name_unsettled(fit, r, 0.05));
        EXPECT_EQ(fit.lafortune->channel[0].reason.find("settled"), std::string::npos);
    }
    {   // growing changes: unsettled, but no geometric tail to promise
        Script s{.fits = {fit_of(-0.9f, 0.8f, 20.0f), fit_of(-0.5f, 0.8f, 20.0f)}};
        JointState state{.fit = fit_of(-0.95f, 0.8f, 20.0f)};
        const JointResult r = joint_estimate(state, {.rounds = 2, .tolerance = 0.005}, s.steps());
        ASSERT_TRUE(r.unsettled_change);
        EXPECT_FALSE(r.unsettled_remaining);
    }
}

// A round undone by the validation error while the kept round had itself moved by 20% (the
// vase on the thesis rig: alpha 11% low): unsettled, by the larger move, with no tail.
TEST(JointEstimate, ARoundUndoneWhileTheMaterialStillMovedIsUnsettled) {
    Script s{.fits = {coated_of(1.45f, 0.09f), coated_of(1.47f, 0.108f), coated_of(1.47f, 0.1094f)},
             .validation = {6e-5, 3e-5, 1.4e-5, 2.1e-5, 2.0e-5}}; // round 3: 2.1e-5, and 2.0e-5 with its own albedo
    JointState state{.fit = coated_of(1.40f, 0.07f)};
    const JointResult r = joint_estimate(state, {.rounds = 8, .tolerance = 0.005}, s.steps());
    ASSERT_EQ(r.rounds.size(), 3u);
    EXPECT_TRUE(r.rounds[2].rejected);
    ASSERT_TRUE(r.unsettled_change);
    EXPECT_NEAR(*r.unsettled_change, (0.108 - 0.09) / 0.09, 1e-5); // the kept round's 20%, not the undone 1.3%
    ASSERT_TRUE(r.unsettled_remaining);
    EXPECT_EQ(*r.unsettled_remaining, 0.0);
    MaterialFit fit = state.fit;
    fit.coated->reason = "converged";
    ASSERT_TRUE(name_unsettled(fit, r, 0.05));
    EXPECT_EQ(fit.coated->status, CoatedFitStatus::Underdetermined);
    EXPECT_NE(fit.coated->reason.find("round 3 was undone"), std::string::npos) << fit.coated->reason;
    // the rounds that ran, not the limit of 8
    EXPECT_NE(fit.coated->reason.find("had not settled after 3 rounds:"), std::string::npos) << fit.coated->reason;
}

// A round whose error rises only through its albedo, solved with the material before its fit
// (coated can, thesis rig, 512 px): scored again with an albedo solved with its own material,
// it does not rise, and the round is kept with that albedo; the next round starts from there.
TEST(JointEstimate, ARoundWhoseOwnAlbedoLowersTheErrorIsKeptWithIt) {
    Script s{.fits = {coated_of(1.45f, 0.09f), coated_of(1.5f, 0.12f), coated_of(1.5f, 0.1201f)},
             .validation = {6e-5, 5e-5, 7e-5, 4e-5, 3.9e-5}};
    JointState state{.fit = coated_of(1.40f, 0.07f)};
    const JointResult r = joint_estimate(state, {.rounds = 8, .tolerance = 0.005}, s.steps());
    ASSERT_EQ(r.rounds.size(), 3u);
    EXPECT_EQ(r.accepted, 3u);
    EXPECT_FALSE(r.rounds[1].rejected);
    EXPECT_TRUE(r.rounds[1].own_albedo);
    EXPECT_DOUBLE_EQ(*r.rounds[1].validation_mse, 4e-5);
    EXPECT_FALSE(r.rounds[2].own_albedo);
    // Solves: round 1 (the first fit), round 2 (round 1's fit), round 2's own (round 2's fit),
    // which round 3 takes as its own solve instead of making it again.
    ASSERT_EQ(s.subtracted.size(), 3u);
    EXPECT_FLOAT_EQ(std::get<CoatedParams>(s.subtracted[2]).alpha, 0.12f);
    EXPECT_EQ(s.tags[2], " (joint round 2) (its own albedo)");
    EXPECT_EQ(state.solve.particles.size(), 3u); // the kept state's solve is that third one
    EXPECT_FLOAT_EQ(std::get<CoatedParams>(*state.solve_options.material).alpha, 0.12f);
    EXPECT_NE(r.stop.find("converged"), std::string::npos) << r.stop;
    EXPECT_FALSE(r.unsettled_change);
}

// The same rise, with another candidate more than kRivalFactor ahead: this one cannot win the
// choice, so no extra solve is spent on it and the round is undone; within the factor it is.
TEST(JointEstimate, ACandidateFarBehindItsRivalSpendsNoSolveOnItsOwnAlbedo) {
    for (const double rival : {4e-6, 6e-6}) { // the state's error after round 1 is 5e-5
        Script s{.fits = {coated_of(1.45f, 0.09f), coated_of(1.5f, 0.12f)}, .validation = {6e-5, 5e-5, 7e-5, 4e-5}};
        JointState state{.fit = coated_of(1.40f, 0.07f)};
        const JointResult r = joint_estimate(state, {.rounds = 2, .tolerance = 0.005, .rival_mse = rival}, s.steps());
        ASSERT_EQ(r.rounds.size(), 2u);
        const bool far_behind = 5e-5 >= kRivalFactor * rival;
        EXPECT_EQ(r.rounds[1].rejected, far_behind) << rival;
        EXPECT_EQ(r.rounds[1].own_albedo, !far_behind) << rival;
        EXPECT_EQ(s.subtracted.size(), far_behind ? 2u : 3u) << rival;
    }
}

// The coated woodenpot on the thesis rig (issue 15): its first fit lands near eta 1 and the
// rounds from there stop at the first rise of the validation error. A coated estimate whose
// rounds end below kCoatedLowEta is estimated again from kCoatedCommonEta, with its alpha,
// and the start of the lower validation error kept, with its rounds; one that climbed out runs once.
TEST(JointEstimate, AnEstimateEndingNearAnIndexOfOneIsEstimatedAgainFromACommonDielectric) {
    // From eta 1.02: round 1 (eta 1.03) raises the error, with its own albedo too: stopped.
    // From eta 1.5: round 1 (1.46) and round 2 (1.459, settled) lower it.
    Script s{.fits = {coated_of(1.03f, 0.3f), coated_of(1.46f, 0.29f), coated_of(1.459f, 0.2901f)},
             .validation = {1e-5, 1.2e-5, 1.1e-5, 5e-6, 1e-6, 9e-7}};
    JointState state{.fit = coated_of(1.02f, 0.31f)};
    const JointResult r = joint_estimate(state, {.rounds = 8, .tolerance = 0.005}, s.steps());
    ASSERT_TRUE(r.restart);
    EXPECT_FLOAT_EQ(static_cast<float>(r.restart->first_eta), 1.02f);
    EXPECT_FLOAT_EQ(static_cast<float>(r.restart->common_eta), kCoatedCommonEta);
    EXPECT_DOUBLE_EQ(*r.restart->first_mse, 1e-5);
    EXPECT_DOUBLE_EQ(*r.restart->common_mse, 9e-7);
    EXPECT_TRUE(r.restart->common_kept);
    // The kept rounds are the second start's, and so is the state.
    EXPECT_EQ(r.accepted, 2u);
    EXPECT_DOUBLE_EQ(*r.first_validation_mse, 5e-6);
    EXPECT_FLOAT_EQ(state.fit.coated->params.eta, 1.459f);
    EXPECT_DOUBLE_EQ(*state.validation_mse, 9e-7);
    // Solves: the first start's round 1 and its own albedo, then the second start's rounds 1 and
    // 2, the first of which subtracted eta 1.5 with the first fit's alpha.
    ASSERT_EQ(s.subtracted.size(), 4u);
    EXPECT_FLOAT_EQ(std::get<CoatedParams>(s.subtracted[2]).eta, kCoatedCommonEta);
    EXPECT_FLOAT_EQ(std::get<CoatedParams>(s.subtracted[2]).alpha, 0.31f);
    EXPECT_EQ(state.solve.particles.size(), 4u);
}

TEST(JointEstimate, TheFirstStartIsKeptWhereItsErrorIsLowerAndOneStartWhereItClimbsTrailsOrTheIndexIsHeld) {
    {
        // From eta 1.05: round 1 (1.0505, settled) lowers the error to 2e-6; from 1.5 the first
        // round raises it (with its own albedo too) and the start ends at 4e-6.
        Script s{.fits = {coated_of(1.0505f, 0.2f), coated_of(1.4f, 0.2f)}, .validation = {3e-6, 2e-6, 4e-6, 5e-6, 4.5e-6}};
        JointState state{.fit = coated_of(1.05f, 0.2f)};
        const JointResult r = joint_estimate(state, {.rounds = 8, .tolerance = 0.005}, s.steps());
        ASSERT_TRUE(r.restart);
        EXPECT_FALSE(r.restart->common_kept);
        EXPECT_DOUBLE_EQ(*r.restart->common_mse, 4e-6);
        EXPECT_FLOAT_EQ(state.fit.coated->params.eta, 1.0505f);
        EXPECT_DOUBLE_EQ(*state.validation_mse, 2e-6);
        EXPECT_EQ(r.accepted, 1u);
        EXPECT_EQ(state.solve.particles.size(), 1u); // the first start's round-1 solve
    }
    {
        // From eta 1.02 the rounds climb to 1.3 and settle: one start.
        Script s{.fits = {coated_of(1.3f, 0.2f), coated_of(1.3001f, 0.2f)}, .validation = {3e-6, 2e-6, 1e-6}};
        JointState state{.fit = coated_of(1.02f, 0.2f)};
        const JointResult r = joint_estimate(state, {.rounds = 8, .tolerance = 0.005}, s.steps());
        EXPECT_FALSE(r.restart);
        EXPECT_EQ(r.accepted, 2u);
        EXPECT_EQ(s.subtracted.size(), 2u);
    }
    {
        // Another candidate more than kRivalFactor ahead (2.9e-6 against 2e-7): one start.
        Script s{.fits = {coated_of(1.0505f, 0.2f)}, .validation = {3e-6, 2.9e-6}};
        JointState state{.fit = coated_of(1.05f, 0.2f)};
        const JointResult r = joint_estimate(state, {.rounds = 8, .tolerance = 0.005, .rival_mse = 2e-7}, s.steps());
        EXPECT_FALSE(r.restart);
        EXPECT_EQ(s.subtracted.size(), 1u);
    }
    {
        // --coated-eta holds the index: one start.
        Script s{.fits = {coated_of(1.02f, 0.2f)}, .validation = {3e-6, 2e-6}};
        JointState state{.fit = coated_of(1.02f, 0.2f)};
        const JointResult r =
            joint_estimate(state, {.rounds = 8, .tolerance = 0.005, .restart_low_index = false}, s.steps());
        EXPECT_FALSE(r.restart);
        EXPECT_EQ(s.subtracted.size(), 1u);
    }
    {
        // Without a validation step (the final estimate on all the train frames): one start.
        Script s{.fits = {coated_of(1.02f, 0.2f)}};
        JointState state{.fit = coated_of(1.02f, 0.2f)};
        const JointResult r = joint_estimate(state, {.rounds = 1, .tolerance = 0.005}, s.steps());
        EXPECT_FALSE(r.restart);
        EXPECT_EQ(s.subtracted.size(), 1u);
    }
}

TEST(JointEstimate, ConvergedLobeKeepsOnlyConvergedChannels) {
    MaterialFit f = fit_of(-0.9f, 0.8f, 20.0f);
    f.lafortune->channel[1].status = LafortuneFitStatus::NoSpecularEnergy;
    const LafortuneRgb l = std::get<LafortuneRgb>(*f.model());
    EXPECT_FLOAT_EQ(l.cx.x, -0.9f);
    EXPECT_FLOAT_EQ(l.cx.y, 0.0f);
    EXPECT_FLOAT_EQ(l.cz.y, 0.0f);
    EXPECT_FLOAT_EQ(l.n.z, 20.0f);
}

TEST(ValidationSplit, OneLightOfEveryViewWithEnoughFramesTurningFromViewToView) {
    LambertInputs in;
    in.views.resize(4);
    in.views[0].frames = {0, 1, 2, 3, 4, 5};
    in.views[1].frames = {6, 7, 8, 9, 10, 11};
    in.views[2].frames = {12, 13, 14};     // too few: kept whole
    in.views[3].frames = {15, 16, 17, 18};
    const ValidationSplit s = split_validation_frames(in);
    EXPECT_EQ(s.held_out, 3u);
    EXPECT_EQ(s.validation.views[0].frames, std::vector<std::uint32_t>{0});
    EXPECT_EQ(s.validation.views[1].frames, std::vector<std::uint32_t>{7});
    EXPECT_TRUE(s.validation.views[2].frames.empty());
    EXPECT_EQ(s.validation.views[3].frames, std::vector<std::uint32_t>{18});
    EXPECT_EQ(s.fit.views[0].frames, (std::vector<std::uint32_t>{1, 2, 3, 4, 5}));
    EXPECT_EQ(s.fit.views[2].frames, (std::vector<std::uint32_t>{12, 13, 14}));
    EXPECT_EQ(s.fit.views[3].frames, (std::vector<std::uint32_t>{15, 16, 17}));
}

} // namespace
} // namespace specula
