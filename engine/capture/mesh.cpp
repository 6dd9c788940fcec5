// glTF 2.0 mesh I/O (Khronos glTF 2.0 specification, sections 3.6 "Buffers and
// Buffer Views", 3.7 "Meshes", 3.5 "Scenes"/"Transformations").
//
// Reading goes through tinygltf (Debian's compiled library) for parsing; every
// index, offset and count taken from the file is range-checked here before it
// is dereferenced, so a malformed file is refused with an InputError instead of
// crashing. Writing builds the .glb (JSON chunk + BIN chunk) directly.
#include "capture/mesh.h"

#include "core/error.h"
#include "core/file_util.h"

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <nlohmann/json.hpp>
#include <tiny_gltf.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <new>
#include <optional>

namespace specula {

namespace fs = std::filesystem;

namespace {

// A triangle is degenerate (zero area) when |e1 x e2| <= kDegenerateRelArea * max_edge^2:
// with float vertices, exactly collinear points give ~1e-7 relative residue after rounding.
constexpr double kDegenerateRelArea = 1e-7;
// Deepest node hierarchy accepted (guards against cycles and stack exhaustion).
constexpr std::size_t kMaxNodeDepth = 1024;
// Largest count accepted for an accessor with no bufferView (all zeros plus sparse values).
constexpr std::size_t kMaxVerticesWithoutData = std::size_t{1} << 26;
// Normals whose length is within this of 1 are taken as unit (float rounding).
constexpr double kUnitTolerance = 1e-6;

// tinygltf decodes embedded textures by default; textures are ignored here (the
// engine builds its own atlas), so image payloads are accepted without decoding.
bool skip_image_data(tinygltf::Image*, const int, std::string*, std::string*, int, int, const unsigned char*, int,
                     void*) {
    return true;
}

// Reads external buffers only from regular files (a FIFO or device would block or never end).
bool read_regular_file(std::vector<unsigned char>* out, std::string* err, const std::string& path, void* user) {
    std::error_code ec;
    if (!fs::is_regular_file(path, ec)) {
        if (err) *err += "'" + path + "' is not a regular file\n";
        return false;
    }
    return tinygltf::ReadWholeFile(out, err, path, user);
}

std::string prim_field(int mesh, int prim) {
    return "meshes[" + std::to_string(mesh) + "].primitives[" + std::to_string(prim) + "]";
}

class GltfReader {
public:
    GltfReader(const fs::path& path, const tinygltf::Model& model) : m_path(path), m_model(model) {}

    // Reads accessor `index` as `components` doubles per element. Integer
    // components are normalized when the accessor says so. Sparse accessors are applied.
    std::vector<double> read_floats(int index, int components, const std::string& field) const {
        const tinygltf::Accessor& acc = accessor(index, field);
        if (tinygltf::GetNumComponentsInType(static_cast<uint32_t>(acc.type)) != components)
            fail(field, "expected " + std::to_string(components) + " components per element");
        // Validate the data range before allocating: the count comes from the file.
        Span s;
        if (acc.bufferView >= 0) s = span(acc.bufferView, acc.byteOffset, acc.componentType, components, acc.count, field);
        else if (acc.count > kMaxVerticesWithoutData) fail(field, "accessor without data is implausibly large");
        std::vector<double> out(acc.count * static_cast<std::size_t>(components), 0.0);
        if (acc.bufferView >= 0) {
            for (std::size_t i = 0; i < acc.count; ++i)
                for (int c = 0; c < components; ++c)
                    out[i * components + c] =
                        component(s.data + i * s.stride, c, acc.componentType, acc.normalized, field);
        }
        if (acc.sparse.isSparse) {
            const std::string sf = field + ".sparse";
            if (acc.sparse.count < 0 || static_cast<std::size_t>(acc.sparse.count) > acc.count)
                fail(sf, "sparse count out of range");
            const auto n = static_cast<std::size_t>(acc.sparse.count);
            const std::vector<std::uint64_t> idx = read_index_span(
                acc.sparse.indices.bufferView, acc.sparse.indices.byteOffset, acc.sparse.indices.componentType, n,
                sf + ".indices");
            if (acc.sparse.values.byteOffset < 0) fail(sf + ".values", "negative byteOffset");
            const Span v = span(acc.sparse.values.bufferView, static_cast<std::size_t>(acc.sparse.values.byteOffset),
                                acc.componentType, components, n, sf + ".values");
            for (std::size_t k = 0; k < n; ++k) {
                if (idx[k] >= acc.count) fail(sf + ".indices", "index " + std::to_string(idx[k]) + " out of range");
                for (int c = 0; c < components; ++c)
                    out[idx[k] * components + c] =
                        component(v.data + k * v.stride, c, acc.componentType, acc.normalized, sf + ".values");
            }
        }
        return out;
    }

