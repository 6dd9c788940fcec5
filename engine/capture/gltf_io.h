#pragma once
// glTF 2.0 I/O (Khronos glTF 2.0 specification), the one path every stage takes: capture's
// mesh (capture/mesh.cpp) and the output bundle (export/bundle.cpp) read and write .glb /
// .gltf files only through this module.
//
// Reading is guarded, because a glTF file is input from anywhere. Before any parser builds
// the document, the JSON text is checked for nesting depth (tinygltf converts "extras"
// recursively: 100,000 levels overflow the stack) and duplicate keys; the parsed document is
// checked for required extensions, buffer and image URIs (inside the file's folder, regular
// files only) and bufferView ranges. Only then does tinygltf (Debian's compiled library)
// build the model, with file callbacks that open nothing but the URIs checked here. Accessors
// are then read through GltfFile, which checks counts, offsets and strides against the
// bufferViews and buffers before it allocates. Every refusal is an InputError naming the file
// and the JSON field.
//
// Writing: GlbWriter builds the BIN chunk and its bufferViews/accessors, and writes the .glb
// container (glTF 2.0 chapter 4) from a JSON document built with nlohmann::json. Not through
// tinygltf's serializer: its Value narrows every JSON integer to int and it leaves out
// default values (roughnessFactor 1), so the bundle's free-form "info" and its viewer material
// would not survive (docs/SPECULA_lafortune.md).
#include "capture/mesh.h"
#include "core/image.h"

#include <nlohmann/json.hpp>
#include <tiny_gltf.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

namespace specula {

/// Deepest JSON nesting accepted, checked on the text before parsing (as capture.json's).
inline constexpr int kMaxGltfJsonDepth = 256;
/// Most elements an accessor may have: 2^28 (a quarter billion vertices or indices, far
/// beyond any mesh Specula reconstructs), so a count from the file never sizes an allocation
/// of gigabytes, even for an accessor without data (all zeros, plus sparse values).
inline constexpr std::size_t kMaxGltfAccessorCount = std::size_t{1} << 28;
/// Largest file, buffer or linked file accepted: a .glb's 32-bit length field caps a binary
/// glTF at 4 GiB - 1 (glTF 2.0 section 4.3, the header), and tinygltf takes lengths as unsigned int.
inline constexpr std::uint64_t kMaxGltfFileBytes = 0xFFFFFFFFull;

/// The extensions Specula honours when a file lists them in extensionsRequired: its own
/// material extension (docs/SPECULA_lafortune.md), and KHR_mesh_quantization (integer vertex
/// attributes, which GltfFile::read_floats decodes, normalized or not). Any other, such as
/// KHR_draco_mesh_compression or EXT_meshopt_compression (compressed geometry), is refused.
inline constexpr const char* kHonouredGltfExtensions[] = {"SPECULA_lafortune", "KHR_mesh_quantization"};

struct GltfLoadOptions {
    /// Keep the encoded bytes of images given by URI (data: or a file), so decode_image can
    /// decode them. Images in a bufferView are always available.
    bool keep_image_bytes = false;
};

/// A checked glTF file: the tinygltf model, the JSON document it came from (numbers exact:
/// tinygltf's Value narrows integers to int, so extensions are read from here) and readers
/// that range-check every index, offset and count before they touch or allocate memory.
class GltfFile {
public:
    /// Reads and checks `path` (.glb or .gltf, told apart by the GLB magic). `field` names
    /// the file in errors about the file as a whole (missing, not a regular file, not glTF),
    /// e.g. "mesh_path"; errors about its content name the JSON field, e.g. "buffers[0].uri".
    [[nodiscard]] static GltfFile load(const std::filesystem::path& path, const std::string& field,
                                       const GltfLoadOptions& options = {});

    [[nodiscard]] const std::filesystem::path& path() const noexcept { return m_path; }
    [[nodiscard]] const tinygltf::Model& model() const noexcept { return m_model; }
    [[nodiscard]] const nlohmann::json& json() const noexcept { return m_json; }
    /// What loading noticed without refusing (e.g. a linked image that does not exist).
    [[nodiscard]] const std::vector<std::string>& warnings() const noexcept { return m_warnings; }

