// glTF mesh I/O: round trips, node transforms, index types, computed normals,
// degenerate triangles, and refusal of broken files (file and field named).
#include "capture/mesh.h"
#include "core/error.h"
#include "core/file_util.h"
#include "gltf_builder.h"
#include "test_dirs.h"

#include "expect_error.h"

#include <gtest/gtest.h>
#include <glm/gtc/matrix_transform.hpp>

#include <sys/stat.h>
#include <fcntl.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <fstream>
#include <future>
#include <limits>

namespace specula {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;

// A closed tetrahedron with per-vertex normals, texcoords and unique vertices per face.
Mesh tetrahedron() {
    const glm::vec3 v[4] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    const glm::uvec3 faces[4] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
    Mesh m;
    for (const glm::uvec3& f : faces) {
        const auto base = static_cast<glm::uint>(m.positions.size());
        for (int k = 0; k < 3; ++k) {
            m.positions.push_back(v[f[k]]);
            m.texcoords.emplace_back(0.25f * static_cast<float>(base / 3), 0.5f * static_cast<float>(k));
        }
        m.triangles.emplace_back(base, base + 1, base + 2);
    }
    m.normals = compute_vertex_normals(m.positions, m.triangles);
    return m;
}

using test::expect_input_error;

void expect_vec_eq(const glm::vec3& a, const glm::vec3& b, float tol = 1e-5f) {
    EXPECT_NEAR(a.x, b.x, tol);
    EXPECT_NEAR(a.y, b.y, tol);
    EXPECT_NEAR(a.z, b.z, tol);
}

// Unit triangle in z = 0, normal +Z; optional indices.
json triangle_primitive(test::GltfBuilder& b, bool with_normals = true) {
    json prim = {{"attributes", {{"POSITION", b.positions({0, 0, 0, 1, 0, 0, 0, 1, 0})}}}};
    if (with_normals) prim["attributes"]["NORMAL"] = b.normals({0, 0, 1, 0, 0, 1, 0, 0, 1});
    return prim;
}

TEST(MeshIo, GlbRoundTripIsExact) {
    test::TempDir dir("mesh");
    const Mesh m = tetrahedron();
    write_mesh_glb(dir / "t.glb", m);
    const MeshLoadResult r = load_mesh(dir / "t.glb");
    EXPECT_TRUE(r.warnings.empty());
    ASSERT_EQ(r.mesh.positions.size(), m.positions.size());
    ASSERT_EQ(r.mesh.triangles.size(), m.triangles.size());
    ASSERT_TRUE(r.mesh.has_texcoords());
    for (std::size_t i = 0; i < m.positions.size(); ++i) {
        EXPECT_EQ(r.mesh.positions[i], m.positions[i]);
        EXPECT_EQ(r.mesh.normals[i], m.normals[i]);
        EXPECT_EQ(r.mesh.texcoords[i], m.texcoords[i]);
    }
    for (std::size_t t = 0; t < m.triangles.size(); ++t) EXPECT_EQ(r.mesh.triangles[t], m.triangles[t]);
}

TEST(MeshIo, GlbIsWellFormedGltf2) {
    test::TempDir dir("mesh");
    Mesh m = tetrahedron();
    m.texcoords.clear();
    write_mesh_glb(dir / "t.glb", m);
    const std::string bytes = read_text_file(dir / "t.glb");
    ASSERT_GE(bytes.size(), 28u);
    auto u32 = [&](std::size_t at) {
        std::uint32_t v;
        std::memcpy(&v, bytes.data() + at, 4);
        return v;
    };
    EXPECT_EQ(bytes.substr(0, 4), "glTF");
    EXPECT_EQ(u32(4), 2u);
    EXPECT_EQ(u32(8), bytes.size());
    const std::uint32_t json_len = u32(12);
    EXPECT_EQ(json_len % 4, 0u);
    EXPECT_EQ(bytes.substr(16, 4), "JSON");
    const json doc = json::parse(bytes.substr(20, json_len));
    const std::uint32_t bin_len = u32(20 + json_len);
    EXPECT_EQ(bin_len % 4, 0u);
    EXPECT_EQ(bytes.substr(24 + json_len, 4), std::string("BIN\0", 4));
    EXPECT_EQ(24u + json_len + 4u + bin_len, bytes.size());
    EXPECT_EQ(doc["asset"]["version"], "2.0");
    EXPECT_EQ(doc["buffers"][0]["byteLength"].get<std::size_t>(), bin_len);
    const json& prim = doc["meshes"][0]["primitives"][0];
    EXPECT_FALSE(prim["attributes"].contains("TEXCOORD_0"));
    const json& pos = doc["accessors"][prim["attributes"]["POSITION"].get<int>()];
    EXPECT_EQ(pos["min"], json({0.0, 0.0, 0.0}));
    EXPECT_EQ(pos["max"], json({1.0, 1.0, 1.0}));
    EXPECT_EQ(doc["accessors"][prim["indices"].get<int>()]["componentType"], 5125);
    for (const json& v : doc["bufferViews"]) EXPECT_EQ(v["byteOffset"].get<std::size_t>() % 4, 0u);
}

TEST(MeshIo, NodeHierarchyTransformsApplied) {
    test::TempDir dir("mesh");
    test::GltfBuilder b;
    const int mesh = b.mesh(json::array({triangle_primitive(b)}));
    // root: translate (1,2,3) -> child: rotate 90 deg about Z, scale 2 -> mesh
    const int child = b.node({{"mesh", mesh}, {"rotation", {0.0, 0.0, std::sqrt(0.5), std::sqrt(0.5)}}, {"scale", {2.0, 2.0, 2.0}}});
    const int root = b.node({{"translation", {1.0, 2.0, 3.0}}, {"children", {child}}});
    // a second root with a column-major matrix: translate (0, 0, -5)
    const int by_matrix = b.node({{"mesh", mesh}, {"matrix", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, -5, 1}}});
    // a node of a scene that is not the default one: ignored
    const int other = b.node({{"mesh", mesh}, {"translation", {100.0, 0.0, 0.0}}});
    b.doc()["scenes"] = {{{"nodes", {root, by_matrix}}}, {{"nodes", {other}}}};
    b.doc()["scene"] = 0;
    b.write(dir / "h.gltf");