    // Reads an index accessor (unsigned byte/short/int scalars).
    std::vector<std::uint64_t> read_indices(int index, const std::string& field) const {
        const tinygltf::Accessor& acc = accessor(index, field);
        if (acc.type != TINYGLTF_TYPE_SCALAR) fail(field, "indices must be scalars");
        if (acc.sparse.isSparse) fail(field, "sparse index accessors are not supported");
        if (acc.bufferView < 0) fail(field, "index accessor has no bufferView");
        return read_index_span(acc.bufferView, acc.byteOffset, acc.componentType, acc.count, field);
    }

    [[noreturn]] void fail(const std::string& field, const std::string& message) const {
        throw InputError(m_path, field, message);
    }

    const tinygltf::Accessor& accessor(int index, const std::string& field) const {
        if (index < 0 || static_cast<std::size_t>(index) >= m_model.accessors.size())
            fail(field, "accessor index " + std::to_string(index) + " out of range");
        return m_model.accessors[static_cast<std::size_t>(index)];
    }

private:
    struct Span {
        const unsigned char* data = nullptr;
        std::size_t stride = 0;
    };

    // Validates that `count` elements of `components` x componentType fit in the bufferView and its buffer.
    Span span(int view_index, std::size_t byte_offset, int component_type, int components, std::size_t count,
              const std::string& field) const {
        if (view_index < 0 || static_cast<std::size_t>(view_index) >= m_model.bufferViews.size())
            fail(field, "bufferView index " + std::to_string(view_index) + " out of range");
        const tinygltf::BufferView& view = m_model.bufferViews[static_cast<std::size_t>(view_index)];
        if (view.buffer < 0 || static_cast<std::size_t>(view.buffer) >= m_model.buffers.size())
            fail(field, "buffer index " + std::to_string(view.buffer) + " out of range");
        const std::vector<unsigned char>& buffer = m_model.buffers[static_cast<std::size_t>(view.buffer)].data;
        const int csize = tinygltf::GetComponentSizeInBytes(static_cast<uint32_t>(component_type));
        if (csize <= 0) fail(field, "unknown componentType " + std::to_string(component_type));
        const std::size_t elem = static_cast<std::size_t>(csize) * static_cast<std::size_t>(components);
        const std::size_t stride = view.byteStride == 0 ? elem : view.byteStride;
        if (stride < elem) fail(field, "byteStride smaller than an element");
        if (view.byteOffset > buffer.size() || view.byteLength > buffer.size() - view.byteOffset)
            fail(field, "bufferView " + std::to_string(view_index) + " exceeds its buffer");
        Span s{buffer.data() + view.byteOffset, stride};
        if (count == 0) return s;
        // byte_offset + stride * (count - 1) + elem <= byteLength, without overflow.
        if (byte_offset > view.byteLength) fail(field, "byteOffset exceeds the bufferView");
        const std::size_t room = view.byteLength - byte_offset;
        if (elem > room || (count - 1) > (room - elem) / stride)
            fail(field, std::to_string(count) + " elements exceed the bufferView");
        s.data += byte_offset;
        return s;
    }

    std::vector<std::uint64_t> read_index_span(int view, std::size_t byte_offset, int component_type,
                                               std::size_t count, const std::string& field) const {
        if (component_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
            component_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
            component_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)
            fail(field, "indices must be unsigned byte, short or int");
        const Span s = span(view, byte_offset, component_type, 1, count, field);
        std::vector<std::uint64_t> out(count);
        for (std::size_t i = 0; i < count; ++i) {
            const unsigned char* p = s.data + i * s.stride;
            switch (component_type) {
            case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: out[i] = *p; break;
            case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
                std::uint16_t v;
                std::memcpy(&v, p, sizeof v);
                out[i] = v;
                break;
            }
            default: {
                std::uint32_t v;
                std::memcpy(&v, p, sizeof v);
                out[i] = v;
            }
            }
        }
        return out;
    }

