// Import of a photometric-stereo dataset folder as a capture of format 1.1 (import_photometric.h).
#include "capture/import_photometric.h"

#include "capture/mesh.h"
#include "core/error.h"
#include "core/file_util.h"
#include "core/format.h"
#include "core/output_dir.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <string_view>
#include <system_error>

namespace specula {

namespace fs = std::filesystem;

namespace {

/// Largest text file of the dataset read (a row is a few dozen bytes: millions of rows).
constexpr std::uintmax_t kMaxDatasetTextBytes = std::uintmax_t{64} << 20;

std::string line_field(int line) { return "line " + std::to_string(line); }

/// The whole text of a dataset file that must exist (a regular file, at most kMaxDatasetTextBytes).
std::string read_dataset_text(const fs::path& path, const std::string& what) {
    std::error_code ec;
    const fs::file_status st = fs::status(path, ec);
    if (!fs::exists(st)) throw InputError(path, "", "file not found (" + what + ")");
    if (!fs::is_regular_file(st)) throw InputError(path, "", "not a regular file (" + what + ")");
    const std::uintmax_t bytes = fs::file_size(path, ec);
    if (!ec && bytes > kMaxDatasetTextBytes)
        throw InputError(path, "",
                         "the file holds " + std::to_string(bytes) + " bytes, more than the " +
                             std::to_string(kMaxDatasetTextBytes) + " a dataset's text file may take");
    return read_text_file(path);
}

/// The non-blank lines of `text` with their 1-based line numbers, '\r' and a leading BOM removed.
std::vector<std::pair<int, std::string_view>> text_rows(std::string_view text) {
    if (text.substr(0, 3) == "\xEF\xBB\xBF") text.remove_prefix(3);
    std::vector<std::pair<int, std::string_view>> rows;
    int line = 0;
    while (!text.empty()) {
        const std::size_t end = std::min(text.find('\n'), text.size());
        std::string_view row = text.substr(0, end);
        text.remove_prefix(std::min(end + 1, text.size()));
        ++line;
        if (!row.empty() && row.back() == '\r') row.remove_suffix(1);
        if (row.find_first_not_of(" \t,") != std::string_view::npos) rows.emplace_back(line, row);
    }
    return rows;
}

/// The tokens of a row separated by spaces, tabs or commas.
std::vector<std::string_view> row_tokens(std::string_view row) {
    std::vector<std::string_view> tokens;
    std::size_t i = 0;
    while (i < row.size()) {
        const std::size_t start = row.find_first_not_of(" \t,", i);
        if (start == std::string_view::npos) break;
        const std::size_t end = std::min(row.find_first_of(" \t,", start), row.size());
        tokens.push_back(row.substr(start, end - start));
        i = end;
    }
    return tokens;
}

/// A token as a finite number; throws InputError(file, "line L", ...) otherwise.
double parse_number(std::string_view token, const fs::path& file, int line) {
    std::string_view digits = token;
    if (!digits.empty() && digits.front() == '+') digits.remove_prefix(1);
    double v = 0.0;
    const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), v);
    if (ec == std::errc::result_out_of_range)
        throw InputError(file, line_field(line), "'" + std::string(token) + "' is out of the range of a double");
    if (ec != std::errc() || end != digits.data() + digits.size())
        throw InputError(file, line_field(line), "'" + std::string(token) + "' is not a number");
    if (!std::isfinite(v)) throw InputError(file, line_field(line), "'" + std::string(token) + "' is not a finite number");
    return v;
}

/// A path named by the dataset (filenames.txt): relative, inside the folder, no NUL.
fs::path checked_dataset_name(std::string_view name, const fs::path& file, int line) {
    const std::string field = line_field(line);
    if (name.find('\0') != std::string_view::npos) throw InputError(file, field, "the name contains a NUL character");
    const fs::path p = fs::path(std::string(name)).lexically_normal();
    if (p.is_absolute())
        throw InputError(file, field,
                         "\"" + std::string(name) + "\" is an absolute path: name the images relative to the dataset's folder");
    if (p.empty() || *p.begin() == ".." || p == ".")
        throw InputError(file, field, "\"" + std::string(name) + "\" is not a file inside the dataset's folder");
    return p;
}