    const MeshLoadResult r = load_mesh(dir / "h.gltf");
    ASSERT_EQ(r.mesh.positions.size(), 6u);
    ASSERT_EQ(r.mesh.triangles.size(), 2u);
    // R(90 about Z) * 2 * (1,0,0) = (0,2,0); * (0,1,0) = (-2,0,0)
    expect_vec_eq(r.mesh.positions[0], {1, 2, 3});
    expect_vec_eq(r.mesh.positions[1], {1, 4, 3});
    expect_vec_eq(r.mesh.positions[2], {-1, 2, 3});
    expect_vec_eq(r.mesh.positions[3], {0, 0, -5});
    expect_vec_eq(r.mesh.positions[4], {1, 0, -5});
    for (const glm::vec3& n : r.mesh.normals) expect_vec_eq(n, {0, 0, 1});
    EXPECT_FALSE(r.mesh.has_texcoords());
}

TEST(MeshIo, AllScenesWhenNoDefault) {
    test::TempDir dir("mesh");
    test::GltfBuilder b;
    const int mesh = b.mesh(json::array({triangle_primitive(b)}));
    const int n0 = b.node({{"mesh", mesh}});
    const int n1 = b.node({{"mesh", mesh}, {"translation", {0.0, 0.0, 1.0}}});
    b.doc()["scenes"] = {{{"nodes", {n0}}}, {{"nodes", {n1}}}};
    b.write(dir / "s.gltf");
    EXPECT_EQ(load_mesh(dir / "s.gltf").mesh.triangle_count(), 2u);
}

TEST(MeshIo, NonUniformAndMirroredTransformsKeepNormalsConsistent) {
    test::TempDir dir("mesh");
    test::GltfBuilder b;
    // triangle in the plane x + y = 1 (tilted), normal (1,1,0)/sqrt2
    const float s = static_cast<float>(std::sqrt(0.5));
    json prim = {{"attributes",
                  {{"POSITION", b.positions({1, 0, 0, 0, 1, 0, 1, 0, 1})},
                   {"NORMAL", b.normals({s, s, 0, s, s, 0, s, s, 0})}}}};
    const int mesh = b.mesh(json::array({prim}));
    const int n0 = b.node({{"mesh", mesh}, {"scale", {-3.0, 1.0, 1.0}}});
    b.doc()["scenes"] = {{{"nodes", {n0}}}};
    b.doc()["scene"] = 0;
    b.write(dir / "m.gltf");
    const Mesh m = load_mesh(dir / "m.gltf").mesh;
    ASSERT_EQ(m.triangle_count(), 1u);
    const glm::uvec3 t = m.triangles[0];
    const glm::vec3 geo = glm::normalize(glm::cross(m.positions[t.y] - m.positions[t.x], m.positions[t.z] - m.positions[t.x]));
    for (const glm::vec3& n : m.normals) {
        EXPECT_NEAR(glm::length(n), 1.0f, 1e-6f);
        expect_vec_eq(n, geo); // inverse transpose + flipped winding agree with the geometry
    }
}

