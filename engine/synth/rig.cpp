#include "synth/rig.h"

#include "core/error.h"

#include <glm/gtc/constants.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace specula::synth {

namespace {

constexpr double kDeg = glm::pi<double>() / 180.0;

void require(bool ok, const std::string& what) {
    if (!ok) throw UsageError(what);
}

// Zig-zag over four elevation levels: 0, 2/3, 1/3, 1 of the range.
double elevation_level(int i) {
    static constexpr double kLevels[4] = {0.0, 2.0 / 3.0, 1.0 / 3.0, 1.0};
    return kLevels[i % 4];
}

glm::dvec3 orbit_position(const glm::dvec3& center, double distance, double azimuth, double elevation) {
    return center + distance * glm::dvec3(std::cos(elevation) * std::sin(azimuth), std::sin(elevation),
                                          std::cos(elevation) * std::cos(azimuth));
}

// A point in the camera's frame: `radius` from the optical axis at `angle`
// (from camera +X toward +Y), `forward` along the viewing direction.
glm::dvec3 around_camera(const glm::dmat4& c2w, double radius, double angle, double forward) {
    const glm::dvec3 right(c2w[0]), up(c2w[1]), back(c2w[2]), eye(c2w[3]);
    return eye + radius * (std::cos(angle) * right + std::sin(angle) * up) - forward * back;
}

} // namespace

RigKind parse_rig_kind(std::string_view text) {
    if (text == "spread") return RigKind::Spread;
    if (text == "thesis") return RigKind::Thesis;
    throw UsageError("--rig: unknown rig '" + std::string(text) + "' (spread, thesis)");
}

std::string_view to_string(RigKind kind) {
    switch (kind) {
    case RigKind::Spread: return "spread";
    case RigKind::Thesis: return "thesis";
    }
    return "?";
}

std::vector<double> RigOptions::train_light_angles_deg() const {
    if (kind == RigKind::Thesis) return {thesis_angle_deg};
    return light_angles_deg;
}

std::size_t Rig::frame_count() const {
    std::size_t n = 0;
    for (const RigView& v : views) n += v.lights.size();
    return n;
}

std::size_t Rig::frame_count(Split split) const {
    std::size_t n = 0;
    for (const RigView& v : views)
        for (std::size_t l = 0; l < v.lights.size(); ++l) n += v.split_of(l) == split ? 1 : 0;
    return n;
}

double exposure_intensity(const Mesh& mesh, const glm::dvec3& position, const RigOptions& options) {
    double d2 = std::numeric_limits<double>::infinity();
    for (const glm::vec3& p : mesh.positions) {
        const glm::dvec3 d = glm::dvec3(p) - position;
        d2 = std::min(d2, glm::dot(d, d));
    }
    return options.exposure * options.target_value * glm::pi<double>() * d2 / options.reference_albedo;
}