/// The images listed in filenames.txt, one name per non-blank line (surrounding blanks trimmed).
void list_named_images(const fs::path& dir, PhotometricDataset& d) {
    const fs::path file = dir / kPhotometricFilenamesFile;
    const std::string text = read_dataset_text(file, "the image names");
    for (const auto& [line, row] : text_rows(text)) {
        std::string_view name = row;
        name.remove_prefix(std::min(name.find_first_not_of(" \t"), name.size()));
        name.remove_suffix(name.size() - (name.find_last_not_of(" \t") + 1));
        d.images.push_back(checked_dataset_name(name, file, line));
        d.image_fields.push_back(std::string(kPhotometricFilenamesFile) + " " + line_field(line));
    }
    if (d.images.empty()) throw InputError(file, "", "no image names (one per line)");
}

/// The number a file name "<digits>.png" stands for (nothing for any other name).
std::optional<long long> numbered_png(const std::string& name) {
    const std::size_t dot = name.rfind('.');
    if (dot == std::string::npos || dot == 0) return std::nullopt;
    std::string ext = name.substr(dot);
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (ext != ".png") return std::nullopt;
    long long n = 0;
    const auto [end, ec] = std::from_chars(name.data(), name.data() + dot, n);
    if (ec != std::errc() || end != name.data() + dot || name[0] == '-' || name[0] == '+') return std::nullopt;
    return n;
}

/// Without filenames.txt: the files named by a number alone (.png), numbered 1 to N.
void list_numbered_images(const fs::path& dir, PhotometricDataset& d) {
    std::map<long long, std::string> numbered;
    std::error_code ec;
    for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
        const std::string name = it->path().filename().string();
        const std::optional<long long> n = numbered_png(name);
        if (!n || !it->is_regular_file(ec)) continue;
        const auto [at, fresh] = numbered.emplace(*n, name);
        if (!fresh)
            throw InputError(dir / name, "images",
                             "numbers the same image as " + at->second + " (image " + std::to_string(*n) + ")");
    }
    if (ec) throw InputError(dir, "", "cannot list the folder: " + ec.message());
    if (numbered.empty())
        throw InputError(dir, "images",
                         std::string("no images: neither ") + kPhotometricFilenamesFile +
                             " nor files named by their number (001.png, 002.png, ...)");
    long long expect = 1;
    for (const auto& [n, name] : numbered) {
        if (n != expect)
            throw InputError(dir, "images",
                             "image " + std::to_string(expect) + " is missing (found " + name +
                                 "): the numbered images must run from 1 to N without a gap, or be listed in " +
                                 kPhotometricFilenamesFile);
        d.images.emplace_back(name);
        d.image_fields.push_back("image " + std::to_string(n) + " of " + std::to_string(numbered.size()));
        ++expect;
    }
}

void check_row_count(const fs::path& file, std::size_t rows, std::size_t images) {
    if (rows != images)
        throw InputError(file, "rows",
                         std::to_string(rows) + " rows but " + std::to_string(images) +
                             " images: one row per image, in the images' order");
}

/// The directions (none zero) and intensities (none negative), one row per image.
void read_light_rows(const fs::path& dir, PhotometricDataset& d) {
    const fs::path dir_file = dir / kPhotometricDirectionsFile;
    d.directions = parse_photometric_rows(read_dataset_text(dir_file, "the light directions"), dir_file, &d.direction_lines);
    for (std::size_t i = 0; i < d.directions.size(); ++i)
        if (d.directions[i] == glm::dvec3(0.0))
            throw InputError(dir_file, line_field(d.direction_lines[i]), "the direction is zero (it points toward the light)");
    const fs::path int_file = dir / kPhotometricIntensitiesFile;
    d.intensities = parse_photometric_rows(read_dataset_text(int_file, "the light intensities"), int_file, &d.intensity_lines);
    for (std::size_t i = 0; i < d.intensities.size(); ++i)
        for (int c = 0; c < 3; ++c)
            if (d.intensities[i][c] < 0.0)
                throw InputError(int_file, line_field(d.intensity_lines[i]),
                                 "intensity " + short_number(d.intensities[i][c]) + " is negative (channel " + std::to_string(c) + ")");
    check_row_count(dir_file, d.directions.size(), d.images.size());
    check_row_count(int_file, d.intensities.size(), d.images.size());
}