TEST(MeshIo, IndexTypesAndNonIndexedPrimitives) {
    test::TempDir dir("mesh");
    test::GltfBuilder b;
    const std::vector<float> quad = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
    json p8 = {{"attributes", {{"POSITION", b.positions(quad)}}}, {"indices", b.indices_u8({0, 1, 2, 0, 2, 3})}};
    json p16 = {{"attributes", {{"POSITION", b.positions(quad)}}}, {"indices", b.indices_u16({0, 1, 2, 0, 2, 3})}};
    json p32 = {{"attributes", {{"POSITION", b.positions(quad)}}}, {"indices", b.indices_u32({0, 1, 2, 0, 2, 3})}, {"mode", 4}};
    json plain = {{"attributes", {{"POSITION", b.positions({0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 0, 0, 1, 1, 0, 0, 1, 0})}}}};
    json strip = {{"attributes", {{"POSITION", b.positions(quad)}}}, {"indices", b.indices_u8({0, 1, 3, 2})}, {"mode", 5}};
    json fan = {{"attributes", {{"POSITION", b.positions(quad)}}}, {"mode", 6}};
    const int mesh = b.mesh(json::array({p8, p16, p32, plain, strip, fan}));
    b.node({{"mesh", mesh}});
    b.write(dir / "i.gltf"); // no scenes: root nodes are taken
    const MeshLoadResult r = load_mesh(dir / "i.gltf");
    EXPECT_TRUE(r.warnings.empty());
    ASSERT_EQ(r.mesh.triangle_count(), 12u);
    for (std::size_t t = 0; t < r.mesh.triangle_count(); ++t) {
        const glm::uvec3 tri = r.mesh.triangles[t];
        const glm::vec3 n = glm::cross(r.mesh.positions[tri.y] - r.mesh.positions[tri.x],
                                       r.mesh.positions[tri.z] - r.mesh.positions[tri.x]);
        EXPECT_GT(n.z, 0.0f) << "triangle " << t << " keeps counter-clockwise winding";
        EXPECT_NEAR(glm::length(n), 1.0f, 1e-6f); // each is half the unit square
    }
    for (const glm::vec3& n : r.mesh.normals) expect_vec_eq(n, {0, 0, 1}); // computed
}

TEST(MeshIo, SparseAccessorApplied) {
    test::TempDir dir("mesh");
    test::GltfBuilder b;
    const int pos = b.positions({0, 0, 0, 1, 0, 0, 0, 1, 0});
    const int idx_view = b.view(std::vector<std::uint16_t>{2, 0});
    const int val_view = b.view(std::vector<float>{0, 5, 0});
    b.doc()["accessors"][pos]["sparse"] = {{"count", 1},
                                          {"indices", {{"bufferView", idx_view}, {"componentType", 5123}}},
                                          {"values", {{"bufferView", val_view}}}};
    const int mesh = b.mesh(json::array({{{"attributes", {{"POSITION", pos}}}}}));
    b.node({{"mesh", mesh}});
    b.write(dir / "sp.gltf");
    const Mesh m = load_mesh(dir / "sp.gltf").mesh;
    ASSERT_EQ(m.positions.size(), 3u);
    expect_vec_eq(m.positions[2], {0, 5, 0});
}

TEST(MeshIo, TexcoordsOnlyWhenEveryPrimitiveHasThem) {
    test::TempDir dir("mesh");
    test::GltfBuilder b;
    json with_uv = triangle_primitive(b);
    with_uv["attributes"]["TEXCOORD_0"] = b.texcoords({0, 0, 1, 0, 0, 1});
    json without = triangle_primitive(b);
    const int m1 = b.mesh(json::array({with_uv}));
    const int m2 = b.mesh(json::array({with_uv, without}));
    b.node({{"mesh", m1}});
    b.write(dir / "uv1.gltf");
    const Mesh a = load_mesh(dir / "uv1.gltf").mesh;
    ASSERT_TRUE(a.has_texcoords());
    EXPECT_EQ(a.texcoords[1], glm::vec2(1, 0));
    b.doc()["nodes"][0]["mesh"] = m2;
    b.write(dir / "uv2.gltf");
    EXPECT_FALSE(load_mesh(dir / "uv2.gltf").mesh.has_texcoords());
}

TEST(MeshIo, ComputedNormalsAreAreaWeighted) {
    // vertex 0 is shared by a big triangle in z = 0 (area 2) and a small one in x = 0 (area 0.005)
    const std::vector<glm::vec3> p = {{0, 0, 0}, {2, 0, 0}, {0, 2, 0}, {0, 0.1f, 0}, {0, 0, 0.1f}};
    const std::vector<glm::uvec3> t = {{0, 1, 2}, {0, 3, 4}};
    const std::vector<glm::vec3> n = compute_vertex_normals(p, t);
    const glm::vec3 expected = glm::normalize(glm::vec3(0, 0, 4) + glm::vec3(0.01f, 0, 0));
    expect_vec_eq(n[0], expected, 1e-6f);
    expect_vec_eq(n[1], {0, 0, 1});
    expect_vec_eq(n[4], {1, 0, 0});
    // a vertex on no triangle gets +Z
    const std::vector<glm::vec3> lonely = compute_vertex_normals({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {5, 5, 5}}, {{0, 1, 2}});
    expect_vec_eq(lonely[3], {0, 0, 1});
}

