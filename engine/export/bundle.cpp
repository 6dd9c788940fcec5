// The output bundle (pipeline.md section 10): a glTF 2.0 binary (Khronos glTF 2.0
// specification: 4.4 "GLB File Format", 3.6 buffers/bufferViews, 3.7 meshes, 3.9
// materials, 3.8 textures/images) plus the SPECULA_lafortune material extension,
// specified in docs/SPECULA_lafortune.md.
//
// Files are read and written through capture/gltf_io: the guarded loader (tinygltf, with
// every index, offset and count range-checked before use) and the .glb writer that the
// capture mesh uses too. The extension is read from the loader's JSON document, whose numbers
// are exact; a .glb without the extension is read through load_mesh (all nodes, transforms
// applied) plus its base colour texture.
#include "export/bundle.h"
#include "export/normal_map.h"

#include "capture/gltf_io.h"
#include "core/error.h"
#include "core/image.h"

#include <tiny_gltf.h>

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstring>
#include <future>
#include <limits>
#include <map>
#include <optional>
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
// Version 5 adds "model" (absent: "lafortune") and the coated family's "coated" object
// (material/material.h CoatedParams), written only for coated bundles: an older reader would
// take such a file for a Lambertian one. Lafortune bundles keep the versions above, byte for byte.
constexpr int kExtensionVersion = 5;
constexpr int kModelVersion = 5;

// The core glTF extensions a coated bundle's viewer material uses (both ratified by Khronos):
// the coating's index and its specular tint. In extensionsUsed only, never extensionsRequired:
// a viewer without them still shows the base colour and the roughness.
constexpr const char* kIorExtension = "KHR_materials_ior";
constexpr const char* kSpecularExtension = "KHR_materials_specular";
constexpr const char* kClearcoatExtension = "KHR_materials_clearcoat";
constexpr std::size_t kMaxExtraTerms = kMaxFactorTerms - 1; // cubeTerms: terms 2..K

constexpr int kLinear = 9729, kClampToEdge = 33071; // glTF 2.0 section 3.8.4 (samplers)

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

// The coated family's core material (docs/SPECULA_lafortune.md, "Viewer approximation"): glTF's
// metallic-roughness specular BRDF is a GGX (Trowbridge-Reitz) microfacet model with
// alpha = roughness^2 (glTF 2.0 specification, appendix B), the coated family's reflection is
// GGX of width alpha (shared/coated.h), so roughness = sqrt(alpha) carries it exactly (in
// double: the JSON number is the square root of the float alpha, rounded once).
double roughness_from_coated(const CoatedParams& c) { return std::sqrt(static_cast<double>(c.alpha)); }

json vec3_json(const glm::vec3& v) {
    return json::array({static_cast<double>(v.x), static_cast<double>(v.y), static_cast<double>(v.z)});
}

