// Closed-form checks of the synthetic-capture renderer and writer:
// radiometry against an analytic sphere, the capture format's projection,
// shadows, a Lafortune highlight, the spread and thesis rigs, determinism, noise
// statistics, a whole capture read back with load_capture, a coated capture against
// its model, ground_truth, the unchanged default, the atomic write, and interreflections
// (the direct renderer unchanged, an analytic sphere interior, determinism and noise, ground_truth).
#include "capture/capture.h"
#include "core/error.h"
#include "core/image.h"
#include "material/material.h"
#include "shared/material.h"
#include "shared/prelude.h"
#include "synth/noise.h"
#include "synth/path_sampling.h"
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
#include <map>
#include <optional>
#include <variant>

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

// The thesis rig (Erdem 2003 section 3.1: six point lights around the camera; the judged rig: a
// ring about 15 degrees around each camera): every light, train and test, 15 degrees off the
// camera direction seen from the object's centre, at the camera's distance; six per train view,
// 60 degrees apart in azimuth about that direction; the test lights between the train ring's.
// The cameras are the spread rig's.
TEST(SynthRig, ThesisRigPutsSixLightsOnA15DegreeRing) {
    const Mesh sphere = make_uv_sphere(glm::vec3(0.2f, 0.5f, -0.1f), 0.5f, 64, 32);
    RigOptions ro;
    ro.size = 64;
    ro.kind = RigKind::Thesis;
    const Rig rig = make_rig(sphere, ro);
    RigOptions spread_options = ro;
    spread_options.kind = RigKind::Spread;
    const Rig spread = make_rig(sphere, spread_options);
    ASSERT_EQ(rig.views.size(), 24u);
    ASSERT_EQ(spread.views.size(), rig.views.size());
    EXPECT_EQ(rig.frame_count(Split::Train), 120u) << "the thesis's 20 views x 6 lights";
    EXPECT_EQ(rig.frame_count(Split::Test), 8u);
    const auto degrees = [](const glm::dvec3& a, const glm::dvec3& b) {
        return std::acos(std::clamp(glm::dot(glm::normalize(a), glm::normalize(b)), -1.0, 1.0)) * 180.0 / kPi;
    };
    for (std::size_t i = 0; i < rig.views.size(); ++i) {
        const RigView& v = rig.views[i];
        EXPECT_EQ(v.camera.camera_to_world, spread.views[i].camera.camera_to_world) << "view " << i;
        ASSERT_EQ(v.lights.size(), v.split == Split::Train ? 6u : 2u) << "view " << i;
        const glm::dvec3 to_eye = v.camera.center() - rig.center;
        std::vector<double> azimuths;
        for (const PointLight& l : v.lights) {
            const glm::dvec3 to_light = l.position - rig.center;
            EXPECT_NEAR(degrees(to_light, to_eye), 15.0, 1.0) << "view " << i;   // the bound
            EXPECT_NEAR(degrees(to_light, to_eye), 15.0, 1e-6) << "view " << i;  // and exactly as built
            EXPECT_NEAR(glm::length(to_light), rig.camera_distance, 1e-9);
            const glm::dvec3 lc = v.camera.to_camera(l.position);
            azimuths.push_back(std::atan2(lc.y, lc.x) * 180.0 / kPi);
        }
        for (std::size_t l = 0; l < azimuths.size(); ++l) {
            const double first = v.split == Split::Train ? 0.0 : 90.0 + 30.0; // (l + 0.5) 360 / 2 + 180 / 6
            const double step = v.split == Split::Train ? 60.0 : 180.0;
            EXPECT_NEAR(std::remainder(azimuths[l] - (first + step * double(l)), 360.0), 0.0, 1e-6) << "view " << i << " light " << l;
        }
    }
    // --lights sets the lights per ring; the ring's angle stays.
    ro.lights = 4;
    const Rig four = make_rig(sphere, ro);
    EXPECT_EQ(four.frame_count(Split::Train), 80u);
    EXPECT_NEAR(degrees(four.views[5].lights[3].position - four.center, four.views[5].camera.center() - four.center), 15.0, 1e-6);
    // Names.
    EXPECT_EQ(parse_rig_kind("thesis"), RigKind::Thesis);
    EXPECT_EQ(parse_rig_kind(to_string(RigKind::Spread)), RigKind::Spread);
    EXPECT_THROW((void)parse_rig_kind("ring"), UsageError);
}

