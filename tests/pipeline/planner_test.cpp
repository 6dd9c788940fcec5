// The planner's decision functions, the sweep's Pareto front and the HTML report, on
// plain data (no capture, no device).
#include "indirect/indirect.h"
#include "pipeline/planner.h"
#include "pipeline/sweep.h"
#include "report/report_html.h"
#include "report/svg_plot.h"

#include <gtest/gtest.h>

#include <random>

namespace specula {
namespace {

using nlohmann::json;

LafortuneRgb lobe(float cx, float cz, float n) {
    LafortuneRgb l;
    l.cx = glm::vec3(cx);
    l.cz = glm::vec3(cz);
    l.n = glm::vec3(n);
    return l;
}

TEST(Planner, NearMirrorLobeGetsAFinerFactorizationGridThanABroadOne) {
    const PlanDecision broad = decide_factorization_grid(lobe(-1.0f, 1.0f, 10.0f), 0, 0);
    const PlanDecision mirror = decide_factorization_grid(lobe(-1.0f, 1.0f, 2000.0f), 0, 0);
    EXPECT_FALSE(broad.forced);
    EXPECT_FALSE(mirror.forced);
    // 2 cells per half-width sqrt(2/N): R_h = ceil(2 sqrt(N)) clamped to [16, 128].
    EXPECT_EQ(broad.detail["grid_h"].get<int>(), 16);
    EXPECT_EQ(mirror.detail["grid_h"].get<int>(), 90);
    EXPECT_GT(mirror.detail["cube_g"].get<int>(), broad.detail["cube_g"].get<int>());
    EXPECT_NE(mirror.reason.find("N = 2000"), std::string::npos) << mirror.reason;
    // Forcing the grid is recorded as forced, and the reason keeps the planner's own choice.
    const PlanDecision forced = decide_factorization_grid(lobe(-1.0f, 1.0f, 10.0f), 64, 32);
    EXPECT_TRUE(forced.forced);
    EXPECT_EQ(forced.detail["grid_h"].get<int>(), 64);
    EXPECT_EQ(forced.detail["grid_d"].get<int>(), 32);
    EXPECT_NE(forced.reason.find("would use h 16"), std::string::npos) << forced.reason;
}

TEST(Planner, FactorizationCostIsAnEstimateWhenAutoAndMeasuredWhenForced) {
    PlanDecision a = decide_factorization_grid(lobe(-1.0f, 1.0f, 10.0f), 0, 0);
    set_factorization_cost(a, 0.01, "matrix and decomposition wall time");
    ASSERT_TRUE(a.avoided_seconds.has_value());
    // 16 x 16 against R_h R_d = 3072: (3072 / 256)^2 = 144 times the entries.
    EXPECT_NEAR(*a.avoided_seconds, 0.01 * 143.0, 1e-9);
    EXPECT_FALSE(a.measured_seconds.has_value());
    PlanDecision f = decide_factorization_grid(lobe(-1.0f, 1.0f, 10.0f), 64, 32);
    set_factorization_cost(f, 0.5, "matrix and decomposition wall time");
    EXPECT_FALSE(f.avoided_seconds.has_value());
    EXPECT_EQ(f.measured_seconds.value_or(0.0), 0.5);
}

TEST(Planner, OcclusionRaysFollowConvexityUnlessForced) {
    ConvexityReport convex;
    convex.convex = true;
    ConvexityReport concave;
    concave.reason = "12 reflex edges";
    EXPECT_EQ(decide_occlusion_rays(convex, Toggle::Auto).value, "skip");
    EXPECT_TRUE(decide_occlusion_rays(convex, Toggle::Auto).skipped);
    EXPECT_EQ(decide_occlusion_rays(concave, Toggle::Auto).value, "cast");
    const PlanDecision on = decide_occlusion_rays(convex, Toggle::On);
    EXPECT_EQ(on.value, "cast");
    EXPECT_TRUE(on.forced);
    const PlanDecision off = decide_occlusion_rays(concave, Toggle::Off);
    EXPECT_EQ(off.value, "skip");
    EXPECT_NE(off.reason.find("biased"), std::string::npos) << off.reason; // honest about what forcing off costs
}

TEST(Planner, SpecularStagesFollowTheEnergyTest) {
    ResidualEnergy quiet{.mean_square = 1e-5, .mean = 0.0, .noise_sigma = 0.004, .ratio = 0.6, .threshold = 4.0, .has_specular = false};
    ResidualEnergy shiny = quiet;
    shiny.ratio = 40.0, shiny.has_specular = true;
    EXPECT_EQ(decide_specular(quiet, Toggle::Auto).value, "skip");
    EXPECT_EQ(decide_specular(shiny, Toggle::Auto).value, "fit");
    const PlanDecision forced = decide_specular(quiet, Toggle::On);
    EXPECT_EQ(forced.value, "fit");
    EXPECT_TRUE(forced.forced);
    PlanDecision skip = decide_specular(quiet, Toggle::Auto);
    set_specular_cost(skip, 0.2, 4000, 200000, std::nullopt);
    EXPECT_NEAR(skip.avoided_seconds.value_or(0.0), 10.0, 1e-9); // 0.2 s x 200000 / 4000
}

// Near-camera lights (the thesis rig) leave a real lobe mostly in the first solve's albedo:
// can, Lafortune truth, 128 px: 2.13 noise variances, below the threshold 4; vase, Lafortune
// truth, 256 px: 0.21, less than a Lambertian truth's 0.35. With validation frames, below the
// threshold the held-out error decides.
TEST(Planner, LittleEnergyWithValidationFramesLetsTheHeldOutErrorDecide) {
    ResidualEnergy weak{.mean_square = 3.4e-5, .mean = 0.0, .noise_sigma = 0.004, .ratio = 2.13, .threshold = 4.0, .has_specular = false};
    const PlanDecision v = decide_specular(weak, Toggle::Auto, 12);
    EXPECT_EQ(v.value, "validate");
    EXPECT_FALSE(v.skipped);
    EXPECT_NE(v.reason.find("diffuse only"), std::string::npos) << v.reason;
    EXPECT_EQ(decide_specular(weak, Toggle::Auto, 0).value, "skip"); // no validation frames: the threshold alone
    ResidualEnergy faint = weak;
    faint.ratio = 0.21;
    EXPECT_EQ(decide_specular(faint, Toggle::Auto, 12).value, "validate");
    EXPECT_EQ(decide_specular(faint, Toggle::Auto, 0).value, "skip");
    ResidualEnergy shiny = weak;
    shiny.ratio = 40.0, shiny.has_specular = true;
    EXPECT_EQ(decide_specular(shiny, Toggle::Auto, 12).value, "fit"); // above the threshold: no competition
    EXPECT_EQ(decide_specular(weak, Toggle::On, 12).value, "fit");
    EXPECT_EQ(decide_specular(weak, Toggle::Off, 12).value, "skip");
}

TEST(Planner, DiffuseModeNeedsNonCoplanarLights) {
    LightConditioning good{.views = 10, .capable_views = 10, .median_rcond = 0.05, .min_rcond = 1e-3, .min_lights = 6};
    LightConditioning bad{.views = 10, .capable_views = 2, .median_rcond = 0.0, .min_rcond = 1e-3, .min_lights = 2};
    EXPECT_EQ(decide_diffuse_mode(good, DiffuseModeChoice::Auto, /*specular_may_run=*/false).value, "photometric");
    EXPECT_EQ(decide_diffuse_mode(bad, DiffuseModeChoice::Auto, false).value, "albedo");
    // While a lobe may be fitted, the photometric solve would eat the highlights.
    const PlanDecision keep = decide_diffuse_mode(good, DiffuseModeChoice::Auto, true);
    EXPECT_EQ(keep.value, "albedo");
    EXPECT_NE(keep.reason.find("highlight"), std::string::npos) << keep.reason;
    const PlanDecision forced = decide_diffuse_mode(bad, DiffuseModeChoice::Photometric, true);
    EXPECT_EQ(forced.value, "photometric");
    EXPECT_TRUE(forced.forced);
    EXPECT_NE(forced.reason.find("would choose albedo"), std::string::npos) << forced.reason;
}

TEST(Planner, AtlasDecisionNamesTheModeAndCountsPatchworkAsForced) {
    AtlasSummary charts;
    charts.mode = "charts";
    charts.size_source = "cameras";
    charts.width = 454;
    charts.height = 355;
    charts.charts = 49;
    charts.seam_edges = 1125;
    charts.mesh_vertices = 14744;
    charts.atlas_vertices = 15915;
    const PlanDecision automatic = decide_atlas(charts, AtlasOptions{}, 125889, 10.0);
    EXPECT_FALSE(automatic.forced);
    EXPECT_EQ(automatic.value.rfind("charts 454x355 (49 charts, 1125 seam edges)", 0), 0u) << automatic.value;
    EXPECT_EQ(automatic.detail["mode"], "charts");
    EXPECT_EQ(automatic.detail["charts"].get<int>(), 49);
    EXPECT_EQ(automatic.detail["vertices"]["atlas"].get<int>(), 15915);
    EXPECT_NE(automatic.reason.find("15915 in the bundle"), std::string::npos) << automatic.reason;
    EXPECT_TRUE(automatic.avoided_seconds.has_value());

    AtlasSummary patchwork = charts;
    patchwork.mode = "patchwork";
    patchwork.charts = patchwork.seam_edges = 0;
    patchwork.atlas_vertices = 86400;
    const PlanDecision forced = decide_atlas(patchwork, AtlasOptions{.mode = AtlasMode::Patchwork}, 485824, 20.0);
    EXPECT_TRUE(forced.forced);
    EXPECT_EQ(forced.value.rfind("patchwork 454x355, 1 texel(s) per pixel", 0), 0u) << forced.value;
    EXPECT_NE(forced.reason.find("--atlas patchwork"), std::string::npos) << forced.reason;
    EXPECT_EQ(forced.measured_seconds, 20.0);
}

TEST(Planner, PlanJsonSaysAutoOrForced) {
    Plan plan;
    plan.add(decide_specular(ResidualEnergy{}, Toggle::Off));
    plan.add(PlanDecision{.name = "atlas", .value = "64x64"});
    plan.add(PlanDecision{.name = "atlas", .value = "128x128"}); // replaces in place
    const json j = plan.to_json();
    ASSERT_EQ(j.size(), 2u);
    EXPECT_EQ(j[0]["mode"], "forced");
    EXPECT_EQ(j[1]["mode"], "auto");
    EXPECT_EQ(j[1]["value"], "128x128");
    EXPECT_TRUE(j[1]["avoided_seconds"].is_null());
}

TEST(Sweep, ParetoFrontIsNonDominatedAndCoversEveryOtherPoint) {
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (int trial = 0; trial < 20; ++trial) {
        std::vector<std::pair<double, double>> xy;
        for (int i = 0; i < 30; ++i) xy.emplace_back(u(rng), u(rng));
        xy.emplace_back(xy[4]); // an exact tie: only one of them is on the front
        const std::vector<std::size_t> front = pareto_front(xy);
        ASSERT_FALSE(front.empty());
        for (std::size_t k = 1; k < front.size(); ++k) {
            EXPECT_LE(xy[front[k - 1]].first, xy[front[k]].first); // by increasing time
            EXPECT_GT(xy[front[k - 1]].second, xy[front[k]].second); // and strictly decreasing error
        }
        for (std::size_t i = 0; i < xy.size(); ++i) {
            const bool on = std::find(front.begin(), front.end(), i) != front.end();
            bool dominated = false;
            for (std::size_t f : front)
                if (f != i && xy[f].first <= xy[i].first && xy[f].second <= xy[i].second) dominated = true;
            EXPECT_NE(on, dominated) << "point " << i;
        }
    }
    const std::vector<std::pair<double, double>> with_nan{{1.0, std::nan("")}, {2.0, 1.0}};
    EXPECT_EQ(pareto_front(with_nan), std::vector<std::size_t>{1});
}

TEST(ReportHtml, EscapesAndEncodes) {
    EXPECT_EQ(report::html_escape("<a href=\"x\">&'</a>"), "&lt;a href=&quot;x&quot;&gt;&amp;&#39;&lt;/a&gt;");
    const std::string text = "Man";
    EXPECT_EQ(report::base64(std::span(reinterpret_cast<const std::uint8_t*>(text.data()), 3)), "TWFu");
    EXPECT_EQ(report::base64(std::span(reinterpret_cast<const std::uint8_t*>(text.data()), 2)), "TWE=");
    EXPECT_EQ(report::base64(std::span(reinterpret_cast<const std::uint8_t*>(text.data()), 1)), "TQ==");
}

TEST(ReportHtml, ShowsPlannerLeftOutAndBothPixelSetsWithEscapedStrings) {
    json q = {{"frames", 3}, {"q1", 93.5}, {"q2", 97.0}, {"rms_percent", 6.5}, {"psnr", 30.1}};
    json r = {{"capture", {{"path", "/tmp/<script>"}, {"views", 4}}},
              {"planner", json::array({{{"name", "occlusion_rays"}, {"value", "skip"}, {"mode", "auto"}, {"skipped", true},
                                        {"reason", "convex & closed"}, {"avoided_seconds", 1.25}, {"cost_basis", "estimate"}}})},
              {"left_out", json::array({{{"what", "occlusion rays"}, {"why", "a < b"}}})},
              {"stages", json::array({{{"name", "visibility"}, {"seconds", 2.0}}})},
              {"evaluation", {{"train", {{"masked", q}, {"full", q}}}, {"test", {{"masked", q}, {"full", q}}}}}};
    const std::string html = report::report_html(r);
    EXPECT_EQ(html.find("<script>"), std::string::npos);
    EXPECT_NE(html.find("/tmp/&lt;script&gt;"), std::string::npos);
    EXPECT_NE(html.find("convex &amp; closed"), std::string::npos);
    EXPECT_NE(html.find("avoided &asymp; 1.25 s"), std::string::npos);
    EXPECT_NE(html.find("a &lt; b"), std::string::npos);
    EXPECT_NE(html.find("<td>masked</td>"), std::string::npos);
    EXPECT_NE(html.find("<td>full</td>"), std::string::npos);
    EXPECT_NE(html.find("<svg"), std::string::npos);
    EXPECT_EQ(html.find("http://"), html.find("http://www.w3.org/2000/svg")); // no external asset
    EXPECT_NE(html.find("name=\"viewport\""), std::string::npos);               // readable on a phone
}

// Issue 20's report polish: counts whole with thousands separators (not 1.14573e+06), and a
// bar chart whose labels' column fits its longest label.
TEST(ReportHtml, CountsAreGroupedAndChartLabelsFit) {
    const json r = {{"capture", {{"path", "cap"}, {"views", 12}, {"train_frames", 1145730}, {"test_frames", 7}}}};
    const std::string html = report::report_html(r);
    EXPECT_NE(html.find("1,145,730 train"), std::string::npos) << html.substr(0, 2000);
    EXPECT_NE(html.find("12 views"), std::string::npos);
    const std::string label = "residual samples (lafortune, validation split) (joint round 1)";
    const std::vector<report::Bar> bars{{label, 2.5}, {"load", 0.5}};
    const std::string svg = report::svg_bar_chart(bars, "s");
    // The label is right-aligned at x = label_w - 6: its start, about 7 px a character to
    // its left, stays inside the chart.
    const std::size_t at = svg.find("text-anchor=\"end\">" + label);
    ASSERT_NE(at, std::string::npos);
    const std::size_t x = svg.rfind("<text x=\"", at);
    const int right = std::stoi(svg.substr(x + 9));
    EXPECT_GE(right - 7 * static_cast<int>(label.size()), 0) << svg.substr(x, 120);
    EXPECT_NE(svg.find("viewBox=\"0 0 "), std::string::npos);
}

// The quality table shows Q1 and PSNR on display and linear values (evaluate.h), display
// first for an sRGB integer capture, linear first for a float one.
TEST(ReportHtml, QualityShowsDisplayAndLinearFiguresDisplayFirstForSrgbCaptures) {
    json q = {{"frames", 3}, {"q1", 93.5}, {"q2", 97.0}, {"rms_percent", 6.5}, {"psnr", 30.1},
              {"q1_display", 91.25}, {"psnr_display", 27.75}};
    for (const char* encoding : {"srgb8", "srgb"}) {
        const json r = {{"evaluation", {{"display_encoding", encoding}, {"test", {{"masked", q}, {"full", q}}}}}};
        const std::string html = report::report_html(r);
        ASSERT_NE(html.find("<th>Q1 display</th>"), std::string::npos);
        ASSERT_NE(html.find("<th>Q1 linear</th>"), std::string::npos);
        EXPECT_NE(html.find("<td>91.25</td><td>27.75</td>"), std::string::npos) << encoding;
        EXPECT_NE(html.find("<td>93.50</td><td>30.10</td>"), std::string::npos) << encoding;
        const bool display_first = std::string(encoding) == "srgb8";
        EXPECT_EQ(html.find("<th>Q1 display</th>") < html.find("<th>Q1 linear</th>"), display_first) << encoding;
        EXPECT_EQ(html.find("<td>91.25</td>") < html.find("<td>93.50</td>"), display_first) << encoding;
        EXPECT_NE(html.find(std::string("<code>") + encoding + "</code>"), std::string::npos) << encoding;
    }
}

// The model choice says where a coated candidate was estimated twice (joint.restart).
TEST(ReportHtml, TheMaterialSectionSaysWhereACandidateStartedTwice) {
    const json restart = {{"first_eta", 1.013}, {"first_validation_mse", 5.57e-6}, {"common_eta", 1.5},
                          {"common_validation_mse", 4.29e-7}, {"kept", "common"}};
    const json r = {{"specular",
                     {{"material",
                       {{"family", "coated"},
                        {"choice", "coated has the least mean square error"},
                        {"candidates", json::array({{{"family", "lafortune"}, {"joint", {{"accepted", 8}}}},
                                                    {{"family", "coated"}, {"joint", {{"accepted", 7}, {"restart", restart}}}}})}}}}}};
    const std::string html = report::report_html(r);
    EXPECT_NE(html.find("The coated candidate's rounds ended at eta 1.013 (validation mean square 5.57e-06)"), std::string::npos)
        << html.substr(html.find("Material model"), 1500);
    EXPECT_NE(html.find("again from eta 1.5, a common dielectric (4.29e-07), and the second start kept"), std::string::npos);
    EXPECT_EQ(html.find("The lafortune candidate's rounds"), std::string::npos);
}

// The transfer's blocks grow with the atlas's density: about kTransferBlockRows rows, at least 2.
TEST(Planner, IndirectBlockAimsAtAboutAHundredThousandRows) {
    EXPECT_EQ(transfer_block_for(0), 2u);
    EXPECT_EQ(transfer_block_for(190000), 2u);  // the knot at 256 px
    EXPECT_EQ(transfer_block_for(432000), 2u);  // at 384 px: sqrt(4.32) = 2.08
    EXPECT_EQ(transfer_block_for(748451), 3u);  // at 512 px: sqrt(7.48) = 2.74
    EXPECT_EQ(transfer_block_for(624999), 2u);  // the steps: sqrt(6.25) = 2.5 ...
    EXPECT_EQ(transfer_block_for(625000), 3u);
    EXPECT_EQ(transfer_block_for(1224999), 3u); // ... and sqrt(12.25) = 3.5
    EXPECT_EQ(transfer_block_for(1225000), 4u);
    EXPECT_EQ(transfer_block_for(4000000), 6u); // sqrt(40) = 6.32
    const PlanDecision a = decide_indirect_block(748451, 0);
    EXPECT_EQ(a.name, "indirect_block");
    EXPECT_FALSE(a.forced);
    EXPECT_EQ(a.value, "3 x 3 texels");
    EXPECT_EQ(decided_indirect_block(a), 3u);
    EXPECT_EQ(a.detail["rows_about"].get<long>(), 83161);
    EXPECT_NE(a.reason.find("about 83161 rows"), std::string::npos) << a.reason;
    const PlanDecision f = decide_indirect_block(748451, 1);
    EXPECT_TRUE(f.forced);
    EXPECT_EQ(decided_indirect_block(f), 1u);
    EXPECT_EQ(f.detail["auto_block"].get<std::uint32_t>(), 3u);
    EXPECT_NE(f.reason.find("--indirect-block 1"), std::string::npos) << f.reason;
}

TEST(SvgPlot, MarksTheDefaultAndDrawsTheFront) {
    const std::vector<report::PlotPoint> pts{{1.0, 5.0, "fast", false, true}, {2.0, 3.0, "default <1>", true, true},
                                             {3.0, 4.0, "slow", false, false}};
    const std::string svg = report::svg_pareto_plot(pts, "t", "x", "y");
    EXPECT_NE(svg.find(">default</text>"), std::string::npos);
    EXPECT_NE(svg.find("<path d=\"M"), std::string::npos);
    EXPECT_NE(svg.find("default &lt;1&gt;"), std::string::npos);
}

} // namespace
} // namespace specula