bool finite3(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

// ---------------------------------------------------------------------------------------------
// Reading the extension (from the loader's JSON document) and its raw float data.

/// obj[key] as a non-negative integer, or throws naming field.key.
std::size_t get_index(const GltfFile& f, const json& obj, const char* key, const std::string& field) {
    if (!obj.is_object() || !obj.contains(key) || !obj[key].is_number_unsigned())
        f.fail(field + "." + key, "missing or not a non-negative integer");
    return obj[key].get<std::size_t>();
}

/// A glTF index (int in tinygltf) from a JSON one; too large ones stay out of range.
int as_index(std::size_t i) { return static_cast<int>(std::min<std::size_t>(i, INT_MAX)); }

/// Raw little-endian float32 data of exactly `count` floats from a bufferView.
std::vector<float> read_float_view(const GltfFile& f, std::size_t index, std::size_t count, const std::string& field) {
    const std::span<const std::uint8_t> bytes = f.view_bytes(as_index(index), field);
    if (bytes.size() != count * sizeof(float))
        f.fail(field, "bufferView holds " + std::to_string(bytes.size()) + " bytes, expected " +
                          std::to_string(count * sizeof(float)) + " (float32)");
    std::vector<float> out(count);
    std::memcpy(out.data(), bytes.data(), bytes.size());
    return out;
}

/// obj[key] as a finite float (a double outside float's range is refused, not narrowed).
float read_number(const GltfFile& f, const json& obj, const char* key, const std::string& field) {
    const std::string k = field + "." + key;
    if (!obj.contains(key) || !obj[key].is_number()) f.fail(k, "missing or not a number");
    const double v = obj[key].get<double>();
    if (!std::isfinite(v) || std::abs(v) > static_cast<double>(std::numeric_limits<float>::max()))
        f.fail(k, "not a finite float32 number");
    return static_cast<float>(v);
}

glm::vec3 read_vec3(const GltfFile& f, const json& obj, const char* key, const std::string& field) {
    const std::string k = field + "." + key;
    if (!obj.contains(key) || !obj[key].is_array() || obj[key].size() != 3) f.fail(k, "missing or not an array of 3 numbers");
    glm::vec3 v;
    for (int i = 0; i < 3; ++i) {
        if (!obj[key][i].is_number()) f.fail(k, "not a number");
        v[i] = static_cast<float>(obj[key][i].get<double>());
    }
    if (!finite3(v)) f.fail(k, "not finite");
    return v;
}

CubeMap read_cube(const GltfFile& f, const json& ext, const char* key, const std::string& ext_field) {
    const std::string field = ext_field + "." + key;
    if (!ext.contains(key)) f.fail(field, "missing: G and H go together");
    const json& c = ext[key];
    if (!c.is_object()) f.fail(field, "not an object");
    CubeMap cube;
    const std::size_t r = get_index(f, c, "resolution", field);
    if (r == 0 || r > 65536) f.fail(field + ".resolution", "out of range");
    cube.resolution = static_cast<std::uint32_t>(r);
    const std::vector<float> rgb = read_float_view(f, get_index(f, c, "bufferView", field), 6 * r * r * 3, field + ".bufferView");
    cube.texels.resize(6 * r * r);
    std::memcpy(cube.texels.data(), rgb.data(), rgb.size() * sizeof(float)); // glm::vec3 is 3 packed floats
    return cube;
}

/// A name for a file beside the bundle: no folder, no "." or "..", no NUL.
bool is_plain_file_name(const std::string& name) {
    return !name.empty() && name != "." && name != ".." && name.find('/') == std::string::npos &&
           name.find('\0') == std::string::npos;
}

/// The float albedo that `albedo.uri` names, beside the .glb (`af`: the field), or nothing
/// when the file is not there.
std::optional<Image> read_float_albedo_file(const GltfFile& f, const json& a, const std::string& af, std::size_t w,
                                            std::size_t h, std::size_t c) {
    const json& uri = a["uri"];
    if (!uri.is_string() || !is_plain_file_name(uri.get<std::string>()))
        f.fail(af + ".uri", "not a plain file name beside the bundle");
    const fs::path file = f.path().parent_path() / uri.get<std::string>();
    std::error_code ec;
    if (!fs::exists(fs::symlink_status(file, ec))) return std::nullopt;
    if (fs::is_symlink(fs::symlink_status(file, ec))) f.fail(af + ".uri", file.string() + " is a symbolic link");
    ImageFileInfo info;
    Image image = read_image(file, ColorSpace::Linear, af + ".uri", &info); // a regular file, the header checked first
    if (static_cast<std::size_t>(image.width) != w || static_cast<std::size_t>(image.height) != h)
        f.fail(af + ".uri", file.string() + " is " + std::to_string(image.width) + " x " + std::to_string(image.height) +
                                " but the extension says " + std::to_string(w) + " x " + std::to_string(h));
    if (static_cast<std::size_t>(image.channels) != c)
        f.fail(af + ".uri", file.string() + " has " + std::to_string(image.channels) + " channel(s), the extension " +
                                std::to_string(c));
    if (!info.is_float) f.fail(af + ".uri", file.string() + " is not a float image (the albedo is linear float)");
    return image;
}

/// The image a texture index names, decoded in `cs` (the header first: an image above the size
/// limit is refused before it is decoded). Refusals name textures[i].source or images[j].
Image decode_texture(const GltfFile& f, std::size_t tex, ColorSpace cs) {
    const tinygltf::Model& model = f.model();
    const std::string tex_entry = "textures[" + std::to_string(tex) + "]";
    if (tex >= model.textures.size()) f.fail(tex_entry, "missing");
    const int img = model.textures[tex].source;
    if (img < 0) f.fail(tex_entry + ".source", "missing or not a non-negative integer");
    const std::string img_field = "images[" + std::to_string(img) + "]";
    if (static_cast<std::size_t>(img) >= model.images.size()) f.fail(img_field, "missing");
    return f.decode_image(img, cs, img_field);
}

/// The base colour texture of the first material a primitive uses, decoded to linear RGB.
Image read_base_color(const GltfFile& f, std::vector<std::string>& warnings) {
    const tinygltf::Model& model = f.model();
    if (model.meshes.empty()) f.fail("meshes[0]", "missing");
    const std::vector<tinygltf::Primitive>& prims = model.meshes[0].primitives;
    if (prims.empty()) f.fail("meshes[0].primitives", "missing");
    if (prims[0].material < 0) f.fail("meshes[0].primitives[0].material", "missing or not a non-negative integer");
    const auto mat_index = static_cast<std::size_t>(prims[0].material);
    const std::string mat_field = "materials[" + std::to_string(mat_index) + "]";
    if (mat_index >= model.materials.size()) f.fail(mat_field, "missing");
    const tinygltf::PbrMetallicRoughness& pbr = model.materials[mat_index].pbrMetallicRoughness;
    const std::string tex_field = mat_field + ".pbrMetallicRoughness.baseColorTexture";
    if (pbr.baseColorTexture.index < 0) f.fail(tex_field, "no base colour texture: nothing to take the albedo from");
    if (pbr.baseColorTexture.texCoord != 0) f.fail(tex_field + ".texCoord", "only TEXCOORD_0 is supported");
    const auto tex = static_cast<std::size_t>(pbr.baseColorTexture.index);
    const Image decoded = decode_texture(f, tex, ColorSpace::Srgb);
    const std::string img_field = "images[" + std::to_string(model.textures[tex].source) + "]";
    Image albedo(decoded.width, decoded.height, 3); // grey replicated, alpha dropped
    for (std::size_t i = 0; i < static_cast<std::size_t>(decoded.width) * decoded.height; ++i)
        for (int c = 0; c < 3; ++c)
            albedo.pixels[i * 3 + c] = decoded.pixels[i * decoded.channels + (decoded.channels >= 3 ? c : 0)];
    if (pbr.baseColorFactor.size() != 4) // linear multiplier (glTF 2.0 section 3.9.2)
        f.fail(mat_field + ".pbrMetallicRoughness.baseColorFactor", "not 4 numbers");
    for (std::size_t i = 0; i < albedo.pixels.size(); ++i)
        albedo.pixels[i] *= static_cast<float>(pbr.baseColorFactor[i % 3]);
    // A float image (OpenEXR) or a huge factor could give NaN or infinity: refused, as the extension's albedo.
    if (!std::all_of(albedo.pixels.begin(), albedo.pixels.end(), [](float v) { return std::isfinite(v); }))
        f.fail(img_field, "the base colour (times baseColorFactor) is not finite everywhere: an albedo is a finite reflectance");
    const bool other_materials = std::any_of(prims.begin(), prims.end(), [&](const tinygltf::Primitive& p) {
        return p.material >= 0 && static_cast<std::size_t>(p.material) != mat_index;
    });
    if (other_materials || model.meshes.size() > 1)
        warnings.push_back("several primitives or meshes: the albedo is the base colour texture of " + mat_field +
                           " for all of them");
    return albedo;
}

/// The normal map's PNG (linear, 8 bits) as a bufferView of `glb`; nothing when the bundle has
/// no normal map (its TANGENT attribute goes with the mesh, write_bundle).
std::optional<std::size_t> add_normal_map(GlbWriter& glb, const Bundle& bundle, const fs::path& path) {
    if (!bundle.normal_map) return std::nullopt;
    const Image& nm = *bundle.normal_map;
    if (nm.width != bundle.albedo.width || nm.height != bundle.albedo.height || nm.channels != 3 ||
        nm.pixels.size() != static_cast<std::size_t>(nm.width) * nm.height * 3)
        throw InputError(path, "normal_map", "not an RGB image of the albedo's size");
    if (!std::all_of(nm.pixels.begin(), nm.pixels.end(), [](float v) { return v >= 0.0f && v <= 1.0f; }))
        throw InputError(path, "normal_map", "a value outside [0, 1] (or not finite): not an encoded normal map");
    std::vector<std::uint8_t> png;
    try {
        png = encode_image(nm, ImageCodec::Png, ColorSpace::Linear, 8);
    } catch (const Error& e) {
        throw InputError(path, "normal_map", e.what());
    }
    return glb.add_view(png.data(), png.size());
}

/// The material's normalTexture decoded (linear), when it has one.
std::optional<Image> read_normal_map(const GltfFile& f) {
    const tinygltf::Model& model = f.model();
    if (model.meshes.empty() || model.meshes[0].primitives.empty() || model.meshes[0].primitives[0].material < 0) return std::nullopt;
    const auto mat_index = static_cast<std::size_t>(model.meshes[0].primitives[0].material);
    if (mat_index >= model.materials.size() || model.materials[mat_index].normalTexture.index < 0) return std::nullopt;
    const std::string field = "materials[" + std::to_string(mat_index) + "].normalTexture";
    const Image decoded = decode_texture(f, static_cast<std::size_t>(model.materials[mat_index].normalTexture.index), ColorSpace::Linear);
    if (decoded.channels < 3) f.fail(field, "the normal map is not RGB");
    Image out(decoded.width, decoded.height, 3);
    for (std::size_t i = 0; i < static_cast<std::size_t>(decoded.width) * decoded.height; ++i)
        for (int c = 0; c < 3; ++c) out.pixels[i * 3 + c] = decoded.pixels[i * decoded.channels + c];
    return out;
}

/// The extension's `core` object (Bundle::core), absent when the extension has none.
std::optional<CoreMaterial> read_core(const GltfFile& f, const json& ext, const std::string& ext_field) {
    if (!ext.contains("core")) return std::nullopt;
    const std::string cf = ext_field + ".core";
    const json& c = ext["core"];
    if (!c.is_object()) f.fail(cf, "not an object");
    const auto number = [&](const char* key) { // a double, read back exactly
        (void)read_number(f, c, key, cf);    // present, a number, finite
        return c[key].get<double>();
    };
    CoreMaterial core{.roughness = number("roughness"), .f0 = number("f0"), .f90 = number("f90")};
    if (c.contains("clearcoat") || c.contains("clearcoat_roughness")) {
        core.clearcoat = number("clearcoat");
        core.clearcoat_roughness = number("clearcoat_roughness");
    }
    if (const std::optional<std::string> why = invalid_parameters(core))
        f.fail(cf + "." + why->substr(0, why->find(':')), why->substr(why->find(':') + 2));
    return core;
}

/// The extension's linear float albedo: from its bufferView, or from the file `uri` names
/// beside the .glb, or (that file missing) from the 8-bit base colour texture with a warning,
/// divided by `base_color_scale` (the core material's, Bundle::core).
Image read_albedo(const GltfFile& f, const json& ext, const std::string& ext_field, std::vector<std::string>& warnings,
                  double base_color_scale) {
    const std::string af = ext_field + ".albedo";
    if (!ext.contains("albedo")) f.fail(af, "missing");
    const json& a = ext["albedo"];
    const std::size_t w = get_index(f, a, "width", af), h = get_index(f, a, "height", af);
    const std::size_t c = a.contains("channels") ? get_index(f, a, "channels", af) : 3;
    if (w == 0 || h == 0 || w > 65536 || h > 65536) f.fail(af, "width/height out of range");
    if (c < 1 || c > 4) f.fail(af + ".channels", "must be 1 to 4");
    if (a.contains("uri") == a.contains("bufferView")) f.fail(af, "needs one of bufferView and uri");
    Image albedo;
    if (a.contains("bufferView")) {
        albedo.width = static_cast<int>(w);
        albedo.height = static_cast<int>(h);
        albedo.channels = static_cast<int>(c);
        albedo.pixels = read_float_view(f, get_index(f, a, "bufferView", af), w * h * c, af + ".bufferView");
    } else if (std::optional<Image> file = read_float_albedo_file(f, a, af, w, h, c)) {
        albedo = std::move(*file);
    } else {
        albedo = read_base_color(f, warnings);
        for (float& v : albedo.pixels) v = static_cast<float>(v / base_color_scale);
        warnings.push_back(af + ".uri: " + a["uri"].get<std::string>() + " is not beside " + f.path().string() +
                           ": the albedo is decoded from the 8-bit sRGB base colour texture (quantized; keep the "
                           "file beside the bundle, or write the bundle with --embed-float-albedo)");
    }
    // A NaN or infinite albedo would render as NaN (or black) without a word: refused, naming the texel.
    const auto finite = [](float v) { return std::isfinite(v); };
    const auto bad = std::find_if_not(albedo.pixels.begin(), albedo.pixels.end(), finite);
    if (bad != albedo.pixels.end()) {
        const auto i = static_cast<std::size_t>(bad - albedo.pixels.begin());
        const auto ch = static_cast<std::size_t>(albedo.channels), width = static_cast<std::size_t>(albedo.width);
        const auto count = static_cast<std::size_t>(std::count_if(albedo.pixels.begin(), albedo.pixels.end(),
                                                                  [&](float v) { return !finite(v); }));
        f.fail(af + (a.contains("uri") ? ".uri" : ".bufferView"),
               std::to_string(count) + " albedo value(s) are not finite (first: texel (" + std::to_string(i / ch % width) +
                   ", " + std::to_string(i / ch / width) + "), channel " + std::to_string(i % ch) + " = " +
                   std::to_string(*bad) + "): an albedo is a finite reflectance");
    }
    return albedo;
}

} // namespace