// A photometric rig (issue 17): one view of 96 lights and 4 held-out lights, which are test
// frames of the same view, none on a train light (at least 2 degrees from every one); with
// `directional`, every light is directional toward where the point light was, of the
// irradiance it gave the centre, its stand-in 5e5 D away.
TEST(SynthRig, HeldOutLightsOfAViewAndDirectionalLights) {
    const Mesh sphere = make_uv_sphere(glm::vec3(0.2f, 0.5f, -0.1f), 0.5f, 64, 32);
    RigOptions ro;
    ro.views = 1;
    ro.lights = 96;
    ro.held_out_lights = 4;
    ro.test_views = 0;
    ro.light_angles_deg = {10.0, 25.0, 40.0, 55.0};
    const Rig rig = make_rig(sphere, ro);
    ASSERT_EQ(rig.views.size(), 1u);
    EXPECT_EQ(rig.frame_count(Split::Train), 96u);
    EXPECT_EQ(rig.frame_count(Split::Test), 4u);
    const RigView& v = rig.views[0];
    const auto degrees = [](const glm::dvec3& a, const glm::dvec3& b) {
        return glm::degrees(std::acos(std::clamp(glm::dot(glm::normalize(a), glm::normalize(b)), -1.0, 1.0)));
    };
    double nearest = 180.0;
    for (std::size_t h = 96; h < 100; ++h) {
        ASSERT_EQ(v.split_of(h), Split::Test);
        for (std::size_t t = 0; t < 96; ++t)
            nearest = std::min(nearest, degrees(v.lights[h].position - rig.center, v.lights[t].position - rig.center));
    }
    std::printf("held-out lights: nearest train light %.2f degrees away\n", nearest);
    EXPECT_GT(nearest, 2.0);

    ro.directional = true;
    const Rig far = make_rig(sphere, ro);
    for (std::size_t l = 0; l < 100; ++l) {
        const PointLight& p = v.lights[l];
        const PointLight& d = far.views[0].lights[l];
        ASSERT_TRUE(d.directional.has_value());
        const glm::dvec3 to = p.position - rig.center;
        EXPECT_NEAR(glm::length(d.directional->direction - glm::normalize(to)), 0.0, 1e-12);
        EXPECT_NEAR(d.directional->irradiance.x, p.intensity.x / glm::dot(to, to), 1e-12 * p.intensity.x / glm::dot(to, to));
        EXPECT_GT(glm::length(d.position - rig.center), 1e5 * rig.radius);
    }
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

// The first hit of a ray on a mesh, in double, by testing every triangle (Moller and Trumbore
// 1997): the surface point and the interpolated unit normal the renderer shades, known
// independently of Embree.
struct MeshHit {
    double t = 0.0;
    glm::dvec3 point{0.0}, normal{0.0}, geometric_normal{0.0};
};
std::optional<MeshHit> first_hit(const Mesh& mesh, const glm::dvec3& o, const glm::dvec3& d) {
    std::optional<MeshHit> best;
    for (const glm::uvec3& tri : mesh.triangles) {
        const glm::dvec3 p0(mesh.positions[tri.x]), e1 = glm::dvec3(mesh.positions[tri.y]) - p0, e2 = glm::dvec3(mesh.positions[tri.z]) - p0;
        const glm::dvec3 pv = glm::cross(d, e2);
        const double det = glm::dot(e1, pv);
        if (std::abs(det) < 1e-15) continue;
        const glm::dvec3 tv = o - p0;
        const double b1 = glm::dot(tv, pv) / det;
        if (b1 < 0.0 || b1 > 1.0) continue;
        const glm::dvec3 qv = glm::cross(tv, e1);
        const double b2 = glm::dot(d, qv) / det, t = glm::dot(e2, qv) / det;
        if (b2 < 0.0 || b1 + b2 > 1.0 || t <= 0.0 || (best && t >= best->t)) continue;
        const double b0 = 1.0 - b1 - b2;
        glm::dvec3 ng = glm::normalize(glm::cross(e1, e2));
        if (glm::dot(ng, d) > 0.0) ng = -ng;
        best = MeshHit{t, o + t * d,
                       glm::normalize(b0 * glm::dvec3(mesh.normals[tri.x]) + b1 * glm::dvec3(mesh.normals[tri.y]) +
                                      b2 * glm::dvec3(mesh.normals[tri.z])),
                       ng};
    }
    return best;
}

// (i) A coated capture's pixels are the model's: a sphere of constant (dark) albedo under a
// tinted coating, lit by the thesis rig (its highlights near the middle of every frame),
// written as png16 and decoded by the capture reader. At the surface point each pixel's centre
// ray hits (found here by first_hit), the pixel equals I max(0, n.u) / d^2 (rho / pi k_d + f_s),
// with k_d = material_diffuse_factor and f_s = material_specular (shared/material.h, double),
// within one code of the 16-bit sRGB encoding.
TEST(SynthCapture, CoatedPixelsAreTheModelTimesTheIrradiance) {
    test::TempDir tmp("synth-coated");
    SynthObject ball;
    ball.name = "ball";
    ball.mesh = make_uv_sphere(glm::vec3(0.1f, 0.2f, -0.1f), 0.5f, 32, 16);
    ball.material.albedo_value = glm::vec3(0.2f, 0.15f, 0.1f); // dark: the highlight stands out
    ball.material.coated = CoatedParams{1.5f, 0.12f, glm::vec3(1.0f, 0.9f, 0.8f)};
    SynthOptions o;
    o.size = 40;
    o.views = 2;
    o.test_views = 1;
    o.rig = RigKind::Thesis;
    o.format = ImageFormat::Png16;
    (void)write_synthetic_capture(ball, tmp / "cap", o);
    const Capture cap = load_capture(tmp / "cap");
    ASSERT_EQ(cap.desc.frames.size(), 14u);
    const shared::MaterialGpu gpu = material_gpu(SpecularModel(*ball.material.coated));
    const glm::dvec3 rho(ball.material.albedo_value);

    std::size_t compared = 0, highlights = 0;
    double worst = 0.0; // error / tolerance
    for (std::size_t k = 0; k < cap.desc.frames.size(); ++k) {
        const FrameDesc& f = cap.desc.frames[k];
        const Camera cam = f.camera();
        const Image& img = cap.images[k].color;
        for (int y = 0; y < img.height; y += 2) {
            for (int x = 0; x < img.width; x += 2) {
                const glm::dvec3 dir = cam.ray_direction(x + 0.5, y + 0.5);
                const std::optional<MeshHit> hit = first_hit(cap.mesh, cam.center(), dir);
                if (!hit) continue;
                const glm::dvec3 to_light = f.light.position - hit->point;
                const double d = glm::length(to_light);
                const glm::dvec3 u = to_light / d, v = -dir;
                const double ci = glm::dot(hit->normal, u), co = glm::dot(hit->normal, v);
                // Away from the terminator, where the faceted surface decides what is lit.
                if (ci < 0.05 || glm::dot(hit->geometric_normal, u) < 0.05) continue;
                const double kd = shared::f64::material_diffuse_factor(gpu, ci, co);
                const glm::dvec3 fs = shared::f64::material_specular(gpu, ci, co, glm::dot(u, v));
                highlights += fs.x > rho.x / kPi * kd;
                for (int c = 0; c < 3; ++c) {
                    const double expected = f.light.intensity[c] * ci / (d * d) * (rho[c] / kPi * kd + fs[c]);
                    if (expected >= 0.99) continue; // clipped at saturation 1.0
                    // One code of the encoding at this value (16-bit sRGB): covers its rounding and
                    // the renderer's float rounding.
                    const float s = linear_to_srgb(static_cast<float>(expected));
                    const double tolerance = srgb_to_linear(std::min(s + 1.0f / 65535.0f, 1.0f)) - expected;
                    worst = std::max(worst, std::abs(img.at(x, y, c) - expected) / tolerance);
                    ++compared;
                }
            }
        }
    }
    EXPECT_GT(compared, 3000u);
    EXPECT_GT(highlights, 30u) << "no pixel where the highlight outshines the diffuse term was compared";
    EXPECT_LE(worst, 1.0);
    std::printf("coated sphere: %zu values compared (%zu pixels in highlights), worst error %.3f of one code\n", compared,
                highlights, worst);
}

// (j) ground_truth records the family and its exact parameters, and the rig; a coated capture
// has no Lafortune lobe. The frames' lights are the thesis rig's: six per train view, each 15
// degrees off the camera direction seen from the recorded object centre.
TEST(SynthCapture, GroundTruthRecordsTheCoatedMaterialAndTheThesisRig) {
    test::TempDir tmp("synth-gt");
    SynthOptions o;
    o.size = 32;
    o.views = 3;
    o.test_views = 1;
    o.rig = RigKind::Thesis;
    const Preset can = make_preset("can", false, MaterialFamily::Coated);
    ASSERT_TRUE(can.material.coated.has_value());
    (void)write_synthetic_capture(to_object(can), tmp / "cap", o);
    const Capture cap = load_capture(tmp / "cap", {.load_images = false});
    const nlohmann::json& gt = cap.desc.ground_truth;
    EXPECT_EQ(gt.at("material").at("family"), "coated");
    const SpecularModel back = material_from_json(gt.at("material"));
    ASSERT_TRUE(std::holds_alternative<CoatedParams>(back));
    const CoatedParams& c = std::get<CoatedParams>(back);
    EXPECT_EQ(c.eta, can.coated.eta); // exactly: the floats survive JSON
    EXPECT_EQ(c.alpha, can.coated.alpha);
    EXPECT_EQ(c.tint, can.coated.tint);
    EXPECT_EQ(c.eta, 1.5f);
    EXPECT_EQ(c.alpha, 0.12f);
    EXPECT_FALSE(gt.contains("lobe")) << "a coated capture has no lobe to compare a fit with";
    EXPECT_EQ(gt.at("lambertian"), false);
    EXPECT_EQ(gt.at("rig").at("name"), "thesis");
    EXPECT_EQ(gt.at("rig").at("light_angles_deg"), nlohmann::json::array({15.0}));

    const nlohmann::json& oc = gt.at("rig").at("object_center");
    const glm::dvec3 center(oc[0].get<double>(), oc[1].get<double>(), oc[2].get<double>());
    std::map<int, int> lights_per_view;
    for (const FrameDesc& f : cap.desc.frames) {
        if (f.split == Split::Train) ++lights_per_view[f.view_index];
        const glm::dvec3 a = glm::normalize(f.light.position - center), b = glm::normalize(f.camera().center() - center);
        EXPECT_NEAR(std::acos(std::clamp(glm::dot(a, b), -1.0, 1.0)) * 180.0 / kPi, 15.0, 1.0) << f.file_path;
    }
    ASSERT_EQ(lights_per_view.size(), 3u);
    for (const auto& [view, n] : lights_per_view) EXPECT_EQ(n, 6) << "view " << view;

    // Both families round-trip, and a broken record is refused.
    const LafortuneRgb lobe = thesis_lobe("vase");
    EXPECT_EQ(material_to_json(lobe).at("family"), "lafortune");
    const SpecularModel lb = material_from_json(material_to_json(lobe));
    ASSERT_TRUE(std::holds_alternative<LafortuneRgb>(lb));
    EXPECT_EQ(std::get<LafortuneRgb>(lb).cz, lobe.cz);
    EXPECT_EQ(std::get<LafortuneRgb>(lb).n, lobe.n);
    EXPECT_THROW((void)material_from_json({{"family", "glossy"}}), Error);
    EXPECT_THROW((void)material_from_json({{"family", "coated"}, {"eta", 1.5}}), Error);
}

// (k) The default is today's capture: --material lafortune and --rig spread, given or not,
// write the same bytes, with the lafortune ground_truth keys; the coated family changes the
// images but not the mask.
TEST(SynthCapture, LafortuneSpreadIsTheDefaultAndUnchanged) {
    test::TempDir tmp("synth-default");
    SynthOptions o;
    o.size = 40;
    o.views = 2;
    o.lights = 3;
    o.test_views = 1;
    o.format = ImageFormat::Png16;
    (void)write_synthetic_capture(to_object(make_preset("vase")), tmp / "default", o);
    SynthOptions explicit_options = o;
    explicit_options.rig = RigKind::Spread;
    (void)write_synthetic_capture(to_object(make_preset("vase", false, MaterialFamily::Lafortune)), tmp / "lafortune", explicit_options);
    (void)write_synthetic_capture(to_object(make_preset("vase", false, MaterialFamily::Coated)), tmp / "coated", o);
    std::size_t images = 0;
    for (const auto& e : fs::directory_iterator(tmp / "default" / "images")) {
        const fs::path rel = fs::path("images") / e.path().filename();
        EXPECT_TRUE(file_bytes(tmp / "default" / rel) == file_bytes(tmp / "lafortune" / rel)) << rel;
        EXPECT_TRUE(file_bytes(tmp / "default" / rel) != file_bytes(tmp / "coated" / rel)) << rel;
        ++images;
    }
    EXPECT_EQ(images, 8u);
    EXPECT_TRUE(file_bytes(tmp / "default" / "masks/v01.png") == file_bytes(tmp / "coated" / "masks/v01.png"));
    EXPECT_TRUE(file_bytes(tmp / "default" / "capture.json") == file_bytes(tmp / "lafortune" / "capture.json"));
    const nlohmann::json gt = nlohmann::json::parse(std::ifstream(tmp / "default" / "capture.json"))["ground_truth"];
    const Preset vase = make_preset("vase");
    EXPECT_EQ(lobe_from_json(gt.at("lobe")).n, vase.material.lobe.n);
    EXPECT_EQ(gt.at("lambertian"), false);
    EXPECT_EQ(gt.at("material").at("family"), "lafortune");
    EXPECT_EQ(std::get<LafortuneRgb>(material_from_json(gt.at("material"))).cx, vase.material.lobe.cx);
    EXPECT_EQ(gt.at("rig").at("name"), "spread");
    EXPECT_EQ(gt.at("rig").at("light_angles_deg"), nlohmann::json(RigOptions{}.light_angles_deg));
}

// (l) Every preset's coated material: tint 1, eta in [1.3, 1.7], alpha in [0.05, 0.4], distinct
// from the other presets' (knot_hd is the knot), valid for the model, and energy-conserving with
// the preset's own albedo (at most coated_max_albedo). The coated family zeroes the lobe and
// keeps the albedo; --lambertian is refused with it, and so is a coated material with a lobe.
TEST(SynthPresets, CoatedMaterialsArePlausibleAndDistinct) {
    std::vector<std::pair<std::string, CoatedParams>> seen;
    for (const PresetInfo& info : list_presets()) {
        if (info.name == "knot_hd") continue; // the knot's mesh at high resolution (checked below)
        const Preset lafortune = make_preset(info.name);
        const Preset coated = make_preset(info.name, false, MaterialFamily::Coated);
        const CoatedParams& c = lafortune.coated;
        EXPECT_FALSE(lafortune.material.coated.has_value()) << info.name;
        ASSERT_TRUE(coated.material.coated.has_value()) << info.name;
        EXPECT_EQ(coated.material.coated->eta, c.eta);
        EXPECT_EQ(coated.material.coated->alpha, c.alpha);
        EXPECT_TRUE(coated.material.lobe.is_zero()) << info.name;
        EXPECT_EQ(coated.material.albedo_texture.pixels, lafortune.material.albedo_texture.pixels) << info.name;
        EXPECT_EQ(coated.material.family(), MaterialFamily::Coated);
        EXPECT_EQ(c.tint, glm::vec3(1.0f)) << info.name;
        EXPECT_GE(c.eta, 1.3f) << info.name;
        EXPECT_LE(c.eta, 1.7f) << info.name;
        EXPECT_GE(c.alpha, 0.05f) << info.name;
        EXPECT_LE(c.alpha, 0.4f) << info.name;
        EXPECT_FALSE(invalid_parameters(SpecularModel(c)).has_value()) << info.name;
        const float max_albedo = *std::max_element(lafortune.material.albedo_texture.pixels.begin(),
                                                   lafortune.material.albedo_texture.pixels.end());
        EXPECT_LE(max_albedo, coated_max_albedo(c.eta)) << info.name;
        for (const auto& [name, other] : seen) {
            EXPECT_FALSE(other.eta == c.eta && other.alpha == c.alpha) << info.name << " and " << name;
        }
        seen.emplace_back(info.name, c);
    }
    EXPECT_EQ(seen.size(), 6u);
    EXPECT_EQ(make_preset("knot_hd").coated.alpha, make_preset("knot").coated.alpha);
    EXPECT_THROW((void)make_preset("can", true, MaterialFamily::Coated), UsageError);

    test::TempDir tmp("synth-refuse");
    SynthOptions o;
    o.size = 16;
    o.views = 1;
    o.lights = 1;
    o.test_views = 0;
    o.lambertian = true;
    EXPECT_THROW((void)write_synthetic_capture(to_object(make_preset("sphere", false, MaterialFamily::Coated)), tmp / "a", o), UsageError);
    Material both = make_preset("sphere").material;
    both.coated = CoatedParams{};
    const Mesh sphere = make_uv_sphere(glm::vec3(0.0f), 1.0f, 16, 8);
    EXPECT_THROW((void)Renderer(sphere, both), Error);
    Material bad;
    bad.coated = CoatedParams{0.9f, 0.1f, glm::vec3(1.0f)};
    EXPECT_THROW((void)Renderer(sphere, bad), Error);
}

// ---- Interreflections (render.h, Interreflection; issue 16 item 4).

// FNV-1a over a frame's float pixels and mask: a fingerprint of the exact bytes.
std::uint64_t fingerprint(const RenderedFrame& f) {
    std::uint64_t h = 0xcbf29ce484222325ull;
    const auto eat = [&h](const void* data, std::size_t n) {
        const auto* p = static_cast<const unsigned char*>(data);
        for (std::size_t i = 0; i < n; ++i) h = (h ^ p[i]) * 0x100000001b3ull;
    };
    eat(f.color.pixels.data(), f.color.pixels.size() * sizeof(float));
    eat(f.mask.data(), f.mask.size());
    return h;
}

// (m) Without bounces the renderer is the one that made every capture so far: the fingerprints
// below are those of the direct-light renderer before interreflections existed (measured with
// it, on this project's toolchain: Debian 12's GCC and Embree), for the knot's lafortune lobe
// under a point light, the can's coated material, and a directional light. bounces = 0 ignores
// the other fields. A change to the direct path's arithmetic changes these on purpose only.
TEST(SynthBounces, DirectLightOnlyIsTheRendererAsItWas) {
    RigOptions ro;
    ro.size = 48;
    ro.views = 3;
    const Preset knot = make_preset("knot");
    const Rig rig = make_rig(knot.mesh, ro);
    const Renderer knot_renderer(knot.mesh, knot.material);
    const RenderedFrame point = knot_renderer.render(rig.views[1].camera, rig.views[1].lights[2], 2);
    const Interreflection ignored{.bounces = 0, .samples = 7, .seed = 99, .frame = 5};
    EXPECT_EQ(point.color.pixels, knot_renderer.render(rig.views[1].camera, rig.views[1].lights[2], 2, ignored).color.pixels);

    const Preset can = make_preset("can", false, MaterialFamily::Coated);
    const Rig can_rig = make_rig(can.mesh, ro);
    const RenderedFrame coated = render_frame(can.mesh, can.material, can_rig.views[0].camera, can_rig.views[0].lights[1], 2);
    ro.directional = true;
    const Rig far = make_rig(knot.mesh, ro);
    const RenderedFrame directional = knot_renderer.render(far.views[2].camera, far.views[2].lights[4], 2);
    EXPECT_EQ(point.lit_pixels, 448u);
    EXPECT_EQ(coated.lit_pixels, 791u);
    EXPECT_EQ(directional.lit_pixels, 190u);
    EXPECT_EQ(fingerprint(point), 0x9d1b24d92f77f467ull) << std::hex << fingerprint(point);
    EXPECT_EQ(fingerprint(coated), 0x49107c326b2c2bd1ull) << std::hex << fingerprint(coated);
    EXPECT_EQ(fingerprint(directional), 0xf5f6cffb7310b687ull) << std::hex << fingerprint(directional);
}

// Inside a closed Lambertian sphere (radius R, albedo rho) the form factor from any point to
// an area element dA is dA / (4 pi R^2): both cosines are d / 2R. So whatever a point light of
// intensity I inside lights directly, the first bounce brings every point the irradiance
// rho Phi / (4 pi R^2) = rho I / R^2 (Phi = 4 pi I, all of it landing on the sphere), and each
// further bounce multiplies that by rho: with N bounces the pixel gains
//     (rho / pi) (I / R^2) (rho + rho^2 + ... + rho^N)
// everywhere. The same kernel makes a cosine-weighted direction from any inner point land
// uniformly on the sphere: one first-bounce sample is X = rho^2 E_0(y) / pi for y uniform on
// the sphere, E_0 the direct irradiance; its variance is a quadrature over the sphere.
struct InsideSphere {
    static constexpr double R = 1.0;
    const glm::dvec3 rho{0.3, 0.5, 0.7};
    const PointLight light{{0.35, -0.2, 0.15}, {1.0, 1.0, 1.0}};
    Mesh mesh = make_uv_sphere(glm::vec3(0.0f), static_cast<float>(R), 128, 64);
    Camera camera = make_camera(24, 24, 70.0, {-0.3, 0.2, -0.1}, {0.5, 0.1, 0.6});
    Material material;

    InsideSphere() {
        // Seen from inside: normals inward, triangles wound the other way.
        for (glm::vec3& n : mesh.normals) n = -n;
        for (glm::uvec3& t : mesh.triangles) std::swap(t.y, t.z);
        material.albedo_value = glm::vec3(rho);
    }
    [[nodiscard]] double indirect(int bounces, int c) const {
        double sum = 0.0, power = 1.0;
        for (int k = 1; k <= bounces; ++k) sum += (power *= rho[c]);
        return rho[c] / kPi * light.intensity[c] / (R * R) * sum;
    }
    // Variance of one first-bounce sample X (channel c): midpoint quadrature of E_0(y) and
    // E_0(y)^2 over the sphere.
    [[nodiscard]] double sample_variance(int c) const {
        const int rings = 600, segments = 1200;
        double area = 0.0, m1 = 0.0, m2 = 0.0;
        for (int i = 0; i < rings; ++i) {
            const double theta = (i + 0.5) * kPi / rings;
            const double dA = std::sin(theta) * (kPi / rings) * (2.0 * kPi / segments) * R * R;
            for (int j = 0; j < segments; ++j) {
                const double phi = (j + 0.5) * 2.0 * kPi / segments;
                const glm::dvec3 y = R * glm::dvec3(std::sin(theta) * std::cos(phi), std::cos(theta),
                                                    std::sin(theta) * std::sin(phi));
                const glm::dvec3 to_light = light.position - y;
                const double d = glm::length(to_light);
                const double e0 = light.intensity[c] * glm::dot(-y / R, to_light / d) / (d * d);
                area += dA, m1 += e0 * dA, m2 += e0 * e0 * dA;
            }
        }
        m1 /= area, m2 /= area;
        const double k = rho[c] * rho[c] / kPi;
        EXPECT_NEAR(m1, light.intensity[c] / (R * R), 1e-3 * m1) << "the quadrature: the mean irradiance is flux / area";
        return k * k * (m2 - m1 * m1);
    }
};

// (n) The bounces inside a sphere add the analytic irradiance: 1, 2 and 3 bounces, each channel
// its own albedo. Tolerances: the mesh (128 x 64) lies within 3e-4 R of the sphere (the means
// measured within 0.06 %); with 256 paths per pixel the worst pixel is off by 0.7 % with one
// bounce (stratified directions) and by up to 5 % with more (the later bounces' directions are
// independent); the mean over the 576 pixels averages that noise away.
TEST(SynthBounces, InsideASphereTheBouncesAddTheAnalyticIrradiance) {
    const InsideSphere s;
    const Renderer renderer(s.mesh, s.material);
    const RenderedFrame direct = renderer.render(s.camera, s.light, 2);
    ASSERT_EQ(direct.lit_pixels, 24u * 24u) << "the camera sees the lit inside everywhere";
    for (int bounces = 1; bounces <= 3; ++bounces) {
        const RenderedFrame frame = renderer.render(s.camera, s.light, 2,
                                                    {.bounces = bounces, .samples = 256, .seed = 3, .frame = 0});
        EXPECT_EQ(frame.mask, direct.mask);
        EXPECT_EQ(frame.lit_pixels, direct.lit_pixels);
        for (int c = 0; c < 3; ++c) {
            const double expected = s.indirect(bounces, c);
            double mean = 0.0, worst = 0.0;
            for (int y = 0; y < 24; ++y)
                for (int x = 0; x < 24; ++x) {
                    const double added = static_cast<double>(frame.color.at(x, y, c)) - direct.color.at(x, y, c);
                    mean += added / (24.0 * 24.0);
                    worst = std::max(worst, std::abs(added - expected));
                }
            EXPECT_NEAR(mean, expected, 0.005 * expected) << bounces << " bounces, channel " << c;
            EXPECT_LT(worst, (bounces == 1 ? 0.015 : 0.08) * expected) << bounces << " bounces, channel " << c;
            std::printf("inside a sphere, %d bounces, rho %.1f: mean added %.6f, analytic %.6f (%+.3f %%), worst pixel %.2f %%\n",
                        bounces, s.rho[c], mean, expected, 100.0 * (mean / expected - 1.0), 100.0 * worst / expected);
        }
    }
}

// (o) Seeded and deterministic: the thread count changes nothing; another seed or another frame
// gives other samples, whose difference is the noise of the estimator: at most that of S
// independent samples (the quadrature's variance: stratification only lowers it; measured 0.09
// of it here, where the light varies smoothly over the sphere), and not vanishingly small.
TEST(SynthBounces, SeededDeterministicAndNoiseOfTheExpectedSize) {
    const InsideSphere s;
    const Renderer renderer(s.mesh, s.material);
    const int samples = 64;
    const Interreflection ir{.bounces = 1, .samples = samples, .seed = 11, .frame = 2};
    const RenderedFrame one = renderer.render(s.camera, s.light, 1, ir);
    const RenderedFrame two = renderer.render(s.camera, s.light, 2, ir);
    const RenderedFrame five = renderer.render(s.camera, s.light, 5, ir);
    EXPECT_EQ(one.color.pixels, two.color.pixels);
    EXPECT_EQ(one.color.pixels, five.color.pixels);
    Interreflection other_seed = ir, other_frame = ir;
    other_seed.seed = 12;
    other_frame.frame = 3;
    const RenderedFrame seed = renderer.render(s.camera, s.light, 2, other_seed);
    const RenderedFrame frame = renderer.render(s.camera, s.light, 2, other_frame);
    EXPECT_NE(one.color.pixels, frame.color.pixels) << "the frame index is ignored";
    for (int c = 0; c < 3; ++c) {
        double sum_sq = 0.0;
        for (int y = 0; y < 24; ++y)
            for (int x = 0; x < 24; ++x) {
                const double d = static_cast<double>(one.color.at(x, y, c)) - seed.color.at(x, y, c);
                sum_sq += d * d;
            }
        const double rms = std::sqrt(sum_sq / (24.0 * 24.0));
        const double independent = std::sqrt(2.0 * s.sample_variance(c) / samples);
        EXPECT_LT(rms, independent) << "channel " << c;
        EXPECT_GT(rms, 0.02 * independent) << "channel " << c;
        std::printf("seed difference, channel %d: RMS %.3g = %.2f x that of %d independent samples (%.3g, %.2f %% of the "
                    "indirect light)\n",
                    c, rms, rms / independent, samples, independent, 100.0 * rms / s.indirect(1, c));
    }
}

// (q) The direction mixture of path_sampling.h is a density and the one its samples follow: for
// glossy lafortune lobes (the vase's; the woodenpot's, whose peak lies below the horizon) and
// GGX coatings (sharp and rough), at normal, oblique and grazing views, the density integrates
// to 1 over the sphere (GGX: at most 1, the half-vectors facing away from v are lost), and the
// mean of g(w) / pdf(w) over its samples is the quadrature of g = f(w, v) max(0, n.w) over the
// hemisphere (f = rho / pi k_d + f_s of shared/material.h), within 4 standard errors.
TEST(SynthBounces, LobeSamplingIsADensityItsSamplesFollow) {
    const glm::dvec3 n(0.0, 0.0, 1.0);
    std::vector<std::pair<const char*, SpecularModel>> models;
    models.emplace_back("vase", thesis_lobe("vase"));
    models.emplace_back("woodenpot", thesis_lobe("woodenpot"));
    models.emplace_back("coated sharp", CoatedParams{1.5f, 0.08f, glm::vec3(1.0f)});
    models.emplace_back("coated rough", CoatedParams{1.7f, 0.4f, glm::vec3(1.0f)});
    const double rho = 0.4;
    for (const auto& [name, model] : models) {
        const shared::MaterialGpu gpu = material_gpu(model);
        const SamplingLobe lobe = SamplingLobe::of(model);
        ASSERT_NE(lobe.kind, SamplingLobe::Kind::None) << name;
        for (const double view_deg : {0.0, 45.0, 80.0}) {
            const double t = view_deg * kPi / 180.0;
            const glm::dvec3 v(std::sin(t), 0.0, std::cos(t));
            const DirectionSampler sampler(lobe, n, v, rho);
            const auto g = [&](const glm::dvec3& w) {
                const double ci = w.z, co = v.z;
                if (!(ci > 0.0)) return 0.0;
                return (rho / kPi * shared::f64::material_diffuse_factor(gpu, ci, co) +
                        shared::f64::material_specular(gpu, ci, co, glm::dot(w, v)).y) *
                       ci;
            };
            // Midpoint quadrature over the sphere, finest near the poles' lobes and the horizon.
            const int rings = 1500, segments = 1500;
            double mass = 0.0, integral = 0.0;
            for (int i = 0; i < rings; ++i) {
                const double theta = (i + 0.5) * kPi / rings;
                const double dw = std::sin(theta) * (kPi / rings) * (2.0 * kPi / segments);
                for (int j = 0; j < segments; ++j) {
                    const double phi = (j + 0.5) * 2.0 * kPi / segments;
                    const glm::dvec3 w(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta));
                    mass += sampler.pdf(w) * dw;
                    integral += g(w) * dw;
                }
            }
            if (lobe.kind == SamplingLobe::Kind::Lafortune) {
                EXPECT_NEAR(mass, 1.0, 2e-3) << name << " at " << view_deg;
            }
            EXPECT_LE(mass, 1.0 + 2e-3) << name << " at " << view_deg;
            EXPECT_GE(mass, sampler.cosine_share() - 2e-3) << name << " at " << view_deg;

            const int count = 400000;
            double sum = 0.0, sum_sq = 0.0;
            std::uint64_t state = 12345;
            const auto next = [&state] { return uniform01(mix64(state++)); };
            for (int k = 0; k < count; ++k) {
                const double a = next(), b = next();
                const glm::dvec3 w = sampler.sample(a, b);
                if (w == glm::dvec3(0.0)) continue; // a failed GGX sample: no light
                ASSERT_NEAR(glm::length(w), 1.0, 1e-9);
                const double p = sampler.pdf(w);
                ASSERT_GT(p, 0.0) << name << ": a sample where the density is 0";
                const double x = g(w) / p;
                sum += x, sum_sq += x * x;
            }
            const double mean = sum / count, se = std::sqrt(std::max(sum_sq / count - mean * mean, 0.0) / count);
            EXPECT_NEAR(mean, integral, 4.0 * se + 2e-3 * integral)
                << name << " at " << view_deg << " degrees (q " << sampler.cosine_share() << ")";
            std::printf("%-13s view %2.0f deg: q %.2f, density mass %.4f, integral %.4f, sampled %.4f +- %.4f\n", name, view_deg,
                        sampler.cosine_share(), mass, integral, mean, se);
        }
    }
}

