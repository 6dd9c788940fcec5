#pragma once
// A synthetic photometric-stereo dataset in the layout `specula import photometric` reads
// (capture/import_photometric.h): the Lambertian "can" preset seen by one camera, lit by
// directional lights given in the camera frame, rendered by engine/synth with the irradiance
// each row times the scale, written as 16-bit linear PNGs 001.png ... with mask.png and the
// two text files. The tests import it and compare with what it was rendered from.
#include "capture/camera.h"
#include "capture/capture.h"
#include "capture/mesh.h"
#include "core/file_util.h"
#include "core/image.h"
#include "synth/presets.h"
#include "synth/render.h"

#include <glm/glm.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <numbers>
#include <string>
#include <vector>

namespace specula::test {

struct PhotometricDatasetSpec {
    int size = 64;
    int lights = 8;
    double irradiance_scale = 1.5; // the importer's --irradiance-scale: rendered with row x this
    std::string preset = "can";
};

struct PhotometricTruth {
    synth::Preset preset;
    Intrinsics intrinsics;
    glm::dmat4 pose{1.0};                // camera-to-world of the one camera
    std::vector<glm::dvec3> camera_dirs; // as written to light_directions.txt (not all unit)
    std::vector<glm::dvec3> world_dirs;  // unit, what the frames were rendered with
    std::vector<glm::dvec3> intensities; // as written to light_intensities.txt
    double irradiance_scale = 1.0;
    std::vector<std::filesystem::path> images; // absolute, in row order
};

/// Text of rows of 3 numbers, written to round-trip exactly.
inline std::string rows_text(const std::vector<glm::dvec3>& rows) {
    std::string text;
    char line[128];
    for (const glm::dvec3& r : rows) {
        std::snprintf(line, sizeof line, "%.17g %.17g %.17g\n", r.x, r.y, r.z);
        text += line;
    }
    return text;
}

/// The camera: looking at the object's centre from 3.5 bounding radii, slightly above and to the
/// side (a pose that is not the identity), the object filling most of the image.
inline void place_camera(PhotometricTruth& t, int size) {
    const Bounds b = mesh_bounds(t.preset.mesh);
    const glm::dvec3 centre(b.center());
    const double radius = 0.5 * glm::length(glm::dvec3(b.max) - glm::dvec3(b.min));
    const glm::dvec3 eye = centre + 3.5 * radius * glm::normalize(glm::dvec3(0.4, 0.3, 1.0));
    t.pose = look_at_camera_to_world(eye, centre, glm::dvec3(0.0, 1.0, 0.0));
    const double half_fov_tan = 1.15 * radius / (3.5 * radius);
    const double fl = 0.5 * size / half_fov_tan;
    t.intrinsics = Intrinsics{size, size, fl, fl, 0.5 * size, 0.5 * size};
}

/// Camera-frame directions spread over a cone about the viewing direction (+z, toward the
/// camera), some not unit (the importer normalizes), and non-uniform RGB intensities.
inline void make_lights(PhotometricTruth& t, int lights) {
    for (int l = 0; l < lights; ++l) {
        const double polar = (20.0 + 35.0 * (l % 2)) * std::numbers::pi / 180.0;
        const double azimuth = 2.0 * std::numbers::pi * l / lights;
        const glm::dvec3 unit(std::sin(polar) * std::cos(azimuth), std::sin(polar) * std::sin(azimuth), std::cos(polar));
        t.camera_dirs.push_back(unit * (l % 3 == 0 ? 2.0 : 1.0));
        t.world_dirs.push_back(glm::normalize(glm::dmat3(t.pose) * unit));
        t.intensities.emplace_back(0.6 + 0.05 * l, 0.9 - 0.03 * l, 0.75 + 0.02 * (l % 4));
    }
}

/// Writes the dataset into `dir` (made if needed) and the preset's mesh to `mesh_file`.
inline PhotometricTruth write_photometric_dataset(const std::filesystem::path& dir, const std::filesystem::path& mesh_file,
                                                  const PhotometricDatasetSpec& spec = {}) {
    namespace fs = std::filesystem;
    PhotometricTruth t;
    t.preset = synth::make_preset(spec.preset, /*lambertian=*/true);
    t.irradiance_scale = spec.irradiance_scale;
    place_camera(t, spec.size);
    make_lights(t, spec.lights);
    fs::create_directories(dir);
    write_mesh_glb(mesh_file, t.preset.mesh);
    const synth::Renderer renderer(t.preset.mesh, t.preset.material);
    const Camera camera(t.intrinsics, t.pose);
    const Bounds bounds = mesh_bounds(t.preset.mesh);
    for (int l = 0; l < spec.lights; ++l) {
        const DirectionalLight light{t.world_dirs[l], t.intensities[l] * spec.irradiance_scale};
        const synth::RenderedFrame frame = renderer.render(camera, directional_stand_in(light, bounds));
        char name[32];
        std::snprintf(name, sizeof name, "%03d.png", l + 1);
        t.images.push_back(dir / name);
        write_image(t.images.back(), frame.color, ColorSpace::Linear, 16);
        if (l == 0) {
            Image mask(spec.size, spec.size, 1);
            for (std::size_t p = 0; p < frame.mask.size(); ++p) mask.pixels[p] = frame.mask[p] != 0 ? 1.0f : 0.0f;
            write_image(dir / "mask.png", mask, ColorSpace::Linear, 8);
        }
    }
    write_text_file(dir / "light_directions.txt", rows_text(t.camera_dirs));
    write_text_file(dir / "light_intensities.txt", rows_text(t.intensities));
    return t;
}

} // namespace specula::test