TEST(MeshIo, DegenerateTrianglesDroppedWithWarning) {
    test::TempDir dir("mesh");
    Mesh m = tetrahedron();
    m.positions.push_back({2, 0, 0});
    m.triangles.emplace_back(0, 0, 1);  // repeated index
    m.triangles.emplace_back(0, 2, 12); // collinear: (0,0,0), (1,0,0), (2,0,0)
    m.normals = compute_vertex_normals(m.positions, m.triangles);
    write_mesh_glb(dir / "d.glb", m);
    const MeshLoadResult r = load_mesh(dir / "d.glb");
    EXPECT_EQ(r.mesh.triangle_count(), 4u);
    ASSERT_EQ(r.warnings.size(), 1u);
    EXPECT_NE(r.warnings[0].find("dropped 2 degenerate"), std::string::npos) << r.warnings[0];
}

TEST(MeshIo, PointsAndLinesSkippedWithWarning) {
    test::TempDir dir("mesh");
    test::GltfBuilder b;
    json points = {{"attributes", {{"POSITION", b.positions({0, 0, 0, 1, 1, 1})}}}, {"mode", 0}};
    json lines = {{"attributes", {{"POSITION", b.positions({0, 0, 0, 1, 1, 1})}}}, {"mode", 1}};
    const int mesh = b.mesh(json::array({points, triangle_primitive(b), lines}));
    b.node({{"mesh", mesh}});
    b.write(dir / "pl.gltf");
    const MeshLoadResult r = load_mesh(dir / "pl.gltf");
    EXPECT_EQ(r.mesh.triangle_count(), 1u);
    ASSERT_EQ(r.warnings.size(), 1u);
    EXPECT_NE(r.warnings[0].find("skipped 2"), std::string::npos) << r.warnings[0];
}

TEST(MeshIo, BoundsOfMesh) {
    const Bounds b = mesh_bounds(tetrahedron());
    EXPECT_EQ(b.min, glm::vec3(0.0f));
    EXPECT_EQ(b.max, glm::vec3(1.0f));
    EXPECT_TRUE(b.contains(glm::dvec3(0.5, 0.5, 0.5)));
    EXPECT_FALSE(b.contains(glm::dvec3(0.5, 0.5, 1.5)));
}

// ---- refusals -----------------------------------------------------------------

TEST(MeshRefusal, MissingFile) {
    test::TempDir dir("mesh");
    const InputError e = expect_input_error([&] { (void)load_mesh(dir / "none.glb"); });
    EXPECT_EQ(e.file(), dir / "none.glb");
    EXPECT_EQ(e.field(), "mesh_path");
}

TEST(MeshRefusal, NotGltf) {
    test::TempDir dir("mesh");
    write_text_file(dir / "x.glb", "this is not a mesh");
    const InputError e = expect_input_error([&] { (void)load_mesh(dir / "x.glb", "mesh_path"); });
    EXPECT_EQ(e.file(), dir / "x.glb");
    EXPECT_EQ(e.field(), "mesh_path");
}

TEST(MeshRefusal, EmptyMesh) {
    test::TempDir dir("mesh");
    test::GltfBuilder b;
    json points = {{"attributes", {{"POSITION", b.positions({0, 0, 0, 1, 1, 1})}}}, {"mode", 0}};
    b.node({{"mesh", b.mesh(json::array({points}))}});
    b.write(dir / "e.gltf");
    const InputError e = expect_input_error([&] { (void)load_mesh(dir / "e.gltf"); });
    EXPECT_EQ(e.field(), "mesh_path");
    EXPECT_NE(std::string(e.what()).find("empty mesh"), std::string::npos);

    // only degenerate triangles: empty too
    Mesh m;
    m.positions = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}};
    m.triangles = {{0, 1, 2}};
    write_mesh_glb(dir / "d.glb", m);
    EXPECT_EQ(expect_input_error([&] { (void)load_mesh(dir / "d.glb"); }).field(), "mesh_path");
}

TEST(MeshRefusal, NonFiniteVertex) {
    test::TempDir dir("mesh");
    test::GltfBuilder b;
    const float nan = std::numeric_limits<float>::quiet_NaN();
    json prim = {{"attributes", {{"POSITION", b.positions({0, 0, 0, 1, 0, 0, 0, nan, 0})}}}};
    b.node({{"mesh", b.mesh(json::array({triangle_primitive(b), prim}))}});
    b.write(dir / "n.gltf");
    const InputError e = expect_input_error([&] { (void)load_mesh(dir / "n.gltf"); });
    EXPECT_EQ(e.file(), dir / "n.gltf");
    EXPECT_EQ(e.field(), "meshes[0].primitives[1].attributes.POSITION");
}

TEST(MeshRefusal, IndexOutOfRange) {
    test::TempDir dir("mesh");
    test::GltfBuilder b;
    json prim = {{"attributes", {{"POSITION", b.positions({0, 0, 0, 1, 0, 0, 0, 1, 0})}}},
                 {"indices", b.indices_u16({0, 1, 3})}};
    b.node({{"mesh", b.mesh(json::array({prim}))}});
    b.write(dir / "o.gltf");
    const InputError e = expect_input_error([&] { (void)load_mesh(dir / "o.gltf"); });
    EXPECT_EQ(e.field(), "meshes[0].primitives[0].indices");
}

