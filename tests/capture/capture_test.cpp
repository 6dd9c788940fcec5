// Capture format v1: loading valid captures (views, intrinsics, decoding, flags),
// round trips of capture.json, and every refusal case of the spec, each checked
// to name the right file and field.
#include "capture/capture.h"
#include "core/error.h"
#include "core/file_util.h"
#include "core/timer.h"
#include "gltf_builder.h"
#include "test_dirs.h"
#include "unit_cube.h"

#include "expect_error.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>

namespace specula {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;

constexpr int kW = 4; // images are 4 x 3: a swapped w/h would be caught
constexpr int kH = 3;

using test::unit_cube_mesh;

json pose_json(double tz, double tx = 0.0) {
    return json::array({json::array({1, 0, 0, tx}), json::array({0, 1, 0, 0}), json::array({0, 0, 1, tz}),
                        json::array({0, 0, 0, 1})});
}

json frame_json(const std::string& file, int view, double tz, const std::vector<double>& light_pos) {
    return {{"file_path", file},
            {"view_index", view},
            {"transform_matrix", pose_json(tz)},
            {"light", {{"type", "point"}, {"position", light_pos}, {"intensity", {10.0, 10.0, 10.0}}}}};
}

json directional_json(const std::vector<double>& direction, const std::vector<double>& irradiance = {0.5, 0.5, 0.5}) {
    return {{"type", "directional"}, {"direction", direction}, {"irradiance", irradiance}};
}

Image solid(int w, int h, int channels, float value) { return Image(w, h, channels, value); }

/// A small valid capture in a temp folder: 2 views x 2 lights, 4 x 3 PNGs,
/// masks for view 0, a cube mesh. Tests mutate `j` (and files), then load().
struct CaptureFixture {
    test::TempDir dir{"capture"};
    json j;

    CaptureFixture() {
        write_mesh_glb(dir / "mesh.glb", unit_cube_mesh());
        fs::create_directories(dir / "images");
        fs::create_directories(dir / "masks");
        for (int v = 0; v < 2; ++v)
            for (int l = 0; l < 2; ++l) write_png(image_name(v, l), solid(kW, kH, 3, 0.25f));
        Image mask(kW, kH, 1, 1.0f);
        for (int y = 0; y < kH; ++y) mask.at(0, y) = 0.0f; // column 0 outside
        write_image(dir / "masks/v0.png", mask, ColorSpace::Linear);
        j = {{"format", "specula-capture"},
             {"version", 1},
             {"mesh_path", "mesh.glb"},
             {"color_space", "srgb"},
             {"w", kW},
             {"h", kH},
             {"fl_x", 5.0},
             {"fl_y", 5.5},
             {"cx", 2.0},
             {"cy", 1.5},
             {"frames", json::array()}};
        // view 1's frames come first in the file: views must still be sorted by view_index
        for (int v : {1, 0})
            for (int l = 0; l < 2; ++l) {
                json f = frame_json(image_name(v, l), v, 3.0 + v, {l == 0 ? 1.0 : -1.0, 0.5, 3.0});
                if (v == 0) f["mask_path"] = "masks/v0.png";
                if (v == 1 && l == 1) f["split"] = "test";
                j["frames"].push_back(f);
            }
    }

    static std::string image_name(int v, int l) {
        return "images/v" + std::to_string(v) + "_l" + std::to_string(l) + ".png";
    }
    void write_png(const std::string& name, const Image& img, ColorSpace cs = ColorSpace::Srgb, int bits = 8) {
        write_image(dir / name, img, cs, bits);
    }
    void write_json() { write_text_file(dir / "capture.json", j.dump(2)); }
    Capture load(const CaptureLoadOptions& options = {}) {
        write_json();
        return load_capture(dir.path(), options);
    }
    // Index in j["frames"] of view v, light l.
    static std::size_t frame_index(int v, int l) { return static_cast<std::size_t>((1 - v) * 2 + l); }
};

using test::expect_input_error;

// ---- valid captures ---------------------------------------------------------------

TEST(CaptureLoad, ValidCaptureHasViewsFramesIntrinsicsAndFlags) {
    CaptureFixture fx;
    const Capture c = fx.load();
    EXPECT_TRUE(c.warnings.empty()) << c.warnings.front();
    ASSERT_EQ(c.desc.frames.size(), 4u);
    ASSERT_EQ(c.views.size(), 2u);
    EXPECT_EQ(c.views[0].view_index, 0);
    EXPECT_EQ(c.views[1].view_index, 1);
    EXPECT_EQ(c.views[0].frames, (std::vector<std::size_t>{2, 3}));
    EXPECT_EQ(c.views[1].frames, (std::vector<std::size_t>{0, 1}));
    EXPECT_DOUBLE_EQ(c.views[0].camera.center().z, 3.0);
    EXPECT_DOUBLE_EQ(c.views[1].camera.center().z, 4.0);
    EXPECT_EQ(c.frame_count(Split::Train), 3u);
    EXPECT_EQ(c.frame_count(Split::Test), 1u);
    const Intrinsics& k = c.desc.frames[0].intrinsics;
    EXPECT_EQ(k.w, kW);
    EXPECT_EQ(k.h, kH);
    EXPECT_DOUBLE_EQ(k.fl_x, 5.0);
    EXPECT_DOUBLE_EQ(k.fl_y, 5.5);
    EXPECT_DOUBLE_EQ(k.cx, 2.0);
    EXPECT_DOUBLE_EQ(k.cy, 1.5);
    EXPECT_EQ(c.mesh.triangle_count(), 12u);
    EXPECT_EQ(c.desc.dir, fx.dir.path());
    ASSERT_EQ(c.images.size(), 4u);
    for (std::size_t i = 0; i < 4; ++i) {
        const FrameImage& im = c.images[i];
        EXPECT_EQ(im.color.width, kW);
        EXPECT_EQ(im.color.height, kH);
        EXPECT_EQ(im.color.channels, 3);
        EXPECT_EQ(im.saturation, 1.0f);
        EXPECT_EQ(im.missing_pixels, 0u);
        const bool masked = c.desc.frames[i].view_index == 0;
        for (int y = 0; y < kH; ++y)
            for (int x = 0; x < kW; ++x) {
                EXPECT_NEAR(im.color.at(x, y, 1), 0.25f, 0.01f);
                const std::uint8_t flag = im.flags[static_cast<std::size_t>(y * kW + x)];
                EXPECT_EQ(flag, (masked && x == 0) ? kOutsideMask : 0) << "frame " << i << " pixel " << x << "," << y;
            }
    }
    const std::string summary = summarize(c);
    EXPECT_NE(summary.find("views:       2 (2 frames per view)"), std::string::npos) << summary;
    EXPECT_NE(summary.find("train 3, test 1"), std::string::npos) << summary;
    EXPECT_NE(summary.find("4 x 3"), std::string::npos) << summary;
    EXPECT_NE(summary.find("12 triangles"), std::string::npos) << summary;
    EXPECT_NE(summary.find("load time"), std::string::npos) << summary;
}

TEST(CaptureLoad, AcceptsFolderOrJsonPath) {
    CaptureFixture fx;
    fx.write_json();
    EXPECT_EQ(load_capture(fx.dir / "capture.json", {.load_images = false}).desc.frames.size(), 4u);
    EXPECT_EQ(capture_json_path(fx.dir.path()), fx.dir / "capture.json");
}

TEST(CaptureLoad, PerFrameIntrinsicsOverride) {
    CaptureFixture fx;
    for (int l = 0; l < 2; ++l) {
        json& f = fx.j["frames"][CaptureFixture::frame_index(1, l)];
        f["fl_x"] = 7.0;
        f["cy"] = 1.0;
    }
    const Capture c = fx.load({.load_images = false});
    const Intrinsics& k1 = c.desc.frames[CaptureFixture::frame_index(1, 0)].intrinsics;
    EXPECT_DOUBLE_EQ(k1.fl_x, 7.0);
    EXPECT_DOUBLE_EQ(k1.fl_y, 5.5);
    EXPECT_DOUBLE_EQ(k1.cy, 1.0);
    EXPECT_DOUBLE_EQ(c.views[1].camera.intrinsics.fl_x, 7.0);
    const Intrinsics& k0 = c.desc.frames[CaptureFixture::frame_index(0, 0)].intrinsics;
    EXPECT_DOUBLE_EQ(k0.fl_x, 5.0);
    EXPECT_DOUBLE_EQ(k0.cy, 1.5);
}

TEST(CaptureLoad, IntrinsicsOnlyPerFrame) {
    CaptureFixture fx;
    for (const char* key : {"w", "h", "fl_x", "fl_y", "cx", "cy"}) {
        for (json& f : fx.j["frames"]) f[key] = fx.j[key];
        fx.j.erase(key);
    }
    EXPECT_DOUBLE_EQ(fx.load({.load_images = false}).desc.frames[3].intrinsics.fl_y, 5.5);
}

TEST(CaptureLoad, SrgbAndLinearDecoding) {
    for (const char* cs : {"srgb", "linear"}) {
        CaptureFixture fx;
        fx.j["color_space"] = cs;
        // byte 51 exactly: linear value 51/255 written without a transfer function
        fx.write_png(CaptureFixture::image_name(0, 0), solid(kW, kH, 3, 51.0f / 255.0f), ColorSpace::Linear);
        // 16-bit: 13107 / 65535 = 0.2
        fx.write_png(CaptureFixture::image_name(0, 1), solid(kW, kH, 3, 0.2f), ColorSpace::Linear, 16);
        const Capture c = fx.load();
        const bool srgb = std::string(cs) == "srgb";
        const float v8 = c.images[CaptureFixture::frame_index(0, 0)].color.at(1, 1, 0);
        const float v16 = c.images[CaptureFixture::frame_index(0, 1)].color.at(1, 1, 2);
        EXPECT_NEAR(v8, srgb ? srgb_to_linear(0.2f) : 0.2f, 1e-6f) << cs;
        EXPECT_NEAR(v16, srgb ? srgb_to_linear(0.2f) : 0.2f, 1e-6f) << cs;
    }
}

TEST(CaptureLoad, FloatImagesAreLinearWithoutSaturation) {
    CaptureFixture fx;
    fx.j["frames"][0]["file_path"] = "images/f.exr";
    Image img = solid(kW, kH, 3, 0.2f);
    img.at(2, 1, 0) = 7.5f; // far above 1: not clipped in a float file
    write_image(fx.dir / "images/f.exr", img, ColorSpace::Linear);
    const Capture c = fx.load();
    const FrameImage& im = c.images[0];
    EXPECT_EQ(im.saturation, std::numeric_limits<float>::infinity());
    EXPECT_FLOAT_EQ(im.color.at(0, 0, 0), 0.2f); // no sRGB decoding for float files
    EXPECT_FLOAT_EQ(im.color.at(2, 1, 0), 7.5f);
    EXPECT_EQ(im.flags[1 * kW + 2], 0);
    EXPECT_EQ(c.images[1].saturation, 1.0f); // integer file of the same capture
}

TEST(CaptureLoad, ClippingFlags) {
    CaptureFixture fx;
    Image img = solid(kW, kH, 3, 0.25f);
    img.at(0, 0, 0) = 1.0f;                  // R at 255
    img.at(1, 0, 1) = 1.0f;                  // G
    img.at(2, 0, 0) = img.at(2, 0, 2) = 1.0f; // R and B
    fx.write_png(CaptureFixture::image_name(1, 0), img);
    Capture c = fx.load();
    const FrameImage& im = c.images[CaptureFixture::frame_index(1, 0)];
    EXPECT_EQ(im.flags[0], kClippedR);
    EXPECT_EQ(im.flags[1], kClippedG);
    EXPECT_EQ(im.flags[2], kClippedR | kClippedB);
    EXPECT_EQ(im.flags[3], 0);

    // A stated saturation applies to every file, float ones included.
    fx.j["saturation"] = 0.2;
    c = fx.load();
    EXPECT_EQ(c.images[0].saturation, 0.2f);
    EXPECT_EQ(c.images[0].flags[5], kClippedAny); // 0.25 >= 0.2 in every channel
}

TEST(CaptureLoad, GrayImagesReplicatedAndAlphaIgnored) {
    CaptureFixture fx;
    fx.write_png(CaptureFixture::image_name(1, 0), solid(kW, kH, 1, 0.5f), ColorSpace::Linear);
    Image rgba = solid(kW, kH, 4, 0.5f);
    for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x) rgba.at(x, y, 3) = 0.0f;
    fx.write_png(CaptureFixture::image_name(1, 1), rgba, ColorSpace::Linear);
    fx.j["color_space"] = "linear";
    const Capture c = fx.load();
    for (std::size_t f : {CaptureFixture::frame_index(1, 0), CaptureFixture::frame_index(1, 1)})
        for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(c.images[f].color.at(3, 2, ch), 0.5f, 0.6f / 255.0f);
}