// (r) Drawing from the lobe changes the noise, not the light: on the vase (glossy, concave; two
// bounces, so paths continue from glossy points seen at grazing angles) the mean indirect light
// over the frame with lobe sampling equals the cosine-only one within their noise, and its noise
// (two seeds' difference) is less than half (measured: 0.30 of it, 1.1 against 3.2 8-bit codes).
TEST(SynthBounces, LobeSamplingKeepsTheMeanAndLowersTheNoise) {
    const Preset vase = make_preset("vase");
    const Renderer renderer(vase.mesh, vase.material);
    RigOptions ro;
    ro.size = 40;
    ro.views = 3;
    const Rig rig = make_rig(vase.mesh, ro);
    const Camera& cam = rig.views[0].camera;
    const PointLight& light = rig.views[0].lights[0];
    const RenderedFrame direct = renderer.render(cam, light, 2);
    struct Run {
        double mean = 0.0, noise = 0.0, code_noise = 0.0;
    };
    const auto code = [](float v) { return 255.0 * linear_to_srgb(std::clamp(v, 0.0f, 1.0f)); };
    const auto run = [&](bool lobe_sampling) {
        Interreflection ir{.bounces = 2, .samples = 1024, .seed = 1, .frame = 0, .lobe_sampling = lobe_sampling};
        const RenderedFrame a = renderer.render(cam, light, 2, ir);
        ir.seed = 2;
        const RenderedFrame b = renderer.render(cam, light, 2, ir);
        Run r;
        std::size_t values = 0;
        for (std::size_t i = 0; i < a.color.pixels.size(); ++i) {
            if (!direct.mask[i / 3]) continue;
            r.mean += 0.5 * ((a.color.pixels[i] - direct.color.pixels[i]) + (b.color.pixels[i] - direct.color.pixels[i]));
            r.noise += (a.color.pixels[i] - b.color.pixels[i]) * (a.color.pixels[i] - b.color.pixels[i]);
            const double dc = code(a.color.pixels[i]) - code(b.color.pixels[i]);
            r.code_noise += dc * dc;
            ++values;
        }
        r.mean /= static_cast<double>(values);
        r.noise = std::sqrt(r.noise / static_cast<double>(values) / 2.0); // one image's
        r.code_noise = std::sqrt(r.code_noise / static_cast<double>(values) / 2.0);
        std::printf("vase, %s: mean indirect %.5f, noise per value %.5f (%.3f 8-bit codes) over %zu values\n",
                    lobe_sampling ? "lobe + cosine" : "cosine only", r.mean, r.noise, r.code_noise, values);
        return std::pair<Run, std::size_t>(r, values);
    };
    const auto [mixture, values] = run(true);
    const auto [cosine, values_c] = run(false);
    ASSERT_EQ(values, values_c);
    // The standard error of the two means' difference: each is the mean of two images, and only the
    // pixels' noise is independent (a pixel's three channels share their paths).
    const double pixels = static_cast<double>(values) / 3.0;
    const double se = std::sqrt((mixture.noise * mixture.noise + cosine.noise * cosine.noise) / (2.0 * pixels));
    EXPECT_GT(mixture.mean, 0.0);
    EXPECT_NEAR(mixture.mean, cosine.mean, 4.0 * se) << "standard error of the difference " << se;
    EXPECT_LT(mixture.noise, 0.5 * cosine.noise);
}

