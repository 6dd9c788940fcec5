// specula import: convert a dataset of another layout into a capture. One layout so far:
// `specula import photometric DIR`, a photometric-stereo folder (DiLiGenT's layout), whose
// conversion is engine/capture/import_photometric.h. Maps options, calls it, prints a summary.
#include "capture/import_photometric.h"
#include "commands.h"
#include "core/error.h"
#include "core/log.h"

#include <cmath>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace specula::cli {

namespace {

struct ImportPhotometricArgs {
    std::string dir;
    std::string out;
    std::string mesh;
    std::string color_space = "linear";
    std::vector<double> pose;
    std::optional<double> fl_y;
    std::optional<double> cx;
    std::optional<double> cy;
    std::optional<double> saturation;
    PhotometricImportOptions options;
};

/// 16 numbers, row-major, as a camera-to-world matrix (glm is column-major).
glm::dmat4 parse_pose(const std::vector<double>& v) {
    if (v.size() != 16)
        throw UsageError("--pose: expected 16 numbers (row-major camera-to-world), got " + std::to_string(v.size()));
    glm::dmat4 m(1.0);
    for (int row = 0; row < 4; ++row)
        for (int col = 0; col < 4; ++col) {
            const double x = v[static_cast<std::size_t>(row * 4 + col)];
            if (!std::isfinite(x)) throw UsageError("--pose: the numbers must be finite");
            m[col][row] = x;
        }
    return m;
}

void run_photometric(ImportPhotometricArgs& a) {
    PhotometricImportOptions o = a.options;
    o.mesh = a.mesh;
    o.fl_y = a.fl_y;
    o.cx = a.cx;
    o.cy = a.cy;
    o.saturation = a.saturation;
    if (a.color_space == "linear") o.color_space = ColorSpace::Linear;
    else if (a.color_space == "srgb") o.color_space = ColorSpace::Srgb;
    else throw UsageError("--color-space: expected linear or srgb, got '" + a.color_space + "'");
    if (!a.pose.empty()) o.pose = parse_pose(a.pose);
    const PhotometricImportResult r = import_photometric(a.dir, a.out, o);
    for (const std::string& w : r.warnings) log::warn(w);
    std::printf("wrote %s\n", r.dir.c_str());
    std::printf("  1 view, %zu frames (%zu train, %zu test) of %d x %d, directional lights (capture format 1.1); "
                "mesh.glb: %zu triangles\n",
                r.frames, r.frames - r.test_frames, r.test_frames, r.w, r.h, r.triangles);
    std::printf("  check it with: specula validate %s\n", r.dir.c_str());
}

void add_photometric(CLI::App& import) {
    auto a = std::make_shared<ImportPhotometricArgs>();
    CLI::App* sub = import.add_subcommand(
        "photometric", "A photometric-stereo dataset folder (DiLiGenT's layout) as a one-view capture with one directional light "
                       "per image (format 1.1). DIR holds light_directions.txt (per image a row \"x y z\": toward the light, "
                       "in the CAMERA frame: x right, y up, z toward the camera), light_intensities.txt (per image \"r g b\": "
                       "the light's intensity, by which the image is divided), mask.png (nonzero = object) and the images "
                       "001.png, 002.png, ... in row order (or the names listed one per line in filenames.txt). Each frame's "
                       "light: direction = pose rotation x row, irradiance = intensity row x --irradiance-scale.");
    sub->add_option("dir", a->dir, "The dataset folder")->required();
    sub->add_option("--mesh", a->mesh,
                    "The object's mesh (.glb copied, .gltf converted to mesh.glb), in the world frame of --pose "
                    "(with the default pose: the camera frame, the object at negative z)")
        ->required();
    sub->add_option("--fl", a->options.fl_x, "Focal length, pixels (fl_x; fl_y too unless --fl-y)")->required();
    sub->add_option("--fl-y", a->fl_y, "Vertical focal length, pixels (default --fl)");
    sub->add_option("--cx", a->cx,
                    "Principal point, pixels from the image's left edge (default w / 2; pixel centres are at "
                    "i + 0.5: add 0.5 to an OpenCV principal point)");
    sub->add_option("--cy", a->cy, "Principal point, pixels from the image's top edge (default h / 2; OpenCV: add 0.5)");
    sub->add_option("--pose", a->pose,
                    "Camera-to-world, 16 numbers row-major (rigid; OpenGL camera axes); default identity: the world "
                    "is the camera frame")
        ->expected(16)
        ->delimiter(',');
    sub->add_option("--irradiance-scale", a->options.irradiance_scale,
                    "Irradiance = intensity row x this (full scale 1: a white Lambertian surface facing the light "
                    "reads E / pi)")
        ->capture_default_str();
    sub->add_option("--color-space", a->color_space, "How the integer images are encoded: linear or srgb")->capture_default_str();
    sub->add_option("--saturation", a->saturation,
                    "Linear value at or above which a channel is clipped (default: 1.0, full scale, for integer images)");
    sub->add_option("--test-every", a->options.test_every,
                    "Every K-th light (rows K, 2K, ...) becomes a held-out test frame; 0: none")
        ->capture_default_str();
    sub->add_option("--out", a->out, "The capture folder (written atomically; must not exist or be empty unless --force)")
        ->required();
    sub->add_flag("--force", a->options.force, "Replace a non-empty --out (only once the new capture is complete)");
    sub->callback([a] { run_photometric(*a); });
}

} // namespace

void add_import_command(CLI::App& app) {
    CLI::App* import = app.add_subcommand("import", "Convert a dataset of another layout into a capture (see its subcommands)");
    import->require_subcommand(1);
    add_photometric(*import);
}

} // namespace specula::cli