TEST(CaptureLoad, NonFinitePixelsAreMissingWithWarning) {
    CaptureFixture fx;
    fx.j["frames"][1]["file_path"] = "images/nan.exr";
    Image img = solid(kW, kH, 3, 0.3f);
    img.at(1, 1, 0) = std::numeric_limits<float>::quiet_NaN();
    img.at(2, 2, 2) = std::numeric_limits<float>::infinity();
    img.at(3, 0, 1) = -std::numeric_limits<float>::infinity();
    write_image(fx.dir / "images/nan.exr", img, ColorSpace::Linear);
    const Capture c = fx.load();
    const FrameImage& im = c.images[1];
    EXPECT_EQ(im.missing_pixels, 3u);
    EXPECT_EQ(im.flags[1 * kW + 1], kMissing);
    EXPECT_EQ(im.flags[2 * kW + 2], kMissing);
    EXPECT_EQ(im.flags[0 * kW + 3], kMissing);
    EXPECT_EQ(im.color.at(1, 1, 0), 0.0f);
    EXPECT_EQ(im.color.at(2, 2, 2), 0.0f);
    EXPECT_FLOAT_EQ(im.color.at(1, 1, 1), 0.0f); // the whole pixel is zeroed
    EXPECT_EQ(im.flags[0], 0);
    ASSERT_EQ(c.warnings.size(), 1u);
    EXPECT_NE(c.warnings[0].find("frames[1]"), std::string::npos) << c.warnings[0];
    EXPECT_NE(c.warnings[0].find(" 3 pixel"), std::string::npos) << c.warnings[0];
}

TEST(CaptureLoad, LightInsideMeshBoundsWarns) {
    CaptureFixture fx;
    fx.j["frames"][2]["light"]["position"] = {0.1, 0.0, 0.2};
    const Capture c = fx.load({.load_images = false});
    ASSERT_EQ(c.warnings.size(), 1u);
    EXPECT_NE(c.warnings[0].find("frames[2].light.position"), std::string::npos) << c.warnings[0];
}

TEST(CaptureLoad, DegenerateMeshTrianglesWarn) {
    CaptureFixture fx;
    Mesh m = unit_cube_mesh();
    m.triangles.emplace_back(0, 1, 1);
    write_mesh_glb(fx.dir / "mesh.glb", m);
    const Capture c = fx.load({.load_images = false});
    EXPECT_EQ(c.mesh.triangle_count(), 12u);
    ASSERT_EQ(c.warnings.size(), 1u);
    EXPECT_NE(c.warnings[0].find("dropped 1 degenerate"), std::string::npos);
}

TEST(CaptureLoad, HeadersOnlyDecodesNothing) {
    CaptureFixture fx;
    const Capture c = fx.load({.load_images = false});
    EXPECT_TRUE(c.images.empty());
    EXPECT_EQ(c.views.size(), 2u);
    EXPECT_NE(summarize(c).find("not decoded"), std::string::npos);
}

TEST(CaptureLoad, SingleThreadMatchesParallel) {
    CaptureFixture fx;
    const Capture a = fx.load({.threads = 1});
    const Capture b = fx.load({.threads = 2});
    ASSERT_EQ(a.images.size(), b.images.size());
    for (std::size_t i = 0; i < a.images.size(); ++i) {
        EXPECT_EQ(a.images[i].color.pixels, b.images[i].color.pixels);
        EXPECT_EQ(a.images[i].flags, b.images[i].flags);
    }
}

