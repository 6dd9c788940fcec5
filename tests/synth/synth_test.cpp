// Closed-form checks of the synthetic-capture renderer and writer:
// radiometry against an analytic sphere, the capture format's projection,
// shadows, a Lafortune highlight, determinism, noise statistics, a whole
// capture read back with load_capture, and the atomic write.
#include "capture/capture.h"
#include "core/error.h"
#include "core/image.h"
#include "shared/prelude.h"
#include "synth/noise.h"
#include "synth/presets.h"
#include "synth/render.h"
#include "synth/rig.h"
#include "synth/shapes.h"
#include "synth/synth.h"
#include "test_dirs.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iterator>

namespace specula::synth {
namespace {

namespace fs = std::filesystem;

Camera make_camera(int w, int h, double fov_deg, const glm::dvec3& eye, const glm::dvec3& target) {
    const double f = 0.5 * w / std::tan(0.5 * fov_deg * kPi / 180.0);
    return Camera(Intrinsics{w, h, f, f, 0.5 * w, 0.5 * h}, look_at_camera_to_world(eye, target, {0, 1, 0}));
}

Material uniform(float albedo, LafortuneRgb lobe = {}) {
    Material m;
    m.albedo_value = glm::vec3(albedo);
    m.lobe = lobe;
    return m;
}

std::string file_bytes(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// (a) Lambertian sphere: pixel = (rho / pi) I max(0, n.u) / d^2 with n, u, d from the
// exact ray-sphere intersection. Tolerance from the tessellation (256 x 128): the mesh
// lies within R (1 - cos(pi / 256)) = 7.5e-5 R of the sphere and its interpolated
// normals within about as many radians; seen at up to 78 degrees from the normal
// (we skip rays with impact parameter > 0.98 R) the hit moves by < 4e-4 R, so the
// value changes by well under 1e-3 of the peak (about 0.2). Near the terminator the
// faceted geometric normal decides whether the light is behind the surface, so
// pixels with n.u < 0.02 are skipped.
TEST(SynthRender, LambertianSphereMatchesClosedForm) {
    const double R = 1.0, rho = 0.6;
    const Mesh sphere = make_uv_sphere(glm::vec3(0.0f), static_cast<float>(R), 256, 128);
    const Camera cam = make_camera(96, 96, 40.0, {0.3, 0.8, 4.0}, {0, 0, 0});
    const PointLight light{{1.5, 1.0, 3.0}, {10.0, 8.0, 6.0}};
    const RenderedFrame frame = render_frame(sphere, uniform(static_cast<float>(rho)), cam, light, 2);

    std::size_t compared = 0;
    double max_err = 0.0, peak = 0.0;
    for (int y = 0; y < 96; ++y) {
        for (int x = 0; x < 96; ++x) {
            const glm::dvec3 o = cam.center(), d = cam.ray_direction(x + 0.5, y + 0.5);
            const double b = glm::dot(o, d), c = glm::dot(o, o) - R * R, disc = b * b - c;
            const bool hit = disc >= 0.0;
            if (!hit || std::sqrt(std::max(0.0, glm::dot(o, o) - b * b)) > 0.98 * R) {
                if (!hit) {
                    EXPECT_EQ(frame.mask[y * 96 + x], 0) << x << "," << y;
                }
                continue;
            }
            ASSERT_EQ(frame.mask[y * 96 + x], 255) << x << "," << y;
            const glm::dvec3 p = o + (-b - std::sqrt(disc)) * d;
            const glm::dvec3 n = p / R;
            const glm::dvec3 to_light = light.position - p;
            const double dist = glm::length(to_light);
            const double cosine = glm::dot(n, to_light / dist);
            if (cosine < 0.02) continue;
            for (int ch = 0; ch < 3; ++ch) {
                const double expected = rho / kPi * light.intensity[ch] * cosine / (dist * dist);
                max_err = std::max(max_err, std::abs(frame.color.at(x, y, ch) - expected));
                peak = std::max(peak, expected);
            }
            ++compared;
        }
    }
    EXPECT_GT(compared, 2500u);
    EXPECT_LT(max_err, 1e-3 * peak) << "peak " << peak;
    std::printf("sphere: %zu pixels compared, max |error| %.3g (peak %.3g)\n", compared, max_err, peak);
}

// (b) The capture format's projection, written out here, puts visible vertices on mask pixels.
TEST(SynthRender, ProjectedVerticesLandOnTheMask) {
    const Mesh scene = make_uv_sphere(glm::vec3(0.2f, -0.1f, 0.0f), 0.7f, 64, 32);
    const int w = 120, h = 90;
    const Intrinsics k{w, h, 100.0, 110.0, 55.0, 49.0}; // non-square pixels, off-centre principal point
    const Camera cam(k, look_at_camera_to_world({2.0, 1.2, 2.6}, {0.1, 0.0, 0.0}, {0, 1, 0}));
    const RenderedFrame frame = render_frame(scene, uniform(0.5f), cam, PointLight{{2, 2, 2}, {1, 1, 1}}, 2);
    const glm::dmat4 world_to_cam = glm::inverse(cam.camera_to_world);
    std::size_t checked = 0;
    double highest = -1e9, lowest = 1e9, row_of_highest = 0.0, row_of_lowest = 0.0;
    for (std::size_t i = 0; i < scene.positions.size(); ++i) {
        const glm::dvec3 X(scene.positions[i]);
        const glm::dvec3 to_eye = glm::normalize(cam.center() - X);
        // Facing the camera well inside the silhouette (a convex object: then visible).
        if (glm::dot(glm::dvec3(scene.normals[i]), to_eye) < 0.6) continue;
        const glm::dvec4 xc = world_to_cam * glm::dvec4(X, 1.0);
        ASSERT_LT(xc.z, 0.0);
        const double px = k.cx + k.fl_x * xc.x / (-xc.z);
        const double py = k.cy - k.fl_y * xc.y / (-xc.z);
        ASSERT_TRUE(px >= 0 && py >= 0 && px < w && py < h);
        EXPECT_EQ(frame.mask[static_cast<int>(py) * w + static_cast<int>(px)], 255) << "vertex " << i;
        if (X.y > highest) highest = X.y, row_of_highest = py;
        if (X.y < lowest) lowest = X.y, row_of_lowest = py;
        ++checked;
    }
    EXPECT_GT(checked, 200u);
    EXPECT_LT(row_of_highest, row_of_lowest) << "image rows must grow downward";
    EXPECT_EQ(frame.mask[0], 0);
}

// (c) A plane point whose path to the light crosses an occluder renders exactly black.
TEST(SynthRender, ShadowedPointIsBlack) {
    Mesh scene = make_quad({-2, 0, 2}, {4, 0, 0}, {0, 0, -4}); // y = 0, normal +Y
    append_mesh(scene, make_quad({-0.2f, 0.5f, 0.2f}, {0.4f, 0, 0}, {0, 0, -0.4f}));
    const Camera cam = make_camera(65, 65, 50.0, {0, 3, 3}, {0, 0, 0});
    const PointLight light{{0, 2, 0}, {5, 5, 5}};
    const RenderedFrame frame = render_frame(scene, uniform(0.7f), cam, light, 2);
    const auto pixel_of = [&](const glm::dvec3& X) {
        const glm::dvec2 p = *cam.project(X);
        return glm::ivec2(static_cast<int>(p.x), static_cast<int>(p.y));
    };
    const glm::ivec2 s = pixel_of({0.0, 0.0, 0.0}); // under the occluder: shadowed
    ASSERT_EQ(frame.mask[s.y * 65 + s.x], 255);
    for (int c = 0; c < 3; ++c) EXPECT_EQ(frame.color.at(s.x, s.y, c), 0.0f);
    const glm::ivec2 lit = pixel_of({1.0, 0.0, 0.0});
    EXPECT_GT(frame.color.at(lit.x, lit.y, 0), 0.01f);
    EXPECT_GT(frame.shadowed_pixels, 20u);
}

// (d) A Lafortune highlight where the lobe predicts it: plane y = 0, camera and light
// mirrored about the normal at the origin, which the centre pixel sees exactly.
TEST(SynthRender, SpecularHighlightMatchesTheLobe) {
    const Mesh plane = make_quad({-4, 0, 4}, {8, 0, 0}, {0, 0, -8});
    const int size = 65; // odd: the centre pixel's centre is the principal point
    const glm::dvec3 eye(0.0, 1.0, 2.0), light_pos(0.0, 1.0, -2.0);
    const Camera cam = make_camera(size, size, 40.0, eye, {0, 0, 0});
    const PointLight light{light_pos, {4, 4, 4}};
    const float rho = 0.5f;
    const double cos_theta = 1.0 / std::sqrt(5.0), d2 = 5.0;

    // A sharp mirror lobe (Cx = -Cz): its peak, 1, is exactly at the mirror direction.
    const LafortuneRgb mirror{glm::vec3(-1.0f), glm::vec3(1.0f), glm::vec3(50.0f)};
    const RenderedFrame diffuse = render_frame(plane, uniform(rho), cam, light, 2);
    const RenderedFrame glossy = render_frame(plane, uniform(rho, mirror), cam, light, 2);
    const int c = size / 2;
    EXPECT_NEAR(diffuse.color.at(c, c, 0), rho / kPi * 4.0 * cos_theta / d2, 1e-5);
    EXPECT_NEAR(glossy.color.at(c, c, 0) - diffuse.color.at(c, c, 0), 1.0 * 4.0 * cos_theta / d2, 1e-3);
    // The BRDF sample (excess divided by I cos / d^2 at the pixel's plane point) peaks at that pixel.
    float best = -1.0f;
    glm::ivec2 arg(0);
    for (int y = 0; y < size; ++y) {
        for (int x = 0; x < size; ++x) {
            const glm::dvec3 dir = cam.ray_direction(x + 0.5, y + 0.5);
            if (dir.y >= 0.0) continue;
            const glm::dvec3 p = eye + (-eye.y / dir.y) * dir;
            const glm::dvec3 to_light = light_pos - p;
            const double dist = glm::length(to_light);
            const double irradiance = 4.0 * (to_light.y / dist) / (dist * dist);
            const float fs = static_cast<float>((glossy.color.at(x, y, 0) - diffuse.color.at(x, y, 0)) / irradiance);
            if (fs > best) best = fs, arg = {x, y};
        }
    }
    EXPECT_LE(std::abs(arg.x - c) + std::abs(arg.y - c), 1);
    EXPECT_NEAR(best, 1.0f, 2e-3f);
    EXPECT_LT(glossy.color.at(0, 0, 0) - diffuse.color.at(0, 0, 0), 1e-6f);

    // The thesis's pepsi lobe, written out: u = (0, 1, -2)/sqrt5, v = (0, 1, 2)/sqrt5 in the
    // frame (t, b, n): ux vx + uy vy = -4/5 (tangential parts opposite), uz vz = 1/5.
    const LafortuneRgb pepsi = thesis_lobe("pepsi");
    const RenderedFrame pep = render_frame(plane, uniform(rho, pepsi), cam, light, 2);
    const double base = -0.8962 * (-0.8) + 0.7587 * 0.2;
    const double expected = (rho / kPi + std::pow(base, 10.11)) * 4.0 * cos_theta / d2;
    EXPECT_NEAR(pep.color.at(c, c, 1), expected, 1e-4 * expected);
}

// The rig: train light l at light_angles_deg[l] off the camera direction seen from the
// object's centre, at the camera's distance, at azimuth 360 l / lights degrees about it (or,
// with no angles, on a ring in the camera's image plane); test lights off every ring;
// cameras look at the object's centre from the stated elevations; exposure puts a facing
// albedo-0.8 Lambertian surface at 0.6.
TEST(SynthRig, LightsAtTheStatedAnglesAndExposureAsStated) {
    const Mesh sphere = make_uv_sphere(glm::vec3(0.0f, 0.5f, 0.0f), 0.5f, 128, 64);
    RigOptions ro;
    ro.size = 64;
    const Rig rig = make_rig(sphere, ro);
    ASSERT_EQ(rig.views.size(), 24u);
    EXPECT_EQ(rig.frame_count(Split::Train), 120u);
    EXPECT_EQ(rig.frame_count(Split::Test), 8u);
    for (const RigView& v : rig.views) {
        const glm::dvec3 eye = v.camera.center();
        EXPECT_NEAR(glm::length(eye - rig.center), rig.camera_distance, 1e-9);
        const double elevation = std::asin((eye.y - rig.center.y) / rig.camera_distance) * 180.0 / kPi;
        EXPECT_GE(elevation, -20.0 - 1e-9);
        EXPECT_LE(elevation, 50.0 + 1e-9);
        const glm::dvec2 c = *v.camera.project(rig.center);
        EXPECT_NEAR(c.x, 32.0, 1e-9);
        EXPECT_NEAR(c.y, 32.0, 1e-9);
        for (const PointLight& l : v.lights) {
            const glm::dvec3 lc = v.camera.to_camera(l.position);
            const double r = std::hypot(lc.x, lc.y) / rig.camera_distance;
            if (v.split == Split::Train) {
                const std::size_t l_index = static_cast<std::size_t>(&l - v.lights.data());
                const glm::dvec3 to_light = l.position - rig.center, to_eye = eye - rig.center;
                EXPECT_NEAR(glm::length(to_light), rig.camera_distance, 1e-9);
                const double angle =
                    std::acos(std::clamp(glm::dot(to_light, to_eye) / (rig.camera_distance * rig.camera_distance), -1.0, 1.0));
                EXPECT_NEAR(angle * 180.0 / kPi, ro.light_angles_deg[l_index % ro.light_angles_deg.size()], 1e-6);
                // Azimuth about the camera direction: the camera-frame (x, y) direction of the light.
                const double az = std::atan2(lc.y, lc.x), expected_az = 2.0 * kPi * double(l_index) / double(ro.lights);
                EXPECT_NEAR(std::remainder(az - expected_az, 2.0 * kPi), 0.0, 1e-6) << "light " << l_index;
            } else {
                EXPECT_NEAR(-lc.z / rig.camera_distance, ro.test_forward, 1e-9);
                EXPECT_NEAR(r, ro.test_ring_radius, 1e-9);
            }
        }
    }
    // Without angles: the thesis-like ring in each camera's image plane.
    RigOptions ring = ro;
    ring.light_angles_deg.clear();
    for (const RigView& v : make_rig(sphere, ring).views) {
        if (v.split != Split::Train) continue;
        for (const PointLight& l : v.lights) {
            const glm::dvec3 lc = v.camera.to_camera(l.position);
            EXPECT_NEAR(lc.z, 0.0, 1e-9);
            EXPECT_NEAR(std::hypot(lc.x, lc.y) / rig.camera_distance, ring.ring_radius, 1e-9);
        }
    }
    // Exposure: the brightest Lambertian albedo-0.8 pixel is about 0.6 (the nearest point
    // to the light faces it on a sphere, up to the pixel grid).
    const RigView& v = rig.views[3];
    const RenderedFrame f = render_frame(sphere, uniform(0.8f), v.camera, v.lights[0], 2);
    const float peak = *std::max_element(f.color.pixels.begin(), f.color.pixels.end());
    EXPECT_LE(peak, 0.6f * 1.001f);
    EXPECT_GT(peak, 0.55f);
    std::size_t covered = 0;
    for (std::uint8_t m : f.mask) covered += m != 0;
    EXPECT_GT(covered, 64u * 64u / 2u) << "the object should fill most of the image";
}

// (e) Same inputs, same bytes: thread count and repeated runs do not change anything.
TEST(SynthDeterminism, ThreadsAndSeedsGiveIdenticalResults) {
    const Preset knot = make_preset("knot");
    const Renderer renderer(knot.mesh, knot.material);
    RigOptions ro;
    ro.size = 64;
    ro.views = 3;
    const Rig rig = make_rig(knot.mesh, ro);
    const RenderedFrame one = renderer.render(rig.views[1].camera, rig.views[1].lights[2], 1);
    const RenderedFrame two = renderer.render(rig.views[1].camera, rig.views[1].lights[2], 2);
    const RenderedFrame five = renderer.render(rig.views[1].camera, rig.views[1].lights[2], 5);
    EXPECT_EQ(one.color.pixels, two.color.pixels);
    EXPECT_EQ(one.color.pixels, five.color.pixels);
    EXPECT_EQ(one.mask, two.mask);
    EXPECT_GT(one.shadowed_pixels, 0u) << "the knot shadows itself";

    test::TempDir tmp("synth-det");
    SynthOptions o;
    o.size = 40;
    o.views = 2;
    o.lights = 2;
    o.test_views = 1;
    o.noise_sigma = 0.01;
    o.shot_noise = 0.001;
    o.seed = 7;
    o.threads = 1;
    (void)write_synthetic_capture(to_object(make_preset("knot")), tmp / "a", o);
    o.threads = 2;
    (void)write_synthetic_capture(to_object(make_preset("knot")), tmp / "b", o);
    o.seed = 8;
    (void)write_synthetic_capture(to_object(make_preset("knot")), tmp / "c", o);
    for (const char* f : {"images/v00_l0.png", "images/v01_l1.png", "images/v02_l1.png", "masks/v01.png", "mesh.glb"})
        EXPECT_TRUE(file_bytes(tmp / "a" / f) == file_bytes(tmp / "b" / f)) << f << " differs";
    // EXR files carry a DateTime attribute (OpenImageIO): compare their pixels.
    EXPECT_EQ(read_image(tmp / "a" / "truth/albedo.exr", ColorSpace::Linear).pixels,
              read_image(tmp / "b" / "truth/albedo.exr", ColorSpace::Linear).pixels);
    EXPECT_TRUE(file_bytes(tmp / "a" / "images/v00_l0.png") != file_bytes(tmp / "c" / "images/v00_l0.png")) << "seed ignored";
}

// (f) Noise statistics: sigma and the shot-noise variance are recovered on a flat
// 256 x 256 x 3 region (196608 samples: the standard error of a standard deviation
// estimate is 0.16 %, so 2 % is a safe bound).
TEST(SynthNoise, RecoversSigmaOnAFlatRegion) {
    const auto stats = [](const Image& img, double mean_ref) {
        double s = 0.0, s2 = 0.0;
        for (float v : img.pixels) s += v - mean_ref, s2 += (v - mean_ref) * (v - mean_ref);
        const double n = static_cast<double>(img.pixels.size());
        return std::pair<double, double>(s / n, std::sqrt(s2 / n - (s / n) * (s / n)));
    };
    Image flat(256, 256, 3, 0.3f);
    apply_noise(flat, NoiseOptions{0.02, 0.0}, 42, 0);
    auto [bias, sd] = stats(flat, 0.3);
    EXPECT_NEAR(sd, 0.02, 0.02 * 0.02);
    EXPECT_NEAR(bias, 0.0, 3.0 * 0.02 / std::sqrt(196608.0));

    Image shot(256, 256, 3, 0.3f);
    apply_noise(shot, NoiseOptions{0.01, 0.001}, 42, 1);
    std::tie(bias, sd) = stats(shot, 0.3);
    const double expected = std::sqrt(0.01 * 0.01 + 0.001 * 0.3);
    EXPECT_NEAR(sd, expected, 0.02 * expected);

    // Different frames (streams) get independent noise.
    Image a(128, 128, 1, 0.0f), b(128, 128, 1, 0.0f);
    apply_noise(a, NoiseOptions{1.0, 0.0}, 42, 3);
    apply_noise(b, NoiseOptions{1.0, 0.0}, 42, 4);
    double corr = 0.0;
    for (std::size_t i = 0; i < a.pixels.size(); ++i) corr += a.pixels[i] * b.pixels[i];
    EXPECT_LT(std::abs(corr / a.pixels.size()), 4.0 / 128.0);
}

// (g) A whole small capture, loaded back by the capture reader.
TEST(SynthCapture, WrittenCaptureLoadsBackWithItsTruth) {
    test::TempDir tmp("synth-capture");
    SynthOptions o;
    o.size = 64;
    o.views = 4;
    o.lights = 3;
    o.test_views = 1;
    o.test_lights = 2;
    const Preset can = make_preset("can");
    const SynthResult r = write_synthetic_capture(to_object(can), tmp / "cap", o);
    EXPECT_EQ(r.train_frames, 12u);
    EXPECT_EQ(r.test_frames, 2u);

    const Capture cap = load_capture(tmp / "cap");
    ASSERT_EQ(cap.desc.frames.size(), 14u);
    EXPECT_EQ(cap.views.size(), 5u);
    EXPECT_EQ(cap.frame_count(Split::Train), 12u);
    EXPECT_EQ(cap.frame_count(Split::Test), 2u);
    EXPECT_EQ(cap.mesh.triangle_count(), can.mesh.triangle_count());
    EXPECT_EQ(cap.desc.color_space, ColorSpace::Srgb);
    const nlohmann::json& gt = cap.desc.ground_truth;
    ASSERT_TRUE(gt.is_object());
    EXPECT_EQ(gt.at("preset"), "can");
    const LafortuneRgb lobe = lobe_from_json(gt.at("lobe"));
    EXPECT_EQ(lobe.cx, can.material.lobe.cx);
    EXPECT_EQ(lobe.cz, can.material.lobe.cz);
    EXPECT_EQ(lobe.n, can.material.lobe.n);
    const Image truth = read_image(cap.desc.resolve(gt.at("albedo_texture").get<std::string>()), ColorSpace::Linear);
    EXPECT_EQ(truth.pixels, can.material.albedo_texture.pixels);

    // The decoded first frame matches an in-memory render within 8-bit sRGB quantization.
    const FrameDesc& f = cap.desc.frames[0];
    const RenderedFrame ref = render_frame(can.mesh, can.material, f.camera(), f.light, 2);
    ASSERT_EQ(cap.images.size(), 14u);
    const Image& img = cap.images[0].color;
    ASSERT_EQ(img.width, 64);
    double max_err = 0.0;
    for (std::size_t i = 0; i < img.pixels.size(); ++i)
        max_err = std::max(max_err, std::abs(img.pixels[i] - std::min(ref.color.pixels[i], 1.0f)) / (std::min(ref.color.pixels[i], 1.0f) + 0.05));
    EXPECT_LT(max_err, 0.01);
}

// (h) A failed write leaves no output folder and no temporary folder; an existing
// folder is refused without force, and kept intact when a forced write fails.
TEST(SynthCapture, FailedWriteLeavesNothingBehind) {
    test::TempDir tmp("synth-atomic");
    SynthOptions o;
    o.size = 32;
    o.views = 2;
    o.lights = 2;
    o.test_views = 0;
    o.on_frame = [](std::size_t done, std::size_t) {
        if (done == 3) throw std::runtime_error("simulated failure");
    };
    const SynthObject sphere = to_object(make_preset("sphere"));
    EXPECT_THROW((void)write_synthetic_capture(sphere, tmp / "out", o), std::runtime_error);
    EXPECT_FALSE(fs::exists(tmp / "out"));
    EXPECT_TRUE(fs::is_empty(tmp.path())) << "temporary folder left behind";

    // Existing, non-empty: refused without force; a failing forced write keeps it.
    fs::create_directories(tmp / "out");
    { std::ofstream(tmp / "out" / "keep.txt") << "old"; }
    o.on_frame = nullptr;
    EXPECT_THROW((void)write_synthetic_capture(sphere, tmp / "out", o), UsageError);
    o.force = true;
    o.on_frame = [](std::size_t done, std::size_t) {
        if (done == 2) throw std::runtime_error("simulated failure");
    };
    EXPECT_THROW((void)write_synthetic_capture(sphere, tmp / "out", o), std::runtime_error);
    EXPECT_TRUE(fs::exists(tmp / "out" / "keep.txt"));
    o.on_frame = nullptr;
    (void)write_synthetic_capture(sphere, tmp / "out", o);
    EXPECT_FALSE(fs::exists(tmp / "out" / "keep.txt"));
    EXPECT_TRUE(fs::exists(tmp / "out" / "capture.json"));
    std::size_t entries = 0;
    for ([[maybe_unused]] const auto& e : fs::directory_iterator(tmp.path())) ++entries;
    EXPECT_EQ(entries, 1u);
}

} // namespace
} // namespace specula::synth