/// Every image's header (one size for all, within the capture format's range) and the mask's.
void read_headers(const fs::path& dir, PhotometricDataset& d) {
    for (std::size_t i = 0; i < d.images.size(); ++i) {
        const ImageFileInfo info = read_image_info(dir / d.images[i], d.image_fields[i]);
        if (i == 0) {
            d.w = info.width;
            d.h = info.height;
            if (d.w < 1 || d.h < 1 || d.w > kMaxImageDimension || d.h > kMaxImageDimension)
                throw InputError(dir / d.images[i], d.image_fields[i],
                                 "image is " + std::to_string(d.w) + " x " + std::to_string(d.h) +
                                     ": a capture's images are 1 to " + std::to_string(kMaxImageDimension) +
                                     " pixels wide and high");
        } else if (info.width != d.w || info.height != d.h) {
            throw InputError(dir / d.images[i], d.image_fields[i],
                             "image is " + std::to_string(info.width) + " x " + std::to_string(info.height) + " but the first (" +
                                 d.images[0].generic_string() + ") is " + std::to_string(d.w) + " x " + std::to_string(d.h));
        }
    }
    d.mask = kPhotometricMaskFile;
    const fs::path mask = dir / d.mask;
    std::error_code ec;
    if (!fs::exists(mask, ec)) throw InputError(mask, "mask", "file not found (the object mask: nonzero inside the object)");
    const ImageFileInfo info = read_image_info(mask, "mask");
    if (info.width != d.w || info.height != d.h)
        throw InputError(mask, "mask",
                         "mask is " + std::to_string(info.width) + " x " + std::to_string(info.height) + " but the images are " +
                             std::to_string(d.w) + " x " + std::to_string(d.h));
}

} // namespace

std::vector<glm::dvec3> parse_photometric_rows(const std::string& text, const fs::path& file, std::vector<int>* lines) {
    std::vector<glm::dvec3> rows;
    if (lines) lines->clear();
    for (const auto& [line, row] : text_rows(text)) {
        const std::vector<std::string_view> tokens = row_tokens(row);
        if (tokens.size() != 3)
            throw InputError(file, line_field(line), "expected 3 numbers, got " + std::to_string(tokens.size()));
        glm::dvec3 v;
        for (int c = 0; c < 3; ++c) v[c] = parse_number(tokens[static_cast<std::size_t>(c)], file, line);
        rows.push_back(v);
        if (lines) lines->push_back(line);
    }
    if (rows.empty()) throw InputError(file, "", "no rows (one row of 3 numbers per image)");
    return rows;
}

PhotometricDataset read_photometric_dataset(const fs::path& dir) {
    std::error_code ec;
    if (!fs::is_directory(dir, ec))
        throw InputError(dir, "", fs::exists(dir, ec) ? "not a folder (the dataset's folder)" : "folder not found");
    PhotometricDataset d;
    d.dir = dir;
    if (fs::exists(dir / kPhotometricFilenamesFile, ec)) list_named_images(dir, d);
    else list_numbered_images(dir, d);
    read_light_rows(dir, d);
    read_headers(dir, d);
    return d;
}

