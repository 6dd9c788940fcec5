// Capture format versions 1 and 1.1 (docs/capture-format.md): parsing and
// validating capture.json, decoding images and masks, writing capture.json back.
// Every refusal throws InputError(file, field, message).
#include "capture/capture.h"

#include "core/error.h"
#include "core/format.h"
#include "core/file_util.h"
#include "core/image_input.h"
#include "core/json_guard.h"
#include "core/memory.h"
#include "core/parallel.h"
#include "core/timer.h"

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <new>
#include <set>
#include <sstream>
#include <tuple>

namespace specula {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr const char* kFormatName = "specula-capture";
constexpr double kFormatVersion = 1.0;
constexpr double kFormatVersionDirectional = 1.1; // version 1 and directional lights
// Intrinsics of frames of one view must agree to this relative tolerance.
constexpr double kIntrinsicsTolerance = 1e-6;

const std::set<std::string>& top_level_keys() {
    static const std::set<std::string> keys{"format", "version", "mesh_path", "color_space", "saturation", "w", "h",
                                            "fl_x",   "fl_y",    "cx",        "cy",          "frames",     "ground_truth"};
    return keys;
}
const std::set<std::string>& frame_keys() {
    static const std::set<std::string> keys{"file_path", "view_index", "transform_matrix", "light", "mask_path", "split",
                                            "w",         "h",          "fl_x",             "fl_y",  "cx",        "cy"};
    return keys;
}
const std::set<std::string>& light_keys() {
    static const std::set<std::string> keys{"type", "position", "intensity", "direction", "irradiance"};
    return keys;
}

const char* type_name(const json& v) {
    switch (v.type()) {
    case json::value_t::null: return "null";
    case json::value_t::object: return "an object";
    case json::value_t::array: return "an array";
    case json::value_t::string: return "a string";
    case json::value_t::boolean: return "a boolean";
    case json::value_t::binary: return "binary data";
    case json::value_t::discarded: return "nothing";
    default: return "a number";
    }
}

std::string out_of_range(double v, const std::string& range, const std::string& why) {
    return short_number(v) + " is out of range (" + range + ": " + why + ", docs/capture-format.md \"Ranges\")";
}

/// Typed access to capture.json with errors naming the file and the field.
class JsonReader {
public:
    explicit JsonReader(const fs::path& file) : m_file(file) {}

    [[noreturn]] void fail(const std::string& field, const std::string& message) const {
        throw InputError(m_file, field, message);
    }

    double number(const json& v, const std::string& field) const {
        if (!v.is_number()) fail(field, std::string("expected a number, got ") + type_name(v));
        const double d = v.get<double>();
        if (!std::isfinite(d)) fail(field, "number is not finite");
        return d;
    }

    int integer(const json& v, const std::string& field) const {
        const double d = number(v, field);
        if (d != std::floor(d) || d < std::numeric_limits<int>::min() || d > std::numeric_limits<int>::max())
            fail(field, "expected an integer, got " + v.dump());
        return static_cast<int>(d);
    }

    std::string string(const json& v, const std::string& field) const {
        if (!v.is_string()) fail(field, std::string("expected a string, got ") + type_name(v));
        return v.get<std::string>();
    }

    glm::dvec3 vec3(const json& v, const std::string& field) const {
        if (!v.is_array() || v.size() != 3) fail(field, "expected an array of 3 numbers");
        return {number(v[0], field + "[0]"), number(v[1], field + "[1]"), number(v[2], field + "[2]")};
    }

    /// A point of the scene: every coordinate within +-kMaxWorldCoordinate.
    glm::dvec3 point(const json& v, const std::string& field) const {
        const glm::dvec3 p = vec3(v, field);
        for (int c = 0; c < 3; ++c)
            if (std::abs(p[c]) > kMaxWorldCoordinate)
                fail(field + "[" + std::to_string(c) + "]", out_of_range(p[c], "|coordinate| <= " + short_number(kMaxWorldCoordinate),
                                                                     "coordinates are squared in float"));
        return p;
    }

    /// A relative path inside the capture's folder: not empty, no NUL (which would cut the
    /// path short where the C library opens it), not absolute, and no ".." that leaves the folder.
    fs::path relative_path(const json& v, const std::string& field) const {
        const std::string text = string(v, field);
        if (text.empty()) fail(field, "empty path");
        if (text.find('\0') != std::string::npos)
            fail(field, "the path contains a NUL character (it would be cut short there)");
        const fs::path path(text);
        if (path.has_root_path())
            fail(field, "\"" + text + "\" is an absolute path: every file of a capture is named relative to the folder of capture.json");
        const fs::path normal = path.lexically_normal();
        if (normal.empty() || *normal.begin() == "..")
            fail(field, "\"" + text + "\" leaves the capture's folder (every file of a capture must be inside it)");
        return path;
    }

    const json& require(const json& obj, const std::string& key, const std::string& prefix) const {
        const auto it = obj.find(key);
        if (it == obj.end()) fail(prefix + key, "missing (required)");
        return *it;
    }

    const fs::path& file() const { return m_file; }

private:
    const fs::path& m_file;
};

// Row-major nested 4x4 list -> glm (column-major) matrix, checked to be rigid with a proper rotation.
} // namespace

std::optional<TransformProblem> transform_problem(const glm::dmat4& m) {
    // Last row 0 0 0 1.
    for (int col = 0; col < 4; ++col) {
        const double want = col == 3 ? 1.0 : 0.0;
        if (!(std::abs(m[col][3] - want) <= kRigidTolerance)) return TransformProblem{"", "last row must be [0, 0, 0, 1]"};
    }
    // Rotation: R^T R = I (orthonormal) and det R = +1 (no reflection, no scale).
    const glm::dmat3 rot(m);
    const glm::dmat3 rtr = glm::transpose(rot) * rot;
    double err = 0.0;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) err = std::max(err, std::abs(rtr[i][j] - (i == j ? 1.0 : 0.0)));
    if (!(err <= kRigidTolerance)) {
        std::ostringstream msg;
        msg << "not a rigid transform: the rotation part is not orthonormal (max |R^T R - I| = " << err
            << ", tolerance " << kRigidTolerance << ")";
        return TransformProblem{"", msg.str()};
    }
    const double det = glm::determinant(rot);
    if (!(std::abs(det - 1.0) <= kRigidTolerance)) {
        std::ostringstream msg;
        msg << "not a valid rotation: determinant " << det << " (must be +1; a reflection or scale is not allowed)";
        return TransformProblem{"", msg.str()};
    }
    // The camera centre: a point of the scene like any other.
    for (int row = 0; row < 3; ++row)
        if (!(std::abs(m[3][row]) <= kMaxWorldCoordinate))
            return TransformProblem{"[" + std::to_string(row) + "][3]",
                                    out_of_range(m[3][row], "|translation| <= " + short_number(kMaxWorldCoordinate),
                                                 "camera centres are points of the scene, whose coordinates are squared in float")};
    return std::nullopt;
}