TEST(MeshRefusal, AccessorBeyondItsBuffer) {
    test::TempDir dir("mesh");
    test::GltfBuilder b;
    json prim = triangle_primitive(b, false);
    b.doc()["accessors"][0]["count"] = 1000;
    b.node({{"mesh", b.mesh(json::array({prim}))}});
    b.write(dir / "b.gltf");
    const InputError e = expect_input_error([&] { (void)load_mesh(dir / "b.gltf"); });
    EXPECT_EQ(e.field(), "meshes[0].primitives[0].attributes.POSITION");
}

TEST(MeshRefusal, NodeCycle) {
    test::TempDir dir("mesh");
    test::GltfBuilder b;
    const int mesh = b.mesh(json::array({triangle_primitive(b)}));
    b.node({{"mesh", mesh}, {"children", {1}}});
    b.node({{"children", {0}}});
    b.doc()["scenes"] = {{{"nodes", {0}}}};
    b.write(dir / "c.gltf");
    try {
        (void)load_mesh(dir / "c.gltf");
        FAIL() << "a node cycle must be refused";
    } catch (const InputError& e) {
        EXPECT_EQ(e.file(), dir / "c.gltf");
    }
}

TEST(MeshRobustness, TruncatedAndCorruptedGlbNeverCrash) {
    test::TempDir dir("mesh");
    write_mesh_glb(dir / "t.glb", tetrahedron());
    const std::string bytes = read_text_file(dir / "t.glb");
    for (std::size_t len = 0; len < bytes.size(); len += 7) {
        write_text_file(dir / "cut.glb", bytes.substr(0, len));
        EXPECT_THROW((void)load_mesh(dir / "cut.glb"), InputError) << "length " << len;
    }
    std::uint32_t state = 12345;
    for (int trial = 0; trial < 200; ++trial) {
        std::string bad = bytes;
        for (int k = 0; k < 4; ++k) {
            state = state * 1664525u + 1013904223u;
            bad[state % bad.size()] = static_cast<char>(state >> 24);
        }
        write_text_file(dir / "bad.glb", bad);
        try {
            (void)load_mesh(dir / "bad.glb");
        } catch (const InputError&) {
        } catch (const std::exception& e) {
            ADD_FAILURE() << "trial " << trial << ": not an InputError: " << e.what();
        }
    }
}


// ---- the loader's guards (capture/gltf_io.h) ------------------------------------
// Each builds its input in a temporary folder and checks that the refusal names the file and
// the JSON field.

// A .glb from a JSON text and a BIN chunk (glTF 2.0 section 4.4), for hand-made JSON.
void write_glb(const fs::path& path, std::string text, std::string bin) {
    while (text.size() % 4 != 0) text.push_back(' ');
    while (bin.size() % 4 != 0) bin.push_back('\0');
    std::string out;
    auto put32 = [&](std::size_t v) {
        const auto u = static_cast<std::uint32_t>(v);
        out.append(reinterpret_cast<const char*>(&u), 4);
    };
    put32(0x46546C67u);
    put32(2);
    put32(12 + 8 + text.size() + 8 + bin.size());
    put32(text.size());
    put32(0x4E4F534Au);
    out += text;
    put32(bin.size());
    put32(0x004E4942u);
    out += bin;
    write_text_file(path, out);
}

// The JSON chunk and the BIN chunk of a .glb.
std::pair<std::string, std::string> glb_chunks(const fs::path& path) {
    const std::string bytes = read_text_file(path);
    std::uint32_t json_len = 0, bin_len = 0;
    std::memcpy(&json_len, bytes.data() + 12, 4);
    std::memcpy(&bin_len, bytes.data() + 20 + json_len, 4);
    return {bytes.substr(20, json_len), bytes.substr(28 + json_len, bin_len)};
}

// One unit triangle (non-indexed) whose buffer the caller places.
test::GltfBuilder one_triangle() {
    test::GltfBuilder b;
    b.node({{"mesh", b.mesh(json::array({triangle_primitive(b)}))}});
    return b;
}

void expect_refusal(const fs::path& file, const std::string& field, const std::string& words,
                    const std::string& field_arg = "mesh_path") {
    const InputError e = expect_input_error([&] { (void)load_mesh(file, field_arg); });
    EXPECT_EQ(e.file(), file);
    EXPECT_EQ(e.field(), field) << e.what();
    EXPECT_NE(e.message().find(words), std::string::npos) << e.what();
}