// Frames are decoded in parallel (core/parallel.h): a broken image in a worker thread
// reaches the caller as the InputError itself, and with two broken frames it is always
// the first one's, as a single thread reports it.
TEST(CaptureLoad, ParallelDecodeReportsTheFirstBrokenFrame) {
    CaptureFixture fx;
    write_text_file(fx.dir / CaptureFixture::image_name(1, 1), "not a png at all"); // frames[1]
    write_text_file(fx.dir / CaptureFixture::image_name(0, 1), "not a png at all"); // frames[3]
    for (int threads : {1, 4, 4, 4, 4, 4, 4, 4, 4}) {
        const InputError e = expect_input_error([&] { (void)fx.load({.threads = threads}); });
        EXPECT_EQ(e.field(), "frames[1].file_path") << threads << " threads: " << e.what();
        EXPECT_EQ(e.file(), fx.dir / CaptureFixture::image_name(1, 1)) << threads << " threads: " << e.what();
    }
}

TEST(CaptureJson, UnknownFieldsSurviveRoundTrip) {
    CaptureFixture fx;
    fx.j["rig"] = {{"name", "six-light dome"}, {"serial", 42}};
    fx.j["ground_truth"] = {{"albedo", {0.5, 0.4, 0.3}}};
    fx.j["frames"][0]["exposure_us"] = 1250;
    fx.j["frames"][0]["light"]["radius"] = 0.01;
    fx.j["frames"][3]["fl_x"] = 5.0; // same as top: written back without an override
    fx.j["frames"][3]["cx"] = 2.0;
    const Capture first = fx.load({.load_images = false});

    CaptureDesc desc = first.desc;
    test::TempDir out("capture-out");
    desc.dir = out.path();
    write_capture_json(desc);
    const json written = json::parse(read_text_file(out / "capture.json"));
    EXPECT_EQ(written["rig"], fx.j["rig"]);
    EXPECT_EQ(written["ground_truth"], fx.j["ground_truth"]);
    EXPECT_EQ(written["frames"][0]["exposure_us"], 1250);
    EXPECT_EQ(written["frames"][0]["light"]["radius"], 0.01);
    EXPECT_FALSE(written["frames"][3].contains("fl_x"));

    const CaptureDesc back = parse_capture_desc(written, out / "capture.json");
    EXPECT_EQ(back.extra, first.desc.extra);
    EXPECT_EQ(back.ground_truth, first.desc.ground_truth);
    EXPECT_EQ(back.mesh_path, first.desc.mesh_path);
    EXPECT_EQ(back.color_space, first.desc.color_space);
    ASSERT_EQ(back.frames.size(), first.desc.frames.size());
    for (std::size_t i = 0; i < back.frames.size(); ++i) {
        const FrameDesc& a = first.desc.frames[i];
        const FrameDesc& b = back.frames[i];
        EXPECT_EQ(a.file_path, b.file_path);
        EXPECT_EQ(a.view_index, b.view_index);
        EXPECT_EQ(a.transform, b.transform);
        EXPECT_EQ(a.light.position, b.light.position);
        EXPECT_EQ(a.light.intensity, b.light.intensity);
        EXPECT_EQ(a.mask_path, b.mask_path);
        EXPECT_EQ(a.split, b.split);
        EXPECT_EQ(a.extra, b.extra);
        EXPECT_EQ(a.light_extra, b.light_extra);
        EXPECT_EQ(a.intrinsics.w, b.intrinsics.w);
        EXPECT_EQ(a.intrinsics.fl_x, b.intrinsics.fl_x);
        EXPECT_EQ(a.intrinsics.cy, b.intrinsics.cy);
    }
}

// Version 1.1: directional lights read back with a unit direction and their irradiance,
// stand in as point lights kDirectionalStandIn D away (capture.h), whose direction and
// irradiance over the mesh differ from the light's by at most the stated bounds; a capture
// written back keeps version 1.1 and the directional light, and one without directional
// lights keeps version 1.
TEST(CaptureJson, DirectionalLightsStandInAndRoundTrip) {
    CaptureFixture fx;
    fx.j["version"] = 1.1;
    fx.j["frames"][1]["light"] = directional_json({0.0, 3.0, 4.0}, {0.25, 0.5, 1.0});
    const Capture c = fx.load({.load_images = false});
    const PointLight& l = c.desc.frames[1].light;
    ASSERT_TRUE(l.directional.has_value());
    EXPECT_NEAR(glm::length(l.directional->direction - glm::dvec3(0.0, 0.6, 0.8)), 0.0, 1e-15);
    EXPECT_EQ(l.directional->irradiance, glm::dvec3(0.25, 0.5, 1.0));
    const Bounds b = mesh_bounds(c.mesh);
    const double size = glm::length(glm::dvec3(b.max) - glm::dvec3(b.min));
    double worst_angle = 0.0, worst_irradiance = 0.0;
    for (const glm::vec3& v : c.mesh.positions) { // every vertex of the mesh
        const glm::dvec3 to = l.position - glm::dvec3(v);
        const double d2 = glm::dot(to, to);
        worst_angle = std::max(worst_angle, std::acos(std::min(1.0, glm::dot(to / std::sqrt(d2), l.directional->direction))));
        worst_irradiance = std::max(worst_irradiance, std::abs(l.intensity.z / d2 / l.directional->irradiance.z - 1.0));
    }
    std::printf("stand-in at %.3g D: worst direction error %.3g rad, worst irradiance error %.3g\n",
                glm::length(l.position - glm::dvec3(b.center())) / size, worst_angle, worst_irradiance);
    EXPECT_LE(worst_angle, 0.5 / kDirectionalStandIn);
    EXPECT_LE(worst_irradiance, 1.0 / kDirectionalStandIn);
    EXPECT_FALSE(c.desc.frames[0].light.directional.has_value());

    const json back = capture_desc_to_json(c.desc);
    EXPECT_EQ(back["version"].get<double>(), 1.1);
    EXPECT_EQ(back["frames"][1]["light"]["type"], "directional");
    EXPECT_FALSE(back["frames"][1]["light"].contains("position"));
    EXPECT_EQ(back["frames"][1]["light"]["irradiance"], json::array({0.25, 0.5, 1.0}));
    EXPECT_EQ(back["frames"][0]["light"]["type"], "point");

    CaptureFixture v1;
    EXPECT_EQ(capture_desc_to_json(v1.load({.load_images = false}).desc)["version"], 1);
}

// A capture loaded without its mesh (specula evaluate, render --frame) still places the
// stand-ins: the same place as with the mesh.
TEST(CaptureLoad, DirectionalStandInsWithoutLoadingTheMesh) {
    CaptureFixture fx;
    fx.j["version"] = 1.1;
    fx.j["frames"][2]["light"] = directional_json({1.0, 0.0, 0.0});
    const Capture with = fx.load({.load_images = false});
    const Capture without = fx.load({.load_mesh = false, .load_images = false});
    EXPECT_TRUE(without.mesh.positions.empty());
    EXPECT_EQ(with.desc.frames[2].light.position, without.desc.frames[2].light.position);
    EXPECT_EQ(with.desc.frames[2].light.intensity, without.desc.frames[2].light.intensity);
    EXPECT_GT(glm::length(without.desc.frames[2].light.position), 1e5);
}

TEST(CaptureJson, PerFrameIntrinsicsWrittenWhereTheyDiffer) {
    CaptureFixture fx;
    for (int l = 0; l < 2; ++l) fx.j["frames"][CaptureFixture::frame_index(0, l)]["fl_y"] = 9.0;
    const CaptureDesc desc = fx.load({.load_images = false}).desc;
    const json written = capture_desc_to_json(desc);
    const CaptureDesc back = parse_capture_desc(written, fx.dir / "capture.json");
    for (std::size_t i = 0; i < desc.frames.size(); ++i)
        EXPECT_EQ(back.frames[i].intrinsics.fl_y, desc.frames[i].intrinsics.fl_y) << i;
}

TEST(CaptureJson, EffectiveSaturation) {
    CaptureDesc desc;
    ImageFileInfo integer_file;
    ImageFileInfo float_file;
    float_file.is_float = true;
    EXPECT_EQ(effective_saturation(desc, integer_file), 1.0f);
    EXPECT_EQ(effective_saturation(desc, float_file), std::numeric_limits<float>::infinity());
    desc.saturation = 0.9;
    EXPECT_EQ(effective_saturation(desc, integer_file), 0.9f);
    EXPECT_EQ(effective_saturation(desc, float_file), 0.9f);
}