namespace {

glm::dmat4 parse_transform(const JsonReader& r, const json& v, const std::string& field) {
    if (!v.is_array() || v.size() != 4) r.fail(field, "expected a 4x4 matrix (4 rows of 4 numbers)");
    glm::dmat4 m(1.0);
    for (int row = 0; row < 4; ++row) {
        const json& rv = v[static_cast<std::size_t>(row)];
        if (!rv.is_array() || rv.size() != 4) r.fail(field, "expected a 4x4 matrix (4 rows of 4 numbers)");
        for (int col = 0; col < 4; ++col)
            m[col][row] = r.number(rv[static_cast<std::size_t>(col)],
                                   field + "[" + std::to_string(row) + "][" + std::to_string(col) + "]");
    }
    if (const std::optional<TransformProblem> p = transform_problem(m)) r.fail(field + p->entry, p->message);
    return m;
}

struct IntrinsicsSource {
    std::optional<int> w, h;
    std::optional<double> fl_x, fl_y, cx, cy;
};

IntrinsicsSource parse_intrinsics(const JsonReader& r, const json& obj, const std::string& prefix) {
    IntrinsicsSource s;
    auto get_size = [&](const char* key) -> std::optional<int> {
        const auto it = obj.find(key);
        if (it == obj.end()) return std::nullopt;
        const int v = r.integer(*it, prefix + key);
        if (v <= 0) r.fail(prefix + key, "image size must be positive, got " + std::to_string(v));
        if (v > kMaxImageDimension)
            r.fail(prefix + key, "image size " + std::to_string(v) + " is above the largest accepted (" +
                                     std::to_string(kMaxImageDimension) + ", what the renderer's devices hold)");
        return v;
    };
    auto get_focal = [&](const char* key) -> std::optional<double> {
        const auto it = obj.find(key);
        if (it == obj.end()) return std::nullopt;
        const double v = r.number(*it, prefix + key);
        if (!(v > 0.0)) r.fail(prefix + key, "focal length must be positive, got " + it->dump());
        return v;
    };
    auto get_center = [&](const char* key) -> std::optional<double> {
        const auto it = obj.find(key);
        if (it == obj.end()) return std::nullopt;
        return r.number(*it, prefix + key);
    };
    s.w = get_size("w");
    s.h = get_size("h");
    s.fl_x = get_focal("fl_x");
    s.fl_y = get_focal("fl_y");
    s.cx = get_center("cx");
    s.cy = get_center("cy");
    return s;
}

bool poses_agree(const glm::dmat4& a, const glm::dmat4& b) {
    for (int c = 0; c < 3; ++c)
        for (int rr = 0; rr < 3; ++rr)
            if (std::abs(a[c][rr] - b[c][rr]) > kPoseAgreementTolerance) return false;
    const glm::dvec3 ta(a[3]), tb(b[3]);
    return glm::length(ta - tb) <= kPoseAgreementTolerance * std::max(1.0, glm::length(ta));
}

bool intrinsics_agree(const Intrinsics& a, const Intrinsics& b) {
    auto near = [](double x, double y) { return std::abs(x - y) <= kIntrinsicsTolerance * std::max(1.0, std::abs(x)); };
    return a.w == b.w && a.h == b.h && near(a.fl_x, b.fl_x) && near(a.fl_y, b.fl_y) && near(a.cx, b.cx) &&
           near(a.cy, b.cy);
}

std::string frame_prefix(std::size_t i) { return "frames[" + std::to_string(i) + "]"; }

std::string line_column(const std::string& text, std::size_t byte) {
    byte = std::min(byte, text.size());
    std::size_t line = 1, col = 1;
    for (std::size_t i = 0; i + 1 < byte; ++i) {
        if (text[i] == '\n') {
            ++line;
            col = 1;
        } else {
            ++col;
        }
    }
    return "line " + std::to_string(line) + ", column " + std::to_string(col);
}

// Pixels of a capture image: the first `channels` (at most 3) channels, linear float.
struct RgbPixels {
    int width = 0;
    int height = 0;
    int channels = 0; // 1 (gray: replicate) or 3
    std::vector<float> values;
    ImageFileInfo info;
};

// sRGB decoding tables for 8- and 16-bit files, built once (srgb_to_linear, exact per code value).
const std::vector<float>& srgb_table(int bits) {
    static const std::vector<float> t8 = [] {
        std::vector<float> t(256);
        for (std::size_t i = 0; i < t.size(); ++i) t[i] = srgb_to_linear(static_cast<float>(i) / 255.0f);
        return t;
    }();
    static const std::vector<float> t16 = [] {
        std::vector<float> t(65536);
        for (std::size_t i = 0; i < t.size(); ++i) t[i] = srgb_to_linear(static_cast<float>(i) / 65535.0f);
        return t;
    }();
    return bits == 8 ? t8 : t16;
}

// Reads the colour channels of an image file, opened as core's readers open it
// (open_image_file: alpha unassociated, the EXR header walked first). Unlike core's
// read_image it reads only the channels it needs and decodes sRGB 8/16-bit files through
// a table.
// `expected` (w, h) is checked from the header, before any pixel memory is allocated.
RgbPixels read_rgb(const fs::path& path, ColorSpace encoding, int max_channels, const std::string& field,
                   const Intrinsics& expected, const char* what) {
    auto in = open_image_file(path, field);
    const OIIO::ImageSpec& spec = in->spec();
    RgbPixels px;
    px.width = spec.width;
    px.height = spec.height;
    px.info.width = spec.width;
    px.info.height = spec.height;
    px.info.channels = spec.nchannels;
    const auto base = spec.format.basetype;
    px.info.is_float = base == OIIO::TypeDesc::FLOAT || base == OIIO::TypeDesc::HALF || base == OIIO::TypeDesc::DOUBLE;
    px.info.bits_per_channel = static_cast<int>(spec.format.size() * 8);
    if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0 || spec.depth > 1)
        throw InputError(path, field, "image has no pixels");
    if (spec.width != expected.w || spec.height != expected.h)
        throw InputError(path, field,
                         std::string(what) + " is " + std::to_string(spec.width) + " x " + std::to_string(spec.height) +
                             " but the frame's w x h is " + std::to_string(expected.w) + " x " +
                             std::to_string(expected.h));
    px.channels = spec.nchannels >= 3 && max_channels >= 3 ? 3 : 1;
    const std::size_t count =
        static_cast<std::size_t>(spec.width) * static_cast<std::size_t>(spec.height) * static_cast<std::size_t>(px.channels);
    try {
        px.values.resize(count);
    } catch (const std::bad_alloc&) {
        throw InputError(path, field, "image too large to decode");
    }
    auto decode_failed = [&] {
        const std::string why = in->geterror();
        throw InputError(path, field, "cannot decode image" + (why.empty() ? std::string() : " (" + why + ")"));
    };
    const bool table = !px.info.is_float && encoding == ColorSpace::Srgb &&
                       (base == OIIO::TypeDesc::UINT8 || base == OIIO::TypeDesc::UINT16);
    if (table && base == OIIO::TypeDesc::UINT8) {
        std::vector<std::uint8_t> raw(count);
        if (!in->read_image(0, 0, 0, px.channels, OIIO::TypeDesc::UINT8, raw.data())) decode_failed();
        const std::vector<float>& t = srgb_table(8);
        for (std::size_t i = 0; i < count; ++i) px.values[i] = t[raw[i]];
    } else if (table) {
        std::vector<std::uint16_t> raw(count);
        if (!in->read_image(0, 0, 0, px.channels, OIIO::TypeDesc::UINT16, raw.data())) decode_failed();
        const std::vector<float>& t = srgb_table(16);
        for (std::size_t i = 0; i < count; ++i) px.values[i] = t[raw[i]];
    } else {
        // Integer data is converted to [0, 1] without a transfer function; float data is kept.
        if (!in->read_image(0, 0, 0, px.channels, OIIO::TypeDesc::FLOAT, px.values.data())) decode_failed();
        if (!px.info.is_float && encoding == ColorSpace::Srgb)
            for (float& v : px.values) v = srgb_to_linear(v);
    }
    // OpenImageIO records an error when the decoder ran out of data or met corrupt data and
    // made up what it could not read (libjpeg fills the missing rows of a truncated JPEG
    // with grey): those pixels were never measured, so the file is refused.
    if (in->has_error())
        throw InputError(path, field, "the image decoded only in part (" + in->geterror() +
                                          "): the file is truncated or corrupt");
    in->close();
    return px;
}

struct DecodedMask {
    int width = 0;
    int height = 0;
    std::vector<std::uint8_t> inside; // 1 where the object is
};