namespace {

void check_option_range(double v, double lo, double hi, const std::string& option, const std::string& what) {
    if (!std::isfinite(v) || v < lo || v > hi)
        throw UsageError(option + ": " + short_number(v) + " is out of range (" + what + ": " + short_number(lo) + " to " + short_number(hi) + ")");
}

/// The intrinsics within the capture format's "Ranges" for w x h images.
void check_intrinsics(const PhotometricImportOptions& o, int w, int h) {
    const double size = std::max(w, h);
    const std::string images = "for " + std::to_string(w) + " x " + std::to_string(h) + " images";
    const std::string focal = "a focal length in pixels " + images;
    check_option_range(o.fl_x, kMinFocalRelative * size, kMaxFocalLength, "--fl", focal);
    if (o.fl_y) check_option_range(*o.fl_y, kMinFocalRelative * size, kMaxFocalLength, "--fl-y", focal);
    const double pp = kMaxPrincipalPointRelative * size;
    if (o.cx) check_option_range(*o.cx, -pp, pp, "--cx", "pixels from the left edge " + images);
    if (o.cy) check_option_range(*o.cy, -pp, pp, "--cy", "pixels from the top edge " + images);
}

/// A rigid camera-to-world transform with a proper rotation (the capture format's own check).
void check_pose(const glm::dmat4& m) {
    if (const std::optional<TransformProblem> p = transform_problem(m))
        throw UsageError("--pose" + p->entry + ": " + p->message + " (16 numbers, row-major camera-to-world)");
}

void check_options(const PhotometricImportOptions& o, int w, int h) {
    check_intrinsics(o, w, h);
    check_pose(o.pose);
    if (!(o.irradiance_scale > 0.0) || !std::isfinite(o.irradiance_scale))
        throw UsageError("--irradiance-scale: must be a positive finite number, got " + short_number(o.irradiance_scale));
    if (o.saturation)
        check_option_range(*o.saturation, kMinSaturation, kMaxSaturation, "--saturation", "linear units, full scale 1");
    if (o.test_every < 0)
        throw UsageError("--test-every: must be 0 (no test frames) or at least 2, got " + std::to_string(o.test_every));
    if (o.test_every == 1)
        throw UsageError("--test-every 1 makes every frame a test frame, leaving nothing to reconstruct from (0: none, K >= 2: "
                         "every K-th light)");
}

/// Row i's light: the direction turned into the world by the pose's rotation, the irradiance
/// intensity x scale within the capture format's range.
DirectionalLight imported_light(const PhotometricDataset& d, std::size_t i, const PhotometricImportOptions& o) {
    const glm::dvec3 dir = d.directions[i];
    const double largest = std::max({std::abs(dir.x), std::abs(dir.y), std::abs(dir.z)}); // no overflow in the length
    DirectionalLight light;
    light.direction = glm::normalize(glm::dmat3(o.pose) * (dir / largest));
    light.irradiance = d.intensities[i] * o.irradiance_scale;
    for (int c = 0; c < 3; ++c) {
        const double e = light.irradiance[c];
        if (e > kMaxIrradiance || (e > 0.0 && e < kMinIrradiance) || !std::isfinite(e))
            throw InputError(d.dir / kPhotometricIntensitiesFile, line_field(d.intensity_lines[i]),
                             "irradiance " + short_number(e) + " (intensity " + short_number(d.intensities[i][c]) + " x --irradiance-scale " +
                                 short_number(o.irradiance_scale) + ", channel " + std::to_string(c) + ") is out of range (0 or " +
                                 short_number(kMinIrradiance) + " to " + short_number(kMaxIrradiance) +
                                 ", full scale 1: docs/capture-format.md \"Ranges\")");
    }
    return light;
}

/// The file's first 4 bytes are glTF's binary magic.
bool is_glb(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    std::array<char, 4> magic{};
    return in.read(magic.data(), magic.size()) && std::string_view(magic.data(), magic.size()) == "glTF";
}

void copy_into(const fs::path& from, const fs::path& to, const std::string& field) {
    std::error_code ec;
    if (fs::exists(to, ec)) return; // a file that several rows name is copied once
    fs::create_directories(to.parent_path(), ec);
    if (!ec) fs::copy_file(from, to, ec);
    if (ec) throw InputError(from, field, "cannot copy it into the capture (" + to.string() + "): " + ec.message());
}

/// The images, the mask, the mesh and capture.json, into the staging folder `tmp`.
void write_capture_files(const PhotometricDataset& d, CaptureDesc desc, const Mesh& mesh, const fs::path& mesh_file,
                         const fs::path& tmp) {
    for (std::size_t i = 0; i < d.images.size(); ++i)
        copy_into(d.dir / d.images[i], tmp / desc.frames[i].file_path, d.image_fields[i]);
    copy_into(d.dir / d.mask, tmp / *desc.frames.front().mask_path, "mask");
    if (is_glb(mesh_file)) copy_into(mesh_file, tmp / desc.mesh_path, "--mesh");
    else write_mesh_glb(tmp / desc.mesh_path, mesh); // a .gltf's buffers lie beside it: one .glb holds it all
    desc.dir = tmp;
    write_capture_json(desc);
}

/// `p` under `out` instead of `staging` (where it is under `staging`).
fs::path as_output_path(const fs::path& p, const fs::path& staging, const fs::path& out) {
    const fs::path rel = fs::absolute(p).lexically_normal().lexically_relative(staging);
    if (rel.empty() || *rel.begin() == "..") return p;
    return rel == "." ? out : out / rel;
}

/// Loads the written capture as `specula validate --no-images` does; a refusal names the
/// output folder's file (the staging folder is removed with it), warnings are returned.
Capture verify_capture(const fs::path& staging, const fs::path& out) {
    CaptureLoadOptions load;
    load.load_images = false;
    try {
        return load_capture(staging, load);
    } catch (const InputError& e) {
        throw InputError(as_output_path(e.file(), staging, out), e.field(),
                         e.message() + " (in the capture being imported: nothing was written)");
    }
}

void replace_all(std::string& text, const std::string& from, const std::string& to) {
    for (std::size_t at = text.find(from); !from.empty() && at != std::string::npos; at = text.find(from, at + to.size()))
        text.replace(at, from.size(), to);
}

} // namespace