    [[noreturn]] void fail(const std::string& field, const std::string& message) const;

    /// Accessor `index` as `components` doubles per element (glTF 2.0 section 3.6.2):
    /// integer components normalized when the accessor says so (section 3.11), sparse values
    /// applied. Refuses a count above kMaxGltfAccessorCount or elements beyond the bufferView.
    [[nodiscard]] std::vector<double> read_floats(int index, int components, const std::string& field) const;
    /// Accessor `index`, which must be FLOAT, as floats: the file's bits exactly.
    [[nodiscard]] std::vector<float> read_float32(int index, int components, const std::string& field) const;
    /// An index accessor (unsigned byte, short or int scalars; not sparse).
    [[nodiscard]] std::vector<std::uint32_t> read_indices(int index, const std::string& field) const;
    /// The bytes of bufferView `index`.
    [[nodiscard]] std::span<const std::uint8_t> view_bytes(int index, const std::string& field) const;
    /// Image `index` (bufferView or URI) decoded to linear float (core/image.h decode_image:
    /// width and height are read from the header and refused above kMaxDecodedImageDimension
    /// before anything is decoded).
    [[nodiscard]] Image decode_image(int index, ColorSpace integer_encoding, const std::string& field) const;

private:
    GltfFile() = default;
    struct Span {
        const unsigned char* data = nullptr;
        std::size_t stride = 0;
    };
    const tinygltf::Accessor& accessor(int index, const std::string& field) const;
    Span span(int view_index, std::size_t byte_offset, int component_type, int components, std::size_t count,
              const std::string& field) const;
    std::vector<std::uint32_t> read_index_span(int view, std::size_t byte_offset, int component_type,
                                               std::size_t count, const std::string& field) const;
    double component(const unsigned char* elem, int c, int type, bool normalized, const std::string& field) const;

    std::filesystem::path m_path;
    tinygltf::Model m_model;
    nlohmann::json m_json;
    std::vector<std::string> m_warnings;
    std::vector<std::vector<std::uint8_t>> m_image_bytes; // per image, when kept (URI images only)
};

/// Builds a .glb: one binary buffer (the BIN chunk) with its bufferViews and accessors, and
/// the JSON document around them.
class GlbWriter {
public:
    /// Appends `bytes` to the BIN chunk at a 4-byte aligned offset (glTF 2.0 section 3.6.2.4:
    /// accessor data must be aligned to its component size) as a new bufferView, with
    /// `target` when non-zero; returns the bufferView's index.
    std::size_t add_view(const void* data, std::size_t bytes, int target = 0);
    /// Adds an accessor; returns its index.
    std::size_t add_accessor(nlohmann::json accessor);
    /// Adds a triangle mesh's accessors: POSITION (with min and max, which glTF requires),
    /// NORMAL (unit: gltf_unit_normals), TEXCOORD_0 when the mesh has texture coordinates, and
    /// uint32 indices, in that order; with `tangents` (one per vertex) also TANGENT (VEC4, after
    /// TEXCOORD_0). Returns the primitive {attributes, indices, mode}.
    /// Checks the mesh first (non-empty, indices in range, finite positions and texture
    /// coordinates) and throws InputError(file, "mesh...", ...) naming `file`, the file being written.
    nlohmann::json add_mesh(const Mesh& mesh, const std::filesystem::path& file, std::span<const glm::vec4> tangents = {});
    /// Adds the buffer, bufferViews and accessors to `doc` and writes the .glb atomically (a
    /// JSON chunk padded with spaces and a BIN chunk padded with zeros, glTF 2.0 section 4.4).
    /// Throws InputError naming the file when the result would exceed 4 GiB.
    void write(const std::filesystem::path& path, nlohmann::json doc);

private:
    std::vector<std::uint8_t> m_bin;
    nlohmann::json m_views = nlohmann::json::array();
    nlohmann::json m_accessors = nlohmann::json::array();
};

} // namespace specula
