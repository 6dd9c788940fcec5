// The joint estimate's loop (pipeline/joint.h) with scripted steps: no capture, no device.
// Each fit the script returns is the next lobe; the test checks which lobe each solve
// subtracted, when the loop stops and what it records.
#include "pipeline/joint.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace specula {
namespace {

LafortuneFitRgb fit_of(float cx, float cz, float n, LafortuneFitStatus status = LafortuneFitStatus::Converged) {
    LafortuneFitRgb f;
    for (LafortuneChannelFit& c : f.channel) {
        c.cx = cx;
        c.cz = cz;
        c.n = n;
        c.status = status;
    }
    return f;
}

struct Script {
    std::vector<LafortuneFitRgb> fits; // returned by the fit step, in order
    std::vector<LafortuneRgb> subtracted; // the lobe each solve was given
    std::vector<std::string> tags;
    std::size_t next = 0;
    JointSteps steps() {
        return JointSteps{.solve =
                              [this](const LambertOptions& o, const std::string& tag) {
                                  subtracted.push_back(o.lobe);
                                  tags.push_back(tag);
                                  return LambertOutputs{};
                              },
                          .residuals = [](const LambertOutputs&, const std::string&) { return ResidualSamples{}; },
                          .fit = [this](std::vector<LafortuneSample>, const std::string&) { return fits.at(next++); }};
    }
};

TEST(JointEstimate, StopsWhenTheLobeSettlesAndSubtractsThePreviousFit) {
    Script s{.fits = {fit_of(-0.9f, 0.8f, 20.0f), fit_of(-0.901f, 0.8f, 20.0f), fit_of(-0.5f, 0.5f, 5.0f)}};
    JointState state{.solve_options = {}, .solve = {}, .residuals = {}, .fit = fit_of(-1.0f, 1.0f, 10.0f)};
    const JointResult r = joint_estimate(state, {.rounds = 3, .tolerance = 0.005}, s.steps());
    ASSERT_EQ(r.rounds.size(), 2u);                  // -0.9 -> -0.901 is 0.11% < 0.5%: the third fit is never asked for
    EXPECT_EQ(s.next, 2u);
    ASSERT_EQ(s.subtracted.size(), 2u);
    EXPECT_FLOAT_EQ(s.subtracted[0].cx.x, -1.0f);    // round 1 subtracts the first fit
    EXPECT_FLOAT_EQ(s.subtracted[1].cx.x, -0.9f);    // round 2 the fit of round 1
    EXPECT_EQ(s.tags[1], " (joint round 2)");
    EXPECT_NEAR(r.rounds[0].max_relative_change, 1.0, 1e-6); // N: 10 -> 20
    EXPECT_LT(r.rounds[1].max_relative_change, 0.005);
    EXPECT_NE(r.stop.find("converged"), std::string::npos) << r.stop;
    EXPECT_FLOAT_EQ(state.fit.channel[0].cx, -0.901f);
    EXPECT_FLOAT_EQ(state.solve_options.lobe.cx.x, -0.9f); // the last solve's options carry its lobe
}

TEST(JointEstimate, StopsAtTheRoundLimit) {
    Script s{.fits = {fit_of(-0.5f, 0.5f, 5.0f), fit_of(-1.0f, 1.0f, 10.0f), fit_of(-0.5f, 0.5f, 5.0f)}};
    JointState state{.solve_options = {}, .solve = {}, .residuals = {}, .fit = fit_of(-1.0f, 1.0f, 10.0f)};
    const JointResult r = joint_estimate(state, {.rounds = 2, .tolerance = 0.005}, s.steps());
    EXPECT_EQ(r.rounds.size(), 2u);
    EXPECT_EQ(r.stop, "joint rounds: 2 allowed");
}

TEST(JointEstimate, NothingToSubtractWithoutAConvergedChannel) {
    Script s{.fits = {fit_of(-0.9f, 0.8f, 20.0f)}};
    JointState state{.solve_options = {}, .solve = {}, .residuals = {},
                     .fit = fit_of(-1.0f, 1.0f, 10.0f, LafortuneFitStatus::Underdetermined)};
    const JointResult r = joint_estimate(state, {.rounds = 3, .tolerance = 0.005}, s.steps());
    EXPECT_TRUE(r.rounds.empty());
    EXPECT_TRUE(s.subtracted.empty());
    EXPECT_NE(r.stop.find("no channel converged"), std::string::npos) << r.stop;
}

TEST(JointEstimate, ZeroRoundsIsTheThesissOnePass) {
    Script s;
    JointState state{.solve_options = {}, .solve = {}, .residuals = {}, .fit = fit_of(-1.0f, 1.0f, 10.0f)};
    const JointResult r = joint_estimate(state, {.rounds = 0, .tolerance = 0.005}, s.steps());
    EXPECT_TRUE(r.rounds.empty());
    EXPECT_TRUE(s.subtracted.empty());
}

TEST(JointEstimate, ConvergedLobeKeepsOnlyConvergedChannels) {
    LafortuneFitRgb f = fit_of(-0.9f, 0.8f, 20.0f);
    f.channel[1].status = LafortuneFitStatus::NoSpecularEnergy;
    const LafortuneRgb l = f.converged_lobe();
    EXPECT_FLOAT_EQ(l.cx.x, -0.9f);
    EXPECT_FLOAT_EQ(l.cx.y, 0.0f);
    EXPECT_FLOAT_EQ(l.cz.y, 0.0f);
    EXPECT_FLOAT_EQ(l.n.z, 20.0f);
}

} // namespace
} // namespace specula
