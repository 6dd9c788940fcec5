#pragma once
// The output bundle (pipeline.md section 10): one self-contained glTF 2.0 binary
// (.glb) that any glTF viewer shows, and that Specula's own renderer reads back exactly.
//  - the mesh with the atlas texture coordinates (TEXCOORD_0), smooth normals;
//  - the albedo atlas as the base colour texture (sRGB PNG, as glTF requires);
//  - a standard metallic-roughness approximation of the lobe for ordinary viewers (for the
//    coated family: its GGX roughness, KHR_materials_ior and KHR_materials_specular, exact);
//  - the extension SPECULA_lafortune (docs/SPECULA_lafortune.md) carrying what
//    Specula needs exactly: the specular model of any family (the per-channel Lafortune
//    lobe, or version 5's "model": "coated" with eta, alpha and tint), its fit status, the
//    linear float albedo (so a round trip is exact, not 8-bit), and the factorization cube-maps.
#include "material/core_material.h"
#include "material/material.h"
#include "core/image.h"
#include "capture/mesh.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace specula {

struct Bundle {
    /// World-space mesh. Every vertex has exactly one atlas coordinate (texcoords),
    /// so triangles that share a position but not a patch have their own vertices.
    Mesh mesh;
    Image albedo;                          ///< linear RGB rho, the atlas
    /// The specular model (absent: Lambertian, or left out) with its fit status per channel, and
    /// its factorization's cube-maps. Written as the extension's "lobe" (Lafortune) or "model":
    /// "coated" with "coated" (version 5), "cubeG"/"cubeH" (term 1),
    /// "cubeTerms" (terms 2..K, version 2) and "parametrization" (the thesis's GSHD when absent;
    /// version 3 when mirrored, 4 when warped, with "warp": the warped terms are multiplied by
    /// the lobe's radial factor, so they need the lobe).
    Material material;
    nlohmann::json info = nlohmann::json::object(); ///< provenance (Specula version, capture, report summary)
    /// Optional tangent-space normal map (export/normal_map.h): per atlas texel the encoded
    /// (c + 1) / 2 in [0, 1]^3, atlas size. Written as glTF's material.normalTexture (8-bit
    /// linear PNG) with the mesh's TANGENT attribute (vertex_tangents); read back from it.
    std::optional<Image> normal_map;
    /// glTF's core material for ordinary viewers, fitted to the captured frames (specular/core_fit.h):
    /// written as roughnessFactor, KHR_materials_ior and KHR_materials_specular, the base colour
    /// texture as the albedo times its base_color_scale(), and as the extension's `core` (read back
    /// from there). Absent: the former formulas (the coated family's parameters; a roughness from
    /// the Lafortune lobe's exponent) and the albedo as the base colour.
    std::optional<CoreMaterial> core;
    /// What read_bundle noticed (e.g. "no SPECULA_lafortune extension: diffuse-only bundle
    /// from the 8-bit base colour texture"). Not written.
    std::vector<std::string> warnings;
};

/// A bundle from the pipeline's pieces: splits mesh vertices so each has one atlas
/// coordinate (corner_uv holds 3 per triangle, Atlas::corner_uv). Vertices with the same
/// position index and bit-identical atlas coordinates are merged; normals are kept (computed
/// area-weighted when the mesh has none). Throws Error when corner_uv.size() != 3 * triangles.
[[nodiscard]] Bundle make_bundle(const Mesh& mesh, std::span<const glm::vec2> corner_uv, Image albedo, Material material);

/// The 3 atlas coordinates of each triangle of a bundle's mesh (what render::Scene::corner_uv takes).
/// Throws Error when the mesh has no texcoords.
[[nodiscard]] std::vector<glm::vec2> corner_uvs(const Mesh& mesh);

/// Where write_bundle puts the linear float albedo (the extension's `albedo`).
struct BundleWriteOptions {
    /// Empty: inside the .glb (a float32 bufferView: one file, 12 bytes a texel, three
    /// quarters of a reconstruction's bundle). Otherwise a file name: the albedo is written
    /// beside the .glb as OpenEXR (32-bit float, exact) and the extension names it
    /// (`albedo.uri`), which keeps the .glb lean for ordinary viewers.
    std::string float_albedo_file;
};

/// Writes the .glb atomically (and the float albedo file, when the options name one).
/// Throws InputError naming the file (and the bundle field) on failure: inconsistent sizes,
/// non-finite lobe, coated parameters outside the bounds of shared/coated.h
/// (invalid_parameters), warped cube-maps without a Lafortune lobe, a file too large for a
/// .glb, a float albedo file name that is not a plain file name.
void write_bundle(const std::filesystem::path& path, const Bundle& bundle, const BundleWriteOptions& options = {});

/// Reads a bundle written by write_bundle (or any glTF with the extension). A .glb
/// without the extension is read as a diffuse-only bundle from its base colour texture
/// (sRGB 8-bit) with a warning. A float albedo named by `albedo.uri` is read from that file
/// beside the .glb (a plain file name, a regular file, its size the extension's); when the
/// file is not there, the albedo comes from the 8-bit base colour texture, with a warning. Throws InputError naming the file and the field (an unknown
/// "model", a coated parameter missing or out of range: e.g.
/// materials[0].extensions.SPECULA_lafortune.coated.eta).
[[nodiscard]] Bundle read_bundle(const std::filesystem::path& path);

} // namespace specula
