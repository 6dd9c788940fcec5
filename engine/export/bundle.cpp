// The output bundle (pipeline.md section 10): a glTF 2.0 binary (Khronos glTF 2.0
// specification: 4.4 "GLB File Format", 3.6 buffers/bufferViews, 3.7 meshes, 3.9
// materials, 3.8 textures/images) plus the SPECULA_lafortune material extension,
// specified in docs/SPECULA_lafortune.md.
//
// Writing builds the JSON and the BIN chunk directly (as write_mesh_glb does). Reading
// parses the GLB container here (nlohmann::json for the JSON chunk) and range-checks every
// index, offset and count before it is dereferenced; a .glb without the extension is read
// through load_mesh (all nodes, transforms applied) plus its base colour texture.
#include "export/bundle.h"

#include "core/error.h"
#include "core/file_util.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>
#include <tiny_gltf.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <tuple>

namespace specula {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr const char* kExtension = "SPECULA_lafortune";
// Version 1: one factorization term (cubeG, cubeH). Version 2 adds cubeTerms (terms 2..K);
// a bundle is written as version 1 when it has one term, so older readers still load it.
// Version 3 adds "parametrization": "mirrored" (shared/gshd.h part 4), written only for such
// cube-maps, which a version 1 or 2 reader would look up wrongly: it refuses version 3 instead.
// Version 4 adds "parametrization": "warped" with its "warp" (shared/gshd.h part 5), written
// only for such cube-maps (they hold the lobe over its radial factor): older readers refuse it.
constexpr int kExtensionVersion = 4;
constexpr std::size_t kMaxExtraTerms = 3; // K <= 4 (render::kMaxFactorTerms)

constexpr std::uint32_t kGlbMagic = 0x46546C67u;  // "glTF"
constexpr std::uint32_t kChunkJson = 0x4E4F534Au; // "JSON"
constexpr std::uint32_t kChunkBin = 0x004E4942u;  // "BIN\0"
constexpr int kArrayBuffer = 34962, kElementArrayBuffer = 34963;
constexpr int kLinear = 9729, kClampToEdge = 33071;
// Normals whose length is within this of 1 are written unchanged (so unit normals
// round-trip bit-exactly); others are renormalized (glTF requires unit NORMALs).

// ---------------------------------------------------------------------------------------------
// The metallic-roughness approximation (docs/SPECULA_lafortune.md, "Viewer approximation").
//
// A Phong-like cosine lobe of exponent N and a GGX (Trowbridge-Reitz) lobe of width alpha
// have about the same highlight when alpha^2 = 2 / (N + 2) (Walter et al. 2007,
// "Microfacet models for refraction through rough surfaces", section 5.2: the Beckmann
// m^2 = 2 / (N + 2) correspondence, used for GGX as well), and glTF's roughness is
// sqrt(alpha) (glTF 2.0 specification, appendix B: alpha = roughness^2).
// The exponent is the mean of the three channels'. No lobe: roughness 1 (matte).
float roughness_from_lobe(const std::optional<LafortuneRgb>& lobe) {
    if (!lobe || lobe->is_zero()) return 1.0f;
    const double n = (static_cast<double>(lobe->n.x) + lobe->n.y + lobe->n.z) / 3.0;
    if (!(n > 0.0)) return 1.0f;
    const double alpha = std::sqrt(2.0 / (n + 2.0));
    return static_cast<float>(std::clamp(std::sqrt(alpha), 0.0, 1.0));
}

json vec3_json(const glm::vec3& v) {
    return json::array({static_cast<double>(v.x), static_cast<double>(v.y), static_cast<double>(v.z)});
}

bool finite3(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

// ---------------------------------------------------------------------------------------------
// PNG in memory through OpenImageIO's IOProxy.

std::vector<unsigned char> encode_srgb_png(const Image& albedo, const fs::path& file) {
    const std::size_t texels = static_cast<std::size_t>(albedo.width) * albedo.height;
    std::vector<std::uint8_t> rgb(texels * 3);
    for (std::size_t i = 0; i < texels; ++i)
        for (int c = 0; c < 3; ++c) {
            const int src = std::min(c, albedo.channels - 1); // grey: replicate
            float v = albedo.pixels[i * albedo.channels + src];
            v = std::isfinite(v) ? std::clamp(v, 0.0f, 1.0f) : 0.0f;
            rgb[i * 3 + c] = static_cast<std::uint8_t>(std::lround(linear_to_srgb(v) * 255.0f));
        }
    std::vector<unsigned char> bytes;
    OIIO::Filesystem::IOVecOutput proxy(bytes);
    auto out = OIIO::ImageOutput::create("png");
    if (!out) throw InputError(file, "albedo", "cannot create a PNG encoder: " + OIIO::geterror());
    OIIO::ImageSpec spec(albedo.width, albedo.height, 3, OIIO::TypeDesc::UINT8);
    void* proxy_ptr = &proxy;
    spec.attribute("oiio:ioproxy", OIIO::TypeDesc::PTR, &proxy_ptr);
    spec.attribute("oiio:ColorSpace", "sRGB");
    if (!out->open("base_color.png", spec) || !out->write_image(OIIO::TypeDesc::UINT8, rgb.data()) || !out->close())
        throw InputError(file, "albedo", "PNG encoding failed: " + out->geterror());
    return bytes;
}

/// Decodes an 8-bit (or 16-bit) PNG/JPEG held in memory to linear RGB (sRGB decoded; alpha dropped).
Image decode_srgb_image(std::span<const std::uint8_t> bytes, const std::string& mime, const fs::path& file,
                        const std::string& field) {
    const std::string name = mime == "image/jpeg" ? "base_color.jpg" : "base_color.png";
    OIIO::Filesystem::IOMemReader proxy(const_cast<std::uint8_t*>(bytes.data()), bytes.size());
    auto in = OIIO::ImageInput::open(name, nullptr, &proxy);
    if (!in) throw InputError(file, field, "cannot decode the image: " + OIIO::geterror());
    const OIIO::ImageSpec& spec = in->spec();
    const int w = spec.width, h = spec.height, nc = spec.nchannels;
    if (w <= 0 || h <= 0 || nc <= 0) throw InputError(file, field, "empty image");
    std::vector<float> px(static_cast<std::size_t>(w) * h * nc);
    if (!in->read_image(0, 0, 0, nc, OIIO::TypeDesc::FLOAT, px.data()))
        throw InputError(file, field, "cannot decode the image: " + in->geterror());
    Image out(w, h, 3);
    for (std::size_t i = 0; i < static_cast<std::size_t>(w) * h; ++i)
        for (int c = 0; c < 3; ++c)
            out.pixels[i * 3 + c] = srgb_to_linear(px[i * nc + std::min(c, nc >= 3 ? c : 0)]);
    return out;
}

// ---------------------------------------------------------------------------------------------
// Reading: the glTF document and its buffers, with range checks.

struct Document {
    fs::path file;
    json doc;
    std::vector<std::vector<std::uint8_t>> buffers;
};

std::uint32_t get_u32(const std::string& s, std::size_t at) {
    std::uint32_t v = 0;
    std::memcpy(&v, s.data() + at, 4); // GLB is little-endian, as is every platform we build on
    return v;
}

Document read_document(const fs::path& path) {
    Document d{path, {}, {}};
    const std::string bytes = read_text_file(path, "bundle");
    std::string json_text;
    std::optional<std::vector<std::uint8_t>> bin;
    if (bytes.size() >= 4 && get_u32(bytes, 0) == kGlbMagic) {
        if (bytes.size() < 20) throw InputError(path, "glb", "truncated GLB header");
        if (get_u32(bytes, 4) != 2) throw InputError(path, "glb.version", "not a glTF 2.0 binary");
        const std::size_t total = get_u32(bytes, 8);
        if (total > bytes.size()) throw InputError(path, "glb.length", "file shorter than its header says");
        std::size_t at = 12;
        bool first = true;
        while (at + 8 <= total) {
            const std::size_t len = get_u32(bytes, at), type = get_u32(bytes, at + 4);
            if (at + 8 + len > total) throw InputError(path, "glb.chunks", "chunk runs past the end of the file");
            if (first && type != kChunkJson) throw InputError(path, "glb.chunks[0]", "first chunk is not JSON");
            if (first) json_text.assign(bytes, at + 8, len);
            else if (type == kChunkBin && !bin) bin.emplace(bytes.begin() + static_cast<std::ptrdiff_t>(at + 8),
                                                             bytes.begin() + static_cast<std::ptrdiff_t>(at + 8 + len));
            first = false;
            at += 8 + len;
        }
        if (first) throw InputError(path, "glb.chunks", "no JSON chunk");
    } else {
        json_text = bytes; // .gltf: JSON, buffers by relative URI
    }
    d.doc = json::parse(json_text, nullptr, false);
    if (d.doc.is_discarded() || !d.doc.is_object()) throw InputError(path, "json", "not valid glTF JSON");
    const json& buffers = d.doc.value("buffers", json::array());
    if (!buffers.is_array()) throw InputError(path, "buffers", "not an array");
    for (std::size_t i = 0; i < buffers.size(); ++i) {
        const std::string field = "buffers[" + std::to_string(i) + "]";
        const json& b = buffers[i];
        if (!b.is_object()) throw InputError(path, field, "not an object");
        std::vector<std::uint8_t> data;
        if (!b.contains("uri")) {
            if (i != 0 || !bin) throw InputError(path, field, "no uri and no GLB BIN chunk");
            data = *bin;
        } else {
            const std::string uri = b["uri"].is_string() ? b["uri"].get<std::string>() : std::string();
            if (uri.empty() || uri.rfind("data:", 0) == 0 || uri.find("://") != std::string::npos)
                throw InputError(path, field + ".uri", "only relative file URIs are supported");
            const std::string text = read_text_file(path.parent_path() / uri, field + ".uri");
            data.assign(text.begin(), text.end());
        }
        if (b.contains("byteLength") &&
            (!b["byteLength"].is_number_unsigned() || b["byteLength"].get<std::uint64_t>() > data.size()))
            throw InputError(path, field + ".byteLength", "larger than the buffer's data");
        d.buffers.push_back(std::move(data));
    }
    return d;
}

/// obj[key] as a non-negative integer, or throws naming field.key.
std::size_t get_index(const Document& d, const json& obj, const char* key, const std::string& field) {
    if (!obj.is_object() || !obj.contains(key) || !obj[key].is_number_unsigned())
        throw InputError(d.file, field + "." + key, "missing or not a non-negative integer");
    return obj[key].get<std::size_t>();
}

const json& get_element(const Document& d, const char* array, std::size_t index) {
    const std::string field = std::string(array) + "[" + std::to_string(index) + "]";
    if (!d.doc.contains(array) || !d.doc[array].is_array() || index >= d.doc[array].size())
        throw InputError(d.file, field, "missing");
    return d.doc[array][index];
}

struct ViewBytes {
    std::span<const std::uint8_t> bytes;
    std::size_t stride = 0;
};

ViewBytes buffer_view(const Document& d, std::size_t index) {
    const std::string field = "bufferViews[" + std::to_string(index) + "]";
    const json& v = get_element(d, "bufferViews", index);
    const std::size_t buffer = get_index(d, v, "buffer", field);
    if (buffer >= d.buffers.size()) throw InputError(d.file, field + ".buffer", "out of range");
    const std::size_t offset = v.contains("byteOffset") ? get_index(d, v, "byteOffset", field) : 0;
    const std::size_t length = get_index(d, v, "byteLength", field);
    const auto& data = d.buffers[buffer];
    if (offset > data.size() || length > data.size() - offset)
        throw InputError(d.file, field, "byteOffset + byteLength runs past the buffer");
    const std::size_t stride = v.contains("byteStride") ? get_index(d, v, "byteStride", field) : 0;
    return {std::span<const std::uint8_t>(data.data() + offset, length), stride};
}

/// An accessor's elements as floats (componentType FLOAT, `components` per element).
std::vector<float> read_float_accessor(const Document& d, std::size_t index, int components, const std::string& field) {
    const json& a = get_element(d, "accessors", index);
    if (a.value("componentType", 0) != TINYGLTF_COMPONENT_TYPE_FLOAT)
        throw InputError(d.file, field, "componentType must be FLOAT (5126)");
    const std::string want = components == 2 ? "VEC2" : "VEC3";
    if (a.value("type", std::string()) != want) throw InputError(d.file, field, "type must be " + want);
    if (a.contains("sparse")) throw InputError(d.file, field, "sparse accessors are not supported");
    const std::size_t count = get_index(d, a, "count", field);
    const std::size_t offset = a.contains("byteOffset") ? get_index(d, a, "byteOffset", field) : 0;
    const ViewBytes view = buffer_view(d, get_index(d, a, "bufferView", field));
    const std::size_t elem = sizeof(float) * components, stride = view.stride ? view.stride : elem;
    if (stride < elem) throw InputError(d.file, field, "byteStride smaller than an element");
    if (count > 0 && (offset > view.bytes.size() || (count - 1) > (view.bytes.size() - offset) / stride ||
                      offset + (count - 1) * stride + elem > view.bytes.size()))
        throw InputError(d.file, field, "count runs past the bufferView");
    std::vector<float> out(count * components);
    for (std::size_t i = 0; i < count; ++i)
        std::memcpy(out.data() + i * components, view.bytes.data() + offset + i * stride, elem);
    return out;
}

std::vector<std::uint32_t> read_index_accessor(const Document& d, std::size_t index, const std::string& field) {
    const json& a = get_element(d, "accessors", index);
    const int type = a.value("componentType", 0);
    const std::size_t size = type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT     ? 4
                             : type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT ? 2
                             : type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE  ? 1
                                                                              : 0;
    if (size == 0) throw InputError(d.file, field, "componentType must be an unsigned integer type");
    if (a.value("type", std::string()) != "SCALAR") throw InputError(d.file, field, "type must be SCALAR");
    if (a.contains("sparse")) throw InputError(d.file, field, "sparse accessors are not supported");
    const std::size_t count = get_index(d, a, "count", field);
    const std::size_t offset = a.contains("byteOffset") ? get_index(d, a, "byteOffset", field) : 0;
    const ViewBytes view = buffer_view(d, get_index(d, a, "bufferView", field));
    if (offset > view.bytes.size() || count > (view.bytes.size() - offset) / size)
        throw InputError(d.file, field, "count runs past the bufferView");
    std::vector<std::uint32_t> out(count);
    for (std::size_t i = 0; i < count; ++i) {
        const std::uint8_t* p = view.bytes.data() + offset + i * size;
        if (size == 4) std::memcpy(&out[i], p, 4);
        else if (size == 2) { std::uint16_t v; std::memcpy(&v, p, 2); out[i] = v; }
        else out[i] = *p;
    }
    return out;
}

/// Raw little-endian float32 data of exactly `count` floats from a bufferView.
std::vector<float> read_float_view(const Document& d, std::size_t index, std::size_t count, const std::string& field) {
    const ViewBytes view = buffer_view(d, index);
    if (view.bytes.size() != count * sizeof(float))
        throw InputError(d.file, field, "bufferView holds " + std::to_string(view.bytes.size()) + " bytes, expected " +
                                            std::to_string(count * sizeof(float)) + " (float32)");
    std::vector<float> out(count);
    std::memcpy(out.data(), view.bytes.data(), view.bytes.size());
    return out;
}

glm::vec3 read_vec3(const Document& d, const json& obj, const char* key, const std::string& field) {
    const std::string f = field + "." + key;
    if (!obj.contains(key) || !obj[key].is_array() || obj[key].size() != 3)
        throw InputError(d.file, f, "missing or not an array of 3 numbers");
    glm::vec3 v;
    for (int i = 0; i < 3; ++i) {
        if (!obj[key][i].is_number()) throw InputError(d.file, f, "not a number");
        v[i] = static_cast<float>(obj[key][i].get<double>());
    }
    if (!finite3(v)) throw InputError(d.file, f, "not finite");
    return v;
}

BundleCubeMap read_cube(const Document& d, const json& ext, const char* key, const std::string& ext_field) {
    const std::string field = ext_field + "." + key;
    if (!ext.contains(key)) throw InputError(d.file, field, "missing: G and H go together");
    const json& c = ext[key];
    if (!c.is_object()) throw InputError(d.file, field, "not an object");
    BundleCubeMap cube;
    const std::size_t r = get_index(d, c, "resolution", field);
    if (r == 0 || r > 65536) throw InputError(d.file, field + ".resolution", "out of range");
    cube.resolution = static_cast<std::uint32_t>(r);
    cube.rgb = read_float_view(d, get_index(d, c, "bufferView", field), 6 * r * r * 3, field + ".bufferView");
    return cube;
}

/// The base colour texture of the first material a primitive uses, decoded to linear RGB.
Image read_base_color(const Document& d, std::vector<std::string>& warnings) {
    const json& mesh = get_element(d, "meshes", 0);
    const json& prims = mesh.value("primitives", json::array());
    if (!prims.is_array() || prims.empty()) throw InputError(d.file, "meshes[0].primitives", "missing");
    const std::size_t mat_index = get_index(d, prims[0], "material", "meshes[0].primitives[0]");
    const std::string mat_field = "materials[" + std::to_string(mat_index) + "]";
    const json& mat = get_element(d, "materials", mat_index);
    const json& pbr = mat.value("pbrMetallicRoughness", json::object());
    const std::string tex_field = mat_field + ".pbrMetallicRoughness.baseColorTexture";
    if (!pbr.is_object() || !pbr.contains("baseColorTexture"))
        throw InputError(d.file, tex_field, "no base colour texture: nothing to take the albedo from");
    const json& info = pbr["baseColorTexture"];
    if (info.value("texCoord", 0) != 0) throw InputError(d.file, tex_field + ".texCoord", "only TEXCOORD_0 is supported");
    const std::size_t tex = get_index(d, info, "index", tex_field);
    const std::size_t img = get_index(d, get_element(d, "textures", tex), "source", "textures[" + std::to_string(tex) + "]");
    const std::string img_field = "images[" + std::to_string(img) + "]";
    const json& image = get_element(d, "images", img);
    Image albedo;
    if (image.contains("bufferView")) {
        const ViewBytes view = buffer_view(d, get_index(d, image, "bufferView", img_field));
        albedo = decode_srgb_image(view.bytes, image.value("mimeType", std::string("image/png")), d.file, img_field);
    } else if (image.contains("uri") && image["uri"].is_string()) {
        const std::string uri = image["uri"].get<std::string>();
        if (uri.rfind("data:", 0) == 0 || uri.find("://") != std::string::npos)
            throw InputError(d.file, img_field + ".uri", "only relative file URIs are supported");
        albedo = read_image(d.file.parent_path() / uri, ColorSpace::Srgb, img_field + ".uri");
        if (albedo.channels != 3) {
            Image rgb(albedo.width, albedo.height, 3);
            for (std::size_t i = 0; i < static_cast<std::size_t>(albedo.width) * albedo.height; ++i)
                for (int c = 0; c < 3; ++c)
                    rgb.pixels[i * 3 + c] = albedo.pixels[i * albedo.channels + (albedo.channels >= 3 ? c : 0)];
            albedo = std::move(rgb);
        }
    } else {
        throw InputError(d.file, img_field, "neither bufferView nor uri");
    }
    if (pbr.contains("baseColorFactor")) { // linear multiplier (glTF 2.0 section 3.9.2)
        const json& f = pbr["baseColorFactor"];
        if (!f.is_array() || f.size() != 4) throw InputError(d.file, mat_field + ".pbrMetallicRoughness.baseColorFactor", "not 4 numbers");
        for (std::size_t i = 0; i < albedo.pixels.size(); ++i) albedo.pixels[i] *= f[i % 3].get<float>();
    }
    std::size_t materials = 0;
    for (const json& p : prims)
        if (p.value("material", mat_index) != mat_index) ++materials;
    if (materials > 0 || d.doc.value("meshes", json::array()).size() > 1)
        warnings.push_back("several primitives or meshes: the albedo is the base colour texture of " + mat_field +
                           " for all of them");
    return albedo;
}

} // namespace

// -------------------------------------------------------------------------------------------------

Bundle make_bundle(const Mesh& mesh, std::span<const glm::vec2> corner_uv, Image albedo, std::optional<LafortuneRgb> lobe) {
    if (corner_uv.size() != mesh.triangles.size() * 3)
        throw Error("make_bundle: " + std::to_string(corner_uv.size()) + " corner coordinates for " +
                    std::to_string(mesh.triangles.size()) + " triangles (3 per triangle expected)");
    const std::vector<glm::vec3> normals = mesh.normals.size() == mesh.positions.size()
                                               ? mesh.normals
                                               : compute_vertex_normals(mesh.positions, mesh.triangles);
    Bundle b;
    b.albedo = std::move(albedo);
    b.lobe = lobe;
    // Key: position index and the uv's bit patterns (identical coordinates only: an atlas
    // gives a vertex the same uv in every triangle of its patch, and different ones across patches).
    std::map<std::tuple<std::uint32_t, std::uint32_t, std::uint32_t>, std::uint32_t> vertex_of;
    b.mesh.triangles.reserve(mesh.triangles.size());
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
        glm::uvec3 out;
        for (int c = 0; c < 3; ++c) {
            const std::uint32_t p = mesh.triangles[t][c];
            if (p >= mesh.positions.size()) throw Error("make_bundle: triangle index out of range");
            const glm::vec2 uv = corner_uv[t * 3 + c];
            std::uint32_t ux, uy;
            std::memcpy(&ux, &uv.x, 4);
            std::memcpy(&uy, &uv.y, 4);
            const auto [it, inserted] =
                vertex_of.try_emplace({p, ux, uy}, static_cast<std::uint32_t>(b.mesh.positions.size()));
            if (inserted) {
                b.mesh.positions.push_back(mesh.positions[p]);
                b.mesh.normals.push_back(normals[p]);
                b.mesh.texcoords.push_back(uv);
            }
            out[c] = it->second;
        }
        b.mesh.triangles.push_back(out);
    }
    return b;
}

