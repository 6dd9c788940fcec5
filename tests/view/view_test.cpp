// specula-view: the orbit math (exact start pose, reset, distances kept), and the
// executable run as a user would: under Xvfb (window, swapchain, screenshot of what is
// presented) against `specula render` of the same capture frame, offscreen against the
// in-memory render, and its errors. The capture is the small convex `sphere` preset
// (96 px, EXR), the bundle its truth (as tests/evaluate builds it). Validation is on in
// the viewer too (SPECULA_VALIDATION=1 from the test environment): any message makes
// it exit 1, which these tests check.
#include "orbit.h"
#include "presenter_probe.h"

#include "capture/capture.h"
#include "core/file_util.h"
#include "core/image.h"
#include "evaluate/bundle_render.h"
#include "export/bundle.h"
#include "synth/presets.h"
#include "synth/synth.h"
#include "test_dirs.h"
#include "vulkan_env.h"

#include <gtest/gtest.h>

#include <glm/gtc/constants.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <memory>
#include <string>
#include <sys/wait.h>

namespace specula::view {
namespace {

using test::TempDir;
using test::VulkanTest;

// ---------------------------------------------------------------------------------------------
// OrbitView

Camera start_camera() {
    const Intrinsics k{64, 48, 70.0, 70.0, 30.5, 25.0};
    return Camera(k, look_at_camera_to_world({0.3, 0.8, 4.0}, {0.1, 0.0, 0.0}, {0.0, 1.0, 0.0}));
}
const Bounds kBounds{{-1.0f, -1.0f, -1.0f}, {1.0f, 1.0f, 1.0f}};
const PointLight kLight{{2.0, 3.0, 4.0}, {10.0, 10.0, 10.0}};

TEST(OrbitView, StartsExactlyAtTheStartCamera) {
    const OrbitView v(start_camera(), kLight, kBounds, {0, 1, 0});
    const Camera c = v.camera(64, 48);
    EXPECT_EQ(c.camera_to_world, start_camera().camera_to_world);
    EXPECT_EQ(c.intrinsics.fl_x, 70.0);
    EXPECT_EQ(c.intrinsics.cx, 30.5);
    EXPECT_EQ(c.intrinsics.cy, 25.0);
    EXPECT_EQ(v.light().position, kLight.position);
}

TEST(OrbitView, OrbitKeepsTheTargetAndDistanceAndResetRestores) {
    OrbitView v(start_camera(), kLight, kBounds, {0, 1, 0});
    const double d = v.distance();
    const glm::dvec3 t = v.target();
    v.orbit(0.7, 0.3);
    const Camera c = v.camera(64, 48);
    EXPECT_NEAR(glm::length(c.center() - t), d, 1e-9);
    EXPECT_GT(glm::length(c.center() - start_camera().center()), 0.5);
    // the target stays on the optical axis (at the principal point)
    const auto p = c.project(t);
    ASSERT_TRUE(p.has_value());
    EXPECT_NEAR(p->x, 30.5, 1e-6);
    EXPECT_NEAR(p->y, 25.0, 1e-6);
    v.pan(5.0, -3.0);
    v.zoom(2.0);
    v.move_light(1.0, 0.5);
    v.reset();
    EXPECT_EQ(v.camera(64, 48).camera_to_world, start_camera().camera_to_world);
    EXPECT_EQ(v.light().position, kLight.position);
}

TEST(OrbitView, PitchStopsShortOfThePole) {
    OrbitView v(start_camera(), kLight, kBounds, {0, 1, 0});
    for (int i = 0; i < 100; ++i) v.orbit(0.0, 0.1); // far past 90 degrees
    const glm::dvec3 back = glm::normalize(glm::dvec3(v.camera(64, 48).camera_to_world[2]));
    EXPECT_LT(std::abs(back.y), 1.0);
    EXPECT_GT(std::abs(back.y), 0.95); // it did climb
}

TEST(OrbitView, LightTurnsAboutTheObjectCentre) {
    OrbitView v(start_camera(), kLight, kBounds, {0, 1, 0});
    v.move_light(glm::half_pi<double>(), 0.0);
    EXPECT_NEAR(glm::length(v.light().position), glm::length(kLight.position), 1e-9);
    EXPECT_NEAR(v.light().position.y, 3.0, 1e-9); // about +Y: height kept
    EXPECT_EQ(v.light().intensity, kLight.intensity);
}

TEST(OrbitView, OtherWindowSizesLetterboxTheStartImage) {
    const OrbitView v(start_camera(), kLight, kBounds, {0, 1, 0});
    // twice as wide: scale 2 from the height, the image centred horizontally
    const ImageRect r = v.image_rect(256, 96);
    EXPECT_DOUBLE_EQ(r.width, 128.0);
    EXPECT_DOUBLE_EQ(r.height, 96.0);
    EXPECT_DOUBLE_EQ(r.x, 64.0);
    EXPECT_DOUBLE_EQ(r.y, 0.0);
    const Camera c = v.camera(256, 96);
    // a world point lands where the start image's pixel lands in the rectangle
    const glm::dvec3 p(0.2, 0.3, -0.1);
    const auto a = start_camera().project(p);
    const auto b = c.project(p);
    ASSERT_TRUE(a && b);
    EXPECT_NEAR(b->x, r.x + 2.0 * a->x, 1e-9);
    EXPECT_NEAR(b->y, r.y + 2.0 * a->y, 1e-9);
}

// ---------------------------------------------------------------------------------------------
// The executable

struct Fixture {
    TempDir dir{"view"};
    std::size_t frame = 0;
};

Bundle bundle_from_truth(const synth::Preset& p) {
    Bundle b;
    b.mesh = p.mesh;
    b.albedo = p.material.albedo_texture;
    if (b.albedo.empty()) b.albedo = Image(1, 1, 3);
    if (p.material.albedo_texture.empty())
        for (int c = 0; c < 3; ++c) b.albedo.at(0, 0, c) = p.material.albedo_value[c];
    b.material.specular = p.material.lobe;
    return b;
}

const Fixture& fixture() {
    static std::unique_ptr<Fixture> f = [] {
        auto f = std::make_unique<Fixture>();
        const synth::Preset preset = synth::make_preset("sphere");
        synth::SynthOptions o;
        o.size = 96;
        o.views = 2;
        o.lights = 2;
        o.test_views = 1;
        o.test_lights = 1;
        o.format = synth::ImageFormat::Exr;
        o.seed = 5;
        (void)synth::write_synthetic_capture(synth::to_object(preset), f->dir / "cap", o);
        write_bundle(f->dir / "truth.glb", bundle_from_truth(preset));
        f->frame = 1;
        return f;
    }();
    return *f;
}

struct RunResult {
    int code = -1;
    std::string err;
};

/// Runs a command line with stderr captured; the exit status (-1 when it did not exit).
RunResult run(const std::string& cmd, const std::filesystem::path& err_file) {
    const std::string full = cmd + " 2> " + err_file.string();
    const int rc = std::system(full.c_str());
    RunResult r;
    r.code = WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
    r.err = std::filesystem::exists(err_file) ? read_text_file(err_file) : "";
    return r;
}

std::string viewer() { return std::string(SPECULA_VIEW_BINARY) + " -q "; }

std::string frame_args(const Fixture& f) {
    return (f.dir / "truth.glb").string() + " --capture " + (f.dir / "cap").string() + " --frame " + std::to_string(f.frame);
}

struct Diff {
    double max = 0.0;
    double mean = 0.0;
    std::size_t lit = 0; // pixels with any channel above 0.05 in `a`
};

Diff compare(const Image& a, const Image& b) {
    Diff d;
    double sum = 0.0;
    for (int y = 0; y < a.height; ++y)
        for (int x = 0; x < a.width; ++x) {
            bool lit = false;
            for (int c = 0; c < 3; ++c) {
                const double e = std::abs(static_cast<double>(a.at(x, y, c)) - b.at(x, y, c));
                d.max = std::max(d.max, e);
                sum += e;
                lit = lit || a.at(x, y, c) > 0.05f;
            }
            d.lit += lit ? 1 : 0;
        }
    d.mean = sum / (3.0 * a.width * a.height);
    return d;
}

class ViewTest : public VulkanTest {};

#ifdef SPECULA_XVFB_RUN
/// Under Xvfb: a window, a swapchain, three presented frames; the screenshot (read back
/// from the presented swapchain image) against `specula render -o x.png` of the same
/// capture frame. Both are the same float image (same passes, bit-exact start camera)
/// encoded to sRGB 8-bit, the viewer's by lavapipe's blit into the B8G8R8A8_SRGB
/// swapchain image and `specula render`'s by OpenImageIO, so the only allowed
/// difference is one 8-bit step of the encoding's rounding: max |a - b| <= 1/255.
TEST_F(ViewTest, XvfbScreenshotMatchesSpeculaRender) {
    const Fixture& f = fixture();
    TempDir out("view_xvfb");
    const std::string xvfb = std::string(SPECULA_XVFB_RUN) + " -a -s \"-screen 0 320x240x24\" ";
    const RunResult v = run(xvfb + viewer() + frame_args(f) + " --frames 3 --screenshot " + (out / "view.png").string(), out / "v.txt");
    ASSERT_EQ(v.code, 0) << v.err;
    EXPECT_EQ(v.err.find("validation"), std::string::npos) << v.err;
    // The viewer draws no shadows by default (viewer.h); render the same.
    const RunResult r = run(std::string(SPECULA_BINARY) + " -q render --no-shadows " + frame_args(f) + " -o " + (out / "render.png").string(),
                      out / "r.txt");
    ASSERT_EQ(r.code, 0) << r.err;

    // ColorSpace::Linear on an 8-bit file: the stored codes / 255, no decoding.
    const Image a = read_image(out / "view.png", ColorSpace::Linear);
    const Image b = read_image(out / "render.png", ColorSpace::Linear);
    ASSERT_EQ(a.width, 96);
    ASSERT_EQ(a.height, 96);
    ASSERT_EQ(b.width, a.width);
    ASSERT_EQ(b.height, a.height);
    const Diff d = compare(a, b);
    EXPECT_GT(d.lit, 96u * 96u / 10) << "the frame should show the lit sphere";
    EXPECT_LE(d.max, 1.0 / 255.0 + 1e-6);
    EXPECT_LT(d.mean, 0.1 / 255.0);
    std::printf("[ viewer vs specula render ] max %.0f/255, mean %.4f/255, %zu lit pixels\n", d.max * 255.0, d.mean * 255.0,
                d.lit);
}

/// The photograph path (C, or --photo): the captured image blitted into the window at
/// 1:1 is the photograph; compared with it encoded to sRGB 8-bit by OpenImageIO (one
/// step of rounding allowed, as above).
TEST_F(ViewTest, XvfbPhotographIsTheCapturedImage) {
    const Fixture& f = fixture();
    TempDir out("view_photo");
    const std::string xvfb = std::string(SPECULA_XVFB_RUN) + " -a -s \"-screen 0 320x240x24\" ";
    const RunResult v = run(xvfb + viewer() + frame_args(f) + " --photo --frames 2 --screenshot " + (out / "photo.png").string(),
                            out / "v.txt");
    ASSERT_EQ(v.code, 0) << v.err;
    const Capture cap = load_capture(f.dir / "cap", {.load_mesh = false, .load_images = false});
    const FrameDesc& fd = cap.desc.frames[f.frame];
    write_image(out / "expected.png", read_image(cap.desc.resolve(fd.file_path), cap.desc.color_space), ColorSpace::Srgb, 8);
    const Diff d = compare(read_image(out / "expected.png", ColorSpace::Linear), read_image(out / "photo.png", ColorSpace::Linear));
    EXPECT_GT(d.lit, 96u * 96u / 10);
    EXPECT_LE(d.max, 1.0 / 255.0 + 1e-6);
}

/// gpu::Presenter on its own (tests/view/presenter_probe.cpp, validation on): a frame that
/// clears the target reads back the clear colour exactly from the target and, from the
/// presented swapchain image, encoded to sRGB 8-bit (one step of rounding allowed, as
/// above); a texture of known sRGB codes blitted 1:1 shows those codes at its rectangle,
/// every other pixel black; scaled 2x (letterboxed) it covers exactly its rectangle.
TEST_F(ViewTest, XvfbPresenterShowsAndReadsBackWhatItWasGiven) {
    namespace pr = probe;
    TempDir out("view_presenter");
    const std::string xvfb = std::string(SPECULA_XVFB_RUN) + " -a -s \"-screen 0 320x240x24\" ";
    const RunResult v = run(xvfb + SPECULA_PRESENTER_PROBE + " " + out.path().string(), out / "p.txt");
    ASSERT_EQ(v.code, 0) << v.err;
    const auto encoded = [](float v) { return linear_to_srgb(std::clamp(v, 0.0f, 1.0f)); };
    const double step = 1.0 / 255.0 + 1e-6;

    const Image target = read_image(out / "target.exr", ColorSpace::Linear);
    const Image shown = read_image(out / "target_shown.exr", ColorSpace::Linear);
    for (const Image* img : {&target, &shown}) {
        ASSERT_EQ(img->width, pr::kWindowW);
        ASSERT_EQ(img->height, pr::kWindowH);
    }
    double target_err = 0.0, shown_err = 0.0;
    for (int y = 0; y < pr::kWindowH; ++y)
        for (int x = 0; x < pr::kWindowW; ++x)
            for (int c = 0; c < 3; ++c) {
                target_err = std::max(target_err, static_cast<double>(std::abs(target.at(x, y, c) - pr::kClear[c])));
                shown_err = std::max(shown_err, static_cast<double>(std::abs(encoded(shown.at(x, y, c)) - encoded(pr::kClear[c]))));
            }
    EXPECT_EQ(target_err, 0.0);
    EXPECT_LE(shown_err, step);

    // A frame that says which rectangle it drew: that rectangle as the whole frame shows it, the
    // rest 0 (the presenter blits only the rectangle), clipped to the window.
    const pr::Rect corner{pr::kWindowW - 5, pr::kWindowH - 4, pr::kWindowW, pr::kWindowH};
    for (const auto& [file, rect] : {std::pair{"partial_shown.exr", pr::kRect}, std::pair{"corner_shown.exr", corner}}) {
        const Image partial = read_image(out / file, ColorSpace::Linear);
        ASSERT_EQ(partial.width, pr::kWindowW);
        ASSERT_EQ(partial.height, pr::kWindowH);
        std::size_t wrong = 0;
        for (int y = 0; y < pr::kWindowH; ++y)
            for (int x = 0; x < pr::kWindowW; ++x)
                for (int c = 0; c < 3; ++c)
                    wrong += rect.contains(x, y) ? (partial.at(x, y, c) == shown.at(x, y, c) ? 0 : 1)
                                                 : (partial.at(x, y, c) == 0.0f ? 0 : 1);
        EXPECT_EQ(wrong, 0u) << file;
    }

    const Image image = read_image(out / "image_shown.exr", ColorSpace::Linear);
    ASSERT_EQ(image.width, pr::kWindowW);
    ASSERT_EQ(image.height, pr::kWindowH);
    double inside_err = 0.0, outside_max = 0.0;
    for (int y = 0; y < pr::kWindowH; ++y)
        for (int x = 0; x < pr::kWindowW; ++x)
            for (int c = 0; c < 3; ++c) {
                if (pr::kRect.contains(x, y)) {
                    const double want = pr::code(x - pr::kRect.x0, y - pr::kRect.y0, c) / 255.0;
                    inside_err = std::max(inside_err, std::abs(encoded(image.at(x, y, c)) - want));
                } else {
                    outside_max = std::max(outside_max, static_cast<double>(image.at(x, y, c)));
                }
            }
    EXPECT_LE(inside_err, step);
    EXPECT_EQ(outside_max, 0.0);

    const Image scaled = read_image(out / "scaled_shown.exr", ColorSpace::Linear);
    ASSERT_EQ(scaled.width, pr::kWindowW);
    ASSERT_EQ(scaled.height, pr::kWindowH);
    std::size_t wrong = 0;
    for (int y = 0; y < pr::kWindowH; ++y)
        for (int x = 0; x < pr::kWindowW; ++x) {
            // every code is at least 10/255, so every pixel of the image is lit; the rest is black
            const float least = std::min({scaled.at(x, y, 0), scaled.at(x, y, 1), scaled.at(x, y, 2)});
            const float most = std::max({scaled.at(x, y, 0), scaled.at(x, y, 1), scaled.at(x, y, 2)});
            wrong += pr::kScaledRect.contains(x, y) ? (least > 0.0f ? 0 : 1) : (most == 0.0f ? 0 : 1);
        }
    EXPECT_EQ(wrong, 0u);
}

/// A resize after the first frame (the swapchain and target recreated, validation on):
/// the last frame is the new size, and shows the start view scaled and letterboxed
/// (OrbitView::camera), as the renderer draws that camera.
TEST_F(ViewTest, XvfbResizeRecreatesTheSwapchain) {
    const Fixture& f = fixture();
    TempDir out("view_resize");
    const std::string xvfb = std::string(SPECULA_XVFB_RUN) + " -a -s \"-screen 0 320x240x24\" ";
    const RunResult v = run(xvfb + viewer() + frame_args(f) + " --frames 3 --resize-to 150x110 --screenshot " +
                                (out / "resized.png").string(),
                            out / "v.txt");
    ASSERT_EQ(v.code, 0) << v.err;
    const Image shot = read_image(out / "resized.png", ColorSpace::Linear);
    ASSERT_EQ(shot.width, 150);
    ASSERT_EQ(shot.height, 110);
    const Bundle bundle = read_bundle(f.dir / "truth.glb");
    const Capture cap = load_capture(f.dir / "cap", {.load_mesh = false, .load_images = false});
    const FrameDesc& fd = cap.desc.frames[f.frame];
    const OrbitView view(fd.camera(), fd.light, mesh_bounds(bundle.mesh), {0, 1, 0});
    evaluate::BundleRenderer r(ctx(), bundle, "truth.glb");
    evaluate::write_rendered_image(out / "expected.png", r.render(view.camera(150, 110), fd.light, {}).color);
    const Diff d = compare(read_image(out / "expected.png", ColorSpace::Linear), shot);
    EXPECT_GT(d.lit, 500u);
    EXPECT_LE(d.max, 1.0 / 255.0 + 1e-6);
}

/// Frame pacing: an interactive window with no input draws its first frame and then
/// waits (no frame per wake-up); SIGTERM ends it cleanly (exit 0, validation checked
/// on the way out). The script waits for the first frame, idles 2 s, then stops it.
TEST_F(ViewTest, XvfbIdleWindowDrawsOnceAndStopsCleanly) {
    const Fixture& f = fixture();
    TempDir out("view_idle");
    const std::string err = (out / "err.txt").string();
    write_text_file(out / "idle.sh", std::string(SPECULA_VIEW_BINARY) + " " + (f.dir / "truth.glb").string() + " > /dev/null 2> " +
                                         err + " &\np=$!\nfor i in $(seq 300); do grep -q 'first frame drawn' " + err +
                                         " && break; sleep 0.1; done\nsleep 2\nkill -TERM $p\nwait $p\n");
    const RunResult v =
        run(std::string(SPECULA_XVFB_RUN) + " -a -s \"-screen 0 640x480x24\" sh " + (out / "idle.sh").string(), out / "xvfb.txt");
    const std::string log = read_text_file(out / "err.txt");
    ASSERT_EQ(v.code, 0) << log << v.err;
    EXPECT_EQ(log.find("validation"), std::string::npos) << log;
    const auto at = log.find(" frame(s) drawn in ");
    ASSERT_NE(at, std::string::npos) << log;
    const int drawn = std::stoi(log.substr(log.rfind(' ', at - 1) + 1));
    EXPECT_GE(drawn, 1);
    EXPECT_LE(drawn, 3) << "an idle window should not keep drawing (an expose may add one): " << log;
}

#ifdef SPECULA_XDOTOOL
/// Input under Xvfb, driven by xdotool (validation on): orbit, pan, wheel and light drags,
/// the mode keys (the title follows), shadows on (S), the photograph (C), a resize by the window system
/// (the swapchain is recreated; the title shows the new size), and Q ends it with exit 0.
TEST_F(ViewTest, XvfbKeysAndMouseDriveTheView) {
    const Fixture& f = fixture();
    TempDir out("view_input");
    const std::string err = (out / "err.txt").string(), titles = (out / "titles.txt").string();
    const std::string x = SPECULA_XDOTOOL;
    std::string sh = std::string(SPECULA_VIEW_BINARY) + " " + frame_args(f) + " > /dev/null 2> " + err + " &\np=$!\n" +
                     "for i in $(seq 300); do grep -q 'first frame drawn' " + err + " && break; sleep 0.1; done\n" +
                     "w=$(" + x + " search --name specula-view | head -1)\n" +
                     "t() { sleep 0.5; echo \"$1: $(" + x + " getwindowname $w)\" >> " + titles + "; }\n" +
                     x + " mousemove --window $w 40 40 mousedown 1 mousemove --window $w 70 50 mouseup 1\n" +
                     x + " mousemove --window $w 50 50 mousedown 3 mousemove --window $w 60 55 mouseup 3\n" +
                     x + " click --window $w 4\n" +
                     x + " keydown --window $w shift mousedown 1 mousemove --window $w 80 70 mouseup 1 keyup shift\n";
    for (const char* k : {"1", "2", "3", "p", "Left", "r", "c"}) sh += x + " key --window $w " + k + "; t " + k + "\n";
    sh += x + " windowsize $w 150 110; t resize\n" + x + " key --window $w c; t c2\n" + x + " key --window $w s; t s\n" + x +
          " key --window $w q\nwait $p\n";
    write_text_file(out / "input.sh", sh);
    const RunResult v =
        run(std::string(SPECULA_XVFB_RUN) + " -a -s \"-screen 0 640x480x24\" sh " + (out / "input.sh").string(), out / "xvfb.txt");
    const std::string log = read_text_file(out / "err.txt");
    ASSERT_EQ(v.code, 0) << log << v.err;
    EXPECT_EQ(log.find("validation"), std::string::npos) << log;
    const std::string t = read_text_file(out / "titles.txt");
    for (const char* want : {"1: specula-view | truth.glb | diffuse/analytic, deferred |", "2: specula-view | truth.glb | specular/analytic, deferred |",
                             "3: specula-view | truth.glb | both/analytic, deferred |", "p: specula-view | truth.glb | both/analytic, 1 pass |",
                             "c: specula-view | truth.glb | captured photograph of frame", "resize: ", "| 150x110",
                             "c2: specula-view | truth.glb | both/analytic, 1 pass |",
                             "s: specula-view | truth.glb | both/analytic, 1 pass, shadows |"})
        EXPECT_NE(t.find(want), std::string::npos) << want << "\n" << t;
}
#endif
#endif

/// With no display, --frames renders offscreen (saying so) and the .exr is exactly the
/// in-memory render of the frame, without shadows as the viewer starts (viewer.h). (Until the
/// shadow map's normal offset became a quarter texel, shadows changed no pixel of this convex
/// sphere; now one pixel at its terminator, 0.002, where the coarse facets seen from the light
/// shadow a point the interpolated normal says is lit.)
TEST_F(ViewTest, OffscreenWithoutDisplayMatchesRendererExactly) {
    const Fixture& f = fixture();
    TempDir out("view_offscreen");
    const RunResult v = run("env -u DISPLAY -u WAYLAND_DISPLAY " + std::string(SPECULA_VIEW_BINARY) + " " + frame_args(f) +
                          " --frames 2 --screenshot " + (out / "view.exr").string() + " > " + (out / "o.txt").string(),
                      out / "v.txt");
    ASSERT_EQ(v.code, 0) << v.err;
    EXPECT_NE(v.err.find("rendering offscreen"), std::string::npos) << v.err;
    const Image file = read_image(out / "view.exr", ColorSpace::Linear);
    const Bundle bundle = read_bundle(f.dir / "truth.glb");
    const Capture cap = load_capture(f.dir / "cap", {.load_mesh = false, .load_images = false});
    const FrameDesc& fd = cap.desc.frames[f.frame];
    evaluate::BundleRenderer r(ctx(), bundle, "truth.glb");
    const Image mem = r.render(fd.camera(), fd.light, {.shadows = false}).color;
    ASSERT_EQ(file.width, mem.width);
    ASSERT_EQ(file.height, mem.height);
    const Diff d = compare(mem, file);
    EXPECT_GT(d.lit, 0u);
    EXPECT_EQ(d.max, 0.0);
}

TEST_F(ViewTest, InteractiveWithoutDisplayIsAClearError) {
    const Fixture& f = fixture();
    TempDir out("view_nodisplay");
    const RunResult v = run("env -u DISPLAY -u WAYLAND_DISPLAY " + viewer() + (f.dir / "truth.glb").string(), out / "v.txt");
    EXPECT_EQ(v.code, 1) << v.err;
    EXPECT_NE(v.err.find("needs a display"), std::string::npos) << v.err;
    EXPECT_NE(v.err.find("xvfb-run"), std::string::npos) << v.err;
}

TEST_F(ViewTest, BadInputsNameWhatIsWrong) {
    const Fixture& f = fixture();
    TempDir out("view_errors");
    const RunResult missing = run(viewer() + (out / "nope.glb").string() + " --offscreen --frames 1", out / "a.txt");
    EXPECT_EQ(missing.code, 1);
    EXPECT_NE(missing.err.find("nope.glb"), std::string::npos) << missing.err;

    const RunResult frame = run(viewer() + (f.dir / "truth.glb").string() + " --capture " + (f.dir / "cap").string() +
                              " --frame 99 --offscreen --frames 1",
                          out / "b.txt");
    EXPECT_EQ(frame.code, 2);
    EXPECT_NE(frame.err.find("--frame: 99 is out of range"), std::string::npos) << frame.err;

    const RunResult shot = run(viewer() + (f.dir / "truth.glb").string() + " --screenshot x.png", out / "c.txt");
    EXPECT_EQ(shot.code, 2);
    EXPECT_NE(shot.err.find("--screenshot needs --frames"), std::string::npos) << shot.err;

    const RunResult fac = run(viewer() + (f.dir / "truth.glb").string() + " --specular factorized --offscreen --frames 1", out / "d.txt");
    EXPECT_EQ(fac.code, 1);
    EXPECT_NE(fac.err.find("truth.glb: the bundle has no factorization cube-maps"), std::string::npos) << fac.err;

    const RunResult help = run(viewer() + "--help > " + (out / "help.txt").string(), out / "e.txt");
    EXPECT_EQ(help.code, 0);
    const std::string text = read_text_file(out / "help.txt");
    for (const char* opt : {"--capture", "--frame", "--frames", "--screenshot", "--bench", "--continuous", "--offscreen"})
        EXPECT_NE(text.find(opt), std::string::npos) << opt;
}

} // namespace
} // namespace specula::view