// ---- refusals: every case of "What a reader must refuse" ---------------------------

struct RefusalCase {
    std::string name;
    std::function<void(CaptureFixture&)> mutate;
    std::string file;  // relative to the capture folder
    std::string field; // exact field
    bool headers_only = false;
};

void PrintTo(const RefusalCase& c, std::ostream* os) { *os << c.name; }

json rot_z(double deg, double tz) {
    const double a = deg * 3.14159265358979323846 / 180.0;
    return json::array({json::array({std::cos(a), -std::sin(a), 0, 0}), json::array({std::sin(a), std::cos(a), 0, 0}),
                        json::array({0, 0, 1, tz}), json::array({0, 0, 0, 1})});
}

std::vector<RefusalCase> refusal_cases() {
    const std::string cj = "capture.json";
    std::vector<RefusalCase> cases = {
        // top level
        {"NotAnObject", [](CaptureFixture& fx) { fx.j = json::array({1, 2}); }, cj, ""},
        {"MissingFormat", [](CaptureFixture& fx) { fx.j.erase("format"); }, cj, "format"},
        {"WrongFormat", [](CaptureFixture& fx) { fx.j["format"] = "nerfstudio"; }, cj, "format"},
        {"WrongVersion", [](CaptureFixture& fx) { fx.j["version"] = 2; }, cj, "version"},
        {"VersionAsString", [](CaptureFixture& fx) { fx.j["version"] = "1"; }, cj, "version"},
        {"MissingMeshPath", [](CaptureFixture& fx) { fx.j.erase("mesh_path"); }, cj, "mesh_path"},
        {"MeshPathNotString", [](CaptureFixture& fx) { fx.j["mesh_path"] = 3; }, cj, "mesh_path"},
        {"BadColorSpace", [](CaptureFixture& fx) { fx.j["color_space"] = "adobe-rgb"; }, cj, "color_space"},
        {"NonPositiveSaturation", [](CaptureFixture& fx) { fx.j["saturation"] = 0.0; }, cj, "saturation"},
        {"FocalZero", [](CaptureFixture& fx) { fx.j["fl_x"] = 0.0; }, cj, "fl_x"},
        {"FocalNegative", [](CaptureFixture& fx) { fx.j["fl_y"] = -5.0; }, cj, "fl_y"},
        {"FocalWrongType", [](CaptureFixture& fx) { fx.j["fl_x"] = "886.8"; }, cj, "fl_x"},
        {"WidthZero", [](CaptureFixture& fx) { fx.j["w"] = 0; }, cj, "w"},
        {"HeightNegative", [](CaptureFixture& fx) { fx.j["h"] = -3; }, cj, "h"},
        {"WidthNotInteger", [](CaptureFixture& fx) { fx.j["w"] = 4.5; }, cj, "w"},
        {"MissingFocalEverywhere", [](CaptureFixture& fx) { fx.j.erase("fl_x"); }, cj, "fl_x"},
        {"MissingCxInOneFrame",
         [](CaptureFixture& fx) {
             fx.j.erase("cx");
             for (std::size_t i = 0; i < 3; ++i) fx.j["frames"][i]["cx"] = 2.0;
         },
         cj, "frames[3].cx"},
        {"FrameFocalNegative", [](CaptureFixture& fx) { fx.j["frames"][1]["fl_y"] = -1.0; }, cj, "frames[1].fl_y"},
        {"MissingFrames", [](CaptureFixture& fx) { fx.j.erase("frames"); }, cj, "frames"},
        {"NoFrames", [](CaptureFixture& fx) { fx.j["frames"] = json::array(); }, cj, "frames"},
        {"FramesNotArray", [](CaptureFixture& fx) { fx.j["frames"] = json::object(); }, cj, "frames"},
        {"FrameNotObject", [](CaptureFixture& fx) { fx.j["frames"][1] = "v0.png"; }, cj, "frames[1]"},
        // frame fields
        {"MissingFilePath", [](CaptureFixture& fx) { fx.j["frames"][2].erase("file_path"); }, cj, "frames[2].file_path"},
        {"MissingViewIndex", [](CaptureFixture& fx) { fx.j["frames"][2].erase("view_index"); }, cj, "frames[2].view_index"},
        {"ViewIndexWrongType", [](CaptureFixture& fx) { fx.j["frames"][0]["view_index"] = "1"; }, cj, "frames[0].view_index"},
        {"MissingTransform", [](CaptureFixture& fx) { fx.j["frames"][3].erase("transform_matrix"); }, cj,
         "frames[3].transform_matrix"},
        {"TransformThreeRows",
         [](CaptureFixture& fx) { fx.j["frames"][3]["transform_matrix"].erase(3); }, cj, "frames[3].transform_matrix"},
        {"TransformShortRow",
         [](CaptureFixture& fx) { fx.j["frames"][3]["transform_matrix"][1].erase(3); }, cj, "frames[3].transform_matrix"},
        {"TransformScaled",
         [](CaptureFixture& fx) {
             for (int r = 0; r < 3; ++r) fx.j["frames"][3]["transform_matrix"][r][r] = 2.0;
         },
         cj, "frames[3].transform_matrix"},
        {"TransformSheared", [](CaptureFixture& fx) { fx.j["frames"][3]["transform_matrix"][0][1] = 0.1; }, cj,
         "frames[3].transform_matrix"},
        {"TransformReflection", [](CaptureFixture& fx) { fx.j["frames"][3]["transform_matrix"][0][0] = -1.0; }, cj,
         "frames[3].transform_matrix"},
        {"TransformLastRow", [](CaptureFixture& fx) { fx.j["frames"][3]["transform_matrix"][3][2] = 0.5; }, cj,
         "frames[3].transform_matrix"},
        {"TransformNotNumbers", [](CaptureFixture& fx) { fx.j["frames"][3]["transform_matrix"][2][3] = "3"; }, cj,
         "frames[3].transform_matrix[2][3]"},
        {"PosesOfViewDisagreeTranslation",
         [](CaptureFixture& fx) { fx.j["frames"][3]["transform_matrix"] = pose_json(3.0, 0.01); }, cj,
         "frames[3].transform_matrix"},
        {"PosesOfViewDisagreeRotation", [](CaptureFixture& fx) { fx.j["frames"][1]["transform_matrix"] = rot_z(1.0, 4.0); },
         cj, "frames[1].transform_matrix"},
        {"IntrinsicsOfViewDisagree", [](CaptureFixture& fx) { fx.j["frames"][1]["fl_x"] = 6.0; }, cj, "frames[1]"},
        {"MissingLight", [](CaptureFixture& fx) { fx.j["frames"][0].erase("light"); }, cj, "frames[0].light"},
        // directional lights (version 1.1)
        {"DirectionalInVersion1", [](CaptureFixture& fx) { fx.j["frames"][1]["light"] = directional_json({0, 0, 1}); }, cj,
         "frames[1].light.type"},
        {"DirectionalZero",
         [](CaptureFixture& fx) {
             fx.j["version"] = 1.1;
             fx.j["frames"][1]["light"] = directional_json({0, 0, 0});
         },
         cj, "frames[1].light.direction"},
        {"DirectionalNotANumber",
         [](CaptureFixture& fx) {
             fx.j["version"] = 1.1;
             fx.j["frames"][1]["light"] = directional_json({0, 0, 1});
             fx.j["frames"][1]["light"]["direction"][2] = "up";
         },
         cj, "frames[1].light.direction[2]"},
        {"DirectionalTwoNumbers",
         [](CaptureFixture& fx) {
             fx.j["version"] = 1.1;
             fx.j["frames"][1]["light"] = directional_json({0, 0, 1});
             fx.j["frames"][1]["light"]["direction"].erase(2);
         },
         cj, "frames[1].light.direction"},
        {"DirectionalMissingDirection",
         [](CaptureFixture& fx) {
             fx.j["version"] = 1.1;
             fx.j["frames"][1]["light"] = directional_json({0, 0, 1});
             fx.j["frames"][1]["light"].erase("direction");
         },
         cj, "frames[1].light.direction"},
        {"DirectionalNegativeIrradiance",
         [](CaptureFixture& fx) {
             fx.j["version"] = 1.1;
             fx.j["frames"][2]["light"] = directional_json({0, 0, 1}, {0.5, -0.1, 0.5});
         },
         cj, "frames[2].light.irradiance[1]"},
        {"DirectionalIrradianceTooHigh",
         [](CaptureFixture& fx) {
             fx.j["version"] = 1.1;
             fx.j["frames"][2]["light"] = directional_json({0, 0, 1}, {0.5, 0.5, 1e16});
         },
         cj, "frames[2].light.irradiance[2]"},
        {"DirectionalMissingIrradiance",
         [](CaptureFixture& fx) {
             fx.j["version"] = 1.1;
             fx.j["frames"][2]["light"] = directional_json({0, 0, 1});
             fx.j["frames"][2]["light"].erase("irradiance");
         },
         cj, "frames[2].light.irradiance"},
        {"DirectionalGivenAPosition",
         [](CaptureFixture& fx) {
             fx.j["version"] = 1.1;
             fx.j["frames"][0]["light"] = directional_json({0, 0, 1});
             fx.j["frames"][0]["light"]["position"] = {0.0, 0.0, 3.0};
         },
         cj, "frames[0].light.position"},
        {"DirectionalGivenAnIntensity",
         [](CaptureFixture& fx) {
             fx.j["version"] = 1.1;
             fx.j["frames"][0]["light"] = directional_json({0, 0, 1});
             fx.j["frames"][0]["light"]["intensity"] = {1.0, 1.0, 1.0};
         },
         cj, "frames[0].light.intensity"},
        {"PointGivenADirection",
         [](CaptureFixture& fx) {
             fx.j["version"] = 1.1;
             fx.j["frames"][3]["light"]["direction"] = {0.0, 0.0, 1.0};
         },
         cj, "frames[3].light.direction"},
        {"UnknownLightTypeIn1_1",
         [](CaptureFixture& fx) {
             fx.j["version"] = 1.1;
             fx.j["frames"][3]["light"]["type"] = "spot";
         },
         cj, "frames[3].light.type"},
        {"LightNotObject", [](CaptureFixture& fx) { fx.j["frames"][0]["light"] = 1; }, cj, "frames[0].light"},
        {"LightBadType", [](CaptureFixture& fx) { fx.j["frames"][0]["light"]["type"] = "spot"; }, cj, "frames[0].light.type"},
        {"LightMissingType", [](CaptureFixture& fx) { fx.j["frames"][0]["light"].erase("type"); }, cj,
         "frames[0].light.type"},
        {"LightPositionTwoNumbers", [](CaptureFixture& fx) { fx.j["frames"][0]["light"]["position"] = {1.0, 2.0}; }, cj,
         "frames[0].light.position"},
        {"LightMissingIntensity", [](CaptureFixture& fx) { fx.j["frames"][0]["light"].erase("intensity"); }, cj,
         "frames[0].light.intensity"},
        {"LightNegativeIntensity", [](CaptureFixture& fx) { fx.j["frames"][0]["light"]["intensity"][1] = -1.0; }, cj,
         "frames[0].light.intensity"},
        {"BadSplit", [](CaptureFixture& fx) { fx.j["frames"][2]["split"] = "validation"; }, cj, "frames[2].split"},
        {"MaskPathNotString", [](CaptureFixture& fx) { fx.j["frames"][2]["mask_path"] = false; }, cj, "frames[2].mask_path"},
        // files
        {"MissingImage", [](CaptureFixture& fx) { fs::remove(fx.dir / CaptureFixture::image_name(0, 1)); },
         "images/v0_l1.png", "frames[3].file_path"},
        {"ImageNotAnImage",
         [](CaptureFixture& fx) { write_text_file(fx.dir / CaptureFixture::image_name(0, 1), "not a png at all"); },
         "images/v0_l1.png", "frames[3].file_path"},
        {"ImageWrongSize",
         [](CaptureFixture& fx) { fx.write_png(CaptureFixture::image_name(1, 1), solid(kH, kW, 3, 0.2f)); },
         "images/v1_l1.png", "frames[1].file_path"},
        {"ImageWrongSizeHeadersOnly",
         [](CaptureFixture& fx) { fx.write_png(CaptureFixture::image_name(1, 1), solid(kW, kH + 1, 3, 0.2f)); },
         "images/v1_l1.png", "frames[1].file_path", true},
        {"MissingMask", [](CaptureFixture& fx) { fs::remove(fx.dir / "masks/v0.png"); }, "masks/v0.png",
         "frames[2].mask_path"},
        {"MaskWrongSize",
         [](CaptureFixture& fx) { write_image(fx.dir / "masks/v0.png", solid(kW + 1, kH, 1, 1.0f), ColorSpace::Linear); },
         "masks/v0.png", "frames[2].mask_path"},
        {"MaskWrongSizeHeadersOnly",
         [](CaptureFixture& fx) { write_image(fx.dir / "masks/v0.png", solid(kW, 1, 1, 1.0f), ColorSpace::Linear); },
         "masks/v0.png", "frames[2].mask_path", true},
        {"MissingMesh", [](CaptureFixture& fx) { fs::remove(fx.dir / "mesh.glb"); }, "mesh.glb", "mesh_path"},
        {"MeshNotGltf", [](CaptureFixture& fx) { write_text_file(fx.dir / "mesh.glb", "solid cube\nendsolid\n"); },
         "mesh.glb", "mesh_path"},
        {"EmptyMesh",
         [](CaptureFixture& fx) {
             Mesh m;
             m.positions = {{0, 0, 0}, {1, 1, 1}, {2, 2, 2}};
             m.triangles = {{0, 1, 2}};
             write_mesh_glb(fx.dir / "mesh.glb", m);
         },
         "mesh.glb", "mesh_path"},
        {"MeshNonFiniteVertex",
         [](CaptureFixture& fx) {
             test::GltfBuilder b;
             const float inf = std::numeric_limits<float>::infinity();
             const int pos = b.positions({0, 0, 0, 1, 0, 0, 0, inf, 0});
             b.node({{"mesh", b.mesh(json::array({{{"attributes", {{"POSITION", pos}}}}}))}});
             b.write(fx.dir / "mesh.gltf");
             fx.j["mesh_path"] = "mesh.gltf";
         },
         "mesh.gltf", "meshes[0].primitives[0].attributes.POSITION"},
        // ranges (docs/capture-format.md "Ranges"): numbers that are finite as doubles but not
        // usable as the floats the engine computes with (issue 21 cases 1-3 and 18)
        {"LightPositionOverflowsFloat", [](CaptureFixture& fx) { fx.j["frames"][0]["light"]["position"] = {1e39, 0.0, 0.0}; },
         cj, "frames[0].light.position[0]"},
        {"TranslationBeyondTheWorld",
         [](CaptureFixture& fx) {
             for (std::size_t f : {0u, 1u}) fx.j["frames"][f]["transform_matrix"][0][3] = 1e20; // every frame of view 1
         },
         cj, "frames[0].transform_matrix[0][3]"},
        {"FocalDenormal", [](CaptureFixture& fx) { fx.j["fl_x"] = 5e-324; }, cj, "fl_x"},
        {"FocalBelowTheFieldOfView", [](CaptureFixture& fx) { fx.j["fl_y"] = 1e-3; }, cj, "fl_y"},
        {"FrameFocalTooLong", [](CaptureFixture& fx) { fx.j["frames"][1]["fl_y"] = 2e6; }, cj, "frames[1].fl_y"},
        {"PrincipalPointFarOff", [](CaptureFixture& fx) { fx.j["cx"] = 1e9; }, cj, "cx"},
        {"WidthAboveTheLimit", [](CaptureFixture& fx) { fx.j["w"] = 16385; }, cj, "w"},
        {"SaturationBelowFloat", [](CaptureFixture& fx) { fx.j["saturation"] = 1e-40; }, cj, "saturation"},
        {"IntensityOverflowsFloat", [](CaptureFixture& fx) { fx.j["frames"][0]["light"]["intensity"][1] = 1e308; }, cj,
         "frames[0].light.intensity[1]"},
        {"IrradianceTooHigh", [](CaptureFixture& fx) { fx.j["frames"][2]["light"]["intensity"] = {1e20, 1.0, 1.0}; }, cj,
         "frames[2].light.intensity"},
        {"IrradianceTooLow", [](CaptureFixture& fx) { fx.j["frames"][2]["light"]["intensity"] = {1.0, 1e-20, 1.0}; }, cj,
         "frames[2].light.intensity[1]"},
        {"LightOnTheSurface", [](CaptureFixture& fx) { fx.j["frames"][3]["light"]["position"] = {0.5, 0.1, 0.2}; }, cj,
         "frames[3].light.position"},
        {"LightFarBeyondTheObject", [](CaptureFixture& fx) { fx.j["frames"][3]["light"]["position"] = {1e8, 0.0, 0.0}; }, cj,
         "frames[3].light.position"},
        {"CameraFarBeyondTheObject",
         [](CaptureFixture& fx) {
             for (std::size_t f : {2u, 3u}) fx.j["frames"][f]["transform_matrix"] = pose_json(1e7);
         },
         cj, "frames[2].transform_matrix"},
        {"MeshBeyondTheWorld",
         [](CaptureFixture& fx) {
             Mesh m = unit_cube_mesh();
             for (glm::vec3& p : m.positions) p = p * 1e30f;
             write_mesh_glb(fx.dir / "mesh.glb", m);
         },
         "mesh.glb", "mesh_path"},
        {"MeshTooSmall",
         [](CaptureFixture& fx) {
             Mesh m = unit_cube_mesh();
             for (glm::vec3& p : m.positions) p = p * 1e-12f;
             write_mesh_glb(fx.dir / "mesh.glb", m);
         },
         "mesh.glb", "mesh_path"},
        // paths: inside the capture's folder, no NUL
        {"MeshPathAbsolute", [](CaptureFixture& fx) { fx.j["mesh_path"] = (fx.dir / "mesh.glb").string(); }, cj, "mesh_path"},
        {"FilePathLeavesTheFolder", [](CaptureFixture& fx) { fx.j["frames"][2]["file_path"] = "images/../../v0_l0.png"; }, cj,
         "frames[2].file_path"},
        {"MaskPathWithNul", [](CaptureFixture& fx) { fx.j["frames"][2]["mask_path"] = std::string("masks/v0.png\0.txt", 16); },
         cj, "frames[2].mask_path"},
        {"FilePathWithNulHeadersOnly",
         [](CaptureFixture& fx) { fx.j["frames"][1]["file_path"] = std::string("images/v1_l1.png\0", 17); }, cj,
         "frames[1].file_path", true},
        {"SymlinkLeavesTheFolder",
         [](CaptureFixture& fx) {
             // a folder of its own, removed when the test program ends (a file put beside the
             // capture's folder stayed in the temp area after every run)
             static const test::TempDir elsewhere{"capture-outside"};
             const fs::path outside = elsewhere / (fx.dir.path().filename().string() + "-outside.png");
             write_image(outside, solid(kW, kH, 3, 0.25f), ColorSpace::Srgb);
             fs::remove(fx.dir / CaptureFixture::image_name(0, 1));
             fs::create_symlink(outside, fx.dir / CaptureFixture::image_name(0, 1));
         },
         "images/v0_l1.png", "frames[3].file_path"},
        // images decoded only in part (issue 21 case 16): a JPEG cut in half
        {"TruncatedJpeg",
         [](CaptureFixture& fx) {
             Image img(64, 48, 3);
             for (std::size_t i = 0; i < img.pixels.size(); ++i) img.pixels[i] = float(i % 97) / 96.0f;
             write_image(fx.dir / "images/whole.jpg", img, ColorSpace::Srgb);
             const std::string bytes = read_text_file(fx.dir / "images/whole.jpg");
             write_text_file(fx.dir / "images/half.jpg", bytes.substr(0, bytes.size() / 2));
             fx.j["frames"][3]["file_path"] = "images/half.jpg";
             fx.j["frames"][3]["w"] = 64;
             fx.j["frames"][3]["h"] = 48;
             fx.j["frames"][2]["w"] = 64; // one view, one size
             fx.j["frames"][2]["h"] = 48;
             fx.j["frames"][2]["file_path"] = "images/whole.jpg";
             fx.j["frames"][2].erase("mask_path");
             fx.j["frames"][3].erase("mask_path");
         },
         "images/half.jpg", "frames[3].file_path"},
    };
    return cases;
}