DecodedMask decode_mask(const fs::path& path, const std::string& field, const Intrinsics& expected) {
    const RgbPixels img = read_rgb(path, ColorSpace::Linear, 1, field, expected, "mask");
    DecodedMask m;
    m.width = img.width;
    m.height = img.height;
    m.inside.resize(static_cast<std::size_t>(img.width) * static_cast<std::size_t>(img.height));
    for (std::size_t p = 0; p < m.inside.size(); ++p) {
        const float v = img.values[p]; // first channel
        m.inside[p] = (std::isfinite(v) && v != 0.0f) ? 1 : 0;
    }
    return m;
}

} // namespace

std::size_t Capture::frame_count(Split split) const {
    return static_cast<std::size_t>(
        std::count_if(desc.frames.begin(), desc.frames.end(), [&](const FrameDesc& f) { return f.split == split; }));
}

fs::path capture_json_path(const fs::path& dir_or_file) {
    std::error_code ec;
    if (fs::is_directory(dir_or_file, ec)) return dir_or_file / "capture.json";
    return dir_or_file;
}

namespace {

/// A frame's "light" (docs/capture-format.md "Lights"): a point light, or with version 1.1 a
/// directional one (its stand-in is placed once the mesh is known: place_directional_lights).
PointLight parse_light(const JsonReader& r, const json& light, const std::string& lp, bool v1_1) {
    const std::string type = r.string(r.require(light, "type", lp + "."), lp + ".type");
    PointLight out;
    if (type == "directional") {
        if (!v1_1)
            r.fail(lp + ".type", "directional lights need \"version\": 1.1 (version 1 knows only \"point\")");
        for (const char* key : {"position", "intensity"})
            if (light.contains(key))
                r.fail(lp + "." + key, std::string("a directional light has no ") + key +
                                           " (give \"direction\", toward the light, and \"irradiance\")");
        DirectionalLight d;
        const glm::dvec3 dir = r.vec3(r.require(light, "direction", lp + "."), lp + ".direction");
        const double len = glm::length(dir);
        if (!(len > 0.0) || !std::isfinite(len))
            r.fail(lp + ".direction", "the direction must be a nonzero vector (from the object toward the light), got [" +
                                          short_number(dir.x) + ", " + short_number(dir.y) + ", " + short_number(dir.z) + "]");
        d.direction = dir / len;
        d.irradiance = r.vec3(r.require(light, "irradiance", lp + "."), lp + ".irradiance");
        for (int c = 0; c < 3; ++c) {
            const std::string field = lp + ".irradiance[" + std::to_string(c) + "]";
            if (d.irradiance[c] < 0.0) r.fail(field, "irradiance must not be negative");
            if (d.irradiance[c] > kMaxIrradiance)
                r.fail(field, out_of_range(d.irradiance[c], "<= " + short_number(kMaxIrradiance),
                                           "full scale 1; the diffuse solve squares irradiances in float"));
            if (d.irradiance[c] > 0.0 && d.irradiance[c] < kMinIrradiance)
                r.fail(field, out_of_range(d.irradiance[c], "0 or >= " + short_number(kMinIrradiance),
                                           "full scale 1; the diffuse solve squares irradiances in float"));
        }
        out.directional = d;
        return out;
    }
    if (type != "point")
        r.fail(lp + ".type", std::string("expected \"point\"") + (v1_1 ? " or \"directional\"" : "") + ", got \"" + type + "\"");
    if (v1_1)
        for (const char* key : {"direction", "irradiance"})
            if (light.contains(key))
                r.fail(lp + "." + key, std::string("a point light has no ") + key +
                                           " (give \"position\" and \"intensity\", or make it \"directional\")");
    out.position = r.point(r.require(light, "position", lp + "."), lp + ".position");
    out.intensity = r.vec3(r.require(light, "intensity", lp + "."), lp + ".intensity");
    for (int c = 0; c < 3; ++c) {
        if (out.intensity[c] < 0.0) r.fail(lp + ".intensity", "intensity must not be negative");
        if (out.intensity[c] > kMaxLightIntensity)
            r.fail(lp + ".intensity[" + std::to_string(c) + "]",
                   out_of_range(out.intensity[c], "<= " + short_number(kMaxLightIntensity),
                                "the engine computes with intensities as floats"));
    }
    return out;
}

} // namespace

PointLight directional_stand_in(const DirectionalLight& light, const Bounds& bounds) {
    const glm::dvec3 lo(bounds.min), hi(bounds.max);
    const double distance = kDirectionalStandIn * glm::length(hi - lo);
    PointLight p;
    p.position = 0.5 * (lo + hi) + distance * light.direction;
    p.intensity = light.irradiance * (distance * distance);
    p.directional = light;
    return p;
}

void place_directional_lights(CaptureDesc& desc, const Mesh& mesh) {
    const Bounds bounds = mesh_bounds(mesh);
    for (FrameDesc& f : desc.frames)
        if (f.light.directional) f.light = directional_stand_in(*f.light.directional, bounds);
}

