// The whole pipeline chooses the material family by held-out error (issue 15): a coated truth
// and a Lafortune truth, each synthesized by the ground-truth renderer (a model the other
// family does not contain), reconstructed with --material auto. The chosen family must be the
// truth's; the coated parameters are compared with capture.json's ground_truth; the joint
// rounds kept must never raise the validation error. Images are 128 px and 12 views to keep
// each case under a minute on two cores (at 128 px the albedo textures are finer than the
// pixels, which biases alpha by about 2%; docs/pipeline.md 5.7 gives the 512 px figures).
#include "pipeline/joint.h"
#include "pipeline/reconstruct.h"
#include "synth/presets.h"
#include "synth/synth.h"
#include "test_dirs.h"
#include "vulkan_env.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <string>

namespace specula {
namespace {

namespace fs = std::filesystem;

struct ChoiceCase {
    std::string name;
    MaterialFamily truth;
    synth::RigKind rig;
    double tol_eta = 0.02, tol_alpha = 0.05;
};

// The can at 128 px, 12 views, of the given truth and rig, reconstructed without evaluation or
// refinement; `grid` > 0 forces a small factorization grid where the choice is the test.
ReconstructResult reconstruct_can(const fs::path& dir, MaterialFamily truth, synth::RigKind rig, bool lambertian,
                                  std::uint32_t grid = 0, Toggle indirect = Toggle::Auto) {
    synth::SynthOptions so;
    so.size = 128;
    so.views = 12;
    so.rig = rig;
    so.lambertian = lambertian;
    const fs::path capture = dir / "can";
    (void)synth::write_synthetic_capture(synth::to_object(synth::make_preset("can", lambertian, truth)), capture, so);
    ReconstructConfig c;
    c.capture = capture;
    c.out_dir = dir / "out";
    c.evaluate = false;
    c.refine_rounds = 0;
    c.threads = 2;
    c.factorization_grid_h = c.factorization_grid_d = grid;
    c.indirect = indirect;
    return reconstruct(c);
}

// The bundle's albedo is solved from every train frame: the validation frames held out for the
// candidates are put back (the first solve leaves them out). Every (pair, frame) sample of the
// final solve is used or rejected once, so the samples add up to the pairs times the views'
// train frames (every view of these captures has as many).
void expect_every_train_frame_solved(const nlohmann::json& report, const fs::path& capture_json) {
    const nlohmann::json frames = nlohmann::json::parse(std::ifstream(capture_json))["frames"];
    std::map<int, std::uint64_t> train;
    for (const nlohmann::json& f : frames)
        if (f["split"] == "train") ++train[f["view_index"].get<int>()];
    ASSERT_FALSE(train.empty());
    const std::uint64_t per_view = train.begin()->second;
    std::uint64_t samples = 0;
    for (const auto& [name, count] : report["diffuse"]["samples"].items()) samples += count.get<std::uint64_t>();
    EXPECT_EQ(samples, report["diffuse"]["pairs"].get<std::uint64_t>() * per_view) << report["diffuse"]["samples"].dump();
}

class MaterialChoice : public ::testing::TestWithParam<ChoiceCase> {};

TEST_P(MaterialChoice, AutoPicksTheTruthsFamilyAndTheRoundsNeverRaiseTheValidationError) {
    const ChoiceCase& cc = GetParam();
    test::TempDir dir("choice");
    const ReconstructResult r = reconstruct_can(dir.path(), cc.truth, cc.rig, /*lambertian=*/false);
    const nlohmann::json& m = r.report["specular"]["material"];
    ASSERT_TRUE(m.is_object()) << r.report["specular"].dump();
    std::printf("%s: %s\n", cc.name.c_str(), m["choice"].get<std::string>().c_str());
    EXPECT_EQ(m["family"], to_string(cc.truth));
    EXPECT_GT(m["validation_frames"].get<int>(), 0);
    ASSERT_EQ(m["candidates"].size(), kMaterialFamilyCount);
    double winner_mse = 0.0;
    std::size_t screened = 0;
    for (const nlohmann::json& cand : m["candidates"])
        if (cand["family"] == m["family"]) winner_mse = cand["validation_mse"].get<double>();
    for (const nlohmann::json& cand : m["candidates"]) {
        const nlohmann::json& joint = cand["joint"];
        std::printf("  %s: %zu rounds, %s\n", cand["family"].get<std::string>().c_str(), joint["rounds"].size(),
                    joint["stop"].get<std::string>().c_str());
        // A screened candidate (its fit on kScreenSamples) is more than kScreenFactor behind
        // another candidate's first fit, has no full fit and no rounds, and does not win.
        const auto screen = cand["screen_samples"].get<std::size_t>();
        EXPECT_EQ(screen != 0, joint["stop"].get<std::string>().starts_with("screened")) << cand["family"];
        if (screen != 0) {
            ++screened;
            EXPECT_NE(cand["family"], m["family"]);
            EXPECT_LE(screen, kScreenSamples);
            EXPECT_TRUE(joint["rounds"].empty());
            double least_other = std::numeric_limits<double>::infinity();
            for (const nlohmann::json& other : m["candidates"])
                if (other["screen_samples"].get<std::size_t>() == 0)
                    least_other = std::min(least_other, other["joint"]["first_validation_mse"].get<double>());
            ASSERT_TRUE(std::isfinite(least_other));
            EXPECT_GT(joint["first_validation_mse"].get<double>(), kScreenFactor * least_other) << cand["family"];
        }
        // A candidate runs no rounds only where its first fit is more than kNoRoundsFactor behind
        // the error another candidate's rounds reached (at least the winner's): it cannot win.
        if (joint["stop"].get<std::string>().starts_with("no rounds")) {
            EXPECT_NE(cand["family"], m["family"]);
            EXPECT_TRUE(joint["rounds"].empty());
            EXPECT_GT(joint["first_validation_mse"].get<double>(), kNoRoundsFactor * winner_mse) << cand["family"];
        }
        double last = joint["first_validation_mse"].get<double>();
        for (const nlohmann::json& round : joint["rounds"]) {
            if (round.value("rejected", false)) continue;
            EXPECT_LE(round["validation_mse"].get<double>(), last) << cand["family"] << " round " << round["round"];
            last = round["validation_mse"].get<double>();
        }
        ASSERT_TRUE(cand["validation_mse"].is_number());
        EXPECT_DOUBLE_EQ(cand["validation_mse"].get<double>(), last) << cand["family"];
    }
    // The bundle's albedo goes with its material: solved once more with the final material
    // wherever the rounds ended with it still moving, or ran none (the first solve's is Lambertian).
    const nlohmann::json& joint = r.report["specular"]["joint"];
    EXPECT_EQ(joint["final_solve"].get<bool>(), !joint["settled"].get<bool>() || joint["accepted"].get<int>() == 0) << joint.dump();
    expect_every_train_frame_solved(r.report, dir.path() / "can" / "capture.json");
    if (cc.truth == MaterialFamily::Coated) {
        const nlohmann::json& fit = r.report["specular"]["coated"];
        const nlohmann::json truth = nlohmann::json::parse(std::ifstream(dir.path() / "can" / "capture.json"))["ground_truth"]["material"];
        const double eta = fit["eta"], alpha = fit["alpha"], teta = truth["eta"], talpha = truth["alpha"];
        std::printf("  eta %.4f (truth %.4f, %+.2f%%), alpha %.4f (truth %.4f, %+.2f%%), %s\n", eta, teta, 100 * (eta - teta) / teta,
                    alpha, talpha, 100 * (alpha - talpha) / talpha, fit["reason"].get<std::string>().c_str());
        EXPECT_NEAR(eta, teta, cc.tol_eta * teta);
        EXPECT_NEAR(alpha, talpha, cc.tol_alpha * talpha);
        EXPECT_EQ(r.report["bundle"]["has_lobe"], true); // the bundle carries the coated specular
    }
    // Where the truth is a Lafortune lobe the coated candidate is far behind and only screened;
    // where it is coated the Lafortune candidate, fitted first, is never screened.
    EXPECT_EQ(screened, cc.truth == MaterialFamily::Lafortune ? 1u : 0u);
}

INSTANTIATE_TEST_SUITE_P(Truths, MaterialChoice,
                         ::testing::Values(ChoiceCase{"coated_spread", MaterialFamily::Coated, synth::RigKind::Spread},
                                           ChoiceCase{"coated_thesis", MaterialFamily::Coated, synth::RigKind::Thesis, 0.02, 0.05},
                                           ChoiceCase{"lafortune_spread", MaterialFamily::Lafortune, synth::RigKind::Spread}),
                         [](const auto& info) { return info.param.name; });

// Without the indirect stage's rounds (which solve every train frame) the first solve is the
// candidates' own, on the train frames less the validation frames: it is not made twice, and
// the validation frames are put back for the bundle's albedo.
TEST(MaterialChoice, TheFirstSolveIsTheCandidatesAndTheBundleGetsEveryTrainFrame) {
    test::TempDir dir("choice");
    const ReconstructResult r =
        reconstruct_can(dir.path(), MaterialFamily::Lafortune, synth::RigKind::Spread, /*lambertian=*/false, 0, Toggle::Off);
    EXPECT_EQ(r.report["specular"]["material"]["family"], "lafortune");
    std::size_t first_solves = 0;
    for (const nlohmann::json& stage : r.report["stages"]) {
        const std::string name = stage["name"];
        first_solves += name == "diffuse solve" || name == "diffuse solve (validation split)";
        EXPECT_EQ(name.find("indirect round"), std::string::npos) << name;
    }
    EXPECT_EQ(first_solves, 1u);
    expect_every_train_frame_solved(r.report, dir.path() / "can" / "capture.json");
}

// The thesis's near-camera rig (issue 15): every light of a particle's best view sees its
// highlight, so the first (Lambertian) solve absorbs most of a real lobe and the residuals keep
// about 2 noise variances of it (can, Lafortune truth, 128 px: 2.13), below the energy
// threshold 4 that used to leave the specular out. With validation frames the planner lets
// the held-out error decide: the Lafortune truth keeps a specular (constrained: the rig shows
// one light-view angle), whose validation error beats "diffuse only"; a Lambertian truth
// (0.35 noise variances: the candidates run too) still ends diffuse only and says why.
ReconstructResult reconstruct_thesis_rig(const fs::path& dir, bool lambertian) {
    return reconstruct_can(dir, MaterialFamily::Lafortune, synth::RigKind::Thesis, lambertian, /*grid=*/16);
}

const nlohmann::json& planner_decision(const nlohmann::json& report, const std::string& name) {
    for (const auto& d : report["planner"])
        if (d["name"] == name) return d;
    static const nlohmann::json kNull;
    ADD_FAILURE() << "no planner decision " << name;
    return kNull;
}

TEST(MaterialChoiceThesisRig, LafortuneTruthKeepsASpecularThatBeatsDiffuseOnly) {
    test::TempDir dir("choice");
    const ReconstructResult r = reconstruct_thesis_rig(dir.path(), false);
    const nlohmann::json& s = r.report["specular"];
    std::printf("energy %.3f noise variances; %s\n", s["energy"]["ratio_to_noise_variance"].get<double>(),
                s["material"].value("choice", std::string()).c_str());
    EXPECT_FALSE(s["energy"]["has_specular"].get<bool>()); // below the threshold: the case this covers
    EXPECT_EQ(planner_decision(r.report, "specular_stages")["value"], "validate");
    ASSERT_TRUE(s["material"].is_object());
    EXPECT_EQ(s["material"]["family"], "lafortune");
    ASSERT_TRUE(s["material"]["diffuse_only"].is_object());
    double best = std::numeric_limits<double>::infinity();
    for (const nlohmann::json& cand : s["material"]["candidates"])
        if (cand["validation_mse"].is_number()) best = std::min(best, cand["validation_mse"].get<double>());
    EXPECT_LT(best, s["material"]["diffuse_only"]["validation_mse"].get<double>());
    for (const nlohmann::json& status : s["lobe"]["status"]) EXPECT_TRUE(status == "constrained" || status == "converged") << status;
    EXPECT_EQ(r.report["bundle"]["has_lobe"], true);
    expect_every_train_frame_solved(r.report, dir.path() / "can" / "capture.json");
}

TEST(MaterialChoiceThesisRig, LambertianTruthEndsDiffuseOnlyAndSaysWhy) {
    test::TempDir dir("choice");
    const ReconstructResult r = reconstruct_thesis_rig(dir.path(), true);
    const nlohmann::json& s = r.report["specular"];
    std::printf("energy %.3f noise variances\n", s["energy"]["ratio_to_noise_variance"].get<double>());
    EXPECT_EQ(planner_decision(r.report, "specular_stages")["value"], "skip");
    EXPECT_TRUE(s["lobe"].is_null());
    EXPECT_EQ(r.report["bundle"]["has_lobe"], false);
    bool said = false;
    for (const auto& l : r.report["left_out"]) said = said || l.dump().find("specular fit") != std::string::npos;
    EXPECT_TRUE(said) << r.report["left_out"].dump();
    expect_every_train_frame_solved(r.report, dir.path() / "can" / "capture.json");
}

} // namespace
} // namespace specula