    double component(const unsigned char* elem, int c, int type, bool normalized, const std::string& field) const {
        // glTF 2.0 section 3.11 "Animations"/"Accessors": normalized integer decoding (signed: max(v / max, -1)).
        auto get = [&](auto tag) {
            using T = decltype(tag);
            T v;
            std::memcpy(&v, elem + static_cast<std::size_t>(c) * sizeof(T), sizeof(T));
            double d = static_cast<double>(v);
            if (normalized) d = std::max(d / static_cast<double>(std::numeric_limits<T>::max()), -1.0);
            return d;
        };
        switch (type) {
        case TINYGLTF_COMPONENT_TYPE_FLOAT: {
            float v;
            std::memcpy(&v, elem + static_cast<std::size_t>(c) * sizeof(float), sizeof v);
            return static_cast<double>(v);
        }
        case TINYGLTF_COMPONENT_TYPE_BYTE: return get(std::int8_t{});
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return get(std::uint8_t{});
        case TINYGLTF_COMPONENT_TYPE_SHORT: return get(std::int16_t{});
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return get(std::uint16_t{});
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: return get(std::uint32_t{});
        default: fail(field, "unsupported componentType " + std::to_string(type));
        }
    }

    const fs::path& m_path;
    const tinygltf::Model& m_model;
};

glm::dmat4 node_local_transform(const tinygltf::Node& node, const GltfReader& reader, const std::string& field) {
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

// Triangle vertex indices of a primitive, as a flat list (3 per triangle).
std::vector<std::uint64_t> triangle_list(int mode, std::vector<std::uint64_t> idx) {
    if (mode == TINYGLTF_MODE_TRIANGLES) {
        idx.resize(idx.size() - idx.size() % 3);
        return idx;
    }
    std::vector<std::uint64_t> out;
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

void add_primitive(Accumulator& acc, const GltfReader& reader, const tinygltf::Primitive& prim, int mesh_i, int prim_i,
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

    std::vector<std::uint64_t> idx;
    if (prim.indices >= 0) {
        idx = reader.read_indices(prim.indices, pf + ".indices");
        for (std::uint64_t i : idx)
            if (i >= n)
                reader.fail(pf + ".indices", "index " + std::to_string(i) + " out of range (" + std::to_string(n) +
                                                 " vertices)");
    } else {
        idx.resize(n);
        for (std::size_t i = 0; i < n; ++i) idx[i] = i;
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

tinygltf::Model parse_gltf(const fs::path& path, const std::string& field) {
    std::error_code ec;
    if (!fs::exists(path, ec)) throw InputError(path, field, "file not found");
    if (!fs::is_regular_file(path, ec)) throw InputError(path, field, "not a regular file");
    char magic[4] = {};
    {
        std::ifstream in(path, std::ios::binary);
        if (!in) throw InputError(path, field, "cannot read file");
        in.read(magic, 4);
    }
    const bool binary = std::memcmp(magic, "glTF", 4) == 0;
    tinygltf::TinyGLTF loader;
    loader.SetImageLoader(&skip_image_data, nullptr);
    loader.SetFsCallbacks({&tinygltf::FileExists, &tinygltf::ExpandFilePath, &read_regular_file, &tinygltf::WriteWholeFile,
                           nullptr});
    tinygltf::Model model;
    std::string err, warn;
    bool ok = false;
    try {
        ok = binary ? loader.LoadBinaryFromFile(&model, &err, &warn, path.string())
                    : loader.LoadASCIIFromFile(&model, &err, &warn, path.string());
    } catch (const std::exception& e) {
        err = e.what();
        ok = false;
    }
    if (!ok) {
        while (!err.empty() && (err.back() == '\n' || err.back() == ' ')) err.pop_back();
        std::replace(err.begin(), err.end(), '\n', ';');
        throw InputError(path, field, "not a readable glTF 2.0 file" + (err.empty() ? std::string() : " (" + err + ")"));
    }
    return model;
}

} // namespace

namespace {
MeshLoadResult load_mesh_unchecked(const fs::path& path, const std::string& field) {
    const tinygltf::Model model = parse_gltf(path, field);
    const GltfReader reader(path, model);

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
    return result;
}
} // namespace

MeshLoadResult load_mesh(const fs::path& path, const std::string& field) {
    try {
        return load_mesh_unchecked(path, field);
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
    if (mesh.positions.empty() || mesh.triangles.empty()) throw InputError(path, "", "refusing to write an empty mesh");
    const std::size_t n = mesh.positions.size();
    for (const glm::uvec3& t : mesh.triangles)
        if (t.x >= n || t.y >= n || t.z >= n) throw InputError(path, "", "triangle index out of range");
    for (const glm::vec3& p : mesh.positions)
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
            throw InputError(path, "", "non-finite vertex position");
    const std::vector<glm::vec3> normals = gltf_unit_normals(mesh);
    const bool has_uv = mesh.has_texcoords();

    // BIN chunk: positions, normals, [texcoords], indices; every block is 4-byte aligned.
    std::vector<unsigned char> bin;
    auto append = [&](const void* data, std::size_t bytes) {
        const std::size_t offset = bin.size();
        bin.resize(offset + bytes);
        std::memcpy(bin.data() + offset, data, bytes);
        return offset;
    };
    nlohmann::json views = nlohmann::json::array();
    nlohmann::json accessors = nlohmann::json::array();
    auto add_view = [&](const void* data, std::size_t bytes, int target) {
        const std::size_t offset = append(data, bytes);
        views.push_back({{"buffer", 0}, {"byteOffset", offset}, {"byteLength", bytes}, {"target", target}});
        return views.size() - 1;
    };
    constexpr int kArrayBuffer = 34962, kElementArrayBuffer = 34963;

    glm::vec3 lo(std::numeric_limits<float>::infinity()), hi(-std::numeric_limits<float>::infinity());
    for (const glm::vec3& p : mesh.positions) {
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
    }
    nlohmann::json attributes;
    {
        const std::size_t v = add_view(mesh.positions.data(), n * sizeof(glm::vec3), kArrayBuffer);
        accessors.push_back({{"bufferView", v}, {"componentType", TINYGLTF_COMPONENT_TYPE_FLOAT}, {"count", n},
                             {"type", "VEC3"},
                             {"min", {static_cast<double>(lo.x), static_cast<double>(lo.y), static_cast<double>(lo.z)}},
                             {"max", {static_cast<double>(hi.x), static_cast<double>(hi.y), static_cast<double>(hi.z)}}});
        attributes["POSITION"] = accessors.size() - 1;
    }
    {
        const std::size_t v = add_view(normals.data(), n * sizeof(glm::vec3), kArrayBuffer);
        accessors.push_back(
            {{"bufferView", v}, {"componentType", TINYGLTF_COMPONENT_TYPE_FLOAT}, {"count", n}, {"type", "VEC3"}});
        attributes["NORMAL"] = accessors.size() - 1;
    }
    if (has_uv) {
        const std::size_t v = add_view(mesh.texcoords.data(), n * sizeof(glm::vec2), kArrayBuffer);
        accessors.push_back(
            {{"bufferView", v}, {"componentType", TINYGLTF_COMPONENT_TYPE_FLOAT}, {"count", n}, {"type", "VEC2"}});
        attributes["TEXCOORD_0"] = accessors.size() - 1;
    }
    std::size_t indices_accessor = 0;
    {
        std::vector<std::uint32_t> idx;
        idx.reserve(mesh.triangles.size() * 3);
        for (const glm::uvec3& t : mesh.triangles) idx.insert(idx.end(), {t.x, t.y, t.z});
        const std::size_t v = add_view(idx.data(), idx.size() * sizeof(std::uint32_t), kElementArrayBuffer);
        accessors.push_back({{"bufferView", v}, {"componentType", TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT},
                             {"count", idx.size()}, {"type", "SCALAR"}});
        indices_accessor = accessors.size() - 1;
    }
    const nlohmann::json doc = {
        {"asset", {{"version", "2.0"}, {"generator", "specula"}}},
        {"scene", 0},
        {"scenes", {{{"nodes", {0}}}}},
        {"nodes", {{{"mesh", 0}}}},
        {"meshes",
         {{{"primitives",
            {{{"attributes", attributes}, {"indices", indices_accessor}, {"mode", TINYGLTF_MODE_TRIANGLES}}}}}}},
        {"buffers", {{{"byteLength", bin.size()}}}},
        {"bufferViews", views},
        {"accessors", accessors},
    };

    // GLB container (glTF 2.0 section 4.4): 12-byte header, JSON chunk padded with
    // spaces, BIN chunk padded with zeros, both to 4 bytes.
    std::string json_text = doc.dump();
    while (json_text.size() % 4 != 0) json_text.push_back(' ');
    while (bin.size() % 4 != 0) bin.push_back(0);
    const auto u32 = [](std::size_t v) { return static_cast<std::uint32_t>(v); };
    const std::size_t total = 12 + 8 + json_text.size() + 8 + bin.size();
    if (total > std::numeric_limits<std::uint32_t>::max()) throw InputError(path, "", "mesh too large for a .glb");
    std::string out;
    out.reserve(total);
    auto put32 = [&](std::uint32_t v) {
        char b[4];
        std::memcpy(b, &v, 4); // GLB is little-endian, as is every platform we build on
        out.append(b, 4);
    };
    put32(0x46546C67u); // "glTF"
    put32(2u);
    put32(u32(total));
    put32(u32(json_text.size()));
    put32(0x4E4F534Au); // "JSON"
    out += json_text;
    put32(u32(bin.size()));
    put32(0x004E4942u); // "BIN\0"
    out.append(reinterpret_cast<const char*>(bin.data()), bin.size());
    write_text_file(path, out);
}

} // namespace specula