TEST(GltfGuard, JsonNestingIsCappedBeforeParsing) {
    test::TempDir dir("gltf");
    write_mesh_glb(dir / "t.glb", tetrahedron());
    const auto [text, bin] = glb_chunks(dir / "t.glb");
    ASSERT_EQ(text.rfind("{\"accessors\":", 0), 0u);
    // "extras" nested k arrays deep inside "asset": the document is 2 + k deep.
    auto nested = [&, text = text](int k) {
        std::string t = text;
        const std::size_t at = t.find("\"asset\":{") + 9;
        t.insert(at, "\"extras\":" + std::string(static_cast<std::size_t>(k), '[') + std::string(static_cast<std::size_t>(k), ']') + ",");
        return t;
    };
    write_glb(dir / "ok.glb", nested(254), bin); // depth 256: accepted
    EXPECT_EQ(load_mesh(dir / "ok.glb").mesh.triangle_count(), 4u);
    write_glb(dir / "over.glb", nested(255), bin); // depth 257
    expect_refusal(dir / "over.glb", "asset.extras[0][0][0][0]", "deeper than 256");
    // 100,000 levels used to overflow the stack (tinygltf converts extras recursively).
    write_glb(dir / "deep.glb", nested(100000), bin);
    expect_refusal(dir / "deep.glb", "asset.extras[0][0][0][0]", "refused before parsing");
    // Brackets inside strings do not count.
    std::string quoted = text;
    quoted.insert(quoted.find("\"asset\":{") + 9, "\"extras\":\"" + std::string(1000, '[') + "\",");
    write_glb(dir / "quoted.glb", quoted, bin);
    EXPECT_EQ(load_mesh(dir / "quoted.glb").mesh.triangle_count(), 4u);
}

TEST(GltfGuard, UrisMustStayInsideTheFilesFolder) {
    test::TempDir dir("gltf");
    const test::GltfBuilder b = one_triangle();
    fs::create_directories(dir / "model");
    const fs::path file = dir / "model" / "m.gltf";
    const std::string bytes(b.bin().begin(), b.bin().end());
    write_text_file(dir / "outside.bin", bytes);
    write_text_file(dir / "model" / "inside.bin", bytes);
    // Inside the folder: read (also through a "sub/.." detour that stays inside).
    b.write_external(file, "inside.bin");
    EXPECT_EQ(load_mesh(file).mesh.triangle_count(), 1u);
    fs::create_directories(dir / "model" / "sub");
    b.write_external(file, "sub/../inside.bin");
    EXPECT_EQ(load_mesh(file).mesh.triangle_count(), 1u);
    // Escapes: "../", percent-encoded "../", an absolute path, a symbolic link out.
    b.write_external(file, "../outside.bin");
    expect_refusal(file, "buffers[0].uri", "leaves the glTF file's folder");
    b.write_external(file, "sub/../../outside.bin");
    expect_refusal(file, "buffers[0].uri", "leaves the glTF file's folder");
    b.write_external(file, "%2E%2E/outside.bin");
    expect_refusal(file, "buffers[0].uri", "leaves the glTF file's folder");
    b.write_external(file, (dir / "outside.bin").string());
    expect_refusal(file, "buffers[0].uri", "absolute path");
    fs::create_symlink(dir / "outside.bin", dir / "model" / "link.bin");
    b.write_external(file, "link.bin");
    expect_refusal(file, "buffers[0].uri", "symbolic link");
    // Images too (a mesh does not need them, but they are opened all the same).
    test::GltfBuilder with_image = one_triangle();
    with_image.doc()["images"] = {{{"uri", "../outside.png"}}};
    with_image.write(file);
    expect_refusal(file, "images[0].uri", "leaves the glTF file's folder");
}

TEST(GltfGuard, FifosDevicesAndFoldersAreRefusedWithoutBlocking) {
    test::TempDir dir("gltf");
    const test::GltfBuilder b = one_triangle();
    const fs::path file = dir / "m.gltf";
    ASSERT_EQ(::mkfifo((dir / "pipe.bin").c_str(), 0600), 0);
    // The load runs aside: should it block on the FIFO, opening the FIFO's other end frees it
    // and the test fails instead of hanging.
    auto load_with_timeout = [&](const fs::path& path, const std::string& field, const std::string& words) {
        auto result = std::async(std::launch::async, [&] {
            try {
                (void)load_mesh(path);
            } catch (const InputError& e) {
                return std::string(e.field()) + "|" + e.what();
            } catch (const std::exception& e) {
                return std::string("other|") + e.what();
            }
            return std::string("loaded|");
        });
        if (result.wait_for(std::chrono::seconds(20)) != std::future_status::ready) {
            ADD_FAILURE() << path << ": the load blocked on the FIFO";
            const int fd = ::open((dir / "pipe.bin").c_str(), O_WRONLY | O_NONBLOCK);
            if (fd >= 0) ::close(fd);
        }
        const std::string r = result.get();
        EXPECT_EQ(r.substr(0, r.find('|')), field) << r;
        EXPECT_NE(r.find(words), std::string::npos) << r;
    };
    b.write_external(file, "pipe.bin");
    load_with_timeout(file, "buffers[0].uri", "a FIFO");
    test::GltfBuilder with_image = one_triangle();
    with_image.doc()["images"] = {{{"uri", "pipe.bin"}}};
    with_image.write(file);
    load_with_timeout(file, "images[0].uri", "a FIFO");
    load_with_timeout(dir / "pipe.bin", "mesh_path", "a FIFO"); // the file itself
    fs::create_directories(dir / "folder.bin");
    b.write_external(file, "folder.bin");
    expect_refusal(file, "buffers[0].uri", "a folder");
    expect_refusal("/dev/null", "mesh_path", "a device");
}

