// Capture format version 1 (docs/capture-format.md): parsing and
// validating capture.json, decoding images and masks, writing capture.json back.
// Every refusal throws InputError(file, field, message).
#include "capture/capture.h"

#include "core/error.h"
#include "core/file_util.h"
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

namespace specula {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr const char* kFormatName = "specula-capture";
constexpr int kFormatVersion = 1;
// Deepest JSON nesting accepted (nlohmann's parser recurses; this keeps a hostile file from exhausting the stack).
constexpr int kMaxJsonDepth = 256;
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
    static const std::set<std::string> keys{"type", "position", "intensity"};
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
    // Last row 0 0 0 1.
    for (int col = 0; col < 4; ++col) {
        const double want = col == 3 ? 1.0 : 0.0;
        if (std::abs(m[col][3] - want) > kRigidTolerance) r.fail(field, "last row must be [0, 0, 0, 1]");
    }
    // Rotation: R^T R = I (orthonormal) and det R = +1 (no reflection, no scale).
    const glm::dmat3 rot(m);
    const glm::dmat3 rtr = glm::transpose(rot) * rot;
    double err = 0.0;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) err = std::max(err, std::abs(rtr[i][j] - (i == j ? 1.0 : 0.0)));
    if (err > kRigidTolerance) {
        std::ostringstream msg;
        msg << "not a rigid transform: the rotation part is not orthonormal (max |R^T R - I| = " << err
            << ", tolerance " << kRigidTolerance << ")";
        r.fail(field, msg.str());
    }
    const double det = glm::determinant(rot);
    if (std::abs(det - 1.0) > kRigidTolerance) {
        std::ostringstream msg;
        msg << "not a valid rotation: determinant " << det << " (must be +1; a reflection or scale is not allowed)";
        r.fail(field, msg.str());
    }
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

// Maximum bracket nesting of a JSON text, outside strings.
int json_depth(const std::string& text) {
    int depth = 0, max_depth = 0;
    bool in_string = false, escaped = false;
    for (const char ch : text) {
        if (in_string) {
            if (escaped) escaped = false;
            else if (ch == '\\') escaped = true;
            else if (ch == '"') in_string = false;
            continue;
        }
        if (ch == '"') in_string = true;
        else if (ch == '[' || ch == '{') max_depth = std::max(max_depth, ++depth);
        else if (ch == ']' || ch == '}') --depth;
    }
    return max_depth;
}

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

