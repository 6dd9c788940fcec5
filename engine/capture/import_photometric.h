#pragma once
// Import of a photometric-stereo dataset (the DiLiGenT layout) as a Specula capture of format
// 1.1: one view, one directional light per image (docs/capture-format.md "Importing a
// photometric-stereo dataset"). The dataset is one folder holding
//   light_directions.txt   one row "x y z" per image: toward the light, CAMERA frame (OpenGL axes:
//                          x right, y up, z toward the camera)
//   light_intensities.txt  one row "r g b" per image: the light's RGB intensity (the images read as
//                          value / intensity are the radiance under a unit light)
//   mask.png               the object (nonzero inside)
//   001.png, 002.png, ...  the images in row order (or any names listed in filenames.txt)
// and the mesh comes from a scan, registered to the camera. Rows are the non-blank lines of a
// file; numbers are separated by spaces, tabs or commas.
//
// The capture: capture.json, the mesh (mesh.glb: a .glb copied byte for byte, a .gltf converted),
// images/<name> and masks/<mask name> copied; every frame has view_index 0, the pose, the mask,
// and a directional light of direction pose rotation x row (normalized) and irradiance
// intensity row x irradiance_scale. Written atomically (core/output_dir.h): on any refusal
// nothing is left. Before it is moved into place, the capture is loaded as `specula validate
// --no-images` would load it (headers only), so the output always loads.
#include "capture/capture.h"
#include "core/image.h"

#include <glm/glm.hpp>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace specula {

/// The dataset's file names (inside its folder).
inline constexpr const char* kPhotometricDirectionsFile = "light_directions.txt";
inline constexpr const char* kPhotometricIntensitiesFile = "light_intensities.txt";
inline constexpr const char* kPhotometricFilenamesFile = "filenames.txt";
inline constexpr const char* kPhotometricMaskFile = "mask.png";

/// One row per image, in row order, as read from the dataset folder (read_photometric_dataset).
struct PhotometricDataset {
    std::filesystem::path dir;
    std::vector<std::filesystem::path> images; ///< relative to `dir`, in row order
    std::vector<std::string> image_fields;     ///< per image, what named it ("filenames.txt line 3", "image 3 of 96")
    std::vector<glm::dvec3> directions;        ///< camera frame, as given (non-zero, not normalized)
    std::vector<int> direction_lines;          ///< per row, its line in light_directions.txt (1-based)
    std::vector<glm::dvec3> intensities;       ///< as given (non-negative)
    std::vector<int> intensity_lines;          ///< per row, its line in light_intensities.txt
    std::filesystem::path mask;                ///< relative to `dir`
    int w = 0;                                 ///< every image's size (from the headers)
    int h = 0;
};

/// Reads and checks the dataset folder: both text files (3 finite numbers per row; a direction
/// not zero, intensities not negative), the images (filenames.txt, else the files named by a
/// number alone with the extension .png, numbered 1 to N without a gap), equal row counts, the
/// mask, and every image's and the mask's header (all of one size). Throws InputError naming
/// the file and the field or line ("light_directions.txt: line 7: expected 3 numbers, got 2").
[[nodiscard]] PhotometricDataset read_photometric_dataset(const std::filesystem::path& dir);

/// Parses one text file of rows of 3 numbers (the format of light_directions.txt and
/// light_intensities.txt). Returns the rows and, in `lines`, each row's 1-based line number.
/// Throws InputError(file, "line L", ...) on a row that is not 3 finite numbers.
[[nodiscard]] std::vector<glm::dvec3> parse_photometric_rows(const std::string& text, const std::filesystem::path& file,
                                                             std::vector<int>* lines = nullptr);

struct PhotometricImportOptions {
    std::filesystem::path mesh;    ///< the object's mesh (.glb or .gltf), registered to the camera
    double fl_x = 0.0;             ///< focal length, pixels
    std::optional<double> fl_y;    ///< default fl_x
    std::optional<double> cx;      ///< principal point, pixels from the left edge (default w / 2)
    std::optional<double> cy;      ///< from the top edge (default h / 2)
    glm::dmat4 pose{1.0};          ///< camera-to-world (rigid); identity: the world is the camera frame
    double irradiance_scale = 1.0; ///< irradiance = intensity row x this
    ColorSpace color_space = ColorSpace::Linear;
    std::optional<double> saturation; ///< written to capture.json when given
    int test_every = 0;               ///< > 0: rows K, 2K, ... (1-based) are test frames; 0: none
    bool force = false;               ///< replace a non-empty output folder
};

struct PhotometricImportResult {
    std::filesystem::path dir; ///< the capture folder written (absolute)
    std::size_t frames = 0;
    std::size_t test_frames = 0;
    int w = 0;
    int h = 0;
    std::size_t triangles = 0;
    std::vector<std::string> warnings; ///< the mesh's and the capture's (load_capture's), for the user
};

/// The capture description of `dataset` under `options` (paths relative to the capture folder:
/// images/<name>, masks/<mask name>, mesh.glb), desc.dir left empty. Throws UsageError on an
/// option out of range (naming it: --fl, --cx, --pose, ...) and InputError(light_intensities.txt,
/// "line L", ...) on an irradiance outside the capture format's range.
[[nodiscard]] CaptureDesc photometric_capture_desc(const PhotometricDataset& dataset, const PhotometricImportOptions& options);

/// Imports the dataset folder `dir` into the capture folder `out` (see the header comment).
[[nodiscard]] PhotometricImportResult import_photometric(const std::filesystem::path& dir, const std::filesystem::path& out,
                                                         const PhotometricImportOptions& options);

} // namespace specula