std::vector<glm::vec2> corner_uvs(const Mesh& mesh) {
    if (!mesh.has_texcoords()) throw Error("corner_uvs: the mesh has no texture coordinates (one per vertex)");
    std::vector<glm::vec2> out;
    out.reserve(mesh.triangles.size() * 3);
    for (const glm::uvec3& t : mesh.triangles)
        for (int c = 0; c < 3; ++c) {
            if (t[c] >= mesh.texcoords.size()) throw Error("corner_uvs: triangle index out of range");
            out.push_back(mesh.texcoords[t[c]]);
        }
    return out;
}

void write_bundle(const fs::path& path, const Bundle& bundle) {
    const Mesh& mesh = bundle.mesh;
    const std::size_t n = mesh.positions.size();
    if (n == 0 || mesh.triangles.empty()) throw InputError(path, "mesh", "refusing to write an empty mesh");
    if (!mesh.has_texcoords()) throw InputError(path, "mesh.texcoords", "one atlas coordinate per vertex required (make_bundle)");
    if (!mesh.normals.empty() && mesh.normals.size() != n)
        throw InputError(path, "mesh.normals", "not one per vertex");
    for (const glm::uvec3& t : mesh.triangles)
        if (t.x >= n || t.y >= n || t.z >= n) throw InputError(path, "mesh.triangles", "index out of range");
    for (const glm::vec3& p : mesh.positions)
        if (!finite3(p)) throw InputError(path, "mesh.positions", "non-finite vertex position");
    for (const glm::vec2& uv : mesh.texcoords)
        if (!std::isfinite(uv.x) || !std::isfinite(uv.y)) throw InputError(path, "mesh.texcoords", "non-finite");
    const Image& albedo = bundle.albedo;
    if (albedo.width <= 0 || albedo.height <= 0 || albedo.channels < 1 || albedo.channels > 4 ||
        albedo.pixels.size() != static_cast<std::size_t>(albedo.width) * albedo.height * albedo.channels)
        throw InputError(path, "albedo", "empty or inconsistent image (1 to 4 channels)");
    if (bundle.lobe && !(finite3(bundle.lobe->cx) && finite3(bundle.lobe->cz) && finite3(bundle.lobe->n)))
        throw InputError(path, "lobe", "non-finite lobe parameters");
    for (const auto* cube : {&bundle.cube_g, &bundle.cube_h})
        if (*cube && (cube->value().resolution == 0 ||
                      cube->value().rgb.size() != 6ull * cube->value().resolution * cube->value().resolution * 3))
            throw InputError(path, cube == &bundle.cube_g ? "cube_g" : "cube_h", "size is not 6 * resolution^2 * 3");
    if (bundle.cube_g.has_value() != bundle.cube_h.has_value())
        throw InputError(path, "cube_g", "the factorization needs both cube-maps (G and H)");
    if (!bundle.extra_terms.empty() && !bundle.cube_g)
        throw InputError(path, "extra_terms", "further factorization terms need term 1 (cube_g, cube_h)");
    if (bundle.extra_terms.size() > kMaxExtraTerms)
        throw InputError(path, "extra_terms", std::to_string(bundle.extra_terms.size()) + " further terms (at most " +
                                                  std::to_string(kMaxExtraTerms) + ")");
    for (std::size_t k = 0; k < bundle.extra_terms.size(); ++k)
        for (const BundleCubeMap* cube : {&bundle.extra_terms[k].g, &bundle.extra_terms[k].h})
            if (cube->resolution == 0 || cube->rgb.size() != 6ull * cube->resolution * cube->resolution * 3)
                throw InputError(path, "extra_terms[" + std::to_string(k) + "]." + (cube == &bundle.extra_terms[k].g ? "g" : "h"),
                                 "size is not 6 * resolution^2 * 3");

    // Unit normals (glTF 3.7.2.1), as write_mesh_glb writes them.
    const std::vector<glm::vec3> normals = gltf_unit_normals(mesh);

    // BIN chunk; every block starts 4-byte aligned.
    std::vector<unsigned char> bin;
    json views = json::array(), accessors = json::array();
    auto add_view = [&](const void* data, std::size_t bytes, int target) {
        while (bin.size() % 4 != 0) bin.push_back(0);
        const std::size_t offset = bin.size();
        bin.resize(offset + bytes);
        if (bytes > 0) std::memcpy(bin.data() + offset, data, bytes);
        json v = {{"buffer", 0}, {"byteOffset", offset}, {"byteLength", bytes}};
        if (target != 0) v["target"] = target;
        views.push_back(std::move(v));
        return views.size() - 1;
    };
    glm::vec3 lo(std::numeric_limits<float>::infinity()), hi(-std::numeric_limits<float>::infinity());
    for (const glm::vec3& p : mesh.positions) {
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
    }
    json attributes;
    accessors.push_back({{"bufferView", add_view(mesh.positions.data(), n * sizeof(glm::vec3), kArrayBuffer)},
                         {"componentType", TINYGLTF_COMPONENT_TYPE_FLOAT}, {"count", n}, {"type", "VEC3"},
                         {"min", vec3_json(lo)}, {"max", vec3_json(hi)}});
    attributes["POSITION"] = accessors.size() - 1;
    accessors.push_back({{"bufferView", add_view(normals.data(), n * sizeof(glm::vec3), kArrayBuffer)},
                         {"componentType", TINYGLTF_COMPONENT_TYPE_FLOAT}, {"count", n}, {"type", "VEC3"}});
    attributes["NORMAL"] = accessors.size() - 1;
    accessors.push_back({{"bufferView", add_view(mesh.texcoords.data(), n * sizeof(glm::vec2), kArrayBuffer)},
                         {"componentType", TINYGLTF_COMPONENT_TYPE_FLOAT}, {"count", n}, {"type", "VEC2"}});
    attributes["TEXCOORD_0"] = accessors.size() - 1;
    {
        std::vector<std::uint32_t> idx;
        idx.reserve(mesh.triangles.size() * 3);
        for (const glm::uvec3& t : mesh.triangles) idx.insert(idx.end(), {t.x, t.y, t.z});
        accessors.push_back({{"bufferView", add_view(idx.data(), idx.size() * sizeof(std::uint32_t), kElementArrayBuffer)},
                             {"componentType", TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT}, {"count", idx.size()},
                             {"type", "SCALAR"}});
    }
    const std::size_t indices_accessor = accessors.size() - 1;

    const std::vector<unsigned char> png = encode_srgb_png(albedo, path);
    const std::size_t png_view = add_view(png.data(), png.size(), 0);

    const bool mirrored = bundle.cube_g && bundle.factor_param == FactorParam::Mirrored;
    const bool warped = bundle.cube_g && bundle.factor_param == FactorParam::Warped;
    if (warped && !bundle.lobe)
        throw InputError(path, "SPECULA_lafortune.parametrization", "warped cube-maps without the lobe (its radial factor)");
    json ext = {{"version", warped ? 4 : mirrored ? 3 : bundle.extra_terms.empty() ? 1 : 2}};
    if (bundle.lobe) {
        ext["lobe"] = {{"cx", vec3_json(bundle.lobe->cx)}, {"cz", vec3_json(bundle.lobe->cz)},
                       {"n", vec3_json(bundle.lobe->n)}, {"status", bundle.lobe_status}};
    }
    ext["albedo"] = {{"bufferView", add_view(albedo.pixels.data(), albedo.pixels.size() * sizeof(float), 0)},
                     {"width", albedo.width}, {"height", albedo.height}, {"channels", albedo.channels}};
    if (bundle.cube_g) {
        ext["cubeG"] = {{"bufferView", add_view(bundle.cube_g->rgb.data(), bundle.cube_g->rgb.size() * sizeof(float), 0)},
                        {"resolution", bundle.cube_g->resolution}};
        ext["cubeH"] = {{"bufferView", add_view(bundle.cube_h->rgb.data(), bundle.cube_h->rgb.size() * sizeof(float), 0)},
                        {"resolution", bundle.cube_h->resolution}};
    }
    if (!bundle.extra_terms.empty()) {
        json terms = json::array();
        for (const BundleFactorTerm& t : bundle.extra_terms)
            terms.push_back({{"cubeG", {{"bufferView", add_view(t.g.rgb.data(), t.g.rgb.size() * sizeof(float), 0)},
                                        {"resolution", t.g.resolution}}},
                             {"cubeH", {{"bufferView", add_view(t.h.rgb.data(), t.h.rgb.size() * sizeof(float), 0)},
                                        {"resolution", t.h.resolution}}}});
        ext["cubeTerms"] = std::move(terms);
    }
    if (mirrored || warped) ext["parametrization"] = to_string(bundle.factor_param);
    if (warped) ext["warp"] = {bundle.factor_warp.x, bundle.factor_warp.y, bundle.factor_warp.z, bundle.factor_warp.w};
    ext["info"] = bundle.info.is_object() ? bundle.info : json::object();

    const json material = {
        {"name", "specula"},
        {"pbrMetallicRoughness",
         {{"baseColorTexture", {{"index", 0}}}, {"metallicFactor", 0.0},
          {"roughnessFactor", static_cast<double>(roughness_from_lobe(bundle.lobe))}}},
        {"extensions", {{kExtension, ext}}},
    };
    while (bin.size() % 4 != 0) bin.push_back(0);
    const json doc = {
        {"asset", {{"version", "2.0"}, {"generator", "Specula"}}},
        {"extensionsUsed", json::array({kExtension})},
        {"scene", 0},
        {"scenes", {{{"nodes", {0}}}}},
        {"nodes", {{{"mesh", 0}, {"name", "specula"}}}},
        {"meshes",
         {{{"primitives",
            {{{"attributes", attributes}, {"indices", indices_accessor}, {"material", 0},
              {"mode", TINYGLTF_MODE_TRIANGLES}}}}}}},
        {"materials", json::array({material})},
        {"textures", {{{"sampler", 0}, {"source", 0}}}},
        {"samplers", {{{"magFilter", kLinear}, {"minFilter", kLinear}, {"wrapS", kClampToEdge}, {"wrapT", kClampToEdge}}}},
        {"images", {{{"bufferView", png_view}, {"mimeType", "image/png"}}}},
        {"buffers", {{{"byteLength", bin.size()}}}},
        {"bufferViews", views},
        {"accessors", accessors},
    };

    // GLB container (glTF 2.0 section 4.4): header, JSON chunk padded with spaces, BIN chunk.
    std::string json_text = doc.dump();
    while (json_text.size() % 4 != 0) json_text.push_back(' ');
    const std::size_t total = 12 + 8 + json_text.size() + 8 + bin.size();
    if (total > std::numeric_limits<std::uint32_t>::max()) throw InputError(path, "", "bundle too large for a .glb (4 GiB)");
    std::string out;
    out.reserve(total);
    auto put32 = [&](std::size_t v) {
        const auto u = static_cast<std::uint32_t>(v);
        char b[4];
        std::memcpy(b, &u, 4);
        out.append(b, 4);
    };
    put32(kGlbMagic);
    put32(2);
    put32(total);
    put32(json_text.size());
    put32(kChunkJson);
    out += json_text;
    put32(bin.size());
    put32(kChunkBin);
    out.append(reinterpret_cast<const char*>(bin.data()), bin.size());
    write_text_file(path, out);
}