TEST(GltfGuard, NulInPathsAndUrisIsRefused) {
    test::TempDir dir("gltf");
    const test::GltfBuilder b = one_triangle();
    const fs::path file = dir / "m.gltf";
    // "in" exists and holds the buffer: a reader that cut the URI at the NUL would load it.
    write_text_file(dir / "in", std::string(b.bin().begin(), b.bin().end()));
    b.write_external(file, std::string("in\0side.bin", 10));
    ASSERT_NE(read_text_file(file).find("\\u0000"), std::string::npos);
    expect_refusal(file, "buffers[0].uri", "NUL");
    b.write_external(file, "in%00side.bin");
    expect_refusal(file, "buffers[0].uri", "NUL");
    b.write_external(file, "in");
    EXPECT_EQ(load_mesh(file).mesh.triangle_count(), 1u); // the control: the file itself is fine
    test::GltfBuilder with_image = one_triangle();
    with_image.doc()["images"] = {{{"uri", std::string("in\0.png", 7)}}};
    with_image.write(file);
    expect_refusal(file, "images[0].uri", "NUL");
    const fs::path nul_path = dir / std::string("m.gltf\0.txt", 11);
    const InputError e = expect_input_error([&] { (void)load_mesh(nul_path); });
    EXPECT_EQ(e.file(), nul_path);
    EXPECT_EQ(e.field(), "mesh_path");
    EXPECT_NE(e.message().find("NUL"), std::string::npos) << e.message();
}

TEST(GltfGuard, AccessorCountsAndByteRangesAreCheckedBeforeAllocation) {
    test::TempDir dir("gltf");
    const fs::path file = dir / "m.gltf";
    const std::string pos = "meshes[0].primitives[0].attributes.POSITION";
    // A count above the maximum (2^28), with data or without (all zeros): refused, not allocated.
    for (const bool with_view : {true, false}) {
        test::GltfBuilder b = one_triangle();
        b.doc()["accessors"][0]["count"] = std::uint64_t{1} << 40;
        if (!with_view) b.doc()["accessors"][0].erase("bufferView");
        b.write(file);
        expect_refusal(file, pos, "above the maximum");
    }
    // Elements past the bufferView, and a byteOffset past it (no overflow).
    test::GltfBuilder b = one_triangle();
    b.doc()["accessors"][0]["count"] = 4;
    b.write(file);
    expect_refusal(file, pos, "exceed the bufferView");
    b = one_triangle();
    b.doc()["accessors"][0]["byteOffset"] = std::numeric_limits<std::uint64_t>::max() - 3;
    b.write(file);
    expect_refusal(file, pos, "byteOffset exceeds the bufferView");
    // A bufferView past its buffer is refused before tinygltf reads anything through it.
    b = one_triangle();
    b.doc()["bufferViews"][1]["byteLength"] = 1000;
    b.write(file);
    expect_refusal(file, "bufferViews[1].byteLength", "runs past buffers[0]");
    b = one_triangle();
    b.doc()["bufferViews"][0]["byteOffset"] = std::numeric_limits<std::uint64_t>::max();
    b.write(file);
    expect_refusal(file, "bufferViews[0].byteLength", "runs past buffers[0]");
    b = one_triangle();
    b.doc()["bufferViews"][0]["buffer"] = 7;
    b.write(file);
    expect_refusal(file, "bufferViews[0].buffer", "does not exist");
    // An image's bufferView out of range (tinygltf would index past the array).
    b = one_triangle();
    b.doc()["images"] = {{{"bufferView", 9}, {"mimeType", "image/png"}}};
    b.write(file);
    expect_refusal(file, "images[0].bufferView", "does not exist");
}

TEST(GltfGuard, RequiredExtensionsSpeculaCannotHonourAreRefused) {
    test::TempDir dir("gltf");
    const fs::path file = dir / "m.gltf";
    test::GltfBuilder b = one_triangle();
    b.doc()["extensionsRequired"] = {"KHR_draco_mesh_compression"};
    b.write(file);
    expect_refusal(file, "extensionsRequired[0]", "KHR_draco_mesh_compression");
    b.doc()["extensionsRequired"] = {"SPECULA_lafortune", "EXT_meshopt_compression"};
    b.write(file);
    expect_refusal(file, "extensionsRequired[1]", "EXT_meshopt_compression");
    b.doc()["extensionsRequired"] = {"VENDOR_never_heard_of"};
    b.write(file);
    expect_refusal(file, "extensionsRequired[0]", "cannot honour");
    b.doc()["extensionsRequired"] = "SPECULA_lafortune";
    b.write(file);
    expect_refusal(file, "extensionsRequired", "not an array");
    b.doc()["extensionsRequired"] = {"SPECULA_lafortune"}; // its own: honoured
    b.write(file);
    EXPECT_EQ(load_mesh(file).mesh.triangle_count(), 1u);
}