CaptureDesc parse_capture_desc(const json& j, const fs::path& json_path) {
    const JsonReader r(json_path);
    if (!j.is_object()) r.fail("", std::string("expected a JSON object at the top level, got ") + type_name(j));

    CaptureDesc desc;
    desc.dir = json_path.has_parent_path() ? json_path.parent_path() : fs::path(".");
    desc.json_file = json_path;

    const std::string format = r.string(r.require(j, "format", ""), "format");
    if (format != kFormatName) r.fail("format", "expected \"" + std::string(kFormatName) + "\", got \"" + format + "\"");
    const json& version = r.require(j, "version", "");
    if (!version.is_number() || (version.get<double>() != kFormatVersion && version.get<double>() != kFormatVersionDirectional))
        r.fail("version", "unsupported version " + version.dump() + " (this reader knows versions 1 and 1.1)");
    const bool v1_1 = version.get<double>() == kFormatVersionDirectional;

    desc.mesh_path = r.relative_path(r.require(j, "mesh_path", ""), "mesh_path");

    if (const auto it = j.find("color_space"); it != j.end()) {
        const std::string cs = r.string(*it, "color_space");
        if (cs == "srgb") desc.color_space = ColorSpace::Srgb;
        else if (cs == "linear") desc.color_space = ColorSpace::Linear;
        else r.fail("color_space", "expected \"srgb\" or \"linear\", got \"" + cs + "\"");
    }
    if (const auto it = j.find("saturation"); it != j.end()) {
        const double s = r.number(*it, "saturation");
        if (!(s > 0.0)) r.fail("saturation", "must be positive");
        if (s < kMinSaturation || s > kMaxSaturation)
            r.fail("saturation", out_of_range(s, "[" + short_number(kMinSaturation) + ", " + short_number(kMaxSaturation) + "]",
                                              "it is compared with pixel values as a float"));
        desc.saturation = s;
    }
    const IntrinsicsSource top = parse_intrinsics(r, j, "");

    const json& frames = r.require(j, "frames", "");
    if (!frames.is_array()) r.fail("frames", std::string("expected an array, got ") + type_name(frames));
    if (frames.empty()) r.fail("frames", "no frames");

    // Which intrinsics some frame gives, to name the right field when one is missing.
    auto any_frame_has = [&](const char* key) {
        return std::any_of(frames.begin(), frames.end(), [&](const json& f) { return f.is_object() && f.contains(key); });
    };

    desc.frames.reserve(frames.size());
    for (std::size_t i = 0; i < frames.size(); ++i) {
        const json& f = frames[i];
        const std::string p = frame_prefix(i);
        if (!f.is_object()) r.fail(p, std::string("expected an object, got ") + type_name(f));
        FrameDesc fd;
        fd.file_path = r.relative_path(r.require(f, "file_path", p + "."), p + ".file_path");
        fd.view_index = r.integer(r.require(f, "view_index", p + "."), p + ".view_index");
        fd.transform = parse_transform(r, r.require(f, "transform_matrix", p + "."), p + ".transform_matrix");

        const json& light = r.require(f, "light", p + ".");
        const std::string lp = p + ".light";
        if (!light.is_object()) r.fail(lp, std::string("expected an object, got ") + type_name(light));
        fd.light = parse_light(r, light, lp, v1_1);
        for (const auto& [key, value] : light.items())
            if (!light_keys().count(key) || (!v1_1 && (key == "direction" || key == "irradiance")))
                fd.light_extra[key] = value; // version 1 had no directional lights: those keys were unknown

        if (const auto it = f.find("mask_path"); it != f.end()) fd.mask_path = r.relative_path(*it, p + ".mask_path");
        if (const auto it = f.find("split"); it != f.end()) {
            const std::string split = r.string(*it, p + ".split");
            if (split == "train") fd.split = Split::Train;
            else if (split == "test") fd.split = Split::Test;
            else r.fail(p + ".split", "expected \"train\" or \"test\", got \"" + split + "\"");
        }

        const IntrinsicsSource own = parse_intrinsics(r, f, p + ".");
        auto resolve = [&](const auto& mine, const auto& global, const char* key) {
            if (mine) return *mine;
            if (global) return *global;
            if (any_frame_has(key)) r.fail(p + "." + key, "missing here and at the top level");
            r.fail(key, "missing (required at the top level or in every frame)");
        };
        fd.intrinsics.w = resolve(own.w, top.w, "w");
        fd.intrinsics.h = resolve(own.h, top.h, "h");
        fd.intrinsics.fl_x = resolve(own.fl_x, top.fl_x, "fl_x");
        fd.intrinsics.fl_y = resolve(own.fl_y, top.fl_y, "fl_y");
        fd.intrinsics.cx = resolve(own.cx, top.cx, "cx");
        fd.intrinsics.cy = resolve(own.cy, top.cy, "cy");
        // Ranges that depend on the image size: named where the value was given.
        const double size = std::max(fd.intrinsics.w, fd.intrinsics.h);
        auto check_focal = [&](double v, bool own_value, const char* key) {
            const std::string field = own_value ? p + "." + key : std::string(key);
            if (v < kMinFocalRelative * size)
                r.fail(field, out_of_range(v, ">= " + short_number(kMinFocalRelative) + " x max(w, h) = " +
                                                  short_number(kMinFocalRelative * size) + " pixels",
                                           "a field of view below 180 degrees"));
            if (v > kMaxFocalLength)
                r.fail(field, out_of_range(v, "<= " + short_number(kMaxFocalLength) + " pixels",
                                           "float positions must project to well under a pixel"));
        };
        auto check_center = [&](double v, bool own_value, const char* key) {
            if (std::abs(v) > kMaxPrincipalPointRelative * size)
                r.fail(own_value ? p + "." + key : std::string(key),
                       out_of_range(v, "|value| <= " + short_number(kMaxPrincipalPointRelative) + " x max(w, h)",
                                    "a principal point that far off the image is an error"));
        };
        check_focal(fd.intrinsics.fl_x, own.fl_x.has_value(), "fl_x");
        check_focal(fd.intrinsics.fl_y, own.fl_y.has_value(), "fl_y");
        check_center(fd.intrinsics.cx, own.cx.has_value(), "cx");
        check_center(fd.intrinsics.cy, own.cy.has_value(), "cy");

        for (const auto& [key, value] : f.items())
            if (!frame_keys().count(key)) fd.extra[key] = value;
        desc.frames.push_back(std::move(fd));
    }

    // Frames of one view share one camera: pose and intrinsics must agree with the view's first frame.
    std::map<int, std::size_t> first_of_view;
    for (std::size_t i = 0; i < desc.frames.size(); ++i) {
        const FrameDesc& f = desc.frames[i];
        const auto [it, inserted] = first_of_view.emplace(f.view_index, i);
        if (inserted) continue;
        const FrameDesc& first = desc.frames[it->second];
        if (!poses_agree(first.transform, f.transform))
            r.fail(frame_prefix(i) + ".transform_matrix",
                   "pose differs from " + frame_prefix(it->second) + " of the same view_index " +
                       std::to_string(f.view_index) + " (tolerance " + std::to_string(kPoseAgreementTolerance) + ")");
        if (!intrinsics_agree(first.intrinsics, f.intrinsics))
            r.fail(frame_prefix(i), "intrinsics differ from " + frame_prefix(it->second) + " of the same view_index " +
                                        std::to_string(f.view_index));
    }

    if (const auto it = j.find("ground_truth"); it != j.end()) desc.ground_truth = *it;
    for (const auto& [key, value] : j.items())
        if (!top_level_keys().count(key)) desc.extra[key] = value;
    return desc;
}

float effective_saturation(const CaptureDesc& desc, const ImageFileInfo& file) {
    if (desc.saturation) return static_cast<float>(*desc.saturation);
    return file.is_float ? std::numeric_limits<float>::infinity() : 1.0f;
}

json capture_desc_to_json(const CaptureDesc& desc) {
    json j = json::object();
    j["format"] = kFormatName;
    const bool directional =
        std::any_of(desc.frames.begin(), desc.frames.end(), [](const FrameDesc& f) { return f.light.directional.has_value(); });
    j["version"] = directional ? kFormatVersionDirectional : kFormatVersion;
    j["mesh_path"] = desc.mesh_path.generic_string();
    j["color_space"] = desc.color_space == ColorSpace::Srgb ? "srgb" : "linear";
    if (desc.saturation) j["saturation"] = *desc.saturation;

    const Intrinsics base = desc.frames.empty() ? Intrinsics{} : desc.frames.front().intrinsics;
    if (!desc.frames.empty()) {
        j["w"] = base.w;
        j["h"] = base.h;
        j["fl_x"] = base.fl_x;
        j["fl_y"] = base.fl_y;
        j["cx"] = base.cx;
        j["cy"] = base.cy;
    }
    json frames = json::array();
    for (const FrameDesc& f : desc.frames) {
        json fj = json::object();
        fj["file_path"] = f.file_path.generic_string();
        fj["view_index"] = f.view_index;
        json m = json::array();
        for (int row = 0; row < 4; ++row) m.push_back({f.transform[0][row], f.transform[1][row], f.transform[2][row], f.transform[3][row]});
        fj["transform_matrix"] = std::move(m);
        json light;
        if (const auto& d = f.light.directional)
            light = {{"type", "directional"},
                     {"direction", {d->direction.x, d->direction.y, d->direction.z}},
                     {"irradiance", {d->irradiance.x, d->irradiance.y, d->irradiance.z}}};
        else
            light = {{"type", "point"},
                     {"position", {f.light.position.x, f.light.position.y, f.light.position.z}},
                     {"intensity", {f.light.intensity.x, f.light.intensity.y, f.light.intensity.z}}};
        if (f.light_extra.is_object())
            for (const auto& [key, value] : f.light_extra.items())
                if (!light.contains(key)) light[key] = value;
        fj["light"] = std::move(light);
        if (f.mask_path) fj["mask_path"] = f.mask_path->generic_string();
        fj["split"] = f.split == Split::Train ? "train" : "test";
        const Intrinsics& k = f.intrinsics;
        if (k.w != base.w) fj["w"] = k.w;
        if (k.h != base.h) fj["h"] = k.h;
        if (k.fl_x != base.fl_x) fj["fl_x"] = k.fl_x;
        if (k.fl_y != base.fl_y) fj["fl_y"] = k.fl_y;
        if (k.cx != base.cx) fj["cx"] = k.cx;
        if (k.cy != base.cy) fj["cy"] = k.cy;
        if (f.extra.is_object())
            for (const auto& [key, value] : f.extra.items())
                if (!fj.contains(key)) fj[key] = value;
        frames.push_back(std::move(fj));
    }
    j["frames"] = std::move(frames);
    if (!desc.ground_truth.is_null()) j["ground_truth"] = desc.ground_truth;
    if (desc.extra.is_object())
        for (const auto& [key, value] : desc.extra.items())
            if (!j.contains(key)) j[key] = value;
    return j;
}

void write_capture_json(const CaptureDesc& desc) {
    write_text_file(desc.dir / "capture.json", capture_desc_to_json(desc).dump(2) + "\n");
}