Bundle read_bundle(const fs::path& path) {
    const Document d = read_document(path);
    Bundle b;

    // The material with the extension (the first one).
    const json* ext = nullptr;
    std::string ext_field;
    const json& materials = d.doc.value("materials", json::array());
    for (std::size_t i = 0; materials.is_array() && i < materials.size() && !ext; ++i) {
        const json& m = materials[i];
        if (m.is_object() && m.contains("extensions") && m["extensions"].is_object() && m["extensions"].contains(kExtension)) {
            ext = &m["extensions"][kExtension];
            ext_field = "materials[" + std::to_string(i) + "].extensions." + kExtension;
        }
    }

    if (!ext) { // a foreign glTF: diffuse only, from the base colour texture
        MeshLoadResult loaded = load_mesh(path, "mesh");
        if (!loaded.mesh.has_texcoords())
            throw InputError(path, "meshes[0].primitives[0].attributes.TEXCOORD_0",
                             std::string("no ") + kExtension + " extension and no texture coordinates: not a bundle");
        b.mesh = std::move(loaded.mesh);
        b.warnings = std::move(loaded.warnings);
        b.albedo = read_base_color(d, b.warnings);
        b.warnings.push_back(std::string("no ") + kExtension +
                             " extension: diffuse-only bundle, albedo decoded from the 8-bit sRGB base colour texture");
        return b;
    }

    if (!ext->is_object()) throw InputError(path, ext_field, "not an object");
    const json version = ext->value("version", json());
    if (!version.is_number_integer() || version.get<int>() < 1 || version.get<int>() > kExtensionVersion)
        throw InputError(path, ext_field + ".version", "unsupported version (this reader knows 1 to " +
                                                           std::to_string(kExtensionVersion) + ")");

    // The mesh: one mesh, one triangle primitive, no node transform (docs/SPECULA_lafortune.md).
    const json& meshes = d.doc.value("meshes", json::array());
    if (!meshes.is_array() || meshes.size() != 1) throw InputError(path, "meshes", "a bundle holds exactly one mesh");
    const json& prims = meshes[0].value("primitives", json::array());
    if (!prims.is_array() || prims.size() != 1)
        throw InputError(path, "meshes[0].primitives", "a bundle holds exactly one primitive");
    const json& prim = prims[0];
    const std::string pf = "meshes[0].primitives[0]";
    if (prim.value("mode", TINYGLTF_MODE_TRIANGLES) != TINYGLTF_MODE_TRIANGLES)
        throw InputError(path, pf + ".mode", "not TRIANGLES");
    for (const json& node : d.doc.value("nodes", json::array()))
        if (node.is_object() && (node.contains("matrix") || node.contains("translation") || node.contains("rotation") ||
                                 node.contains("scale") || node.contains("children")))
            throw InputError(path, "nodes", "a bundle's mesh is in world space: node transforms are not supported");
    const json& attrs = prim.value("attributes", json::object());
    const std::vector<float> pos = read_float_accessor(d, get_index(d, attrs, "POSITION", pf + ".attributes"), 3,
                                                       pf + ".attributes.POSITION");
    const std::vector<float> uv = read_float_accessor(d, get_index(d, attrs, "TEXCOORD_0", pf + ".attributes"), 2,
                                                      pf + ".attributes.TEXCOORD_0");
    const std::size_t n = pos.size() / 3;
    if (n == 0) throw InputError(path, pf + ".attributes.POSITION", "no vertices");
    if (uv.size() / 2 != n) throw InputError(path, pf + ".attributes.TEXCOORD_0", "count differs from POSITION's");
    b.mesh.positions.resize(n);
    b.mesh.texcoords.resize(n);
    std::memcpy(b.mesh.positions.data(), pos.data(), pos.size() * sizeof(float));
    std::memcpy(b.mesh.texcoords.data(), uv.data(), uv.size() * sizeof(float));
    for (const glm::vec3& p : b.mesh.positions)
        if (!finite3(p)) throw InputError(path, pf + ".attributes.POSITION", "non-finite vertex position");
    if (!prim.contains("indices")) throw InputError(path, pf + ".indices", "missing (a bundle is indexed)");
    const std::vector<std::uint32_t> idx = read_index_accessor(d, get_index(d, prim, "indices", pf), pf + ".indices");
    if (idx.empty() || idx.size() % 3 != 0) throw InputError(path, pf + ".indices", "count is not a positive multiple of 3");
    b.mesh.triangles.resize(idx.size() / 3);
    for (std::size_t t = 0; t < b.mesh.triangles.size(); ++t) {
        const glm::uvec3 tri(idx[3 * t], idx[3 * t + 1], idx[3 * t + 2]);
        if (tri.x >= n || tri.y >= n || tri.z >= n) throw InputError(path, pf + ".indices", "index out of range");
        b.mesh.triangles[t] = tri;
    }
    if (attrs.contains("NORMAL")) {
        const std::vector<float> nrm = read_float_accessor(d, get_index(d, attrs, "NORMAL", pf + ".attributes"), 3,
                                                           pf + ".attributes.NORMAL");
        if (nrm.size() / 3 != n) throw InputError(path, pf + ".attributes.NORMAL", "count differs from POSITION's");
        b.mesh.normals.resize(n);
        std::memcpy(b.mesh.normals.data(), nrm.data(), nrm.size() * sizeof(float));
    } else {
        b.mesh.normals = compute_vertex_normals(b.mesh.positions, b.mesh.triangles);
        b.warnings.push_back("no NORMAL attribute: area-weighted normals computed");
    }

    // The extension's payload.
    if (ext->contains("lobe")) {
        const json& l = (*ext)["lobe"];
        const std::string lf = ext_field + ".lobe";
        if (!l.is_object()) throw InputError(path, lf, "not an object");
        b.lobe = LafortuneRgb{read_vec3(d, l, "cx", lf), read_vec3(d, l, "cz", lf), read_vec3(d, l, "n", lf)};
        if (l.contains("status")) {
            if (!l["status"].is_array()) throw InputError(path, lf + ".status", "not an array of strings");
            for (const json& s : l["status"]) {
                if (!s.is_string()) throw InputError(path, lf + ".status", "not an array of strings");
                b.lobe_status.push_back(s.get<std::string>());
            }
        }
    }
    {
        const std::string af = ext_field + ".albedo";
        if (!ext->contains("albedo")) throw InputError(path, af, "missing");
        const json& a = (*ext)["albedo"];
        const std::size_t w = get_index(d, a, "width", af), h = get_index(d, a, "height", af);
        const std::size_t c = a.contains("channels") ? get_index(d, a, "channels", af) : 3;
        if (w == 0 || h == 0 || w > 65536 || h > 65536) throw InputError(path, af, "width/height out of range");
        if (c < 1 || c > 4) throw InputError(path, af + ".channels", "must be 1 to 4");
        b.albedo.width = static_cast<int>(w);
        b.albedo.height = static_cast<int>(h);
        b.albedo.channels = static_cast<int>(c);
        b.albedo.pixels = read_float_view(d, get_index(d, a, "bufferView", af), w * h * c, af + ".bufferView");
    }
    if (ext->contains("cubeG") != ext->contains("cubeH"))
        throw InputError(path, ext_field + (ext->contains("cubeG") ? ".cubeH" : ".cubeG"), "missing: G and H go together");
    if (ext->contains("cubeG")) {
        b.cube_g = read_cube(d, *ext, "cubeG", ext_field);
        b.cube_h = read_cube(d, *ext, "cubeH", ext_field);
    }
    if (ext->contains("cubeTerms")) { // terms 2..K, version 2
        const std::string tf = ext_field + ".cubeTerms";
        const json& terms = (*ext)["cubeTerms"];
        if (version.get<int>() < 2) throw InputError(path, tf, "present in a version 1 extension (needs version 2)");
        if (!ext->contains("cubeG")) throw InputError(path, tf, "further terms without term 1 (cubeG, cubeH)");
        if (!terms.is_array() || terms.empty() || terms.size() > kMaxExtraTerms)
            throw InputError(path, tf, "not an array of 1 to " + std::to_string(kMaxExtraTerms) + " terms");
        for (std::size_t k = 0; k < terms.size(); ++k) {
            const std::string kf = tf + "[" + std::to_string(k) + "]";
            if (!terms[k].is_object()) throw InputError(path, kf, "not an object");
            b.extra_terms.push_back({read_cube(d, terms[k], "cubeG", kf), read_cube(d, terms[k], "cubeH", kf)});
        }
    }
    if (ext->contains("parametrization")) { // version 3; absent: the thesis's GSHD
        const std::string pf = ext_field + ".parametrization";
        const json& p = (*ext)["parametrization"];
        const std::optional<FactorParam> param = p.is_string() ? factor_param_from_string(p.get<std::string>()) : std::nullopt;
        if (!param) throw InputError(path, pf, "not \"gshd\", \"mirrored\" or \"warped\"");
        const int needs = *param == FactorParam::Warped ? 4 : *param == FactorParam::Mirrored ? 3 : 1;
        if (version.get<int>() < needs)
            throw InputError(path, pf, std::string(to_string(*param)) + " in a version " + std::to_string(version.get<int>()) +
                                           " extension (needs version " + std::to_string(needs) + ")");
        if (!ext->contains("cubeG")) throw InputError(path, pf, "a parametrization without cube-maps (cubeG, cubeH)");
        if (*param == FactorParam::Warped && !b.lobe) throw InputError(path, pf, "warped without a lobe (its radial factor)");
        b.factor_param = *param;
    }
    if (ext->contains("warp") || b.factor_param == FactorParam::Warped) { // version 4
        const std::string wf = ext_field + ".warp";
        if (b.factor_param != FactorParam::Warped) throw InputError(path, wf, "present without \"parametrization\": \"warped\"");
        const json& w = ext->value("warp", json());
        if (!w.is_array() || w.size() != 4 || !std::all_of(w.begin(), w.end(), [](const json& x) { return x.is_number(); }))
            throw InputError(path, wf, "not an array of 4 numbers (s, k_r, k_g, k_b)");
        for (int c = 0; c < 4; ++c) b.factor_warp[c] = w[static_cast<std::size_t>(c)].get<float>();
        if (!valid_warp(b.factor_warp)) throw InputError(path, wf, "must be (+-1, k_r, k_g, k_b) with every k in [1/64, 64]");
    }
    if (ext->contains("info")) {
        if (!(*ext)["info"].is_object()) throw InputError(path, ext_field + ".info", "not an object");
        b.info = (*ext)["info"];
    }
    return b;
}

} // namespace specula
