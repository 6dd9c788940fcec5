// glTF 2.0 mesh I/O (Khronos glTF 2.0 specification, sections 3.6 "Buffers and
// Buffer Views", 3.7 "Meshes", 3.5 "Scenes"/"Transformations").
//
// Files are read and written through capture/gltf_io (the guarded tinygltf loader and the
// .glb writer); this file turns the glTF scene into one world-space triangle mesh. Every
// index taken from the file is range-checked here before it is dereferenced, so a malformed
// file is refused with an InputError instead of crashing.
#include "capture/mesh.h"

#include "capture/gltf_io.h"
#include "core/error.h"

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <nlohmann/json.hpp>
#include <tiny_gltf.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

namespace specula {

namespace fs = std::filesystem;

namespace {

// A triangle is degenerate (zero area) when |e1 x e2| <= kDegenerateRelArea * max_edge^2:
// with float vertices, exactly collinear points give ~1e-7 relative residue after rounding.
constexpr double kDegenerateRelArea = 1e-7;
// Deepest node hierarchy accepted (guards against cycles and stack exhaustion).
constexpr std::size_t kMaxNodeDepth = 1024;
// Normals whose length is within this of 1 are taken as unit (float rounding).
constexpr double kUnitTolerance = 1e-6;

std::string prim_field(int mesh, int prim) {
    return "meshes[" + std::to_string(mesh) + "].primitives[" + std::to_string(prim) + "]";
}

glm::dmat4 node_local_transform(const tinygltf::Node& node, const GltfFile& reader, const std::string& field) {
    if (!node.matrix.empty()) {
        if (node.matrix.size() != 16) reader.fail(field + ".matrix", "must have 16 numbers");
        glm::dmat4 m;
        for (int i = 0; i < 16; ++i) {
            if (!std::isfinite(node.matrix[static_cast<std::size_t>(i)])) reader.fail(field + ".matrix", "non-finite number");
            m[i / 4][i % 4] = node.matrix[static_cast<std::size_t>(i)]; // column-major, as glm
        }
        return m;
    }
    glm::dmat4 m(1.0);
    auto check = [&](const std::vector<double>& v, std::size_t n, const char* name) {
        if (v.empty()) return false;
        if (v.size() != n) reader.fail(field + "." + name, "must have " + std::to_string(n) + " numbers");
        for (double x : v)
            if (!std::isfinite(x)) reader.fail(field + "." + name, "non-finite number");
        return true;
    };
    if (check(node.translation, 3, "translation"))
        m = glm::translate(m, glm::dvec3(node.translation[0], node.translation[1], node.translation[2]));
    if (check(node.rotation, 4, "rotation")) {
        glm::dquat q(node.rotation[3], node.rotation[0], node.rotation[1], node.rotation[2]); // glTF: x, y, z, w
        const double len = glm::length(q);
        if (!(len > 0.0)) reader.fail(field + ".rotation", "zero quaternion");
        m = m * glm::mat4_cast(q / len);
    }
    if (check(node.scale, 3, "scale")) m = glm::scale(m, glm::dvec3(node.scale[0], node.scale[1], node.scale[2]));
    return m;
}

struct Accumulator {
    Mesh mesh;
    bool all_have_texcoords = true;
    std::size_t degenerate = 0;
    std::size_t skipped_primitives = 0;
};

// Triangle vertex indices of a primitive, as a flat list (3 per triangle). A TRIANGLES
// primitive's count must be a multiple of 3 (glTF 2.0 section 3.7.2.1), checked by the caller.
std::vector<std::uint32_t> triangle_list(int mode, std::vector<std::uint32_t> idx) {
    if (mode == TINYGLTF_MODE_TRIANGLES) return idx;
    std::vector<std::uint32_t> out;
    if (idx.size() < 3) return out;
    out.reserve((idx.size() - 2) * 3);
    for (std::size_t i = 0; i + 2 < idx.size(); ++i) {
        if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) { // glTF 2.0 section 3.7.2.1: odd triangles swap the first two
            if (i % 2 == 0) out.insert(out.end(), {idx[i], idx[i + 1], idx[i + 2]});
            else out.insert(out.end(), {idx[i + 1], idx[i], idx[i + 2]});
        } else { // fan
            out.insert(out.end(), {idx[i + 1], idx[i + 2], idx[0]});
        }
    }
    return out;
}

void add_primitive(Accumulator& acc, const GltfFile& reader, const tinygltf::Primitive& prim, int mesh_i, int prim_i,
                   const glm::dmat4& world) {
    const std::string pf = prim_field(mesh_i, prim_i);
    const int mode = prim.mode < 0 ? TINYGLTF_MODE_TRIANGLES : prim.mode;
    if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP && mode != TINYGLTF_MODE_TRIANGLE_FAN) {
        ++acc.skipped_primitives;
        return;
    }
    const auto pos_it = prim.attributes.find("POSITION");
    if (pos_it == prim.attributes.end()) reader.fail(pf + ".attributes.POSITION", "missing");
    const std::string pos_field = pf + ".attributes.POSITION";
    const std::vector<double> pos = reader.read_floats(pos_it->second, 3, pos_field);
    const std::size_t n = pos.size() / 3;
    for (double v : pos)
        if (!std::isfinite(v)) reader.fail(pos_field, "non-finite vertex position");