class CaptureRefusal : public ::testing::TestWithParam<RefusalCase> {};

TEST_P(CaptureRefusal, NamesFileAndField) {
    const RefusalCase& rc = GetParam();
    CaptureFixture fx;
    rc.mutate(fx);
    const InputError e = expect_input_error([&] { (void)fx.load({.load_images = !rc.headers_only}); });
    EXPECT_EQ(e.file(), fx.dir / rc.file) << e.what();
    EXPECT_EQ(e.field(), rc.field) << e.what();
    EXPECT_FALSE(e.message().empty());
}

INSTANTIATE_TEST_SUITE_P(SpecCases, CaptureRefusal, ::testing::ValuesIn(refusal_cases()),
                         [](const ::testing::TestParamInfo<RefusalCase>& info) { return info.param.name; });

TEST(CaptureRefusalText, MissingCaptureJson) {
    test::TempDir dir("capture");
    const InputError e = expect_input_error([&] { (void)load_capture(dir.path()); });
    EXPECT_EQ(e.file(), dir / "capture.json");
    EXPECT_NE(e.message().find("not found"), std::string::npos);
}

TEST(CaptureRefusalText, MalformedJsonSaysWhere) {
    CaptureFixture fx;
    write_text_file(fx.dir / "capture.json", "{\n  \"format\": \"specula-capture\",\n  \"version\": 1,,\n}");
    const InputError e = expect_input_error([&] { (void)load_capture(fx.dir.path()); });
    EXPECT_EQ(e.file(), fx.dir / "capture.json");
    EXPECT_NE(e.message().find("line 3"), std::string::npos) << e.what();
}