CaptureDesc parse_capture_text(std::string_view text, const fs::path& json_path) {
    const std::string_view view = text;
    // Checked on the text, before a parser builds the document (core/json_guard.h): nesting
    // (the parser recurses) and duplicate keys (readers disagree on which value counts).
    if (const std::optional<std::string> deep = json_too_deep(view, kMaxCaptureJsonDepth))
        throw InputError(json_path, *deep, "JSON nested deeper than " + std::to_string(kMaxCaptureJsonDepth) +
                                               " levels (refused before parsing)");
    const std::string copy(text); // line_column and the parser's messages index the text
    const JsonKeyReport keys = check_json_keys(view);
    if (!keys.duplicate_field.empty())
        throw InputError(json_path, keys.duplicate_field,
                         "duplicate JSON key (readers disagree on which value counts: this one would keep the last)");
    if (!keys.error.empty())
        throw InputError(json_path, "", "malformed JSON at " + line_column(copy, keys.error_byte) + ": " + keys.error);
    json j;
    try {
        j = json::parse(copy);
    } catch (const json::exception& e) { // defensive: the SAX pass above accepted the same text
        throw InputError(json_path, "", std::string("malformed JSON: ") + e.what());
    }
    try {
        return parse_capture_desc(j, json_path);
    } catch (const json::exception& e) { // defensive: every access is type-checked
        throw InputError(json_path, "", std::string("invalid capture description: ") + e.what());
    }
}

std::uint64_t decoded_image_bytes(const CaptureDesc& desc, int threads) {
    std::uint64_t total = 0, largest = 0;
    std::set<fs::path> images, masks;
    for (const FrameDesc& f : desc.frames) {
        const std::uint64_t pixels = static_cast<std::uint64_t>(f.intrinsics.w) * static_cast<std::uint64_t>(f.intrinsics.h);
        total += pixels * (3 * sizeof(float) + 1); // FrameImage: linear RGB and one flag byte a pixel
        largest = std::max(largest, pixels);
        images.insert(desc.resolve(f.file_path).lexically_normal());
        if (f.mask_path && masks.insert(desc.resolve(*f.mask_path).lexically_normal()).second) total += pixels;
    }
    // Files decoded at the same time: each holds its float values and its raw 8/16-bit codes
    // (3 channels: 12 + 6 bytes a pixel) until its frames are filled.
    const std::uint64_t concurrent = std::min<std::uint64_t>(static_cast<std::uint64_t>(std::max(1, threads)), images.size());
    return total + concurrent * largest * 18;
}

namespace {

// Whether canonical path `child` lies inside canonical folder `parent`.
bool inside_folder(const fs::path& child, const fs::path& parent) {
    auto c = child.begin();
    for (auto p = parent.begin(); p != parent.end(); ++p, ++c)
        if (c == child.end() || *c != *p) return false;
    return c != child.end();
}

// A file of the capture must resolve inside its folder: the paths were checked to stay
// inside it (JsonReader::relative_path), and a symbolic link may not lead out either (as
// glTF URIs, capture/gltf_io.h). A path that does not resolve is left to the reader, which
// says "file not found".
void check_inside_capture(const fs::path& root, const fs::path& file, const std::string& field) {
    std::error_code ec;
    const fs::path resolved = fs::canonical(file, ec);
    if (ec) return;
    if (!inside_folder(resolved, root))
        throw InputError(file, field, "a symbolic link that leads outside the capture's folder (to " + resolved.string() + ")");
}

// The point of triangle abc closest to p: the Voronoi-region walk of Ericson, "Real-Time
// Collision Detection" (2005), section 5.1.5 (vertex regions, then edge regions, then the face).
glm::dvec3 closest_on_triangle(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c) {
    const glm::dvec3 ab = b - a, ac = c - a;
    const glm::dvec3 ap = p - a;
    const double d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
    if (d1 <= 0.0 && d2 <= 0.0) return a;
    const glm::dvec3 bp = p - b;
    const double d3 = glm::dot(ab, bp), d4 = glm::dot(ac, bp);
    if (d3 >= 0.0 && d4 <= d3) return b;
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) return a + ab * (d1 / (d1 - d3));
    const glm::dvec3 cp = p - c;
    const double d5 = glm::dot(ab, cp), d6 = glm::dot(ac, cp);
    if (d6 >= 0.0 && d5 <= d6) return c;
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) return a + ac * (d2 / (d2 - d6));
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0) return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    const double inv = 1.0 / (va + vb + vc);
    return a + ab * (vb * inv) + ac * (vc * inv);
}

double distance_to_mesh(const glm::dvec3& p, const Mesh& mesh) {
    double best = std::numeric_limits<double>::infinity();
    for (const glm::uvec3& t : mesh.triangles) {
        const glm::dvec3 q = closest_on_triangle(p, glm::dvec3(mesh.positions[t.x]), glm::dvec3(mesh.positions[t.y]),
                                                 glm::dvec3(mesh.positions[t.z]));
        best = std::min(best, glm::length(p - q));
    }
    return best;
}

double distance_to_box(const glm::dvec3& p, const glm::dvec3& lo, const glm::dvec3& hi) {
    const glm::dvec3 outside = glm::max(glm::max(lo - p, p - hi), glm::dvec3(0.0));
    return glm::length(outside);
}

double farthest_box_corner(const glm::dvec3& p, const glm::dvec3& lo, const glm::dvec3& hi) {
    return glm::length(glm::max(glm::abs(p - lo), glm::abs(p - hi)));
}

// Whether view `camera` can see any of the box: false when every corner is behind the
// camera, or all are in front and their projections miss the image. (A box that straddles
// the camera plane may be seen.)
bool box_may_be_seen(const Camera& camera, const glm::dvec3& lo, const glm::dvec3& hi) {
    glm::dvec2 pmin(std::numeric_limits<double>::infinity()), pmax(-std::numeric_limits<double>::infinity());
    int in_front = 0;
    for (int k = 0; k < 8; ++k) {
        const glm::dvec3 corner((k & 1) ? hi.x : lo.x, (k & 2) ? hi.y : lo.y, (k & 4) ? hi.z : lo.z);
        const std::optional<glm::dvec2> q = camera.project(corner);
        if (!q) continue;
        ++in_front;
        pmin = glm::min(pmin, *q);
        pmax = glm::max(pmax, *q);
    }
    if (in_front == 0) return false;
    if (in_front < 8) return true;
    const Intrinsics& k = camera.intrinsics;
    return pmax.x >= 0.0 && pmax.y >= 0.0 && pmin.x <= k.w && pmin.y <= k.h;
}

std::string list_first(const std::vector<std::string>& items, std::size_t n) {
    std::string s;
    for (std::size_t i = 0; i < items.size() && i < n; ++i) s += (i ? ", " : "") + items[i];
    if (items.size() > n) s += ", ...";
    return s;
}

} // namespace