// (p) The capture records the bounces (only when there are some: a capture of direct light is
// unchanged), loads back, and is brighter where the object sees itself; bad counts are usage errors.
TEST(SynthBounces, CaptureRecordsTheBounces) {
    test::TempDir tmp("synth-bounces");
    SynthOptions o;
    o.size = 32;
    o.views = 2;
    o.lights = 1;
    o.test_views = 0;
    o.format = ImageFormat::Exr;
    (void)write_synthetic_capture(to_object(make_preset("knot")), tmp / "direct", o);
    o.bounces = 2;
    o.bounce_samples = 8;
    (void)write_synthetic_capture(to_object(make_preset("knot")), tmp / "bounced", o);
    const Capture direct = load_capture(tmp / "direct");
    const Capture bounced = load_capture(tmp / "bounced");
    EXPECT_FALSE(direct.desc.ground_truth.contains("bounces"));
    EXPECT_FALSE(direct.desc.ground_truth.contains("bounce_samples"));
    EXPECT_EQ(bounced.desc.ground_truth.at("bounces"), 2);
    EXPECT_EQ(bounced.desc.ground_truth.at("bounce_samples"), 8);
    ASSERT_EQ(bounced.images.size(), 2u);
    std::size_t brighter = 0;
    for (std::size_t k = 0; k < 2; ++k) {
        const Image& a = direct.images[k].color;
        const Image& b = bounced.images[k].color;
        for (std::size_t i = 0; i < a.pixels.size(); ++i) {
            EXPECT_GE(b.pixels[i], a.pixels[i]) << "frame " << k << " value " << i;
            brighter += b.pixels[i] > a.pixels[i];
        }
    }
    EXPECT_GT(brighter, 100u);

    for (const auto& [bounces, samples] :
         {std::pair{5, 8}, std::pair{-1, 8}, std::pair{1, 0}, std::pair{1, Interreflection::kMaxSamples + 1}}) {
        o.bounces = bounces;
        o.bounce_samples = samples;
        EXPECT_THROW((void)write_synthetic_capture(to_object(make_preset("sphere")), tmp / "refused", o), UsageError)
            << bounces << " " << samples;
    }
    EXPECT_FALSE(fs::exists(tmp / "refused"));
    const Mesh sphere = make_uv_sphere(glm::vec3(0.0f), 1.0f, 16, 8);
    const Camera cam = make_camera(8, 8, 40.0, {0, 0, 4}, {0, 0, 0});
    EXPECT_THROW((void)render_frame(sphere, uniform(0.5f), cam, PointLight{{0, 0, 3}, {1, 1, 1}}, 1, {.bounces = 5}), Error);
    EXPECT_THROW((void)render_frame(sphere, uniform(0.5f), cam, PointLight{{0, 0, 3}, {1, 1, 1}}, 1,
                                    {.bounces = 1, .samples = 0}),
                 Error);
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