    std::vector<double> nrm;
    if (auto it = prim.attributes.find("NORMAL"); it != prim.attributes.end()) {
        nrm = reader.read_floats(it->second, 3, pf + ".attributes.NORMAL");
        if (nrm.size() != pos.size()) reader.fail(pf + ".attributes.NORMAL", "count differs from POSITION");
    }
    std::vector<double> uv;
    if (auto it = prim.attributes.find("TEXCOORD_0"); it != prim.attributes.end()) {
        uv = reader.read_floats(it->second, 2, pf + ".attributes.TEXCOORD_0");
        if (uv.size() / 2 != n) reader.fail(pf + ".attributes.TEXCOORD_0", "count differs from POSITION");
    }

    std::vector<std::uint32_t> idx;
    if (prim.indices >= 0) {
        idx = reader.read_indices(prim.indices, pf + ".indices");
        for (std::uint32_t i : idx)
            if (i >= n)
                reader.fail(pf + ".indices", "index " + std::to_string(i) + " out of range (" + std::to_string(n) +
                                                 " vertices)");
        if (mode == TINYGLTF_MODE_TRIANGLES && idx.size() % 3 != 0)
            reader.fail(pf + ".indices", std::to_string(idx.size()) + " indices: a TRIANGLES count must be a multiple of 3");
    } else {
        // Non-indexed: the vertices in order. n < 2^32 (the accessor count is capped), so they fit uint32.
        if (mode == TINYGLTF_MODE_TRIANGLES && n % 3 != 0)
            reader.fail(pos_field, std::to_string(n) +
                                       " vertices without indices: a TRIANGLES count must be a multiple of 3");
        idx.resize(n);
        for (std::size_t i = 0; i < n; ++i) idx[i] = static_cast<std::uint32_t>(i);
    }
    idx = triangle_list(mode, std::move(idx));

    const glm::dmat3 linear(world);
    const glm::dmat3 normal_matrix = glm::transpose(glm::inverse(linear));
    const bool mirrored = glm::determinant(linear) < 0.0; // glTF: negative determinant reverses the winding

    const std::size_t base = acc.mesh.positions.size();
    if (base + n > std::numeric_limits<std::uint32_t>::max()) reader.fail(pos_field, "too many vertices");
    std::vector<glm::vec3> world_pos(n);
    for (std::size_t i = 0; i < n; ++i) {
        const glm::dvec4 p = world * glm::dvec4(pos[3 * i], pos[3 * i + 1], pos[3 * i + 2], 1.0);
        world_pos[i] = glm::vec3(p);
        if (!std::isfinite(world_pos[i].x) || !std::isfinite(world_pos[i].y) || !std::isfinite(world_pos[i].z))
            reader.fail(pos_field, "vertex position is not finite after the node transforms");
    }

    std::vector<glm::uvec3> tris;
    tris.reserve(idx.size() / 3);
    for (std::size_t t = 0; t + 2 < idx.size(); t += 3) {
        glm::uvec3 tri(static_cast<glm::uint>(idx[t]), static_cast<glm::uint>(idx[t + 1]),
                       static_cast<glm::uint>(idx[t + 2]));
        if (mirrored) std::swap(tri.y, tri.z);
        tris.push_back(tri);
    }