std::vector<std::string> check_capture_scene(const CaptureDesc& desc, const std::vector<View>& views, const Mesh& mesh,
                                             const fs::path& mesh_file) {
    std::vector<std::string> warnings;
    const fs::path& json_file = desc.json_file.empty() ? desc.dir / "capture.json" : desc.json_file;
    const Bounds bounds = mesh_bounds(mesh);
    const glm::dvec3 lo(bounds.min), hi(bounds.max);
    for (int c = 0; c < 3; ++c) {
        const double extreme = std::max(std::abs(lo[c]), std::abs(hi[c]));
        if (extreme > kMaxWorldCoordinate)
            throw InputError(mesh_file, "mesh_path",
                             "a vertex coordinate of " + short_number(std::abs(lo[c]) > std::abs(hi[c]) ? lo[c] : hi[c]) +
                                 " is out of range (|coordinate| <= " + short_number(kMaxWorldCoordinate) +
                                 ": coordinates are squared in float, docs/capture-format.md \"Ranges\")");
    }
    const double size = glm::length(hi - lo); // D, the object's size
    if (size < kMinMeshDiagonal)
        throw InputError(mesh_file, "mesh_path",
                         "the mesh's bounding box diagonal is " + short_number(size) + ", below " + short_number(kMinMeshDiagonal) +
                             " (distances a 10,000th of it are squared in float, docs/capture-format.md \"Ranges\")");
    const glm::dvec3 centre = 0.5 * (lo + hi);
    // Float coordinates are spaced |x| 2^-23 apart; rays leave the surface 1e-4 D away from it
    // (RayScene::kRayOffsetRelative), so beyond 100 D from the origin the spacing is an eighth of that.
    if (glm::length(centre) > 100.0 * size)
        warnings.push_back("the mesh lies " + short_number(glm::length(centre) / size) +
                           " times its size from the origin: its float coordinates are spaced " +
                           short_number(glm::length(centre) * std::ldexp(1.0, -23) / size) +
                           " of its size apart there; move the scene (mesh, cameras, lights) near the origin");

    const double far = kMaxDistanceToObject * size;
    auto far_message = [&](const char* what, double distance) {
        return std::string(what) + " is " + short_number(distance) + " from the mesh's centre, " +
               short_number(distance / size) + " times the mesh's size (" + short_number(size) + "), beyond " +
               short_number(kMaxDistanceToObject) + " times (docs/capture-format.md \"Ranges\")";
    };
    std::vector<std::string> blind, blind_train;
    for (const View& v : views) {
        if (v.frames.empty()) continue;
        const std::string field = "frames[" + std::to_string(v.frames.front()) + "].transform_matrix";
        const double distance = glm::length(v.camera.center() - centre);
        if (distance > far)
            throw InputError(json_file, field,
                             far_message("the camera centre", distance) +
                                 ": the whole mesh would fit in one pixel (are the mesh and the poses in the same unit?)");
        if (!box_may_be_seen(v.camera, lo, hi)) {
            const std::string name = "view_index " + std::to_string(v.view_index) + " (frames[" + std::to_string(v.frames.front()) + "])";
            blind.push_back(name);
            if (std::any_of(v.frames.begin(), v.frames.end(), [&](std::size_t f) { return desc.frames[f].split == Split::Train; }))
                blind_train.push_back(name);
        }
    }
    const std::size_t train_views = static_cast<std::size_t>(std::count_if(views.begin(), views.end(), [&](const View& v) {
        return std::any_of(v.frames.begin(), v.frames.end(), [&](std::size_t f) { return desc.frames[f].split == Split::Train; });
    }));
    if (!blind.empty()) {
        std::string w = std::to_string(blind.size()) + " of " + std::to_string(views.size()) +
                        " views cannot see the mesh (it is behind the camera or outside the image): " + list_first(blind, 5);
        if (train_views > 0 && blind_train.size() == train_views)
            w += "; no train view sees it, so nothing can be reconstructed (do the poses and the mesh share one "
                 "coordinate frame and unit?)";
        warnings.push_back(w);
    }

    // Lights: within reach, off the surface, irradiance within range.
    struct Reach {
        double nearest = 0.0, farthest = 0.0;
    };
    std::map<std::tuple<double, double, double>, Reach> reach; // per distinct position
    std::size_t dark_frames = 0;
    std::optional<std::size_t> first_dark;
    glm::bvec3 channel_lit(false);
    for (std::size_t i = 0; i < desc.frames.size(); ++i) {
        const FrameDesc& f = desc.frames[i];
        const std::string lp = "frames[" + std::to_string(i) + "].light";
        if (const auto& d = f.light.directional) { // its irradiance was range-checked when parsed
            for (int c = 0; c < 3; ++c) channel_lit[c] = channel_lit[c] || (d->irradiance[c] > 0.0 && f.split == Split::Train);
            if (d->irradiance.x <= 0.0 && d->irradiance.y <= 0.0 && d->irradiance.z <= 0.0) {
                ++dark_frames;
                if (!first_dark) first_dark = i;
            }
            continue;
        }
        const glm::dvec3 p = f.light.position;
        const double distance = glm::length(p - centre);
        if (distance > far)
            throw InputError(json_file, lp + ".position",
                             far_message("the light", distance) + ": move it to 1e5 times the size in the same direction, "
                                                                  "with its intensity scaled by the squared ratio of the distances");
        auto [it, added] = reach.try_emplace({p.x, p.y, p.z});
        if (added) {
            const double box = distance_to_box(p, lo, hi);
            // The box's distance bounds the surface's from below; near or inside the box, measure the surface.
            it->second.nearest = box >= kMinLightDistanceRelative * size ? box : distance_to_mesh(p, mesh);
            it->second.farthest = farthest_box_corner(p, lo, hi);
        }
        const Reach& r = it->second;
        if (r.nearest < kMinLightDistanceRelative * size)
            throw InputError(json_file, lp + ".position",
                             "the light is " + short_number(r.nearest) + " from the mesh's surface, below " +
                                 short_number(kMinLightDistanceRelative) + " times the mesh's size: the irradiance I / d^2 "
                                                                           "has no bound there (docs/capture-format.md \"Ranges\")");
        const glm::dvec3 I = f.light.intensity;
        const double peak = std::max({I.x, I.y, I.z}) / (r.nearest * r.nearest);
        if (peak > kMaxIrradiance)
            throw InputError(json_file, lp + ".intensity",
                             "gives the mesh an irradiance I / d^2 of up to " + short_number(peak) + " (d = " +
                                 short_number(r.nearest) + " at the nearest point), above " + short_number(kMaxIrradiance) +
                                 " (full scale 1; the diffuse solve squares irradiances in float, docs/capture-format.md "
                                 "\"Ranges\")");
        for (int c = 0; c < 3; ++c) {
            if (I[c] <= 0.0) continue;
            channel_lit[c] = channel_lit[c] || f.split == Split::Train;
            const double low = I[c] / (r.farthest * r.farthest);
            if (low < kMinIrradiance)
                throw InputError(json_file, lp + ".intensity[" + std::to_string(c) + "]",
                                 "gives the mesh an irradiance I / d^2 as low as " + short_number(low) + " (d = " +
                                     short_number(r.farthest) + " at the farthest point), below " +
                                     short_number(kMinIrradiance) +
                                     " (full scale 1; the diffuse solve squares irradiances in float, "
                                     "docs/capture-format.md \"Ranges\")");
        }
        if (I.x <= 0.0 && I.y <= 0.0 && I.z <= 0.0) {
            ++dark_frames;
            if (!first_dark) first_dark = i;
        }
    }
    if (dark_frames > 0)
        warnings.push_back(std::to_string(dark_frames) + " frame(s) have a light of intensity 0 in every channel (first: frames[" +
                           std::to_string(*first_dark) + "].light.intensity): they light nothing and carry no information");
    const bool any_train = std::any_of(desc.frames.begin(), desc.frames.end(), [](const FrameDesc& f) { return f.split == Split::Train; });
    static const char* const kChannel[3] = {"red", "green", "blue"};
    for (int c = 0; c < 3; ++c)
        if (any_train && !channel_lit[c])
            warnings.push_back(std::string("no train frame lights the ") + kChannel[c] + " channel (light.intensity[" +
                               std::to_string(c) + "] is 0 in every one): its albedo cannot be recovered");
    return warnings;
}