TEST(CaptureRefusalText, NonFiniteNumber) {
    CaptureFixture fx;
    std::string text = fx.j.dump();
    const std::string from = "\"fl_x\":5.0";
    ASSERT_NE(text.find(from), std::string::npos) << text;
    text.replace(text.find(from), from.size(), "\"fl_x\":1e999");
    write_text_file(fx.dir / "capture.json", text);
    const InputError e = expect_input_error([&] { (void)load_capture(fx.dir.path()); });
    EXPECT_EQ(e.file(), fx.dir / "capture.json");
    // nlohmann reads 1e999 as infinity (refused as a non-finite number) or refuses it as malformed
    EXPECT_TRUE(e.field() == "fl_x" || e.field().empty()) << e.what();
}

TEST(CaptureRefusalText, NonFiniteLightIntensity) {
    CaptureFixture fx;
    fx.j["frames"][0]["light"]["intensity"] = {1.0, 1.0, 1.0};
    std::string text = fx.j.dump();
    const std::string from = "\"intensity\":[1.0,1.0,1.0]";
    ASSERT_NE(text.find(from), std::string::npos) << text;
    text.replace(text.find(from), from.size(), "\"intensity\":[1.0,-1e999,1.0]");
    write_text_file(fx.dir / "capture.json", text);
    const InputError e = expect_input_error([&] { (void)load_capture(fx.dir.path()); });
    EXPECT_EQ(e.file(), fx.dir / "capture.json");
    // nlohmann refuses -1e999 as a number overflow (malformed, with its place), or reads -inf (non-finite)
    if (e.field().empty()) EXPECT_NE(e.message().find("line 1, column"), std::string::npos) << e.what();
    else EXPECT_EQ(e.field(), "frames[0].light.intensity[1]") << e.what();
}

TEST(CaptureRefusalText, RangeRefusalsSayWhatAndWhy) {
    CaptureFixture fx;
    fx.j["frames"][0]["light"]["intensity"][0] = 1e308;
    InputError e = expect_input_error([&] { (void)fx.load(); });
    EXPECT_NE(e.message().find("1e+308 is out of range"), std::string::npos) << e.what();
    EXPECT_NE(e.message().find("Ranges"), std::string::npos) << e.what();
    CaptureFixture g;
    g.j["frames"][2]["light"]["intensity"] = {1e20, 1.0, 1.0};
    e = expect_input_error([&] { (void)g.load(); });
    EXPECT_NE(e.message().find("irradiance I / d^2 of up to"), std::string::npos) << e.what();
    EXPECT_NE(e.message().find("d = 2.5"), std::string::npos) << e.what(); // light (-1, 0.5, 3), box face z = 0.5
}