    // Normals: read ones transformed by the inverse transpose; computed (area-weighted, world space) where absent or unusable.
    std::vector<glm::vec3> normals(n);
    std::optional<std::vector<glm::vec3>> computed;
    for (std::size_t i = 0; i < n; ++i) {
        glm::dvec3 v(0.0);
        if (!nrm.empty()) v = normal_matrix * glm::dvec3(nrm[3 * i], nrm[3 * i + 1], nrm[3 * i + 2]);
        const double len = glm::length(v);
        if (std::isfinite(len) && len > 1e-20) {
            // Renormalize only when needed, so unit normals under an identity transform load bit-exact.
            normals[i] = glm::vec3(std::abs(len - 1.0) > kUnitTolerance ? v / len : v);
        } else {
            if (!computed) computed = compute_vertex_normals(world_pos, tris);
            normals[i] = (*computed)[i];
        }
    }

    for (const glm::uvec3& tri : tris) {
        const glm::dvec3 a(world_pos[tri.x]), b(world_pos[tri.y]), c(world_pos[tri.z]);
        const glm::dvec3 e1 = b - a, e2 = c - a, e3 = c - b;
        const double max_edge2 = std::max({glm::dot(e1, e1), glm::dot(e2, e2), glm::dot(e3, e3)});
        if (!(glm::length(glm::cross(e1, e2)) > kDegenerateRelArea * max_edge2)) {
            ++acc.degenerate;
            continue;
        }
        acc.mesh.triangles.emplace_back(tri + glm::uvec3(static_cast<glm::uint>(base)));
    }
    acc.mesh.positions.insert(acc.mesh.positions.end(), world_pos.begin(), world_pos.end());
    acc.mesh.normals.insert(acc.mesh.normals.end(), normals.begin(), normals.end());
    if (uv.empty()) {
        acc.all_have_texcoords = false;
    } else if (acc.all_have_texcoords) {
        for (std::size_t i = 0; i < n; ++i)
            acc.mesh.texcoords.emplace_back(static_cast<float>(uv[2 * i]), static_cast<float>(uv[2 * i + 1]));
    }
}

} // namespace

MeshLoadResult load_mesh(const GltfFile& reader, const std::string& field) {
    const fs::path& path = reader.path();
    const tinygltf::Model& model = reader.model();

    // Root nodes: the default scene's, else every scene's, else nodes that are nobody's child.
    std::vector<int> roots;
    if (model.defaultScene >= 0 && static_cast<std::size_t>(model.defaultScene) < model.scenes.size()) {
        roots = model.scenes[static_cast<std::size_t>(model.defaultScene)].nodes;
    } else if (!model.scenes.empty()) {
        for (const auto& scene : model.scenes) roots.insert(roots.end(), scene.nodes.begin(), scene.nodes.end());
    } else {
        std::vector<bool> is_child(model.nodes.size(), false);
        for (const auto& node : model.nodes)
            for (int c : node.children)
                if (c >= 0 && static_cast<std::size_t>(c) < model.nodes.size()) is_child[static_cast<std::size_t>(c)] = true;
        for (std::size_t i = 0; i < model.nodes.size(); ++i)
            if (!is_child[i]) roots.push_back(static_cast<int>(i));
    }

    Accumulator acc;
    struct Item {
        int node;
        glm::dmat4 parent;
        std::size_t depth;
    };
    std::vector<Item> stack;
    for (auto it = roots.rbegin(); it != roots.rend(); ++it) stack.push_back({*it, glm::dmat4(1.0), 0});
    std::size_t visits = 0;
    const std::size_t max_visits = model.nodes.size() * 64 + 64; // a tree visits each node once per scene reference
    while (!stack.empty()) {
        const Item item = stack.back();
        stack.pop_back();
        const std::string nf = "nodes[" + std::to_string(item.node) + "]";
        if (item.node < 0 || static_cast<std::size_t>(item.node) >= model.nodes.size())
            reader.fail(nf, "node index out of range");
        if (item.depth > kMaxNodeDepth || ++visits > max_visits)
            reader.fail(nf, "node hierarchy is not a tree (cycle or excessive depth)");
        const tinygltf::Node& node = model.nodes[static_cast<std::size_t>(item.node)];
        const glm::dmat4 world = item.parent * node_local_transform(node, reader, nf);
        if (node.mesh >= 0) {
            if (static_cast<std::size_t>(node.mesh) >= model.meshes.size()) reader.fail(nf + ".mesh", "mesh index out of range");
            const tinygltf::Mesh& mesh = model.meshes[static_cast<std::size_t>(node.mesh)];
            for (std::size_t p = 0; p < mesh.primitives.size(); ++p)
                add_primitive(acc, reader, mesh.primitives[p], node.mesh, static_cast<int>(p), world);
        }
        for (auto it = node.children.rbegin(); it != node.children.rend(); ++it)
            stack.push_back({*it, world, item.depth + 1});
    }

    MeshLoadResult result;
    result.mesh = std::move(acc.mesh);
    if (!acc.all_have_texcoords) result.mesh.texcoords.clear();
    if (acc.skipped_primitives > 0)
        result.warnings.push_back(path.string() + ": skipped " + std::to_string(acc.skipped_primitives) +
                                  " primitive(s) that are points or lines");
    if (acc.degenerate > 0)
        result.warnings.push_back(path.string() + ": dropped " + std::to_string(acc.degenerate) +
                                  " degenerate (zero-area) triangle(s)");
    if (result.mesh.triangles.empty())
        throw InputError(path, field, "empty mesh: no (non-degenerate) triangles in the scene");
    result.warnings.insert(result.warnings.begin(), reader.warnings().begin(), reader.warnings().end());
    return result;
}