Rig make_rig(const Mesh& mesh, const RigOptions& o) {
    require(o.size >= 8 && o.size <= 16384, "--size must be between 8 and 16384 pixels");
    require(o.views >= 1 && o.views <= 1000, "--views must be between 1 and 1000");
    require(o.lights >= 1 && o.lights <= 1024, "--lights must be between 1 and 1024");
    require(o.test_views >= 0 && o.test_views <= 1000, "--test-views must be between 0 and 1000");
    require(o.test_lights >= 1 && o.test_lights <= 64, "test lights must be between 1 and 64");
    require(o.held_out_lights >= 0 && o.held_out_lights <= 1024, "--held-out-lights must be between 0 and 1024");
    require(o.fov_deg > 1.0 && o.fov_deg < 170.0, "field of view must be in (1, 170) degrees");
    require(o.fill > 0.05 && o.fill <= 1.0, "fill must be in (0.05, 1]");
    require(o.ring_radius > 0.0 && o.test_ring_radius > 0.0, "light ring radii must be positive");
    for (double a : o.light_angles_deg)
        require(std::isfinite(a) && a >= 0.0 && a <= 150.0, "--light-angles must be between 0 and 150 degrees");
    require(std::isfinite(o.thesis_angle_deg) && o.thesis_angle_deg > 0.0 && o.thesis_angle_deg <= 150.0,
            "the thesis rig's light angle must be in (0, 150] degrees");
    require(std::isfinite(o.exposure) && o.exposure > 0.0, "--exposure must be positive");
    require(o.target_value > 0.0 && o.reference_albedo > 0.0, "target value and reference albedo must be positive");
    if (mesh.positions.empty()) throw Error("make_rig: the mesh is empty");

    Rig rig;
    const Bounds b = mesh_bounds(mesh);
    rig.center = glm::dvec3(b.center());
    for (const glm::vec3& p : mesh.positions) rig.radius = std::max(rig.radius, glm::length(glm::dvec3(p) - rig.center));
    if (!(rig.radius > 0.0)) throw Error("make_rig: the mesh has no extent");

    const double half_fov = 0.5 * o.fov_deg * kDeg;
    const double focal = 0.5 * o.size / std::tan(half_fov);
    rig.intrinsics = Intrinsics{o.size, o.size, focal, focal, 0.5 * o.size, 0.5 * o.size};
    rig.camera_distance = rig.radius / std::sin(o.fill * half_fov);

    const double e0 = o.elevation_min_deg * kDeg, e1 = o.elevation_max_deg * kDeg;
    const glm::dvec3 up(0.0, 1.0, 0.0);
    const auto make_view = [&](int index, Split split, double azimuth, double elevation) {
        RigView view;
        view.view_index = index;
        view.split = split;
        const glm::dvec3 eye = orbit_position(rig.center, rig.camera_distance, azimuth, elevation);
        view.camera = Camera(rig.intrinsics, look_at_camera_to_world(eye, rig.center, up));
        return view;
    };

    // A light `off` radians off the camera direction seen from the object's centre, at the
    // camera's distance, at `azimuth` about that direction (from camera +X toward +Y).
    const auto off_camera = [&](const RigView& view, double off, double azimuth) {
        const glm::dmat4& c2w = view.camera.camera_to_world;
        const glm::dvec3 back(c2w[2]); // from the object toward the camera
        const glm::dvec3 side = std::cos(azimuth) * glm::dvec3(c2w[0]) + std::sin(azimuth) * glm::dvec3(c2w[1]);
        return rig.center + rig.camera_distance * (std::cos(off) * back + std::sin(off) * side);
    };
    const std::vector<double> angles = o.train_light_angles_deg();

    const double az_step = glm::two_pi<double>() / o.views;
    for (int i = 0; i < o.views; ++i) {
        RigView view = make_view(i, Split::Train, az_step * i, glm::mix(e0, e1, elevation_level(i)));
        // Train lights at azimuths l / lights of a turn, at angles[l] off the camera. Held-out
        // ones between them: at (l + 0.5) / count moved on by half a train step, and halfway
        // between two of the angles, so that none falls on (or next to) a train light.
        const auto add_lights = [&](int count, bool held_out, Split split) {
            for (int l = 0; l < count; ++l) {
                const double turn = held_out ? (l + 0.5) / count + 0.5 / o.lights : double(l) / count;
                const double angle = glm::two_pi<double>() * turn;
                PointLight light;
                const std::size_t a = std::size_t(l) % std::max<std::size_t>(1, angles.size());
                if (angles.empty())
                    light.position = around_camera(view.camera.camera_to_world, o.ring_radius * rig.camera_distance, angle, 0.0);
                else if (held_out && angles.size() > 1)
                    light.position = off_camera(view, 0.5 * (angles[a] + angles[(a + 1) % angles.size()]) * kDeg, angle);
                else
                    light.position = off_camera(view, angles[a] * kDeg, angle);
                light.intensity = glm::dvec3(exposure_intensity(mesh, light.position, o));
                view.lights.push_back(light);
                view.light_splits.push_back(split);
            }
        };
        add_lights(o.lights, false, Split::Train);
        add_lights(o.held_out_lights, true, Split::Test);
        rig.views.push_back(std::move(view));
    }

    for (int t = 0; t < o.test_views; ++t) {
        // Halfway between train views j and j + 1, spread over the circle.
        const int j = static_cast<int>(static_cast<long long>(t) * o.views / std::max(o.test_views, 1));
        const double elevation = glm::mix(e0, e1, 0.5 * (elevation_level(j) + elevation_level(j + 1)));
        RigView view = make_view(o.views + t, Split::Test, az_step * (j + 0.5), elevation);
        for (int l = 0; l < o.test_lights; ++l) {
            const double angle = glm::two_pi<double>() * (l + 0.5) / o.test_lights + glm::pi<double>() / o.lights;
            PointLight light;
            if (o.kind == RigKind::Thesis)
                light.position = off_camera(view, o.thesis_angle_deg * kDeg, angle);
            else
                light.position = around_camera(view.camera.camera_to_world, o.test_ring_radius * rig.camera_distance, angle,
                                               o.test_forward * rig.camera_distance);
            light.intensity = glm::dvec3(exposure_intensity(mesh, light.position, o));
            view.lights.push_back(light);
        }
        rig.views.push_back(std::move(view));
    }
    if (o.directional) // the same irradiance at the centre, from the same direction
        for (RigView& v : rig.views)
            for (PointLight& l : v.lights) {
                const glm::dvec3 to_light = l.position - rig.center;
                const double d = glm::length(to_light);
                l = directional_stand_in(DirectionalLight{to_light / d, l.intensity / (d * d)}, b);
            }
    return rig;
}

} // namespace specula::synth
