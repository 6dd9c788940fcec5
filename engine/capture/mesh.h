#pragma once
// Triangle meshes in world coordinates, read from and written to glTF 2.0
// (.glb / .gltf) through capture/gltf_io (the guarded tinygltf loader and the .glb writer).
#include <glm/glm.hpp>

#include <filesystem>
#include <string>
#include <vector>

namespace specula {

class GltfFile;

struct Mesh {
    std::vector<glm::vec3> positions;  // world space, all node transforms applied
    std::vector<glm::vec3> normals;    // unit, one per position (read or computed area-weighted)
    std::vector<glm::vec2> texcoords;  // optional (empty when the file has none); synthetic truth textures use them
    std::vector<glm::uvec3> triangles; // indices into positions; degenerate triangles removed

    [[nodiscard]] std::size_t triangle_count() const noexcept { return triangles.size(); }
    [[nodiscard]] bool has_texcoords() const noexcept { return !texcoords.empty() && texcoords.size() == positions.size(); }
};

struct MeshLoadResult {
    Mesh mesh;
    std::vector<std::string> warnings; // e.g. "dropped 3 degenerate triangles"
};

/// Loads every triangle primitive of every node of the default scene (all
/// scenes' root nodes when there is no default), with node transforms applied
/// (normals by the inverse transpose). Computes area-weighted normals where a
/// primitive has none. Drops degenerate (zero-area) triangles with a warning.
/// Throws InputError naming the file and the field (e.g. "mesh_path",
/// "meshes[2].primitives[0].attributes.POSITION") on: missing/unreadable file,
/// empty mesh, non-finite vertices, out-of-range indices, a TRIANGLES primitive whose
/// index (or, without indices, vertex) count is not a multiple of 3, and everything the
/// loader guards against (capture/gltf_io.h: JSON nesting, duplicate keys, URIs outside the
/// file's folder or not regular files, required extensions, accessor ranges).
[[nodiscard]] MeshLoadResult load_mesh(const std::filesystem::path& path, const std::string& field = "mesh_path");

/// The same from a file already loaded (capture/gltf_io.h); `field` names it in errors about
/// the mesh as a whole (e.g. "empty mesh").
[[nodiscard]] MeshLoadResult load_mesh(const GltfFile& file, const std::string& field);

/// Writes a single-primitive .glb (POSITION, NORMAL, TEXCOORD_0 when present, uint32 indices), atomically.
void write_mesh_glb(const std::filesystem::path& path, const Mesh& mesh);

/// The mesh's normals as glTF requires them (unit length, glTF 3.7.2.1): those within 1e-6 of
/// unit length unchanged, others renormalized, zero or non-finite ones (or all, when the mesh
/// has none) replaced by the computed area-weighted normal.
[[nodiscard]] std::vector<glm::vec3> gltf_unit_normals(const Mesh& mesh);

/// Area-weighted vertex normals (normalized; a vertex on no triangle gets +Z).
[[nodiscard]] std::vector<glm::vec3> compute_vertex_normals(const std::vector<glm::vec3>& positions,
                                                            const std::vector<glm::uvec3>& triangles);

/// Axis-aligned bounds.
struct Bounds {
    glm::vec3 min{0.0f};
    glm::vec3 max{0.0f};
    [[nodiscard]] glm::vec3 center() const { return 0.5f * (min + max); }
    [[nodiscard]] float radius() const { return 0.5f * glm::length(max - min); }
    [[nodiscard]] bool contains(const glm::dvec3& p) const {
        return p.x >= min.x && p.y >= min.y && p.z >= min.z && p.x <= max.x && p.y <= max.y && p.z <= max.z;
    }
};
[[nodiscard]] Bounds mesh_bounds(const Mesh& mesh);

} // namespace specula