namespace {

CaptureDesc read_capture_file(const fs::path& json_path) {
    std::error_code ec;
    if (fs::exists(json_path, ec)) {
        if (!fs::is_regular_file(json_path, ec)) throw InputError(json_path, "", "not a regular file");
        const std::uintmax_t bytes = fs::file_size(json_path, ec);
        if (!ec && bytes > kMaxCaptureJsonBytes)
            throw InputError(json_path, "", "the file holds " + format_bytes(bytes) + ", above the " +
                                                format_bytes(kMaxCaptureJsonBytes) + " a capture description may take");
    }
    return parse_capture_text(read_text_file(json_path), json_path);
}

// The mesh and the checks that need it (with `keep`), and the stand-ins of directional lights
// (capture.h PointLight), which are placed about the mesh whether it is kept or not.
void load_capture_mesh(Capture& capture, bool keep) {
    const CaptureDesc& desc = capture.desc;
    const bool directional =
        std::any_of(desc.frames.begin(), desc.frames.end(), [](const FrameDesc& f) { return f.light.directional.has_value(); });
    if (!keep && !directional) return;
    const fs::path mesh_file = desc.resolve(desc.mesh_path);
    MeshLoadResult m = load_mesh(mesh_file, "mesh_path");
    place_directional_lights(capture.desc, m.mesh);
    if (!keep) return;
    capture.mesh = std::move(m.mesh);
    capture.warnings.insert(capture.warnings.end(), m.warnings.begin(), m.warnings.end());
    const std::vector<std::string> scene = check_capture_scene(desc, capture.views, capture.mesh, mesh_file);
    capture.warnings.insert(capture.warnings.end(), scene.begin(), scene.end());
    const Bounds bounds = mesh_bounds(capture.mesh);
    std::vector<std::size_t> inside;
    for (std::size_t i = 0; i < desc.frames.size(); ++i)
        if (!desc.frames[i].light.directional && bounds.contains(desc.frames[i].light.position)) inside.push_back(i);
    if (!inside.empty())
        capture.warnings.push_back(std::to_string(inside.size()) + " frame(s) have their light inside the mesh's " +
                                   "bounding box (first: " + frame_prefix(inside.front()) + ".light.position)");
}

Capture load_capture_unguarded(const fs::path& json_path, const CaptureLoadOptions& options) {
    const Stopwatch clock;
    std::error_code ec;
    Capture capture;
    capture.desc = read_capture_file(json_path);
    const CaptureDesc& desc = capture.desc;

    // Views, sorted by view_index, frames in file order.
    std::map<int, std::size_t> view_of;
    for (std::size_t i = 0; i < desc.frames.size(); ++i) view_of.emplace(desc.frames[i].view_index, 0);
    for (auto& [index, slot] : view_of) {
        slot = capture.views.size();
        View v;
        v.view_index = index;
        capture.views.push_back(std::move(v));
    }
    for (std::size_t i = 0; i < desc.frames.size(); ++i) {
        View& v = capture.views[view_of[desc.frames[i].view_index]];
        if (v.frames.empty()) v.camera = desc.frames[i].camera();
        v.frames.push_back(i);
    }

    // Every file the capture names resolves inside its folder.
    const fs::path root = fs::weakly_canonical(fs::absolute(desc.dir, ec), ec);
    check_inside_capture(root, desc.resolve(desc.mesh_path), "mesh_path");

    load_capture_mesh(capture, options.load_mesh);

    // Image files and masks: each distinct file decoded once, whatever frames name it (a
    // view's frames usually share one mask; a converter may name one image many times).
    struct SharedFile {
        fs::path path;
        std::vector<std::size_t> frames; // that name it, in file order
    };
    std::vector<SharedFile> image_files, mask_files;
    std::map<fs::path, std::size_t> image_slot, mask_slot;
    std::vector<std::optional<std::size_t>> mask_of(desc.frames.size());
    for (std::size_t i = 0; i < desc.frames.size(); ++i) {
        const fs::path p = desc.resolve(desc.frames[i].file_path).lexically_normal();
        const auto [it, added] = image_slot.emplace(p, image_files.size());
        if (added) {
            check_inside_capture(root, p, frame_prefix(i) + ".file_path");
            image_files.push_back({p, {}});
        }
        image_files[it->second].frames.push_back(i);
        if (!desc.frames[i].mask_path) continue;
        const fs::path m = desc.resolve(*desc.frames[i].mask_path).lexically_normal();
        const auto [mt, madded] = mask_slot.emplace(m, mask_files.size());
        if (madded) {
            check_inside_capture(root, m, frame_prefix(i) + ".mask_path");
            mask_files.push_back({m, {}});
        }
        mask_files[mt->second].frames.push_back(i);
        mask_of[i] = mt->second;
    }
    auto check_size = [&](std::size_t frame, int width, int height, const fs::path& file, const std::string& field,
                          const char* what) {
        const Intrinsics& k = desc.frames[frame].intrinsics;
        if (width != k.w || height != k.h)
            throw InputError(file, field,
                             std::string(what) + " is " + std::to_string(width) + " x " + std::to_string(height) +
                                 " but the frame's w x h is " + std::to_string(k.w) + " x " + std::to_string(k.h));
    };

    // Decoding errors are deterministic: parallel_for rethrows the lowest failing index's,
    // the one a single thread would have met first.
    const unsigned threads = static_cast<unsigned>(std::max(1, options.threads));
    if (!options.load_images) {
        parallel_for(mask_files.size(), threads, [&](std::size_t m) {
            for (const std::size_t i : mask_files[m].frames) {
                const std::string field = frame_prefix(i) + ".mask_path";
                const ImageFileInfo info = read_image_info(mask_files[m].path, field);
                check_size(i, info.width, info.height, mask_files[m].path, field, "mask");
            }
        });
        parallel_for(image_files.size(), threads, [&](std::size_t k) {
            for (const std::size_t i : image_files[k].frames) {
                const std::string field = frame_prefix(i) + ".file_path";
                const ImageFileInfo info = read_image_info(image_files[k].path, field);
                check_size(i, info.width, info.height, image_files[k].path, field, "image");
            }
        });
        capture.load_seconds = clock.seconds();
        return capture;
    }

    // Refused before any pixel is decoded when the decoded images cannot fit.
    const std::uint64_t need = decoded_image_bytes(desc, options.threads);
    const MemoryAvailable have = options.memory_available ? MemoryAvailable{*options.memory_available, "the memory allowed"}
                                                          : available_memory();
    if (need > have.bytes) {
        int largest_w = 0, largest_h = 0;
        for (const FrameDesc& f : desc.frames)
            if (std::int64_t(f.intrinsics.w) * f.intrinsics.h > std::int64_t(largest_w) * largest_h) {
                largest_w = f.intrinsics.w;
                largest_h = f.intrinsics.h;
            }
        throw InputError(json_path, "",
                         "the decoded images need " + format_bytes(need) + " (" + std::to_string(desc.frames.size()) +
                             " frames of up to " + std::to_string(largest_w) + " x " + std::to_string(largest_h) +
                             " pixels, 13 bytes a pixel as linear float RGB and flags, plus decoding buffers) but " +
                             format_bytes(have.bytes) + " is available (" + have.limit +
                             "); use smaller images or fewer frames (`specula validate --no-images` checks the "
                             "capture without decoding its images)");
    }

    std::vector<DecodedMask> masks(mask_files.size());
    parallel_for(mask_files.size(), threads, [&](std::size_t m) {
        const std::size_t first = mask_files[m].frames.front();
        masks[m] = decode_mask(mask_files[m].path, frame_prefix(first) + ".mask_path", desc.frames[first].intrinsics);
        for (const std::size_t i : mask_files[m].frames)
            check_size(i, masks[m].width, masks[m].height, mask_files[m].path, frame_prefix(i) + ".mask_path", "mask");
    });
    capture.images.resize(desc.frames.size());
    parallel_for(image_files.size(), threads, [&](std::size_t k) {
        const std::size_t first = image_files[k].frames.front();
        const RgbPixels src = read_rgb(image_files[k].path, desc.color_space, 3, frame_prefix(first) + ".file_path",
                                       desc.frames[first].intrinsics, "image");
        for (const std::size_t i : image_files[k].frames) {
            check_size(i, src.width, src.height, image_files[k].path, frame_prefix(i) + ".file_path", "image");
            const DecodedMask* mask = mask_of[i] ? &masks[*mask_of[i]] : nullptr;
            FrameImage& out = capture.images[i];
            out.saturation = effective_saturation(desc, src.info);
            out.file_info = src.info;
            const std::size_t pixels = static_cast<std::size_t>(src.width) * static_cast<std::size_t>(src.height);
            out.color = Image(src.width, src.height, 3);
            out.flags.assign(pixels, 0);
            const std::size_t sc = static_cast<std::size_t>(src.channels);
            // Gray (with or without alpha) is replicated to RGB; alpha and extra channels were not read.
            const std::size_t map[3] = {0, sc >= 3 ? 1u : 0u, sc >= 3 ? 2u : 0u};
            const float sat = out.saturation;
            for (std::size_t p = 0; p < pixels; ++p) {
                const float* in = src.values.data() + p * sc;
                float* dst = out.color.pixels.data() + p * 3;
                std::uint8_t flag = 0;
                bool usable = true;
                for (int c = 0; c < 3; ++c) {
                    const float v = in[map[c]];
                    // Non-finite, or beyond the range the solve multiplies by irradiances (kMaxPixelMagnitude).
                    usable = usable && std::isfinite(v) && std::abs(v) <= kMaxPixelMagnitude;
                    dst[c] = v;
                    if (v >= sat) flag |= static_cast<std::uint8_t>(kClippedR << c);
                }
                if (!usable) {
                    dst[0] = dst[1] = dst[2] = 0.0f;
                    flag = kMissing; // a missing pixel carries no value to be clipped
                    ++out.missing_pixels;
                }
                if (mask && !mask->inside[p]) flag |= kOutsideMask;
                out.flags[p] = flag;
            }
        }
    });
    capture.image_files_decoded = image_files.size();
    for (std::size_t i = 0; i < capture.images.size(); ++i)
        if (capture.images[i].missing_pixels > 0)
            capture.warnings.push_back(frame_prefix(i) + " (" + desc.frames[i].file_path.generic_string() +
                                       "): " + std::to_string(capture.images[i].missing_pixels) +
                                       " pixel(s) with non-finite values (or beyond +-" +
                                       short_number(kMaxPixelMagnitude) + "), treated as missing");
    // Masks that cover nothing: the frames that use them see nothing.
    std::vector<std::string> empty_masks;
    std::size_t frames_blind = 0;
    for (std::size_t m = 0; m < masks.size(); ++m)
        if (std::none_of(masks[m].inside.begin(), masks[m].inside.end(), [](std::uint8_t v) { return v != 0; })) {
            const std::size_t first = mask_files[m].frames.front();
            empty_masks.push_back(frame_prefix(first) + ".mask_path (" + desc.frames[first].mask_path->generic_string() + ")");
            frames_blind += mask_files[m].frames.size();
        }
    if (!empty_masks.empty()) {
        std::string w = std::to_string(empty_masks.size()) + " of " + std::to_string(masks.size()) +
                        " mask file(s) are empty (no pixel inside the object): " + list_first(empty_masks, 3) + "; the " +
                        std::to_string(frames_blind) + " frame(s) that use them see nothing";
        if (frames_blind == desc.frames.size()) w += ": no frame sees the object, so nothing can be reconstructed";
        capture.warnings.push_back(w);
    }

    capture.load_seconds = clock.seconds();
    return capture;
}

} // namespace