// KHR_mesh_quantization (honoured): normalized SHORT positions decode as v / 32767.
TEST(GltfGuard, QuantizedPositionsAreHonoured) {
    test::TempDir dir("gltf");
    test::GltfBuilder b;
    const int pos = b.accessor(std::vector<std::int16_t>{0, 0, 0, 0, 0, 32767, 0, 0, 0, -16384, 32767, 0},
                               5122, "VEC3", 3); // each element padded to 8 bytes: byteStride 8
    b.doc()["bufferViews"][b.doc()["accessors"][pos]["bufferView"].get<int>()]["byteStride"] = 8;
    b.doc()["accessors"][pos]["normalized"] = true;
    b.node({{"mesh", b.mesh(json::array({{{"attributes", {{"POSITION", pos}}}}}))}});
    b.doc()["extensionsUsed"] = {"KHR_mesh_quantization"};
    b.doc()["extensionsRequired"] = {"KHR_mesh_quantization"};
    b.write(dir / "q.gltf");
    const Mesh m = load_mesh(dir / "q.gltf").mesh;
    ASSERT_EQ(m.positions.size(), 3u);
    expect_vec_eq(m.positions[0], {0, 0, 0}, 0.0f);
    expect_vec_eq(m.positions[1], {0, 1, 0}, 0.0f);
    expect_vec_eq(m.positions[2], {0, -16384.0f / 32767.0f, 1}, 1e-7f);
}

TEST(GltfGuard, TriangleCountsMustBeMultiplesOf3) {
    test::TempDir dir("gltf");
    const fs::path file = dir / "m.gltf";
    const std::vector<float> quad = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
    test::GltfBuilder b;
    b.node({{"mesh", b.mesh(json::array({{{"attributes", {{"POSITION", b.positions(quad)}}}}}))}});
    b.write(file); // 4 vertices, no indices
    expect_refusal(file, "meshes[0].primitives[0].attributes.POSITION", "multiple of 3");
    test::GltfBuilder i;
    json prim = {{"attributes", {{"POSITION", i.positions(quad)}}}, {"indices", i.indices_u16({0, 1, 2, 3})}};
    i.node({{"mesh", i.mesh(json::array({prim}))}});
    i.write(file);
    expect_refusal(file, "meshes[0].primitives[0].indices", "multiple of 3");
    // A strip of 4 vertices is two triangles: fine.
    i.doc()["meshes"][0]["primitives"][0]["mode"] = 5;
    i.write(file);
    EXPECT_EQ(load_mesh(file).mesh.triangle_count(), 2u);
}

TEST(GltfGuard, DuplicateJsonKeysAreRefusedNamingTheKey) {
    test::TempDir dir("gltf");
    const fs::path file = dir / "m.gltf";
    test::GltfBuilder b;
    const int mesh = b.mesh(json::array({triangle_primitive(b)}));
    b.node({{"mesh", mesh}, {"name", "first"}});
    b.doc()["scenes"] = {{{"nodes", {0}}}};
    b.write(file);
    ASSERT_EQ(load_mesh(file).mesh.triangle_count(), 1u);
    // Which "translation" counts? nlohmann and tinygltf take the last, other readers the first.
    std::string text = b.text();
    const std::size_t at = text.find("\"name\": \"first\"");
    ASSERT_NE(at, std::string::npos) << text;
    text.insert(at, "\"translation\": [0, 0, 1], \"translation\": [0, 0, 2], ");
    write_text_file(file, text);
    expect_refusal(file, "nodes[0].translation", "duplicate JSON key");
    // At the top level too; the same key in different objects is fine.
    text = b.text();
    text.insert(1, "\"asset\": {\"version\": \"2.0\"},");
    write_text_file(file, text);
    expect_refusal(file, "asset", "duplicate JSON key");
}

TEST(GltfGuard, MissingLinkedImageIsOnlyAWarningForAMesh) {
    test::TempDir dir("gltf");
    test::GltfBuilder b = one_triangle();
    b.doc()["images"] = {{{"uri", "texture.png"}}};
    b.write(dir / "m.gltf");
    const MeshLoadResult r = load_mesh(dir / "m.gltf");
    EXPECT_EQ(r.mesh.triangle_count(), 1u);
    ASSERT_EQ(r.warnings.size(), 1u);
    EXPECT_NE(r.warnings[0].find("images[0].uri: file not found"), std::string::npos) << r.warnings[0];
}

} // namespace
} // namespace specula
