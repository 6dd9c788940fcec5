// Evaluation (engine/evaluate) on a synthetic capture of the convex `sphere` preset
// (96 px, 4 views x 3 lights + 1 test view x 2 lights, EXR: no quantization) against a
// bundle built in memory from the truth: the preset's own mesh and texture coordinates,
// its albedo texture as the atlas, its lobe. The sphere is convex (nothing casts a shadow,
// with or without the renderer's shadow map), so only pixels lit from behind the geometric
// (flat) facet can differ.
// Every test runs on lavapipe with the validation layer (VulkanTest).
#include "capture/capture.h"
#include "core/file_util.h"
#include "core/image.h"
#include "evaluate/bundle_render.h"
#include "evaluate/evaluate.h"
#include "evaluate/indirect_light.h"
#include "export/bundle.h"
#include "factorization/factorization.h"
#include "synth/presets.h"
#include "synth/synth.h"
#include "test_dirs.h"
#include "vulkan_env.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <memory>
#include <string>
#include <sys/wait.h>

namespace specula::evaluate {
namespace {

using test::TempDir;
using test::VulkanTest;

struct SphereCapture {
    TempDir dir{"evaluate"};
    synth::Preset preset = synth::make_preset("sphere");
    synth::SynthResult synth;
    Capture capture;
    Bundle truth;
};

Bundle bundle_from_truth(const synth::Preset& p) {
    Bundle b;
    b.mesh = p.mesh; // every vertex has its texture coordinate: the texture is the atlas
    b.albedo = p.material.albedo_texture;
    if (b.albedo.empty()) b.albedo = Image(1, 1, 3);
    if (p.material.albedo_texture.empty())
        for (int c = 0; c < 3; ++c) b.albedo.at(0, 0, c) = p.material.albedo_value[c];
    b.material.specular = p.material.lobe;
    return b;
}

const SphereCapture& sphere() {
    static std::unique_ptr<SphereCapture> s = [] {
        auto s = std::make_unique<SphereCapture>();
        synth::SynthOptions o;
        o.size = 96;
        o.views = 4;
        o.lights = 3;
        o.test_views = 1;
        o.test_lights = 2;
        o.format = synth::ImageFormat::Exr;
        o.seed = 3;
        s->synth = synth::write_synthetic_capture(synth::to_object(s->preset), s->dir / "cap", o);
        s->capture = load_capture(s->dir / "cap");
        s->truth = bundle_from_truth(s->preset);
        return s;
    }();
    return *s;
}

bool all_finite(const nlohmann::json& j) {
    if (j.is_number_float()) return std::isfinite(j.get<double>());
    if (j.is_structured())
        for (const auto& v : j)
            if (!all_finite(v)) return false;
    return true;
}

class EvaluateTest : public VulkanTest {};

TEST_F(EvaluateTest, TruthBundleScoresNearPerfect) {
    const SphereCapture& s = sphere();
    const EvaluationResult r = evaluate(ctx(), s.truth, s.capture, {.render = {.mode = render::Mode::Both}});
    std::printf("%s", format_summary(r).c_str());
    std::printf("synth shadowed object pixels (all frames): %zu of %zu\n", s.synth.shadowed_pixels, s.synth.object_pixels);
    ASSERT_EQ(r.train_frames, 12u);
    ASSERT_EQ(r.test_frames, 2u);
    EXPECT_GE(r.metrics.test_masked.q1, 99.0);
    EXPECT_GE(r.metrics.test_masked.psnr, 40.0);
    EXPECT_GE(r.metrics.train_masked.q1, 99.0);
    EXPECT_GE(r.metrics.train_masked.psnr, 40.0);
    EXPECT_GT(r.metrics.test_masked.ssim, 0.99);
    EXPECT_GE(r.metrics.test_full.q1, r.metrics.test_masked.q1 - 1e-9); // the background agrees exactly (both 0)
    for (const FrameEvaluation& f : r.frames) {
        EXPECT_EQ(f.mask_source, "capture");
        EXPECT_GT(f.masked.pixels, 500u) << f.file;
        EXPECT_EQ(f.full.pixels, 96u * 96u);
    }
}

TEST_F(EvaluateTest, JsonHasEverySplitAndNoNaN) {
    const SphereCapture& s = sphere();
    const nlohmann::json j = to_json(evaluate(ctx(), s.truth, s.capture), ".");
    for (const char* split : {"train", "test"})
        for (const char* set : {"masked", "full"}) {
            ASSERT_TRUE(j.contains(split) && j[split].contains(set)) << split << "." << set;
            const nlohmann::json& m = j[split][set];
            for (const char* key : {"q1", "q2", "rms_percent", "dde_percent", "psnr", "ssim", "ncc", "l1", "l2", "hausdorff", "frames"})
                EXPECT_TRUE(m.contains(key) && m[key].is_number()) << split << "." << set << "." << key << " = " << m.value(key, nlohmann::json());
        }
    EXPECT_EQ(j["train"]["masked"]["frames"], 12);
    EXPECT_EQ(j["test"]["full"]["frames"], 2);
    ASSERT_TRUE(j["frames"].is_array());
    EXPECT_EQ(j["frames"].size(), 14u);
    EXPECT_TRUE(j["frames"][0].contains("masked") && j["frames"][0]["masked"]["psnr"].is_number());
    // Display and linear figures side by side; the unsuffixed keys are the linear ones. An EXR
    // capture has no display encoding of its own: sRGB, clipped, not quantized.
    EXPECT_EQ(j["display_encoding"], "srgb");
    for (const char* split : {"train", "test"})
        for (const char* set : {"masked", "full"}) {
            const nlohmann::json& m = j[split][set];
            EXPECT_EQ(m["display_encoding"], "srgb");
            for (const std::string key : {"q1", "rms", "rms_percent", "psnr"}) {
                EXPECT_TRUE(m[key + "_display"].is_number()) << split << "." << set << "." << key;
                EXPECT_EQ(m[key + "_linear"], m[key]) << split << "." << set << "." << key;
            }
            EXPECT_NE(m["psnr_display"], m["psnr_linear"]);
        }
    for (const std::string key : {"rms", "rms_percent", "psnr"}) {
        EXPECT_TRUE(j["frames"][0]["masked"][key + "_display"].is_number()) << key;
        EXPECT_EQ(j["frames"][0]["masked"][key + "_linear"], j["frames"][0]["masked"][key]) << key;
    }
    EXPECT_EQ(j["frames"][0]["display_encoding"], "srgb");
    EXPECT_TRUE(all_finite(j));
    EXPECT_TRUE(j.contains("timings") && j["timings"]["per_frame_ms"].is_number());
}

TEST_F(EvaluateTest, SplitWithoutFramesIsAbsent) {
    const SphereCapture& s = sphere();
    Capture train_only = s.capture;
    for (FrameDesc& f : train_only.desc.frames) f.split = Split::Train;
    const nlohmann::json j = to_json(evaluate(ctx(), s.truth, train_only, {.max_frames_per_split = 3}), ".");
    EXPECT_TRUE(j.contains("train"));
    EXPECT_FALSE(j.contains("test"));
    EXPECT_EQ(j["train"]["masked"]["frames"], 3);
}

TEST_F(EvaluateTest, HalvedAlbedoScoresWorse) {
    const SphereCapture& s = sphere();
    Bundle wrong = s.truth;
    for (float& v : wrong.albedo.pixels) v *= 0.5f;
    const EvaluationResult good = evaluate(ctx(), s.truth, s.capture);
    const EvaluationResult bad = evaluate(ctx(), wrong, s.capture);
    std::printf("truth: test masked Q1 %.3f PSNR %.2f; halved albedo: Q1 %.3f PSNR %.2f\n", good.metrics.test_masked.q1,
                good.metrics.test_masked.psnr, bad.metrics.test_masked.q1, bad.metrics.test_masked.psnr);
    EXPECT_LT(bad.metrics.test_masked.q1, good.metrics.test_masked.q1 - 2.0);
    EXPECT_LT(bad.metrics.test_masked.psnr, good.metrics.test_masked.psnr - 10.0);
    EXPECT_LT(bad.metrics.train_masked.q1, good.metrics.train_masked.q1 - 2.0);
}

TEST_F(EvaluateTest, CpuAndVulkanMetricsAgree) {
    const SphereCapture& s = sphere();
    const EvaluationResult vk = evaluate(ctx(), s.truth, s.capture, {.max_frames_per_split = 2});
    const EvaluationResult cpu = evaluate(ctx(), s.truth, s.capture, {.metrics_backend = Backend::Cpu, .max_frames_per_split = 2});
    ASSERT_EQ(vk.frames.size(), cpu.frames.size());
    EXPECT_NEAR(vk.metrics.test_masked.q1, cpu.metrics.test_masked.q1, 1e-4);
    EXPECT_NEAR(vk.metrics.train_full.q2, cpu.metrics.train_full.q2, 1e-4);
    EXPECT_NEAR(vk.metrics.train_masked.ssim, cpu.metrics.train_masked.ssim, 1e-4);
}

// The evaluation renders with the deferred pass by default: the same figures as the thesis's two
// forward passes (the pixels agree to float rounding), frame by frame.
TEST_F(EvaluateTest, TheDeferredPassScoresAsTheThesisPasses) {
    const SphereCapture& s = sphere();
    EXPECT_EQ(EvaluateOptions{}.render.passes, render::Passes::Deferred);
    const EvaluationResult deferred = evaluate(ctx(), s.truth, s.capture, {.max_frames_per_split = 3});
    const EvaluationResult separate =
        evaluate(ctx(), s.truth, s.capture, {.render = {.passes = render::Passes::Separate}, .max_frames_per_split = 3});
    EXPECT_EQ(deferred.render.passes, render::Passes::Deferred);
    ASSERT_EQ(deferred.frames.size(), separate.frames.size());
    ASSERT_FALSE(deferred.frames.empty());
    for (std::size_t i = 0; i < deferred.frames.size(); ++i) {
        EXPECT_EQ(deferred.frames[i].covered_pixels, separate.frames[i].covered_pixels);
        EXPECT_NEAR(deferred.frames[i].masked.psnr, separate.frames[i].masked.psnr, 1e-3) << deferred.frames[i].file;
        EXPECT_NEAR(deferred.frames[i].full.ssim, separate.frames[i].full.ssim, 1e-5) << deferred.frames[i].file;
    }
}

// An 8-bit sRGB capture (synth png8) of the same sphere: the display figures are those of the
// stored codes. Checked against an independent computation: the frame rendered again, encoded
// with the sRGB formula written out here (IEC 61966-2-1) and rounded to 8 bits, against the
// codes read raw from the PNG file, over the capture's masked pixels, in double.
TEST_F(EvaluateTest, DisplayFiguresOfAn8BitCaptureAreThoseOfTheStoredCodes) {
    const SphereCapture& s = sphere();
    TempDir dir("evaluate_png8");
    synth::SynthOptions o;
    o.size = 96;
    o.views = 2;
    o.lights = 2;
    o.test_views = 1;
    o.test_lights = 1;
    o.format = synth::ImageFormat::Png8;
    o.seed = 3;
    (void)synth::write_synthetic_capture(synth::to_object(s.preset), dir / "cap", o);
    const Capture cap = load_capture(dir / "cap");
    const EvaluationResult r = evaluate(ctx(), s.truth, cap, {.metrics_backend = Backend::Cpu});
    std::printf("%s", format_summary(r).c_str());
    EXPECT_EQ(r.display_encoding, "srgb8");
    EXPECT_TRUE(r.display_first);
    const std::string table = format_summary(r);
    ASSERT_NE(table.find("Q1 disp"), std::string::npos) << table;
    EXPECT_LT(table.find("Q1 disp"), table.find("Q1 lin")) << "display first for an sRGB capture\n" << table;

    const auto encode8 = [](double v) { // linear -> 8-bit code, clipped
        v = std::clamp(v, 0.0, 1.0);
        const double e = v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1.0 / 2.4) - 0.055;
        return std::floor(std::clamp(e, 0.0, 1.0) * 255.0 + 0.5);
    };
    BundleRenderer renderer(ctx(), s.truth, "truth");
    ASSERT_FALSE(r.frames.empty());
    for (const FrameEvaluation& fe : r.frames) {
        EXPECT_EQ(fe.display_encoding, "srgb8");
        const FrameDesc& fd = cap.desc.frames[fe.frame];
        const FrameImage& im = cap.images[fe.frame];
        const Image codes = read_image(cap.desc.resolve(fd.file_path), ColorSpace::Linear); // code / 255, no transfer
        const Image ren = renderer.render(fd.camera(), fd.light, {}).color;
        double sum_sq = 0.0, sum_sq_linear = 0.0;
        std::size_t n = 0;
        for (int y = 0; y < ren.height; ++y)
            for (int x = 0; x < ren.width; ++x) {
                const std::size_t p = static_cast<std::size_t>(y) * ren.width + x;
                if ((im.flags[p] & (kOutsideMask | kMissing)) != 0) continue;
                ++n;
                for (int c = 0; c < 3; ++c) {
                    const double stored = std::round(codes.at(x, y, c) * 255.0);
                    const double d = (encode8(ren.at(x, y, c)) - stored) / 255.0;
                    sum_sq += d * d;
                    const double dl = std::min(ren.at(x, y, c), im.saturation) - im.color.at(x, y, c);
                    sum_sq_linear += dl * dl;
                }
            }
        ASSERT_EQ(fe.masked_display.pixels, n) << fe.file;
        const double mse = sum_sq / (3.0 * static_cast<double>(n));
        EXPECT_NEAR(fe.masked_display.mse, mse, 1e-6 * mse + 1e-12) << fe.file;
        if (mse > 0.0) {
            EXPECT_NEAR(fe.masked_display.psnr, 10.0 * std::log10(1.0 / mse), 1e-4) << fe.file;
        }
        EXPECT_NEAR(fe.masked.mse, sum_sq_linear / (3.0 * static_cast<double>(n)), 1e-6 * fe.masked.mse + 1e-12) << fe.file;
    }
    // Q1 on display values: 100 - the mean over frames of 100 RMS (G = 1).
    double mean_rms = 0.0;
    std::size_t test_frames = 0;
    for (const FrameEvaluation& fe : r.frames)
        if (fe.split == Split::Test) {
            mean_rms += fe.masked_display.rms;
            ++test_frames;
        }
    ASSERT_GT(test_frames, 0u);
    EXPECT_NEAR(r.display_metrics.test_masked.q1, 100.0 - 100.0 * mean_rms / static_cast<double>(test_frames), 1e-9);
    // The truth against its own 8-bit capture: within a code or so on display values.
    EXPECT_LT(r.display_metrics.test_masked.rms, 1.5 / 255.0);
}

TEST_F(EvaluateTest, WritesSheetsOfChosenFrames) {
    const SphereCapture& s = sphere();
    TempDir out("sheets");
    const EvaluationResult r = evaluate(ctx(), s.truth, s.capture, {.sheet_dir = out / "sheets"});
    ASSERT_EQ(r.sheets.size(), 2u); // the first train and the first test frame
    for (const auto& p : r.sheets) {
        ASSERT_TRUE(std::filesystem::exists(p)) << p;
        const ImageFileInfo info = read_image_info(p);
        EXPECT_EQ(info.width, 3 * 96 + 8);
        EXPECT_EQ(info.height, 96);
    }
    EXPECT_THROW((void)evaluate(ctx(), s.truth, s.capture, {.sheet_dir = out / "x", .sheet_frames = {999}}), UsageError);
}

TEST_F(EvaluateTest, FactorizedWithoutCubeMapsIsRefused) {
    const SphereCapture& s = sphere();
    try {
        (void)evaluate(ctx(), s.truth, s.capture, {.render = {.specular = render::SpecularPath::Factorized}, .bundle_name = "truth.glb"});
        FAIL() << "expected an error";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("truth.glb"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("cube-maps"), std::string::npos) << e.what();
    }
}

/// The bundle's parametrization reaches the renderer (BundleRenderer): the sphere's lobe
/// (Cx < 0) factorized in each parametrization on its default grids (measured train masked
/// PSNR: analytic 69.7 dB against the noiseless capture, plain K = 4 44.9 dB, mirrored K = 3
/// 59.1 dB); the mirrored cube-maps in a bundle that says plain GSHD 28.2 dB.
TEST_F(EvaluateTest, FactorizedBundleIsLookedUpInItsParametrization) {
    const SphereCapture& s = sphere();
    const EvaluationResult analytic = evaluate(ctx(), s.truth, s.capture, {});
    const EvaluateOptions factorized{.render = {.specular = render::SpecularPath::Factorized}};
    double psnr[2] = {0.0, 0.0}; // per FactorParam
    for (const FactorParam param : {FactorParam::Gshd, FactorParam::Mirrored}) {
        const factorization::Factorization f =
            factorization::factorize_cpu(std::get<LafortuneRgb>(*s.truth.material.specular), {.param = param});
        Bundle b = s.truth;
        b.material.factorized = f.cubes;
        b.material.factorized->param = param;
        const EvaluationResult r = evaluate(ctx(), b, s.capture, factorized);
        std::printf("%s K = %u: train masked PSNR %.2f dB (analytic %.2f dB)\n", to_string(param), f.term_count(),
                    r.metrics.train_masked.psnr, analytic.metrics.train_masked.psnr);
        EXPECT_GE(r.metrics.train_masked.psnr, 40.0) << to_string(param);
        psnr[static_cast<std::size_t>(param)] = r.metrics.train_masked.psnr;
        if (param == FactorParam::Mirrored) {
            b.material.factorized->param = FactorParam::Gshd;
            const EvaluationResult wrong = evaluate(ctx(), b, s.capture, factorized);
            std::printf("mirrored cube-maps looked up as gshd: %.2f dB\n", wrong.metrics.train_masked.psnr);
            EXPECT_LE(wrong.metrics.train_masked.psnr, r.metrics.train_masked.psnr - 10.0);
        }
    }
    EXPECT_GE(psnr[1], psnr[0] + 10.0);
}

// A bundle's Material is rendered as it is, whatever its family: a coated one (built in memory)
// goes through BundleRenderer (what `specula render`, `specula evaluate` and specula-view draw)
// to the renderer unchanged, pixel for pixel the render of the same Material by render::Renderer,
// in both specular paths; evaluate() scores it without the "no specular lobe" warning a bundle
// without a specular term gets.
TEST_F(EvaluateTest, CoatedBundleIsRenderedAsItIs) {
    const SphereCapture& s = sphere();
    const CoatedParams model{.eta = 1.5f, .alpha = 0.2f, .tint = glm::vec3(1.0f)};
    Bundle b = s.truth;
    b.material.specular = model;
    b.material.factorized = factorization::factorize_cpu(model, {.grid_h = 16, .grid_d = 16, .param = FactorParam::Gshd}).cubes;
    BundleRenderer coated(ctx(), b, "coated");
    EXPECT_TRUE(coated.has_specular());
    EXPECT_TRUE(coated.has_factorization());
    EXPECT_EQ(coated.renderer().material().family.x, shared::kMaterialCoated);
    const std::vector<glm::vec2> corner_uv = corner_uvs(b.mesh);
    render::Renderer direct(ctx(), render::Scene{.mesh = &b.mesh, .corner_uv = corner_uv, .albedo = &b.albedo, .material = b.material});
    BundleRenderer lafortune(ctx(), s.truth, "truth");
    const FrameDesc& fd = s.capture.desc.frames[1];
    for (const render::SpecularPath path : {render::SpecularPath::Analytic, render::SpecularPath::Factorized}) {
        const render::Frame a = coated.render(fd.camera(), fd.light, {.specular = path});
        const render::Frame d = direct.render(fd.camera(), fd.light, {.specular = path});
        EXPECT_TRUE(a.info.specular_pass);
        EXPECT_EQ(a.mask, d.mask);
        EXPECT_EQ(a.color.pixels, d.color.pixels) << render::specular_path_name(path);
        if (path == render::SpecularPath::Analytic) {
            EXPECT_NE(a.color.pixels, lafortune.render(fd.camera(), fd.light, {}).color.pixels);
        }
    }
    const EvaluationResult r = evaluate(ctx(), b, s.capture, {});
    for (const std::string& w : r.warnings) EXPECT_EQ(w.find("no specular"), std::string::npos) << w;
    EXPECT_GT(r.train_frames, 0u);
    Bundle none = s.truth;
    none.material.specular.reset();
    const EvaluationResult rn = evaluate(ctx(), none, s.capture, {});
    ASSERT_FALSE(rn.warnings.empty());
    EXPECT_NE(rn.warnings.front().find("no specular lobe"), std::string::npos);
}

// The core material's renders made by the bundle's evaluation, each right after its own frame
// (its G-buffer and shadow map drawn once), score exactly as a core-material evaluation that draws
// them itself; a frame it did not make is drawn there, and keys not evaluated are taken out.
TEST_F(EvaluateTest, CoreRendersBesideTheBundlesScoreAsTheirOwnEvaluation) {
    const SphereCapture& s = sphere();
    Bundle bundle = s.truth;
    bundle.core = CoreMaterial{.roughness = 0.35, .f0 = 0.06, .f90 = 0.9};
    const EvaluateOptions core_options{.render = {.mode = render::Mode::Both, .passes = render::Passes::Deferred}, .core_material = true};
    const EvaluationResult own = evaluate(ctx(), bundle, s.capture, core_options);
    ASSERT_EQ(own.frames.size(), 14u);
    std::map<std::size_t, render::Frame> renders;
    for (const FrameEvaluation& f : own.frames) renders[f.frame];
    renders[s.capture.desc.frames.size() + 5]; // not a frame: taken out
    EvaluateOptions bundle_options{.render = {.mode = render::Mode::Both, .passes = render::Passes::Deferred}};
    bundle_options.max_train_frames = 6; // half the train frames: the others are drawn by the core evaluation
    bundle_options.core_renders = &renders;
    const EvaluationResult with = evaluate(ctx(), bundle, s.capture, bundle_options);
    ASSERT_EQ(renders.size(), with.frames.size());
    for (const FrameEvaluation& f : with.frames) {
        ASSERT_TRUE(renders.contains(f.frame));
        EXPECT_TRUE(renders.at(f.frame).info.shadow_kept) << f.frame;
        EXPECT_TRUE(renders.at(f.frame).info.gbuffer_kept) << f.frame;
    }
    // The bundle's own figures are those of an evaluation without the core renders.
    EvaluateOptions plain = bundle_options;
    plain.core_renders = nullptr;
    EXPECT_EQ(evaluate(ctx(), bundle, s.capture, plain).metrics.train_masked.psnr, with.metrics.train_masked.psnr);
    EvaluateOptions reuse = core_options;
    reuse.rendered = &renders;
    const EvaluationResult shared = evaluate(ctx(), bundle, s.capture, reuse);
    EXPECT_TRUE(renders.empty()); // every render taken
    ASSERT_EQ(shared.frames.size(), own.frames.size());
    for (std::size_t i = 0; i < own.frames.size(); ++i) {
        EXPECT_EQ(shared.frames[i].frame, own.frames[i].frame);
        EXPECT_EQ(shared.frames[i].masked.rms, own.frames[i].masked.rms) << own.frames[i].frame;
        EXPECT_EQ(shared.frames[i].full.rms, own.frames[i].full.rms) << own.frames[i].frame;
        EXPECT_EQ(shared.frames[i].masked_display.rms, own.frames[i].masked_display.rms) << own.frames[i].frame;
    }
    EXPECT_EQ(shared.metrics.test_masked.psnr, own.metrics.test_masked.psnr);
    EXPECT_EQ(shared.metrics.train_masked.psnr, own.metrics.train_masked.psnr);
    EXPECT_NE(shared.metrics.test_masked.rms, with.metrics.test_masked.rms); // another material was scored
    // The core renders go with the bundle's own renders only.
    std::map<std::size_t, render::Frame> more;
    EvaluateOptions wrong = core_options;
    wrong.core_renders = &more;
    EXPECT_THROW((void)evaluate(ctx(), bundle, s.capture, wrong), UsageError);
}

TEST(EvaluateSelect, EvenlySpacedPerSplit) {
    CaptureDesc d;
    for (int i = 0; i < 10; ++i) d.frames.push_back(FrameDesc{.split = i < 8 ? Split::Train : Split::Test});
    EXPECT_EQ(select_frames(d, 0).size(), 10u);
    EXPECT_EQ(select_frames(d, 4), (std::vector<std::size_t>{0, 2, 4, 6, 8, 9}));
    EXPECT_EQ(select_frames(d, 1), (std::vector<std::size_t>{0, 8}));
}

TEST(EvaluateSheet, DifferencePanelIsMidGrayWhereEqual) {
    Image a(2, 1, 3, 0.25f), b = a;
    b.at(1, 0, 0) = 0.5f;
    const Image sheet = make_sheet(a, b);
    ASSERT_EQ(sheet.width, 3 * 2 + 8);
    const int x0 = 2 * (2 + 4);
    EXPECT_NEAR(linear_to_srgb(sheet.at(x0, 0, 0)), 0.5f, 1e-5f);
    EXPECT_GT(linear_to_srgb(sheet.at(x0 + 1, 0, 0)), 0.9f);
    EXPECT_EQ(sheet.at(2, 0, 0), 1.0f); // the gap
}

TEST(EvaluateCamera, FreeCameraChecksItsInput) {
    const Camera c = free_camera({0, 0, 3}, {0, 0, 0}, {0, 1, 0}, 200, 100, 90.0, std::nullopt);
    EXPECT_NEAR(c.intrinsics.fl_y, 50.0, 1e-9);
    const auto p = c.project({0, 0, 0});
    ASSERT_TRUE(p.has_value());
    EXPECT_NEAR(p->x, 100.0, 1e-9);
    EXPECT_NEAR(p->y, 50.0, 1e-9);
    EXPECT_THROW((void)free_camera({0, 0, 3}, {0, 0, 0}, {0, 0, 1}, 64, 64, 40.0, std::nullopt), UsageError);
    EXPECT_THROW((void)free_camera({0, 0, 3}, {0, 0, 0}, {0, 1, 0}, 64, 64, 40.0, 100.0), UsageError);
    EXPECT_THROW((void)write_rendered_image("x.jpg2", Image(1, 1, 3)), UsageError);
}

#ifdef SPECULA_BINARY
/// `specula render BUNDLE --capture DIR --frame I -o x.exr` writes what the in-memory render gives.
TEST_F(EvaluateTest, CliRenderMatchesInMemoryRender) {
    const SphereCapture& s = sphere();
    TempDir out("render_cli");
    write_bundle(out / "truth.glb", s.truth);
    const Bundle read = read_bundle(out / "truth.glb");
    const std::size_t frame = s.capture.desc.frames.size() - 1; // a test frame
    const std::string cmd = std::string(SPECULA_BINARY) + " -q render " + (out / "truth.glb").string() + " --capture " +
                            (s.dir / "cap").string() + " --frame " + std::to_string(frame) + " -o " + (out / "r.exr").string();
    ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
    const Image file = read_image(out / "r.exr", ColorSpace::Linear);
    BundleRenderer r(ctx(), read, "truth.glb");
    const FrameDesc& f = s.capture.desc.frames[frame];
    const Image mem = r.render(f.camera(), f.light, {}).color;
    ASSERT_EQ(file.width, mem.width);
    ASSERT_EQ(file.height, mem.height);
    ASSERT_GE(file.channels, 3);
    double max_diff = 0.0;
    for (int y = 0; y < mem.height; ++y)
        for (int x = 0; x < mem.width; ++x)
            for (int c = 0; c < 3; ++c) max_diff = std::max(max_diff, static_cast<double>(std::abs(file.at(x, y, c) - mem.at(x, y, c))));
    EXPECT_EQ(max_diff, 0.0);

    // png: sRGB 8-bit of the same frame
    const std::string png = std::string(SPECULA_BINARY) + " -q render " + (out / "truth.glb").string() + " --capture " +
                            (s.dir / "cap").string() + " --frame 0 -o " + (out / "r.png").string();
    ASSERT_EQ(std::system(png.c_str()), 0) << png;
    EXPECT_EQ(read_image_info(out / "r.png").bits_per_channel, 8);

    // factorized without cube-maps: exit status 1, the bundle named
    const std::string fac = std::string(SPECULA_BINARY) + " -q render " + (out / "truth.glb").string() + " --capture " +
                            (s.dir / "cap").string() + " --frame 0 --specular factorized -o " + (out / "f.png").string() +
                            " 2> " + (out / "err.txt").string();
    const int rc = std::system(fac.c_str());
    EXPECT_TRUE(WIFEXITED(rc) && WEXITSTATUS(rc) == 1) << rc;
    EXPECT_NE(read_text_file(out / "err.txt").find("truth.glb: the bundle has no factorization cube-maps"), std::string::npos)
        << read_text_file(out / "err.txt");
}

/// `specula evaluate BUNDLE CAPTURE --json J --sheets D` writes the JSON and the sheets.
TEST_F(EvaluateTest, CliEvaluateWritesJsonAndSheets) {
    const SphereCapture& s = sphere();
    TempDir out("evaluate_cli");
    write_bundle(out / "truth.glb", s.truth);
    const std::string cmd = std::string(SPECULA_BINARY) + " -q evaluate " + (out / "truth.glb").string() + " " +
                            (s.dir / "cap").string() + " --json " + (out / "e.json").string() + " --sheets " +
                            (out / "sheets").string() + " > " + (out / "stdout.txt").string();
    ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
    const nlohmann::json j = nlohmann::json::parse(read_text_file(out / "e.json"));
    for (const char* split : {"train", "test"})
        for (const char* set : {"masked", "full"})
            for (const char* key : {"q1", "q2", "rms_percent", "dde_percent", "psnr", "ssim", "frames"})
                EXPECT_TRUE(j[split][set][key].is_number()) << split << "." << set << "." << key;
    EXPECT_GE(j["test"]["masked"]["q1"].get<double>(), 99.0);
    EXPECT_TRUE(j["test"]["masked"]["q1_display"].is_number());
    EXPECT_TRUE(j["test"]["masked"]["psnr_linear"].is_number());
    EXPECT_EQ(j["frames"].size(), 14u);
    EXPECT_TRUE(all_finite(j));
    EXPECT_EQ(j["sheets"].size(), 2u);
    EXPECT_NE(read_text_file(out / "stdout.txt").find("test masked"), std::string::npos);
    // An EXR capture: linear figures first, then display ones.
    const std::string table = read_text_file(out / "stdout.txt");
    ASSERT_NE(table.find("Q1 lin"), std::string::npos) << table;
    ASSERT_NE(table.find("Q1 disp"), std::string::npos) << table;
    EXPECT_LT(table.find("Q1 lin"), table.find("Q1 disp")) << table;
    EXPECT_NE(table.find("display values: srgb"), std::string::npos) << table;
    // --metrics auto: the C++ measures on a CPU Vulkan driver, the kernels on a GPU.
    EXPECT_EQ(j["settings"]["metrics_backend"], ctx().info().kind == gpu::DeviceKind::Cpu ? "cpu" : "vulkan");
    EXPECT_EQ(j["settings"]["passes"], "deferred");
    EXPECT_NE(table.find("(deferred)"), std::string::npos) << table;
}
#endif

// What a bundle says of the light its albedo had removed, read back for the renders: the
// transfer's rays and blocks where recorded, else the defaults of bundles made before.
TEST(BundleIndirectInfo, TransferIsTheRecordedOneElseTheOldDefaults) {
    Bundle b;
    EXPECT_FALSE(evaluate::indirect_removed_from_albedo(b));
    EXPECT_EQ(evaluate::indirect_transfer_of(b).block, kTransferBlock);
    EXPECT_EQ(evaluate::indirect_transfer_of(b).rays, kTransferRays);
    b.info = {{"indirect_light", {{"removed_from_albedo", true}, {"bounces", 3}, {"transfer", {{"rays", 100}, {"block", 3}}}}}};
    EXPECT_TRUE(evaluate::indirect_removed_from_albedo(b));
    EXPECT_EQ(evaluate::indirect_bounces_of(b), 3u);
    EXPECT_EQ(evaluate::indirect_transfer_of(b).block, 3u);
    EXPECT_EQ(evaluate::indirect_transfer_of(b).rays, 100u);
    // Malformed or out-of-range values: the defaults, or the nearest allowed.
    b.info["indirect_light"]["transfer"] = {{"rays", "many"}, {"block", 1000}};
    EXPECT_EQ(evaluate::indirect_transfer_of(b).rays, kTransferRays);
    EXPECT_EQ(evaluate::indirect_transfer_of(b).block, 64u);
    b.info["indirect_light"]["transfer"] = {{"rays", -5}, {"block", 0}};
    EXPECT_EQ(evaluate::indirect_transfer_of(b).rays, 1u);
    EXPECT_EQ(evaluate::indirect_transfer_of(b).block, 1u);
    b.info["indirect_light"]["transfer"] = nlohmann::json::array({1, 2});
    EXPECT_EQ(evaluate::indirect_transfer_of(b).block, kTransferBlock);
    b.info["indirect_light"] = "yes";
    EXPECT_EQ(evaluate::indirect_transfer_of(b).rays, kTransferRays);
}

} // namespace
} // namespace specula::evaluate