TEST(CaptureRefusalText, DuplicateKeysAreRefusedNamingTheKey) {
    CaptureFixture fx;
    fx.j["frames"][1]["light"]["position"] = {-1.0, 0.6, 3.0}; // makes frames[1]'s light unique in the text
    std::string text = fx.j.dump();
    // A second "fl_x" at the top level: nlohmann (and most readers) would keep the last one silently.
    const std::string top = "\"fl_x\":5.0";
    ASSERT_NE(text.find(top), std::string::npos);
    write_text_file(fx.dir / "capture.json", std::string(text).replace(text.find(top), top.size(), top + ",\"fl_x\":7.0"));
    InputError e = expect_input_error([&] { (void)load_capture(fx.dir.path()); });
    EXPECT_EQ(e.file(), fx.dir / "capture.json");
    EXPECT_EQ(e.field(), "fl_x") << e.what();
    EXPECT_NE(e.message().find("duplicate JSON key"), std::string::npos) << e.what();
    // Deeper: frames[1].light.type twice (frames[1]'s light differs from every other frame's).
    const std::string light = fx.j["frames"][1]["light"].dump();
    ASSERT_EQ(text.find(light), text.rfind(light));
    std::string text2 = text;
    text2.replace(text2.find(light), light.size(), light.substr(0, light.size() - 1) + ",\"type\":\"point\"}");
    write_text_file(fx.dir / "capture.json", text2);
    e = expect_input_error([&] { (void)load_capture(fx.dir.path(), {.load_images = false}); });
    EXPECT_EQ(e.field(), "frames[1].light.type") << e.what();
    // The same text without the duplicate loads.
    write_text_file(fx.dir / "capture.json", text);
    EXPECT_NO_THROW((void)load_capture(fx.dir.path(), {.load_images = false}));
}

TEST(CaptureRefusalText, NulInsideAPathIsRefusedNotCutShort) {
    CaptureFixture fx;
    // "images/v1_l0.png\u0000x" would open images/v1_l0.png, which exists.
    fx.j["frames"][0]["file_path"] = std::string("images/v1_l0.png\0x", 18);
    const InputError e = expect_input_error([&] { (void)fx.load(); });
    EXPECT_EQ(e.field(), "frames[0].file_path");
    EXPECT_NE(e.message().find("NUL"), std::string::npos) << e.what();
}

TEST(CaptureRefusalText, EveryPathStaysInsideTheCapture) {
    for (const std::string& path : {std::string("../mesh.glb"), std::string("a/../../mesh.glb"), std::string("/tmp/mesh.glb")}) {
        CaptureFixture fx;
        fx.j["mesh_path"] = path;
        const InputError e = expect_input_error([&] { (void)fx.load(); });
        EXPECT_EQ(e.field(), "mesh_path") << path;
        EXPECT_TRUE(e.message().find("leaves the capture's folder") != std::string::npos ||
                    e.message().find("absolute path") != std::string::npos)
            << e.what();
    }
    CaptureFixture fx; // ".." that stays inside is fine
    fx.j["frames"][0]["file_path"] = "masks/../" + CaptureFixture::image_name(1, 0);
    EXPECT_NO_THROW((void)fx.load());
}

// ---- memory (issue 21 cases 7, 8) --------------------------------------------------

TEST(CaptureMemory, AnImageNamedByManyFramesIsDecodedOnce) {
    CaptureFixture fx;
    Image img(kW, kH, 3);
    for (std::size_t i = 0; i < img.pixels.size(); ++i) img.pixels[i] = float(i) / float(img.pixels.size());
    fx.write_png("images/shared.png", img, ColorSpace::Linear, 16);
    json frames = json::array();
    for (int k = 0; k < 150; ++k) {
        json f = frame_json("images/shared.png", k % 2, 3.0 + k % 2, {1.0, 0.5, 3.0 + 0.01 * k});
        frames.push_back(f);
    }
    fx.j["frames"] = frames;
    fx.j["color_space"] = "linear";
    const Capture c = fx.load();
    EXPECT_EQ(c.image_files_decoded, 1u);
    ASSERT_EQ(c.images.size(), 150u);
    for (const FrameImage& im : c.images) EXPECT_EQ(im.color.pixels, c.images.front().color.pixels);
    EXPECT_NEAR(c.images[149].color.at(3, 2, 1), img.at(3, 2, 1), 1e-4f);
    // The original fixture: 4 distinct files, 4 decodes.
    CaptureFixture g;
    EXPECT_EQ(g.load().image_files_decoded, 4u);
}

// What an output folder may not be or contain (core/output_dir.h): read from capture.json
// alone, each distinct file once.
TEST(CaptureInputs, FolderMeshImagesAndMasksFromTheDescriptionAlone) {
    CaptureFixture fx;
    fx.write_json();
    const CaptureDesc desc = read_capture_desc(fx.dir.path());
    EXPECT_EQ(desc.dir, fx.dir.path());
    const std::vector<fs::path> paths = capture_input_paths(desc);
    const std::vector<fs::path> expected{fx.dir.path(),
                                         fx.dir / "mesh.glb",
                                         fx.dir / CaptureFixture::image_name(1, 0),
                                         fx.dir / CaptureFixture::image_name(1, 1),
                                         fx.dir / CaptureFixture::image_name(0, 0),
                                         fx.dir / "masks/v0.png",
                                         fx.dir / CaptureFixture::image_name(0, 1)};
    EXPECT_EQ(paths, expected); // the mask two frames share, once
    // The same refusals as load_capture for a broken description; no image is opened.
    fs::remove(fx.dir / CaptureFixture::image_name(0, 0));
    EXPECT_NO_THROW((void)read_capture_desc(fx.dir / "capture.json"));
    fx.j["w"] = -1;
    fx.write_json();
    EXPECT_THROW((void)read_capture_desc(fx.dir.path()), InputError);
}

TEST(CaptureMemory, DecodedImageBytesCountFramesMasksAndDecodeBuffers) {
    CaptureFixture fx;
    const Capture c = fx.load({.load_images = false});
    const std::uint64_t pixels = kW * kH;
    // 4 frames x 13 bytes, 1 mask file x 1 byte, and 2 threads decoding a file each (18 bytes a pixel).
    EXPECT_EQ(decoded_image_bytes(c.desc, 2), 4 * pixels * 13 + pixels + 2 * pixels * 18);
    EXPECT_EQ(decoded_image_bytes(c.desc, 1), 4 * pixels * 13 + pixels + pixels * 18);
}

TEST(CaptureMemory, ACaptureThatCannotFitIsRefusedBeforeDecoding) {
    // Issue 21 case 7: 150 frames all naming one 4096 x 4096 PNG need 150 decoded copies
    // (32.7 GB). The PNG here only claims that size in its header: nothing is decoded.
    CaptureFixture fx;
    fx.j["w"] = 4096;
    fx.j["h"] = 4096;
    fx.j["fl_x"] = 5000.0;
    fx.j["fl_y"] = 5000.0;
    fx.j["cx"] = 2048.0;
    fx.j["cy"] = 2048.0;
    json frames = json::array();
    for (int k = 0; k < 150; ++k) frames.push_back(frame_json("images/big.png", k % 2, 3.0 + k % 2, {1.0, 0.5, 3.0}));
    fx.j["frames"] = frames;
    write_text_file(fx.dir / "images/big.png", "not decoded");
    const InputError e = expect_input_error([&] { (void)fx.load({.memory_available = std::uint64_t{4} << 30}); });
    EXPECT_EQ(e.file(), fx.dir / "capture.json");
    // 150 x 4096^2 x 13 bytes = 32.7 GB, and one file's decode buffers (4096^2 x 18 bytes).
    EXPECT_NE(e.message().find("need 33.0 GB"), std::string::npos) << e.what();
    EXPECT_NE(e.message().find("150 frames of up to 4096 x 4096"), std::string::npos) << e.what();
    EXPECT_NE(e.message().find("4.29 GB is available"), std::string::npos) << e.what();
    EXPECT_NE(e.message().find("--no-images"), std::string::npos) << e.what();
}

// ---- warnings on legal but useless data (issue 21 case 15) ---------------------------

bool has_warning(const Capture& c, const std::string& text) {
    return std::any_of(c.warnings.begin(), c.warnings.end(), [&](const std::string& w) { return w.find(text) != std::string::npos; });
}