MeshLoadResult load_mesh(const fs::path& path, const std::string& field) {
    const GltfFile file = GltfFile::load(path, field);
    try {
        return load_mesh(file, field);
    } catch (const std::bad_alloc&) { // sizes come from the file: a hostile one must not escape as bad_alloc
        throw InputError(path, field, "out of memory while reading the mesh (implausible sizes in the file?)");
    }
}

std::vector<glm::vec3> compute_vertex_normals(const std::vector<glm::vec3>& positions,
                                              const std::vector<glm::uvec3>& triangles) {
    // Unnormalized face normal = 2 * area * unit normal, so summing it weights by area.
    std::vector<glm::dvec3> sum(positions.size(), glm::dvec3(0.0));
    for (const glm::uvec3& t : triangles) {
        if (t.x >= positions.size() || t.y >= positions.size() || t.z >= positions.size()) continue;
        const glm::dvec3 a(positions[t.x]), b(positions[t.y]), c(positions[t.z]);
        const glm::dvec3 n = glm::cross(b - a, c - a);
        sum[t.x] += n;
        sum[t.y] += n;
        sum[t.z] += n;
    }
    std::vector<glm::vec3> out(positions.size());
    for (std::size_t i = 0; i < sum.size(); ++i) {
        const double len = glm::length(sum[i]);
        out[i] = (std::isfinite(len) && len > 0.0) ? glm::vec3(sum[i] / len) : glm::vec3(0.0f, 0.0f, 1.0f);
    }
    return out;
}

Bounds mesh_bounds(const Mesh& mesh) {
    Bounds b;
    if (mesh.positions.empty()) return b;
    b.min = glm::vec3(std::numeric_limits<float>::infinity());
    b.max = glm::vec3(-std::numeric_limits<float>::infinity());
    for (const glm::vec3& p : mesh.positions) {
        b.min = glm::min(b.min, p);
        b.max = glm::max(b.max, p);
    }
    return b;
}

std::vector<glm::vec3> gltf_unit_normals(const Mesh& mesh) {
    const std::size_t n = mesh.positions.size();
    std::vector<glm::vec3> normals =
        mesh.normals.size() == n ? mesh.normals : compute_vertex_normals(mesh.positions, mesh.triangles);
    std::optional<std::vector<glm::vec3>> computed;
    for (std::size_t i = 0; i < n; ++i) {
        const glm::dvec3 v(normals[i]);
        const double len = glm::length(v);
        if (std::isfinite(len) && len > 1e-20) {
            if (std::abs(len - 1.0) > kUnitTolerance) normals[i] = glm::vec3(v / len);
        } else {
            if (!computed) computed = compute_vertex_normals(mesh.positions, mesh.triangles);
            normals[i] = (*computed)[i];
        }
    }
    return normals;
}

void write_mesh_glb(const fs::path& path, const Mesh& mesh) {
    GlbWriter glb;
    const nlohmann::json primitive = glb.add_mesh(mesh, path);
    glb.write(path, {
                        {"asset", {{"version", "2.0"}, {"generator", "specula"}}},
                        {"scene", 0},
                        {"scenes", {{{"nodes", {0}}}}},
                        {"nodes", {{{"mesh", 0}}}},
                        {"meshes", {{{"primitives", {primitive}}}}},
                    });
}

} // namespace specula