// -------------------------------------------------------------------------------------------------

Bundle make_bundle(const Mesh& mesh, std::span<const glm::vec2> corner_uv, Image albedo, Material material) {
    if (corner_uv.size() != mesh.triangles.size() * 3)
        throw Error("make_bundle: " + std::to_string(corner_uv.size()) + " corner coordinates for " +
                    std::to_string(mesh.triangles.size()) + " triangles (3 per triangle expected)");
    const std::vector<glm::vec3> normals = mesh.normals.size() == mesh.positions.size()
                                               ? mesh.normals
                                               : compute_vertex_normals(mesh.positions, mesh.triangles);
    Bundle b;
    b.albedo = std::move(albedo);
    b.material = std::move(material);
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

void write_bundle(const fs::path& path, const Bundle& bundle, const BundleWriteOptions& options) {
    const Mesh& mesh = bundle.mesh;
    const std::size_t n = mesh.positions.size();
    if (n == 0 || mesh.triangles.empty()) throw InputError(path, "mesh", "refusing to write an empty mesh");
    if (!mesh.has_texcoords()) throw InputError(path, "mesh.texcoords", "one atlas coordinate per vertex required (make_bundle)");
    if (!mesh.normals.empty() && mesh.normals.size() != n)
        throw InputError(path, "mesh.normals", "not one per vertex");
    // The mesh first in the BIN chunk: POSITION, NORMAL (unit, glTF 3.7.2.1), TEXCOORD_0 and
    // the indices, as write_mesh_glb writes them (add_mesh also checks indices and finiteness).
    GlbWriter glb;
    // With a normal map, its TANGENT attribute (export/normal_map.h) after TEXCOORD_0.
    json primitive = glb.add_mesh(mesh, path, bundle.normal_map ? vertex_tangents(mesh) : std::vector<glm::vec4>{});
    primitive["material"] = 0;
    const Image& albedo = bundle.albedo;
    if (albedo.width <= 0 || albedo.height <= 0 || albedo.channels < 1 || albedo.channels > 4 ||
        albedo.pixels.size() != static_cast<std::size_t>(albedo.width) * albedo.height * albedo.channels)
        throw InputError(path, "albedo", "empty or inconsistent image (1 to 4 channels)");
    const Material& mat = bundle.material;
    const LafortuneRgb* lobe_model = mat.specular ? std::get_if<LafortuneRgb>(&*mat.specular) : nullptr;
    const CoatedParams* coated = mat.specular ? std::get_if<CoatedParams>(&*mat.specular) : nullptr;
    const std::optional<LafortuneRgb> lobe = lobe_model ? std::optional<LafortuneRgb>(*lobe_model) : std::nullopt;
    if (lobe && !(finite3(lobe->cx) && finite3(lobe->cz) && finite3(lobe->n)))
        throw InputError(path, "material.specular", "non-finite lobe parameters");
    if (coated)
        if (const std::optional<std::string> why = invalid_parameters(*mat.specular))
            throw InputError(path, "material.specular.coated." + why->substr(0, why->find(':')), *why);
    if (mat.factorized) {
        const std::vector<FactorTerm>& terms = mat.factorized->terms;
        if (terms.empty() || terms.size() > kMaxFactorTerms)
            throw InputError(path, "material.factorized.terms",
                             std::to_string(terms.size()) + " terms (1 to " + std::to_string(kMaxFactorTerms) + ")");
        for (std::size_t k = 0; k < terms.size(); ++k)
            for (const CubeMap* cube : {&terms[k].g, &terms[k].h})
                if (cube->resolution == 0 || cube->texels.size() != 6ull * cube->resolution * cube->resolution)
                    throw InputError(path, "material.factorized.terms[" + std::to_string(k) + "]." + (cube == &terms[k].g ? "g" : "h"),
                                     "size is not 6 * resolution^2");
    }

    // The base colour for ordinary viewers: the albedo as 8-bit sRGB PNG (glTF images are
    // PNG or JPEG), RGB (grey replicated), clamped to [0, 1].
    // With a fitted core material, times its base_color_scale() (glTF dims the diffuse by 1 - F,
    // and by 1 - Fcc under a clearcoat).
    if (bundle.core)
        if (const std::optional<std::string> why = invalid_parameters(*bundle.core))
            throw InputError(path, "core." + why->substr(0, why->find(':')), *why);
    const float base_scale = bundle.core ? static_cast<float>(bundle.core->base_color_scale()) : 1.0f;
    // The float albedo beside the bundle (OpenEXR, float32), compressed while the PNG is.
    std::future<void> float_albedo;
    if (!options.float_albedo_file.empty()) {
        if (!is_plain_file_name(options.float_albedo_file))
            throw InputError(path, "float_albedo_file", "\"" + options.float_albedo_file + "\" is not a plain file name");
        float_albedo = std::async(std::launch::async, [&] {
            write_image(path.parent_path() / options.float_albedo_file, albedo, ColorSpace::Linear);
        });
    }
    Image rgb(albedo.width, albedo.height, 3);
    for (std::size_t i = 0; i < static_cast<std::size_t>(albedo.width) * albedo.height; ++i)
        for (int c = 0; c < 3; ++c)
            rgb.pixels[i * 3 + c] = base_scale * albedo.pixels[i * albedo.channels + std::min(c, albedo.channels - 1)];
    std::vector<std::uint8_t> png;
    try {
        png = encode_image(rgb, ImageCodec::Png, ColorSpace::Srgb, 8);
    } catch (const Error& e) { // the encoder failed
        throw InputError(path, "albedo", e.what());
    }
    const std::size_t png_view = glb.add_view(png.data(), png.size());
    const std::optional<std::size_t> normal_view = add_normal_map(glb, bundle, path);

    const bool mirrored = mat.factorized && mat.factorized->param == FactorParam::Mirrored;
    const bool warped = mat.factorized && mat.factorized->param == FactorParam::Warped;
    const bool multi_term = mat.factorized && mat.factorized->terms.size() > 1;
    if (warped && !lobe)
        throw InputError(path, "SPECULA_lafortune.parametrization",
                         "warped cube-maps without a Lafortune lobe (their radial factor)");
    json ext = {{"version", coated ? kModelVersion : warped ? 4 : mirrored ? 3 : multi_term ? 2 : 1}};
    if (lobe) {
        ext["lobe"] = {{"cx", vec3_json(lobe->cx)}, {"cz", vec3_json(lobe->cz)}, {"n", vec3_json(lobe->n)}, {"status", mat.status}};
    }
    if (coated) {
        ext["model"] = to_string(MaterialFamily::Coated);
        ext["coated"] = {{"eta", static_cast<double>(coated->eta)},
                         {"alpha", static_cast<double>(coated->alpha)},
                         {"tint", vec3_json(coated->tint)},
                         {"status", mat.status}};
    }
    ext["albedo"] = {{"width", albedo.width}, {"height", albedo.height}, {"channels", albedo.channels}};
    if (options.float_albedo_file.empty()) {
        ext["albedo"]["bufferView"] = glb.add_view(albedo.pixels.data(), albedo.pixels.size() * sizeof(float));
    } else {
        float_albedo.get(); // its error, if any, here
        ext["albedo"]["uri"] = options.float_albedo_file;
    }
    const auto cube_json = [&](const CubeMap& c) {
        return json{{"bufferView", glb.add_view(c.texels.data(), c.texels.size() * sizeof(glm::vec3))}, {"resolution", c.resolution}};
    };
    if (mat.factorized) {
        const std::vector<FactorTerm>& terms = mat.factorized->terms;
        ext["cubeG"] = cube_json(terms[0].g);
        ext["cubeH"] = cube_json(terms[0].h);
        if (terms.size() > 1) {
            json more = json::array();
            for (std::size_t k = 1; k < terms.size(); ++k) more.push_back({{"cubeG", cube_json(terms[k].g)}, {"cubeH", cube_json(terms[k].h)}});
            ext["cubeTerms"] = std::move(more);
        }
        const glm::vec4& w = mat.factorized->warp;
        if (mirrored || warped) ext["parametrization"] = to_string(mat.factorized->param);
        if (warped) ext["warp"] = {w.x, w.y, w.z, w.w};
    }
    if (bundle.core) {
        ext["core"] = {{"roughness", bundle.core->roughness}, {"f0", bundle.core->f0}, {"f90", bundle.core->f90}};
        if (bundle.core->clearcoat > 0.0) {
            ext["core"]["clearcoat"] = bundle.core->clearcoat;
            ext["core"]["clearcoat_roughness"] = bundle.core->clearcoat_roughness;
        }
    }
    ext["info"] = bundle.info.is_object() ? bundle.info : json::object();

    json extensions = {{kExtension, ext}};
    json extensions_used = json::array({kExtension});
    if (bundle.core) {
        // The fitted core material (material/core_material.h core_gltf_fields).
        const CoreGltfFields g = core_gltf_fields(*bundle.core);
        extensions[kIorExtension] = {{"ior", g.ior}};
        const double sc = g.specular_color_factor;
        extensions[kSpecularExtension] = {{"specularColorFactor", {sc, sc, sc}}, {"specularFactor", g.specular_factor}};
        extensions_used.push_back(kIorExtension);
        extensions_used.push_back(kSpecularExtension);
        if (g.clearcoat_factor > 0.0) {
            extensions[kClearcoatExtension] = {{"clearcoatFactor", g.clearcoat_factor},
                                               {"clearcoatRoughnessFactor", g.clearcoat_roughness_factor}};
            extensions_used.push_back(kClearcoatExtension);
        }
    } else if (coated) {
        // glTF's dielectric with both extensions has F0 = min(((ior - 1) / (ior + 1))^2
        // specularColorFactor, 1) specularFactor (KHR_materials_specular, "Interaction with other
        // extensions"; KHR_materials_ior): with ior = eta, specularColorFactor = tint (values above
        // 1 are allowed) and specularFactor = 1 that is the coated reflection's tint times its
        // Fresnel reflectance at normal incidence. The parameters are exact; the viewer's BRDF
        // is not ours (Schlick's Fresnel, untinted at grazing; its diffuse weight 1 - max F
        // instead of T(ci) T(co) / T(1)^2): docs/SPECULA_lafortune.md, "Viewer approximation".
        extensions[kIorExtension] = {{"ior", static_cast<double>(coated->eta)}};
        extensions[kSpecularExtension] = {{"specularColorFactor", vec3_json(coated->tint)}, {"specularFactor", 1.0}};
        extensions_used.push_back(kIorExtension);
        extensions_used.push_back(kSpecularExtension);
    }
    const double roughness = bundle.core ? core_gltf_fields(*bundle.core).roughness_factor
                             : coated    ? roughness_from_coated(*coated)
                                         : roughness_from_lobe(lobe);
    json material = {
        {"name", "specula"},
        {"pbrMetallicRoughness",
         {{"baseColorTexture", {{"index", 0}}}, {"metallicFactor", 0.0}, {"roughnessFactor", roughness}}},
        {"extensions", std::move(extensions)},
    };
    json textures = {{{"sampler", 0}, {"source", 0}}};
    json images = {{{"bufferView", png_view}, {"mimeType", "image/png"}}};
    if (normal_view) {
        material["normalTexture"] = {{"index", 1}};
        textures.push_back({{"sampler", 0}, {"source", 1}});
        images.push_back({{"bufferView", *normal_view}, {"mimeType", "image/png"}});
    }
    glb.write(path, {
                        {"asset", {{"version", "2.0"}, {"generator", "Specula"}}},
                        {"extensionsUsed", std::move(extensions_used)},
                        {"scene", 0},
                        {"scenes", {{{"nodes", {0}}}}},
                        {"nodes", {{{"mesh", 0}, {"name", "specula"}}}},
                        {"meshes", {{{"primitives", {primitive}}}}},
                        {"materials", json::array({material})},
                        {"textures", std::move(textures)},
                        {"samplers",
                         {{{"magFilter", kLinear}, {"minFilter", kLinear}, {"wrapS", kClampToEdge}, {"wrapT", kClampToEdge}}}},
                        {"images", std::move(images)},
                    });
}

Bundle read_bundle(const fs::path& path) {
    const GltfFile f = GltfFile::load(path, "bundle", {.keep_image_bytes = true});
    const json& doc = f.json();
    const tinygltf::Model& model = f.model();
    Bundle b;

    // The material with the extension (the first one).
    const json* ext = nullptr;
    std::string ext_field;
    const json& materials = doc.value("materials", json::array());
    for (std::size_t i = 0; materials.is_array() && i < materials.size() && !ext; ++i) {
        const json& m = materials[i];
        if (m.is_object() && m.contains("extensions") && m["extensions"].is_object() && m["extensions"].contains(kExtension)) {
            ext = &m["extensions"][kExtension];
            ext_field = "materials[" + std::to_string(i) + "].extensions." + kExtension;
        }
    }

    if (!ext) { // a foreign glTF: diffuse only, from the base colour texture
        MeshLoadResult loaded = load_mesh(f, "mesh");
        if (!loaded.mesh.has_texcoords())
            f.fail("meshes[0].primitives[0].attributes.TEXCOORD_0",
                   std::string("no ") + kExtension + " extension and no texture coordinates: not a bundle");
        b.mesh = std::move(loaded.mesh);
        b.warnings = std::move(loaded.warnings);
        b.albedo = read_base_color(f, b.warnings);
        b.warnings.push_back(std::string("no ") + kExtension +
                             " extension: diffuse-only bundle, albedo decoded from the 8-bit sRGB base colour texture");
        return b;
    }

    if (!ext->is_object()) f.fail(ext_field, "not an object");
    const json version = ext->value("version", json());
    if (!version.is_number_integer() || version.get<int>() < 1 || version.get<int>() > kExtensionVersion)
        f.fail(ext_field + ".version",
               "unsupported version (this reader knows 1 to " + std::to_string(kExtensionVersion) + ")");

    // The mesh: one mesh, one triangle primitive, no node transform (docs/SPECULA_lafortune.md).
    if (model.meshes.size() != 1) f.fail("meshes", "a bundle holds exactly one mesh");
    if (model.meshes[0].primitives.size() != 1) f.fail("meshes[0].primitives", "a bundle holds exactly one primitive");
    const tinygltf::Primitive& prim = model.meshes[0].primitives[0];
    const std::string pf = "meshes[0].primitives[0]";
    if (prim.mode >= 0 && prim.mode != TINYGLTF_MODE_TRIANGLES) f.fail(pf + ".mode", "not TRIANGLES");
    for (const tinygltf::Node& node : model.nodes)
        if (!node.matrix.empty() || !node.translation.empty() || !node.rotation.empty() || !node.scale.empty() ||
            !node.children.empty())
            f.fail("nodes", "a bundle's mesh is in world space: node transforms are not supported");
    auto attribute = [&](const char* name) {
        const auto it = prim.attributes.find(name);
        if (it == prim.attributes.end()) f.fail(pf + ".attributes." + name, "missing or not a non-negative integer");
        return it->second;
    };
    const std::vector<float> pos = f.read_float32(attribute("POSITION"), 3, pf + ".attributes.POSITION");
    const std::vector<float> uv = f.read_float32(attribute("TEXCOORD_0"), 2, pf + ".attributes.TEXCOORD_0");
    const std::size_t n = pos.size() / 3;
    if (n == 0) f.fail(pf + ".attributes.POSITION", "no vertices");
    if (uv.size() / 2 != n) f.fail(pf + ".attributes.TEXCOORD_0", "count differs from POSITION's");
    b.mesh.positions.resize(n);
    b.mesh.texcoords.resize(n);
    std::memcpy(b.mesh.positions.data(), pos.data(), pos.size() * sizeof(float));
    std::memcpy(b.mesh.texcoords.data(), uv.data(), uv.size() * sizeof(float));
    for (const glm::vec3& p : b.mesh.positions)
        if (!finite3(p)) f.fail(pf + ".attributes.POSITION", "non-finite vertex position");
    if (prim.indices < 0) f.fail(pf + ".indices", "missing (a bundle is indexed)");
    const std::vector<std::uint32_t> idx = f.read_indices(prim.indices, pf + ".indices");
    if (idx.empty() || idx.size() % 3 != 0) f.fail(pf + ".indices", "count is not a positive multiple of 3");
    b.mesh.triangles.resize(idx.size() / 3);
    for (std::size_t t = 0; t < b.mesh.triangles.size(); ++t) {
        const glm::uvec3 tri(idx[3 * t], idx[3 * t + 1], idx[3 * t + 2]);
        if (tri.x >= n || tri.y >= n || tri.z >= n) f.fail(pf + ".indices", "index out of range");
        b.mesh.triangles[t] = tri;
    }
    if (prim.attributes.count("NORMAL") != 0) {
        const std::vector<float> nrm = f.read_float32(attribute("NORMAL"), 3, pf + ".attributes.NORMAL");
        if (nrm.size() / 3 != n) f.fail(pf + ".attributes.NORMAL", "count differs from POSITION's");
        b.mesh.normals.resize(n);
        std::memcpy(b.mesh.normals.data(), nrm.data(), nrm.size() * sizeof(float));
    } else {
        b.mesh.normals = compute_vertex_normals(b.mesh.positions, b.mesh.triangles);
        b.warnings.push_back("no NORMAL attribute: area-weighted normals computed");
    }

    // The extension's payload. The model (version 5; absent: the thesis's Lafortune lobe).
    MaterialFamily family = MaterialFamily::Lafortune;
    if (ext->contains("model")) {
        const std::string mf = ext_field + ".model";
        const json& m = (*ext)["model"];
        const std::optional<MaterialFamily> named = m.is_string() ? material_family_from_string(m.get<std::string>()) : std::nullopt;
        if (!named) f.fail(mf, "unknown model " + m.dump() + " (this reader knows \"lafortune\" and \"coated\")");
        if (version.get<int>() < kModelVersion)
            f.fail(mf, "present in a version " + std::to_string(version.get<int>()) + " extension (needs version " +
                           std::to_string(kModelVersion) + ")");
        family = *named;
    }
    if (family == MaterialFamily::Coated) {
        const std::string cf = ext_field + ".coated";
        if (ext->contains("lobe")) f.fail(ext_field + ".lobe", "a Lafortune lobe in a \"coated\" model");
        if (!ext->contains("coated")) f.fail(cf, "missing (\"model\": \"coated\" needs eta, alpha and tint)");
        const json& c = (*ext)["coated"];
        if (!c.is_object()) f.fail(cf, "not an object");
        CoatedParams p;
        p.eta = read_number(f, c, "eta", cf);
        p.alpha = read_number(f, c, "alpha", cf);
        p.tint = read_vec3(f, c, "tint", cf);
        // The bounds the fit and the renderer assume (shared/coated.h), named per parameter.
        if (const std::optional<std::string> why = invalid_parameters(p)) f.fail(cf + "." + why->substr(0, why->find(':')), *why);
        if (c.contains("status")) {
            if (!c["status"].is_array()) f.fail(cf + ".status", "not an array of strings");
            for (const json& s : c["status"]) {
                if (!s.is_string()) f.fail(cf + ".status", "not an array of strings");
                b.material.status.push_back(s.get<std::string>());
            }
        }
        b.material.specular = p;
    } else if (ext->contains("coated")) {
        f.fail(ext_field + ".coated", "present without \"model\": \"coated\"");
    }
    if (family == MaterialFamily::Lafortune && ext->contains("lobe")) {
        const json& l = (*ext)["lobe"];
        const std::string lf = ext_field + ".lobe";
        if (!l.is_object()) f.fail(lf, "not an object");
        b.material.specular = LafortuneRgb{read_vec3(f, l, "cx", lf), read_vec3(f, l, "cz", lf), read_vec3(f, l, "n", lf)};
        if (l.contains("status")) {
            if (!l["status"].is_array()) f.fail(lf + ".status", "not an array of strings");
            for (const json& s : l["status"]) {
                if (!s.is_string()) f.fail(lf + ".status", "not an array of strings");
                b.material.status.push_back(s.get<std::string>());
            }
        }
    }
    b.core = read_core(f, *ext, ext_field);
    b.albedo = read_albedo(f, *ext, ext_field, b.warnings, b.core ? b.core->base_color_scale() : 1.0);
    b.normal_map = read_normal_map(f);
    if (ext->contains("cubeG") != ext->contains("cubeH"))
        f.fail(ext_field + (ext->contains("cubeG") ? ".cubeH" : ".cubeG"), "missing: G and H go together");
    if (ext->contains("cubeG")) {
        b.material.factorized = FactorizedSpecular{};
        b.material.factorized->terms.push_back(
            FactorTerm{.g = read_cube(f, *ext, "cubeG", ext_field), .h = read_cube(f, *ext, "cubeH", ext_field)});
    }
    if (ext->contains("cubeTerms")) { // terms 2..K, version 2
        const std::string tf = ext_field + ".cubeTerms";
        const json& terms = (*ext)["cubeTerms"];
        if (version.get<int>() < 2) f.fail(tf, "present in a version 1 extension (needs version 2)");
        if (!ext->contains("cubeG")) f.fail(tf, "further terms without term 1 (cubeG, cubeH)");
        if (!terms.is_array() || terms.empty() || terms.size() > kMaxExtraTerms)
            f.fail(tf, "not an array of 1 to " + std::to_string(kMaxExtraTerms) + " terms");
        for (std::size_t k = 0; k < terms.size(); ++k) {
            const std::string kf = tf + "[" + std::to_string(k) + "]";
            if (!terms[k].is_object()) f.fail(kf, "not an object");
            b.material.factorized->terms.push_back(FactorTerm{.g = read_cube(f, terms[k], "cubeG", kf), .h = read_cube(f, terms[k], "cubeH", kf)});
        }
    }
    if (ext->contains("parametrization")) { // version 3; absent: the thesis's GSHD
        const std::string pf = ext_field + ".parametrization";
        const json& p = (*ext)["parametrization"];
        const std::optional<FactorParam> param = p.is_string() ? factor_param_from_string(p.get<std::string>()) : std::nullopt;
        if (!param) f.fail(pf, "not \"gshd\", \"mirrored\" or \"warped\"");
        const int needs = *param == FactorParam::Warped ? 4 : *param == FactorParam::Mirrored ? 3 : 1;
        if (version.get<int>() < needs)
            f.fail(pf, std::string(to_string(*param)) + " in a version " + std::to_string(version.get<int>()) +
                                           " extension (needs version " + std::to_string(needs) + ")");
        if (!ext->contains("cubeG")) f.fail(pf, "a parametrization without cube-maps (cubeG, cubeH)");
        if (*param == FactorParam::Warped && !(b.material.specular && std::holds_alternative<LafortuneRgb>(*b.material.specular)))
            f.fail(pf, "warped without a Lafortune lobe (its radial factor)");
        b.material.factorized->param = *param;
    }
    const FactorParam read_param = b.material.factorized ? b.material.factorized->param : FactorParam::Gshd;
    if (ext->contains("warp") || read_param == FactorParam::Warped) { // version 4
        const std::string wf = ext_field + ".warp";
        if (read_param != FactorParam::Warped) f.fail(wf, "present without \"parametrization\": \"warped\"");
        const json& w = ext->value("warp", json());
        if (!w.is_array() || w.size() != 4 || !std::all_of(w.begin(), w.end(), [](const json& x) { return x.is_number(); }))
            f.fail(wf, "not an array of 4 numbers (s, k_r, k_g, k_b)");
        glm::vec4& warp = b.material.factorized->warp;
        for (int c = 0; c < 4; ++c) warp[c] = w[static_cast<std::size_t>(c)].get<float>();
        if (!valid_warp(warp)) f.fail(wf, "must be (+-1, k_r, k_g, k_b) with every k in [1/64, 64]");
    }
    if (ext->contains("info")) {
        if (!(*ext)["info"].is_object()) f.fail(ext_field + ".info", "not an object");
        b.info = (*ext)["info"];
    }
    return b;
}

} // namespace specula