Capture load_capture(const fs::path& dir_or_file, const CaptureLoadOptions& options) {
    const fs::path json_path = capture_json_path(dir_or_file);
    try {
        return load_capture_unguarded(json_path, options);
    } catch (const std::bad_alloc&) {
        // The last resort: an allocation the checks above did not foresee. Never a bare std::bad_alloc.
        throw InputError(json_path, "", "out of memory while loading the capture (" + format_bytes(available_memory().bytes) +
                                            " available now); use smaller images or fewer frames");
    }
}

CaptureDesc read_capture_desc(const fs::path& dir_or_file) { return read_capture_file(capture_json_path(dir_or_file)); }

std::vector<fs::path> capture_input_paths(const CaptureDesc& desc) {
    // The folder holds capture.json; "" (capture.json named without a folder) is the working directory.
    std::vector<fs::path> paths{desc.dir.empty() ? fs::path(".") : desc.dir, desc.resolve(desc.mesh_path)};
    std::set<fs::path> seen(paths.begin(), paths.end());
    const auto add = [&](const fs::path& p) {
        if (seen.insert(p).second) paths.push_back(p);
    };
    for (const FrameDesc& f : desc.frames) {
        add(desc.resolve(f.file_path));
        if (f.mask_path) add(desc.resolve(*f.mask_path));
    }
    return paths;
}

std::string summarize(const Capture& capture) {
    const CaptureDesc& desc = capture.desc;
    std::ostringstream s;
    s << "capture:     " << desc.dir.string() << "\n";
    std::size_t min_per_view = std::numeric_limits<std::size_t>::max(), max_per_view = 0;
    for (const View& v : capture.views) {
        min_per_view = std::min(min_per_view, v.frames.size());
        max_per_view = std::max(max_per_view, v.frames.size());
    }
    s << "views:       " << capture.views.size();
    if (!capture.views.empty()) {
        s << " (" << min_per_view;
        if (max_per_view != min_per_view) s << " to " << max_per_view;
        s << " frame" << (max_per_view == 1 ? "" : "s") << " per view)";
    }
    s << "\n";
    s << "frames:      " << desc.frames.size() << " (train " << capture.frame_count(Split::Train) << ", test "
      << capture.frame_count(Split::Test) << ")\n";
    std::set<std::pair<int, int>> sizes;
    for (const FrameDesc& f : desc.frames) sizes.emplace(f.intrinsics.w, f.intrinsics.h);
    s << "image size:  ";
    bool first = true;
    for (const auto& [w, h] : sizes) {
        s << (first ? "" : ", ") << w << " x " << h;
        first = false;
    }
    s << "\n";
    std::set<std::tuple<double, double, double>> lights, directions;
    for (const FrameDesc& f : desc.frames) {
        if (const auto& d = f.light.directional) directions.emplace(d->direction.x, d->direction.y, d->direction.z);
        else lights.emplace(f.light.position.x, f.light.position.y, f.light.position.z);
    }
    s << "lights:      ";
    if (!lights.empty()) s << lights.size() << " distinct position" << (lights.size() == 1 ? "" : "s");
    if (!lights.empty() && !directions.empty()) s << ", ";
    if (!directions.empty()) s << directions.size() << " distinct direction" << (directions.size() == 1 ? "" : "s") << " (directional)";
    s << "\n";
    s << "color space: " << (desc.color_space == ColorSpace::Srgb ? "srgb" : "linear") << ", saturation ";
    if (desc.saturation) s << *desc.saturation;
    else s << "default (1.0 for integer files, none for float files)";
    s << "\n";
    s << "mesh:        " << desc.mesh_path.generic_string();
    if (!capture.mesh.triangles.empty())
        s << " (" << capture.mesh.triangle_count() << " triangles, " << capture.mesh.positions.size() << " vertices)";
    else s << " (not loaded)";
    s << "\n";
    if (capture.images.empty()) {
        s << "images:      headers checked, not decoded\n";
    } else {
        std::size_t missing = 0, clipped = 0;
        for (const FrameImage& im : capture.images) {
            missing += im.missing_pixels;
            clipped += static_cast<std::size_t>(std::count_if(
                im.flags.begin(), im.flags.end(), [](std::uint8_t f) { return (f & kClippedAny) != 0; }));
        }
        s << "images:      " << capture.images.size() << " decoded (" << clipped << " clipped pixels, " << missing
          << " missing)\n";
    }
    s << "warnings:    " << capture.warnings.size() << "\n";
    for (const std::string& w : capture.warnings) s << "  - " << w << "\n";
    std::ostringstream t;
    t.setf(std::ios::fixed);
    t.precision(3);
    t << capture.load_seconds;
    s << "load time:   " << t.str() << " s\n";
    return s.str();
}

} // namespace specula