// Reads the colour channels of an image file. Unlike core's read_image this opens
// the file with unassociated alpha, so an alpha channel is truly ignored (OIIO
// would otherwise premultiply PNG colour by alpha), reads only the channels it
// needs, and decodes sRGB 8/16-bit files through a table.
// `expected` (w, h) is checked from the header, before any pixel memory is allocated.
RgbPixels read_rgb(const fs::path& path, ColorSpace encoding, int max_channels, const std::string& field,
                   const Intrinsics& expected, const char* what) {
    std::error_code ec;
    if (!fs::exists(path, ec)) throw InputError(path, field, "file not found");
    if (!fs::is_regular_file(path, ec)) throw InputError(path, field, "not a regular file");
    OIIO::ImageSpec config;
    config.attribute("oiio:UnassociatedAlpha", 1);
    auto in = OIIO::ImageInput::open(path.string(), &config);
    if (!in) {
        const std::string why = OIIO::geterror();
        throw InputError(path, field, "cannot read image" + (why.empty() ? std::string() : " (" + why + ")"));
    }
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

CaptureDesc parse_capture_desc(const json& j, const fs::path& json_path) {
    const JsonReader r(json_path);
    if (!j.is_object()) r.fail("", std::string("expected a JSON object at the top level, got ") + type_name(j));

    CaptureDesc desc;
    desc.dir = json_path.has_parent_path() ? json_path.parent_path() : fs::path(".");

    const std::string format = r.string(r.require(j, "format", ""), "format");
    if (format != kFormatName) r.fail("format", "expected \"" + std::string(kFormatName) + "\", got \"" + format + "\"");
    const json& version = r.require(j, "version", "");
    if (!version.is_number() || version.get<double>() != kFormatVersion)
        r.fail("version", "unsupported version " + version.dump() + " (this reader knows version " +
                              std::to_string(kFormatVersion) + ")");

    desc.mesh_path = r.string(r.require(j, "mesh_path", ""), "mesh_path");
    if (desc.mesh_path.empty()) r.fail("mesh_path", "empty path");

    if (const auto it = j.find("color_space"); it != j.end()) {
        const std::string cs = r.string(*it, "color_space");
        if (cs == "srgb") desc.color_space = ColorSpace::Srgb;
        else if (cs == "linear") desc.color_space = ColorSpace::Linear;
        else r.fail("color_space", "expected \"srgb\" or \"linear\", got \"" + cs + "\"");
    }
    if (const auto it = j.find("saturation"); it != j.end()) {
        const double s = r.number(*it, "saturation");
        if (!(s > 0.0)) r.fail("saturation", "must be positive");
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
        fd.file_path = r.string(r.require(f, "file_path", p + "."), p + ".file_path");
        if (fd.file_path.empty()) r.fail(p + ".file_path", "empty path");
        fd.view_index = r.integer(r.require(f, "view_index", p + "."), p + ".view_index");
        fd.transform = parse_transform(r, r.require(f, "transform_matrix", p + "."), p + ".transform_matrix");

        const json& light = r.require(f, "light", p + ".");
        const std::string lp = p + ".light";
        if (!light.is_object()) r.fail(lp, std::string("expected an object, got ") + type_name(light));
        const std::string type = r.string(r.require(light, "type", lp + "."), lp + ".type");
        if (type != "point") r.fail(lp + ".type", "expected \"point\", got \"" + type + "\"");
        fd.light.position = r.vec3(r.require(light, "position", lp + "."), lp + ".position");
        fd.light.intensity = r.vec3(r.require(light, "intensity", lp + "."), lp + ".intensity");
        for (int c = 0; c < 3; ++c)
            if (fd.light.intensity[c] < 0.0) r.fail(lp + ".intensity", "intensity must not be negative");
        for (const auto& [key, value] : light.items())
            if (!light_keys().count(key)) fd.light_extra[key] = value;

        if (const auto it = f.find("mask_path"); it != f.end()) {
            fd.mask_path = fs::path(r.string(*it, p + ".mask_path"));
            if (fd.mask_path->empty()) r.fail(p + ".mask_path", "empty path");
        }
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
    j["version"] = kFormatVersion;
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
        json light = {{"type", "point"},
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

Capture load_capture(const fs::path& dir_or_file, const CaptureLoadOptions& options) {
    const Stopwatch clock;
    const fs::path json_path = capture_json_path(dir_or_file);
    std::error_code ec;
    if (fs::exists(json_path, ec) && !fs::is_regular_file(json_path, ec))
        throw InputError(json_path, "", "not a regular file");
    const std::string text = read_text_file(json_path);
    if (json_depth(text) > kMaxJsonDepth)
        throw InputError(json_path, "", "malformed JSON: nesting deeper than " + std::to_string(kMaxJsonDepth));
    json j;
    try {
        j = json::parse(text);
    } catch (const json::parse_error& e) {
        throw InputError(json_path, "", "malformed JSON at " + line_column(text, e.byte) + ": " + e.what());
    } catch (const json::exception& e) {
        // e.g. out_of_range 406 "number overflow parsing '1e999'": locate the quoted token when possible.
        std::string where;
        const std::string what = e.what();
        const auto open = what.find('\''), close = what.rfind('\'');
        if (open != std::string::npos && close > open + 1) {
            const auto at = text.find(what.substr(open + 1, close - open - 1));
            if (at != std::string::npos) where = " at " + line_column(text, at + 1);
        }
        throw InputError(json_path, "", "malformed JSON" + where + ": " + what);
    }

    Capture capture;
    try {
        capture.desc = parse_capture_desc(j, json_path);
    } catch (const json::exception& e) { // defensive: every access above is type-checked
        throw InputError(json_path, "", std::string("invalid capture description: ") + e.what());
    }
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

    if (options.load_mesh) {
        MeshLoadResult m = load_mesh(desc.resolve(desc.mesh_path), "mesh_path");
        capture.mesh = std::move(m.mesh);
        capture.warnings.insert(capture.warnings.end(), m.warnings.begin(), m.warnings.end());
        const Bounds bounds = mesh_bounds(capture.mesh);
        std::vector<std::size_t> inside;
        for (std::size_t i = 0; i < desc.frames.size(); ++i)
            if (bounds.contains(desc.frames[i].light.position)) inside.push_back(i);
        if (!inside.empty())
            capture.warnings.push_back(std::to_string(inside.size()) + " frame(s) have their light inside the mesh's " +
                                       "bounding box (first: " + frame_prefix(inside.front()) + ".light.position)");
    }

    // Masks: each distinct file decoded once (a view's frames usually share one).
    std::vector<fs::path> mask_files;
    std::map<fs::path, std::size_t> mask_slot;
    std::vector<std::size_t> mask_first_frame;
    for (std::size_t i = 0; i < desc.frames.size(); ++i) {
        if (!desc.frames[i].mask_path) continue;
        const fs::path p = desc.resolve(*desc.frames[i].mask_path);
        if (mask_slot.emplace(p, mask_files.size()).second) {
            mask_files.push_back(p);
            mask_first_frame.push_back(i);
        }
    }
    auto mask_of = [&](std::size_t frame) -> std::optional<std::size_t> {
        if (!desc.frames[frame].mask_path) return std::nullopt;
        return mask_slot.at(desc.resolve(*desc.frames[frame].mask_path));
    };
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
            const ImageFileInfo info = read_image_info(mask_files[m], frame_prefix(mask_first_frame[m]) + ".mask_path");
            (void)info;
        });
        parallel_for(desc.frames.size(), threads, [&](std::size_t i) {
            const std::string field = frame_prefix(i) + ".file_path";
            const fs::path file = desc.resolve(desc.frames[i].file_path);
            const ImageFileInfo info = read_image_info(file, field);
            check_size(i, info.width, info.height, file, field, "image");
            if (const auto m = mask_of(i)) {
                const ImageFileInfo mi = read_image_info(mask_files[*m], frame_prefix(i) + ".mask_path");
                check_size(i, mi.width, mi.height, mask_files[*m], frame_prefix(i) + ".mask_path", "mask");
            }
        });
    } else {
        std::vector<DecodedMask> masks(mask_files.size());
        parallel_for(mask_files.size(), threads, [&](std::size_t m) {
            const std::size_t first = mask_first_frame[m];
            masks[m] = decode_mask(mask_files[m], frame_prefix(first) + ".mask_path", desc.frames[first].intrinsics);
        });
        capture.images.resize(desc.frames.size());
        parallel_for(desc.frames.size(), threads, [&](std::size_t i) {
            const FrameDesc& f = desc.frames[i];
            const std::string field = frame_prefix(i) + ".file_path";
            const fs::path file = desc.resolve(f.file_path);
            const RgbPixels src = read_rgb(file, desc.color_space, 3, field, f.intrinsics, "image");
            const DecodedMask* mask = nullptr;
            if (const auto m = mask_of(i)) {
                mask = &masks[*m];
                check_size(i, mask->width, mask->height, mask_files[*m], frame_prefix(i) + ".mask_path", "mask");
            }

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
                bool finite = true;
                for (int c = 0; c < 3; ++c) {
                    const float v = in[map[c]];
                    finite = finite && std::isfinite(v);
                    dst[c] = v;
                    if (v >= sat) flag |= static_cast<std::uint8_t>(kClippedR << c);
                }
                if (!finite) {
                    dst[0] = dst[1] = dst[2] = 0.0f;
                    flag = kMissing; // a missing pixel carries no value to be clipped
                    ++out.missing_pixels;
                }
                if (mask && !mask->inside[p]) flag |= kOutsideMask;
                out.flags[p] = flag;
            }
        });
        for (std::size_t i = 0; i < capture.images.size(); ++i)
            if (capture.images[i].missing_pixels > 0)
                capture.warnings.push_back(frame_prefix(i) + " (" + desc.frames[i].file_path.generic_string() +
                                           "): " + std::to_string(capture.images[i].missing_pixels) +
                                           " pixel(s) with non-finite values, treated as missing");
    }

    capture.load_seconds = clock.seconds();
    return capture;
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
    std::set<std::tuple<double, double, double>> lights;
    for (const FrameDesc& f : desc.frames) lights.emplace(f.light.position.x, f.light.position.y, f.light.position.z);
    s << "lights:      " << lights.size() << " distinct position" << (lights.size() == 1 ? "" : "s") << "\n";
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