TEST(CaptureWarnings, EmptyMasksAreNamed) {
    CaptureFixture fx;
    write_image(fx.dir / "masks/v0.png", Image(kW, kH, 1, 0.0f), ColorSpace::Linear);
    Capture c = fx.load();
    EXPECT_TRUE(has_warning(c, "1 of 1 mask file(s) are empty")) << summarize(c);
    EXPECT_TRUE(has_warning(c, "frames[2].mask_path (masks/v0.png)")) << summarize(c);
    EXPECT_FALSE(has_warning(c, "no frame sees the object")) << summarize(c); // view 1 has no mask
    for (std::size_t f : {0u, 1u}) fx.j["frames"][f]["mask_path"] = "masks/v0.png";
    c = fx.load();
    EXPECT_TRUE(has_warning(c, "no frame sees the object")) << summarize(c);
}

TEST(CaptureWarnings, ViewsThatCannotSeeTheMeshAreNamed) {
    CaptureFixture fx;
    // view 1 turned around (180 degrees about y): it looks away from the cube.
    const json away = json::array({json::array({-1, 0, 0, 0}), json::array({0, 1, 0, 0}), json::array({0, 0, -1, 4.0}),
                                   json::array({0, 0, 0, 1})});
    for (std::size_t f : {0u, 1u}) fx.j["frames"][f]["transform_matrix"] = away;
    Capture c = fx.load();
    EXPECT_TRUE(has_warning(c, "1 of 2 views cannot see the mesh")) << summarize(c);
    EXPECT_TRUE(has_warning(c, "view_index 1 (frames[0])")) << summarize(c);
    EXPECT_FALSE(has_warning(c, "no train view sees it")) << summarize(c);
    // view 0 shifted sideways far enough that the cube projects outside its 4 x 3 image.
    for (std::size_t f : {2u, 3u}) fx.j["frames"][f]["transform_matrix"] = pose_json(3.0, 20.0);
    c = fx.load();
    EXPECT_TRUE(has_warning(c, "2 of 2 views cannot see the mesh")) << summarize(c);
    EXPECT_TRUE(has_warning(c, "no train view sees it")) << summarize(c);
    CaptureFixture ok;
    EXPECT_FALSE(has_warning(ok.load(), "cannot see the mesh"));
}

TEST(CaptureWarnings, DarkLightsAndUnlitChannels) {
    CaptureFixture fx;
    fx.j["frames"][0]["light"]["intensity"] = {0.0, 0.0, 0.0};
    for (std::size_t f = 0; f < 4; ++f) fx.j["frames"][f]["light"]["intensity"][2] = 0.0;
    const Capture c = fx.load();
    EXPECT_TRUE(has_warning(c, "1 frame(s) have a light of intensity 0 in every channel (first: frames[0]")) << summarize(c);
    EXPECT_TRUE(has_warning(c, "no train frame lights the blue channel")) << summarize(c);
    EXPECT_FALSE(has_warning(c, "lights the red channel")) << summarize(c);
}

TEST(CaptureWarnings, MeshFarFromTheOriginForItsSize) {
    CaptureFixture fx;
    Mesh m = unit_cube_mesh();
    for (glm::vec3& p : m.positions) p.x += 1000.0f;
    write_mesh_glb(fx.dir / "mesh.glb", m);
    for (std::size_t f = 0; f < 4; ++f) {
        const double tz = fx.j["frames"][f]["transform_matrix"][2][3].get<double>();
        fx.j["frames"][f]["transform_matrix"] = pose_json(tz, 1000.0);
        fx.j["frames"][f]["light"]["position"][0] = fx.j["frames"][f]["light"]["position"][0].get<double>() + 1000.0;
    }
    const Capture c = fx.load();
    EXPECT_TRUE(has_warning(c, "times its size from the origin")) << summarize(c);
    CaptureFixture ok;
    EXPECT_FALSE(has_warning(ok.load(), "from the origin"));
}

TEST(CaptureWarnings, PixelsBeyondTheRangeAreMissing) {
    CaptureFixture fx;
    Image img = solid(kW, kH, 3, 0.5f);
    img.at(1, 1, 0) = 1e16f; // finite, but beyond what the solve may multiply by an irradiance
    img.at(2, 1, 2) = -3e20f;
    img.at(3, 2, 1) = 1e14f; // kept
    write_image(fx.dir / "images/f.exr", img, ColorSpace::Linear);
    fx.j["frames"][1]["file_path"] = "images/f.exr";
    const Capture c = fx.load();
    EXPECT_EQ(c.images[1].missing_pixels, 2u);
    EXPECT_EQ(c.images[1].flags[1 * kW + 1], kMissing);
    EXPECT_EQ(c.images[1].color.at(1, 1, 0), 0.0f);
    EXPECT_EQ(c.images[1].color.at(3, 2, 1), 1e14f);
    EXPECT_TRUE(has_warning(c, "2 pixel(s) with non-finite values (or beyond +-1e+15)")) << summarize(c);
}

// ---- robustness ------------------------------------------------------------------

TEST(CaptureRobustness, TruncatedJsonAlwaysRefused) {
    CaptureFixture fx;
    const std::string text = fx.j.dump(1);
    for (std::size_t len = 0; len < text.size(); len += 3) {
        write_text_file(fx.dir / "capture.json", text.substr(0, len));
        EXPECT_THROW((void)load_capture(fx.dir.path(), {.load_images = false}), InputError) << "length " << len;
    }
}

TEST(CaptureRobustness, DeepNestingRefused) {
    CaptureFixture fx;
    write_text_file(fx.dir / "capture.json", std::string(200000, '[') + std::string(200000, ']'));
    EXPECT_THROW((void)load_capture(fx.dir.path()), InputError);
}

TEST(CaptureRobustness, RandomByteFlipsNeverCrash) {
    CaptureFixture fx;
    const std::string text = fx.j.dump();
    std::uint32_t state = 2024;
    for (int trial = 0; trial < 300; ++trial) {
        std::string bad = text;
        for (int k = 0; k < 3; ++k) {
            state = state * 1664525u + 1013904223u;
            bad[state % bad.size()] = static_cast<char>(state >> 24);
        }
        write_text_file(fx.dir / "capture.json", bad);
        try {
            (void)load_capture(fx.dir.path());
        } catch (const InputError&) {
        } catch (const std::exception& e) {
            ADD_FAILURE() << "trial " << trial << ": not an InputError: " << e.what();
        }
    }
}

// Timing of a default-sized capture: 20 views x 6 lights of 512 x 512 PNGs.
// Run with --gtest_also_run_disabled_tests.
TEST(CaptureTiming, DISABLED_Load120Images512) {
    test::TempDir dir("capture-timing");
    write_mesh_glb(dir / "mesh.glb", unit_cube_mesh());
    Image img(512, 512, 3);
    for (int y = 0; y < 512; ++y)
        for (int x = 0; x < 512; ++x)
            for (int c = 0; c < 3; ++c) img.at(x, y, c) = static_cast<float>((x * 7 + y * 3 + c * 50) % 256) / 255.0f;
    json j = {{"format", "specula-capture"}, {"version", 1}, {"mesh_path", "mesh.glb"}, {"w", 512}, {"h", 512},
              {"fl_x", 886.8}, {"fl_y", 886.8}, {"cx", 256.0}, {"cy", 256.0}, {"frames", json::array()}};
    for (int v = 0; v < 20; ++v) {
        const std::string mask = "masks/v" + std::to_string(v) + ".png";
        write_image(dir / mask, Image(512, 512, 1, 1.0f), ColorSpace::Linear);
        for (int l = 0; l < 6; ++l) {
            const std::string name = "images/v" + std::to_string(v) + "_l" + std::to_string(l) + ".png";
            write_image(dir / name, img, ColorSpace::Srgb);
            json f = frame_json(name, v, 3.0 + v, {1.0 * l, 2.0, 3.0});
            f["mask_path"] = mask;
            j["frames"].push_back(f);
        }
    }
    write_text_file(dir / "capture.json", j.dump());
    for (int threads : {1, 2}) {
        const Stopwatch clock;
        const Capture c = load_capture(dir.path(), {.threads = threads});
        std::printf("load of 120 images 512x512 with %d thread(s): %.3f s\n", threads, clock.seconds());
        EXPECT_EQ(c.images.size(), 120u);
    }
}

} // namespace
} // namespace specula