CaptureDesc photometric_capture_desc(const PhotometricDataset& d, const PhotometricImportOptions& o) {
    check_options(o, d.w, d.h);
    CaptureDesc desc;
    desc.mesh_path = "mesh.glb";
    desc.color_space = o.color_space;
    desc.saturation = o.saturation;
    const Intrinsics k{d.w, d.h, o.fl_x, o.fl_y.value_or(o.fl_x), o.cx.value_or(0.5 * d.w), o.cy.value_or(0.5 * d.h)};
    for (std::size_t i = 0; i < d.images.size(); ++i) {
        FrameDesc f;
        f.file_path = fs::path("images") / d.images[i];
        f.view_index = 0;
        f.transform = o.pose;
        f.intrinsics = k;
        f.light.directional = imported_light(d, i, o);
        f.mask_path = fs::path("masks") / d.mask;
        f.split = o.test_every > 0 && (i + 1) % static_cast<std::size_t>(o.test_every) == 0 ? Split::Test : Split::Train;
        desc.frames.push_back(std::move(f));
    }
    desc.extra["imported"] = {{"generator", "specula import photometric"},
                              {"dataset", folder_name(d.dir)},
                              {"mesh", o.mesh.filename().generic_string()},
                              {"irradiance_scale", o.irradiance_scale}};
    return desc;
}

PhotometricImportResult import_photometric(const fs::path& dir, const fs::path& out, const PhotometricImportOptions& options) {
    if (options.mesh.empty()) throw UsageError("--mesh is required: the object's mesh (.glb or .gltf), registered to the camera");
    const PhotometricDataset dataset = read_photometric_dataset(dir);
    const CaptureDesc desc = photometric_capture_desc(dataset, options);
    const MeshLoadResult mesh = load_mesh(options.mesh, "--mesh");
    // Every input is checked before the output folder is made; it may neither be nor hold them.
    OutputFolder folder(out, {.option = "--out", .force = options.force, .inputs = {dir, options.mesh}});
    write_capture_files(dataset, desc, mesh.mesh, options.mesh, folder.staging());
    const Capture capture = verify_capture(folder.staging(), folder.path());
    folder.commit();

    PhotometricImportResult r;
    r.dir = folder.path();
    r.frames = capture.desc.frames.size();
    r.test_frames = capture.frame_count(Split::Test);
    r.w = dataset.w;
    r.h = dataset.h;
    r.triangles = capture.mesh.triangle_count();
    r.warnings = capture.warnings;
    for (std::string& w : r.warnings) replace_all(w, folder.staging().string(), folder.path().string());
    return r;
}

} // namespace specula
