// The pose options of `specula render` and `specula-view` (engine/evaluate/pose.h): the
// strict image-size parser, a capture frame's pose taken exactly (and its index checked),
// free poses (given, and the default that frames an object), the refusals and their
// wording, and the frame's photograph. No GPU: the capture is a small synthetic one
// (the `sphere` preset at 24 px, rendered on the CPU).
#include "evaluate/pose.h"

#include "capture/capture.h"
#include "core/error.h"
#include "core/image.h"
#include "expect_error.h"
#include "synth/presets.h"
#include "synth/synth.h"
#include "test_dirs.h"

#include <gtest/gtest.h>

#include <glm/gtc/constants.hpp>

#include <cmath>
#include <memory>
#include <string>

namespace specula::evaluate {
namespace {

using test::TempDir;

/// The UsageError message f throws (a failure when it throws nothing or something else).
template <class F>
std::string usage_error(F&& f) {
    try {
        f();
    } catch (const UsageError& e) {
        return e.what();
    } catch (const std::exception& e) {
        ADD_FAILURE() << "expected a UsageError, got: " << e.what();
        return {};
    }
    ADD_FAILURE() << "expected a UsageError, nothing was thrown";
    return {};
}

// ---------------------------------------------------------------------------------------------
// parse_image_size

TEST(ParseImageSize, TakesNAndWxH) {
    EXPECT_EQ(parse_image_size("640x480", "--size"), std::make_pair(640, 480));
    EXPECT_EQ(parse_image_size("512", "--size"), std::make_pair(512, 512));
    EXPECT_EQ(parse_image_size("1x16384", "--size"), std::make_pair(1, 16384));
    EXPECT_EQ(parse_image_size("007x3", "--size"), std::make_pair(7, 3));
}

TEST(ParseImageSize, RefusesAnythingElseNamingTheOption) {
    for (const char* bad : {"12abc", "0x5", "5x0", "0", "x5", "5x", "", "x", "+5", " 5", "5 ", "-3", "5x-3", "5x5x5", "5X5",
                            "16385", "99999x2", "1e3", "5.0", "123456"}) {
        const std::string e = usage_error([&] { (void)parse_image_size(bad, "--resize-to"); });
        EXPECT_NE(e.find("--resize-to: '" + std::string(bad) + "' is not N or WxH"), std::string::npos) << bad << ": " << e;
    }
}

// ---------------------------------------------------------------------------------------------
// Free poses

TEST(ResolvePose, FreeCameraAndLightAsGiven) {
    const Pose p = resolve_pose({.camera = "0,0,3,0,0,0,0,2,0", .light = "1,2,3,10", .size = "64x48", .fov = 30.0});
    EXPECT_EQ(p.what, "a free pose");
    EXPECT_FALSE(p.frame.has_value());
    EXPECT_EQ(p.camera.intrinsics.w, 64);
    EXPECT_EQ(p.camera.intrinsics.h, 48);
    EXPECT_NEAR(p.camera.intrinsics.fl_y, 24.0 / std::tan(glm::radians(15.0)), 1e-9);
    EXPECT_DOUBLE_EQ(p.camera.intrinsics.cx, 32.0);
    EXPECT_DOUBLE_EQ(p.camera.intrinsics.cy, 24.0);
    EXPECT_NEAR(glm::length(p.camera.center() - glm::dvec3(0, 0, 3)), 0.0, 1e-12);
    const auto target = p.camera.project({0.0, 0.0, 0.0});
    ASSERT_TRUE(target.has_value());
    EXPECT_NEAR(target->x, 32.0, 1e-9);
    EXPECT_NEAR(target->y, 24.0, 1e-9);
    EXPECT_EQ(p.up, glm::dvec3(0, 1, 0)); // --camera's up, normalized
    EXPECT_EQ(p.light.position, glm::dvec3(1, 2, 3));
    EXPECT_EQ(p.light.intensity, glm::dvec3(10, 10, 10));

    const Pose q = resolve_pose({.camera = "0,0,3,0,0,0,0,1,0", .light = "1,2,3,0.1,0.2,0.3", .size = "20", .fl = 50.0});
    EXPECT_EQ(q.camera.intrinsics.w, 20);
    EXPECT_EQ(q.camera.intrinsics.h, 20);
    EXPECT_DOUBLE_EQ(q.camera.intrinsics.fl_x, 50.0);
    EXPECT_EQ(q.light.intensity, glm::dvec3(0.1, 0.2, 0.3));
    // --fov defaults to 40 degrees
    const Pose d = resolve_pose({.camera = "0,0,3,0,0,0,0,1,0", .light = "1,2,3,1", .size = "100"});
    EXPECT_NEAR(d.camera.intrinsics.fl_y, 50.0 / std::tan(glm::radians(20.0)), 1e-9);
}

TEST(ResolvePose, DefaultFreePoseFramesTheObject) {
    const Bounds box{{-1.0f, 0.0f, 2.0f}, {1.0f, 2.0f, 4.0f}}; // centre (0, 1, 3), radius sqrt(3)
    const glm::dvec3 center(0.0, 1.0, 3.0);
    const Pose p = resolve_pose({.size = "80x60"}, box);
    EXPECT_EQ(p.camera.intrinsics.w, 80);
    EXPECT_EQ(p.camera.intrinsics.h, 60);
    EXPECT_EQ(p.up, glm::dvec3(0, 1, 0));
    // the centre on the optical axis, the bounding sphere inside the vertical field of view
    const auto c = p.camera.project(center);
    ASSERT_TRUE(c.has_value());
    EXPECT_NEAR(c->x, 40.0, 1e-9);
    EXPECT_NEAR(c->y, 30.0, 1e-9);
    const double distance = glm::length(p.camera.center() - center);
    EXPECT_NEAR(distance, 1.15 * std::sqrt(3.0) / std::sin(glm::radians(20.0)), 1e-5);
    EXPECT_GT(p.camera.center().y, center.y); // from a little above
    EXPECT_GT(p.camera.center().z, center.z); // from the front (+Z)
    // the light: above right of the camera, I = 0.8 pi d^2 at its distance d from the centre
    const glm::dvec3 to_light = p.light.position - p.camera.center();
    EXPECT_GT(glm::dot(to_light, glm::dvec3(p.camera.camera_to_world[0])), 0.0);
    EXPECT_GT(glm::dot(to_light, glm::dvec3(p.camera.camera_to_world[1])), 0.0);
    const double d = glm::length(p.light.position - center);
    EXPECT_NEAR(p.light.intensity.x, 0.8 * glm::pi<double>() * d * d, 1e-9 * d * d);

    // a given --camera with the default light; a given --light with the default camera
    const Pose q = resolve_pose({.camera = "0,5,0,0,0,0,0,0,-1", .size = "32"}, box);
    EXPECT_NEAR(glm::length(q.camera.center() - glm::dvec3(0, 5, 0)), 0.0, 1e-12);
    EXPECT_EQ(q.up, glm::dvec3(0, 0, -1));
    EXPECT_GT(q.light.intensity.x, 0.0);
    const Pose r = resolve_pose({.light = "7,8,9,3", .size = "32"}, box);
    EXPECT_EQ(r.light.position, glm::dvec3(7, 8, 9));
    EXPECT_NEAR(glm::length(r.camera.center() - center), 1.15 * std::sqrt(3.0) / std::sin(glm::radians(20.0)), 1e-5);
}

TEST(ResolvePose, FreePoseRefusalsNameTheOption) {
    const std::string cam = "0,0,3,0,0,0,0,1,0", light = "1,2,3,10";
    EXPECT_NE(usage_error([&] { (void)resolve_pose({}); }).find("give --capture DIR --frame INDEX, or --camera"),
              std::string::npos);
    EXPECT_NE(usage_error([&] { (void)resolve_pose({.camera = cam}); }).find("a free pose needs both --camera and --light"),
              std::string::npos);
    EXPECT_NE(usage_error([&] { (void)resolve_pose({.camera = cam, .light = light, .size = "12abc"}); })
                  .find("--size: '12abc' is not N or WxH"),
              std::string::npos);
    EXPECT_NE(usage_error([&] { (void)resolve_pose({.camera = cam, .light = light, .size = "0x5"}); }).find("--size: '0x5'"),
              std::string::npos);
    EXPECT_NE(usage_error([&] { (void)resolve_pose({.camera = "0,0,3", .light = light}); }).find("--camera: expected"),
              std::string::npos);
    EXPECT_NE(usage_error([&] { (void)resolve_pose({.camera = cam, .light = "1,2,x,4"}); }).find("--light: 'x' is not a number"),
              std::string::npos);
    EXPECT_NE(usage_error([&] { (void)resolve_pose({.camera = cam, .light = light, .fov = 180.0}); }).find("--fov: must be in (0, 180)"),
              std::string::npos);
    // with an object to frame, a bad --fov or --size is refused just the same
    const Bounds box{{-1.0f, -1.0f, -1.0f}, {1.0f, 1.0f, 1.0f}};
    EXPECT_NE(usage_error([&] { (void)resolve_pose({.fov = 0.0}, box); }).find("--fov: must be in (0, 180)"), std::string::npos);
    EXPECT_NE(usage_error([&] { (void)resolve_pose({.fl = -2.0}, box); }).find("--fl: must be a positive"), std::string::npos);
    EXPECT_NE(usage_error([&] { (void)resolve_pose({.size = "64x"}, box); }).find("--size: '64x'"), std::string::npos);
}

// ---------------------------------------------------------------------------------------------
// Capture frames

struct Fixture {
    TempDir dir{"pose"};
};

const Fixture& fixture() {
    static std::unique_ptr<Fixture> f = [] {
        auto f = std::make_unique<Fixture>();
        synth::SynthOptions o;
        o.size = 24;
        o.views = 2;
        o.lights = 2;
        o.test_views = 1;
        o.test_lights = 1;
        o.format = synth::ImageFormat::Exr;
        (void)synth::write_synthetic_capture(synth::to_object(synth::make_preset("sphere")), f->dir / "cap", o);
        return f;
    }();
    return *f;
}

TEST(ResolvePose, CaptureFrameIsTakenExactly) {
    const Fixture& f = fixture();
    const Capture cap = load_capture(f.dir / "cap", {.load_mesh = false, .load_images = false});
    ASSERT_GE(cap.desc.frames.size(), 2u);
    const FrameDesc& fd = cap.desc.frames[1];
    // --size and --fov do not apply to a capture frame (not even checked)
    const Pose p = resolve_pose({.capture = (f.dir / "cap").string(), .frame = 1, .size = "12abc"}, Bounds{});
    EXPECT_EQ(p.camera.camera_to_world, fd.camera().camera_to_world);
    EXPECT_EQ(p.camera.intrinsics.w, fd.intrinsics.w);
    EXPECT_EQ(p.camera.intrinsics.fl_x, fd.intrinsics.fl_x);
    EXPECT_EQ(p.light.position, fd.light.position);
    EXPECT_EQ(p.light.intensity, fd.light.intensity);
    EXPECT_EQ(p.what, "frame 1 (" + fd.file_path.generic_string() + ")");
    ASSERT_TRUE(p.frame.has_value());
    EXPECT_EQ(p.frame->index, 1u);
    EXPECT_EQ(p.frame->image, cap.desc.resolve(fd.file_path));
    // up: the world axis nearest the camera's up
    const glm::dvec3 u(fd.camera().camera_to_world[1]);
    EXPECT_DOUBLE_EQ(glm::length(p.up), 1.0);
    EXPECT_GT(glm::dot(p.up, glm::normalize(u)), 0.5);

    const Image photo = read_frame_photo(*p.frame);
    EXPECT_EQ(photo.width, fd.intrinsics.w);
    EXPECT_EQ(photo.height, fd.intrinsics.h);
    const Image direct = read_image(cap.desc.resolve(fd.file_path), cap.desc.color_space);
    EXPECT_EQ(photo.pixels, direct.pixels);
}

TEST(ResolvePose, CaptureRefusalsNameTheOption) {
    const Fixture& f = fixture();
    const std::string cap = (f.dir / "cap").string();
    const std::size_t n = load_capture(cap, {.load_mesh = false, .load_images = false}).desc.frames.size();
    const std::string range = usage_error([&] { (void)resolve_pose({.capture = cap, .frame = 99}); });
    EXPECT_NE(range.find("--frame: 99 is out of range: "), std::string::npos) << range;
    EXPECT_NE(range.find("capture.json has " + std::to_string(n) + " frames (0 to " + std::to_string(n - 1) + ")"),
              std::string::npos)
        << range;
    EXPECT_NE(usage_error([&] { (void)resolve_pose({.capture = cap, .frame = -1}); }).find("--frame: -1 is out of range"),
              std::string::npos);
    EXPECT_NE(usage_error([&] { (void)resolve_pose({.capture = cap, .frame = static_cast<long long>(n)}); })
                  .find("--frame: " + std::to_string(n) + " is out of range"),
              std::string::npos);
    EXPECT_NE(usage_error([&] { (void)resolve_pose({.capture = cap}); }).find("--capture needs --frame INDEX"), std::string::npos);
    EXPECT_NE(usage_error([&] { (void)resolve_pose({.frame = 0}); }).find("--frame needs --capture DIR"), std::string::npos);
    EXPECT_NE(usage_error([&] { (void)resolve_pose({.capture = cap, .frame = 0, .light = "1,2,3,4"}); })
                  .find("give either --capture and --frame, or --camera and --light, not both"),
              std::string::npos);
}

TEST(ResolvePose, PhotographOfTheWrongSizeIsAnInputError) {
    const Fixture& f = fixture();
    TempDir out("pose_photo");
    const Pose p = resolve_pose({.capture = (f.dir / "cap").string(), .frame = 0});
    ASSERT_TRUE(p.frame.has_value());
    PoseFrame wrong = *p.frame;
    wrong.image = out / "small.exr";
    write_image(wrong.image, Image(5, 4, 3), ColorSpace::Linear);
    const InputError e = test::expect_input_error([&] { (void)read_frame_photo(wrong); });
    EXPECT_EQ(e.file(), wrong.image);
    EXPECT_EQ(e.field(), "frames[0].file_path");
    EXPECT_NE(std::string(e.what()).find("the image is 5x4 but the frame's intrinsics say 24x24"), std::string::npos) << e.what();
}

} // namespace
} // namespace specula::evaluate
