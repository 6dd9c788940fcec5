// The output bundle (engine/export): make_bundle / corner_uvs, the exact round trip
// through write_bundle / read_bundle, the viewer approximation in the material,
// foreign .glb files, errors naming the file and the field, and the Khronos glTF
// validator on a written bundle (skipped when node or the validator is not installed).
#include "bundle_fixtures.h"
#include "test_dirs.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <set>
#include <tuple>

namespace specula {
namespace {

using test::TempDir;
using nlohmann::json;

bool same_bits(const std::vector<float>& a, const std::vector<float>& b) {
    return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0);
}
template <class V> bool same_bits(const std::vector<V>& a, const std::vector<V>& b) {
    return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(V)) == 0);
}

TEST(MakeBundle, SplitsVerticesAndCornerUvsInvertsIt) {
    const test::BundlePieces p = test::make_pieces();
    const Bundle b = make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, p.lobe);
    ASSERT_EQ(b.mesh.triangles.size(), p.mesh.triangles.size());
    ASSERT_TRUE(b.mesh.has_texcoords());
    ASSERT_EQ(b.mesh.normals.size(), b.mesh.positions.size());
    // corner_uvs gives back exactly the atlas's coordinates.
    const std::vector<glm::vec2> uv = corner_uvs(b.mesh);
    ASSERT_TRUE(same_bits(uv, p.atlas.corner_uv));
    // Each corner keeps its position and normal; vertices = distinct (position, uv) pairs.
    std::set<std::tuple<std::uint32_t, float, float>> distinct;
    for (std::size_t t = 0; t < p.mesh.triangles.size(); ++t)
        for (int c = 0; c < 3; ++c) {
            const std::uint32_t src = p.mesh.triangles[t][c], dst = b.mesh.triangles[t][c];
            EXPECT_EQ(b.mesh.positions[dst], p.mesh.positions[src]);
            EXPECT_EQ(b.mesh.normals[dst], p.mesh.normals[src]);
            distinct.insert({src, p.atlas.corner_uv[t * 3 + c].x, p.atlas.corner_uv[t * 3 + c].y});
        }
    EXPECT_EQ(b.mesh.positions.size(), distinct.size());
    EXPECT_GT(b.mesh.positions.size(), p.mesh.positions.size()); // the atlas has seams
    EXPECT_TRUE(same_bits(b.albedo.pixels, p.albedo.pixels));
    ASSERT_TRUE(b.lobe.has_value());
    EXPECT_EQ(b.lobe->n, p.lobe.n);
}

TEST(MakeBundle, MergesSharedCornersOnlyWhenTheirUvIsIdentical) {
    Mesh m;
    m.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
    m.triangles = {{0, 1, 2}, {0, 2, 3}};
    const Image albedo(2, 2, 3, 0.5f);
    const std::vector<glm::vec2> same = {{0, 0}, {1, 0}, {1, 1}, {0, 0}, {1, 1}, {0, 1}};
    const Bundle a = make_bundle(m, same, albedo, std::nullopt);
    EXPECT_EQ(a.mesh.positions.size(), 4u);
    EXPECT_EQ(a.mesh.normals.size(), 4u); // computed: the mesh had none
    EXPECT_EQ(a.mesh.normals[0], glm::vec3(0, 0, 1));
    const std::vector<glm::vec2> seam = {{0, 0}, {0.5f, 0}, {0.5f, 0.5f}, {0.6f, 0.6f}, {1, 1}, {0.6f, 1}};
    const Bundle b = make_bundle(m, seam, albedo, std::nullopt);
    EXPECT_EQ(b.mesh.positions.size(), 6u);
    EXPECT_TRUE(same_bits(corner_uvs(b.mesh), seam));
    EXPECT_THROW((void)make_bundle(m, std::span(seam).first(5), albedo, std::nullopt), Error);
    EXPECT_THROW((void)corner_uvs(m), Error);
}

TEST(Bundle, RoundTripWithLobeAndCubeMapsIsExact) {
    const test::BundlePieces p = test::make_pieces();
    Bundle b = make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, p.lobe);
    b.lobe_status = {"converged", "converged", "max_iterations"};
    b.cube_g = test::random_cube(8, 1);
    b.cube_h = test::random_cube(16, 2);
    b.albedo.pixels[5] = 1.0e-42f;          // a denormal
    b.albedo.pixels[6] = -0.0f;             // a negative zero
    b.albedo.pixels[7] = 0.1f + 1.0e-8f;    // no decimal round trip needed: raw bits
    b.info = {{"specula_version", "test"}, {"capture", "sphere"}, {"summary", {{"psnr_db", 41.25}}}};
    TempDir dir("bundle");
    const auto file = dir / "out.glb";
    write_bundle(file, b);
    const Bundle r = read_bundle(file);
    EXPECT_TRUE(r.warnings.empty());
    EXPECT_TRUE(same_bits(r.mesh.positions, b.mesh.positions));
    EXPECT_TRUE(same_bits(r.mesh.normals, b.mesh.normals));
    EXPECT_TRUE(same_bits(r.mesh.texcoords, b.mesh.texcoords));
    EXPECT_TRUE(same_bits(r.mesh.triangles, b.mesh.triangles));
    EXPECT_EQ(r.albedo.width, b.albedo.width);
    EXPECT_EQ(r.albedo.height, b.albedo.height);
    EXPECT_EQ(r.albedo.channels, b.albedo.channels);
    EXPECT_TRUE(same_bits(r.albedo.pixels, b.albedo.pixels));
    ASSERT_TRUE(r.lobe.has_value());
    EXPECT_EQ(r.lobe->cx, b.lobe->cx);
    EXPECT_EQ(r.lobe->cz, b.lobe->cz);
    EXPECT_EQ(r.lobe->n, b.lobe->n);
    EXPECT_EQ(r.lobe_status, b.lobe_status);
    ASSERT_TRUE(r.cube_g && r.cube_h);
    EXPECT_EQ(r.cube_g->resolution, 8u);
    EXPECT_EQ(r.cube_h->resolution, 16u);
    EXPECT_TRUE(same_bits(r.cube_g->rgb, b.cube_g->rgb));
    EXPECT_TRUE(same_bits(r.cube_h->rgb, b.cube_h->rgb));
    EXPECT_EQ(r.info, b.info);
    EXPECT_TRUE(r.extra_terms.empty());
    EXPECT_EQ(test::glb_json(file)["materials"][0]["extensions"]["SPECULA_lafortune"]["version"], 1)
        << "a one-term bundle stays version 1 (older readers load it)";
    // Writing what was read gives the same file, byte for byte.
    write_bundle(dir / "again.glb", r);
    EXPECT_EQ(read_text_file(dir / "again.glb"), read_text_file(file));
}

TEST(Bundle, RoundTripWithSeveralFactorTermsIsExact) {
    const test::BundlePieces p = test::make_pieces();
    Bundle b = make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, p.lobe);
    b.cube_g = test::random_cube(8, 1);
    b.cube_h = test::random_cube(16, 2);
    b.extra_terms = {{test::random_cube(8, 3), test::random_cube(16, 4)}, {test::random_cube(8, 5), test::random_cube(16, 6)}};
    b.extra_terms[1].g.rgb[3] = -0.25f; // residual terms take either sign
    TempDir dir("bundle");
    const auto file = dir / "terms.glb";
    write_bundle(file, b);
    EXPECT_EQ(test::glb_json(file)["materials"][0]["extensions"]["SPECULA_lafortune"]["version"], 2);
    const Bundle r = read_bundle(file);
    ASSERT_EQ(r.extra_terms.size(), 2u);
    for (std::size_t k = 0; k < 2; ++k) {
        EXPECT_EQ(r.extra_terms[k].g.resolution, 8u);
        EXPECT_EQ(r.extra_terms[k].h.resolution, 16u);
        EXPECT_TRUE(same_bits(r.extra_terms[k].g.rgb, b.extra_terms[k].g.rgb));
        EXPECT_TRUE(same_bits(r.extra_terms[k].h.rgb, b.extra_terms[k].h.rgb));
    }
    write_bundle(dir / "again.glb", r);
    EXPECT_EQ(read_text_file(dir / "again.glb"), read_text_file(file));
    // Inconsistent further terms are refused on writing.
    Bundle bad = b;
    bad.extra_terms[0].h.rgb.pop_back();
    EXPECT_THROW(write_bundle(dir / "bad.glb", bad), InputError);
    bad = b;
    bad.cube_g.reset();
    bad.cube_h.reset();
    EXPECT_THROW(write_bundle(dir / "bad.glb", bad), InputError);
}

// The mirrored parametrization (shared/gshd.h part 4) is recorded as version 3 with
// "parametrization": "mirrored"; a plain bundle is written exactly as before (no field,
// version 1 or 2) and read as plain GSHD.
TEST(Bundle, RoundTripWithTheMirroredParametrization) {
    const test::BundlePieces p = test::make_pieces();
    Bundle b = make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, p.lobe);
    b.cube_g = test::random_cube(8, 1);
    b.cube_h = test::random_cube(16, 2);
    TempDir dir("bundle");
    write_bundle(dir / "plain.glb", b);
    const json plain = test::glb_json(dir / "plain.glb")["materials"][0]["extensions"]["SPECULA_lafortune"];
    EXPECT_EQ(plain["version"], 1);
    EXPECT_FALSE(plain.contains("parametrization"));
    EXPECT_EQ(read_bundle(dir / "plain.glb").factor_param, FactorParam::Gshd);
    for (const std::size_t terms : {1u, 3u}) {
        b.extra_terms.assign(terms - 1, {test::random_cube(8, 3), test::random_cube(16, 4)});
        b.factor_param = FactorParam::Mirrored;
        const auto file = dir / ("mirrored" + std::to_string(terms) + ".glb");
        write_bundle(file, b);
        const json ext = test::glb_json(file)["materials"][0]["extensions"]["SPECULA_lafortune"];
        EXPECT_EQ(ext["version"], 3);
        EXPECT_EQ(ext["parametrization"], "mirrored");
        const Bundle r = read_bundle(file);
        EXPECT_EQ(r.factor_param, FactorParam::Mirrored);
        EXPECT_EQ(r.extra_terms.size(), terms - 1);
        EXPECT_TRUE(same_bits(r.cube_h->rgb, b.cube_h->rgb));
        write_bundle(dir / "again.glb", r);
        EXPECT_EQ(read_text_file(dir / "again.glb"), read_text_file(file));
    }
    // Warped (shared/gshd.h part 5): version 4, the parametrization and its warp, bit for bit.
    b.extra_terms.clear();
    b.factor_param = FactorParam::Warped;
    b.factor_warp = glm::vec4(-1.0f, 0.4661f, 0.473f, 0.48f);
    write_bundle(dir / "warped.glb", b);
    const json warped = test::glb_json(dir / "warped.glb")["materials"][0]["extensions"]["SPECULA_lafortune"];
    EXPECT_EQ(warped["version"], 4);
    EXPECT_EQ(warped["parametrization"], "warped");
    EXPECT_EQ(warped["warp"].size(), 4u);
    const Bundle rw = read_bundle(dir / "warped.glb");
    EXPECT_EQ(rw.factor_param, FactorParam::Warped);
    EXPECT_EQ(rw.factor_warp, b.factor_warp);
    Bundle no_lobe = b;
    no_lobe.lobe.reset(); // the radial factor needs the lobe
    EXPECT_THROW(write_bundle(dir / "bad.glb", no_lobe), InputError);
    // Without cube-maps the parametrization means nothing and is not written.
    b.cube_g.reset();
    b.cube_h.reset();
    b.extra_terms.clear();
    write_bundle(dir / "diffuse.glb", b);
    const json none = test::glb_json(dir / "diffuse.glb")["materials"][0]["extensions"]["SPECULA_lafortune"];
    EXPECT_EQ(none["version"], 1);
    EXPECT_FALSE(none.contains("parametrization"));
}

TEST(Bundle, MaterialCarriesTheViewerApproximationAndAnOptionalExtension) {
    const test::BundlePieces p = test::make_pieces();
    TempDir dir("bundle");
    write_bundle(dir / "b.glb", make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, p.lobe));
    const json doc = test::glb_json(dir / "b.glb");
    EXPECT_EQ(doc["extensionsUsed"], json::array({"SPECULA_lafortune"}));
    EXPECT_FALSE(doc.contains("extensionsRequired"));
    const json& pbr = doc["materials"][0]["pbrMetallicRoughness"];
    EXPECT_EQ(pbr["metallicFactor"].get<double>(), 0.0);
    const double n = (24.0 + 30.0 + 36.5) / 3.0; // mean exponent; roughness = sqrt(alpha), alpha^2 = 2 / (N + 2)
    EXPECT_NEAR(pbr["roughnessFactor"].get<double>(), std::sqrt(std::sqrt(2.0 / (n + 2.0))), 1e-6);
    const json& image = doc["images"][pbr["baseColorTexture"]["index"].get<int>()];
    EXPECT_EQ(image["mimeType"], "image/png");
    // The base colour PNG is the albedo, sRGB encoded and clamped.
    json stripped = doc;
    stripped["materials"][0].erase("extensions");
    stripped.erase("extensionsUsed");
    test::rewrite_glb_json(dir / "b.glb", stripped);
    const Bundle r = read_bundle(dir / "b.glb");
    ASSERT_EQ(r.albedo.width, p.albedo.width);
    for (std::size_t i = 0; i < r.albedo.pixels.size(); ++i) {
        const float want = std::min(p.albedo.pixels[i], 1.0f);
        ASSERT_NEAR(linear_to_srgb(r.albedo.pixels[i]), linear_to_srgb(want), 0.5f / 255.0f + 1e-5f) << i;
    }
}

TEST(Bundle, WithoutLobeOrCubeMaps) {
    const test::BundlePieces p = test::make_pieces();
    TempDir dir("bundle");
    write_bundle(dir / "d.glb", make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, std::nullopt));
    const json doc = test::glb_json(dir / "d.glb");
    const json& ext = doc["materials"][0]["extensions"]["SPECULA_lafortune"];
    EXPECT_FALSE(ext.contains("lobe"));
    EXPECT_FALSE(ext.contains("cubeG"));
    EXPECT_EQ(doc["materials"][0]["pbrMetallicRoughness"]["roughnessFactor"].get<double>(), 1.0);
    const Bundle r = read_bundle(dir / "d.glb");
    EXPECT_FALSE(r.lobe.has_value());
    EXPECT_TRUE(r.lobe_status.empty());
    EXPECT_FALSE(r.cube_g.has_value());
    EXPECT_FALSE(r.cube_h.has_value());
    EXPECT_TRUE(same_bits(r.albedo.pixels, p.albedo.pixels));
    EXPECT_TRUE(r.warnings.empty());
}

TEST(Bundle, ForeignGlbWithoutMaterialIsRefusedNamingTheField) {
    test::BundlePieces p = test::make_pieces();
    TempDir dir("bundle");
    // A plain mesh (write_mesh_glb) with texture coordinates but no material.
    const Bundle b = make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, std::nullopt);
    write_mesh_glb(dir / "plain.glb", b.mesh);
    try {
        (void)read_bundle(dir / "plain.glb");
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        EXPECT_EQ(e.file(), dir / "plain.glb");
        EXPECT_EQ(e.field(), "meshes[0].primitives[0].material");
    }
    // Without texture coordinates: not a bundle at all.
    write_mesh_glb(dir / "bare.glb", p.mesh);
    try {
        (void)read_bundle(dir / "bare.glb");
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        EXPECT_EQ(e.field(), "meshes[0].primitives[0].attributes.TEXCOORD_0");
        EXPECT_NE(std::string(e.what()).find("SPECULA_lafortune"), std::string::npos);
    }
}

TEST(Bundle, ForeignGlbWithBaseColourIsReadDiffuseOnlyWithAWarning) {
    const test::BundlePieces p = test::make_pieces();
    TempDir dir("bundle");
    Bundle b = make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, p.lobe);
    b.cube_g = test::random_cube(4, 3);
    b.cube_h = test::random_cube(4, 4);
    write_bundle(dir / "f.glb", b);
    json doc = test::glb_json(dir / "f.glb");
    doc["materials"][0].erase("extensions");
    doc.erase("extensionsUsed");
    test::rewrite_glb_json(dir / "f.glb", doc);
    const Bundle r = read_bundle(dir / "f.glb");
    EXPECT_FALSE(r.lobe.has_value());
    EXPECT_FALSE(r.cube_g.has_value());
    ASSERT_FALSE(r.warnings.empty());
    EXPECT_NE(r.warnings.back().find("diffuse-only"), std::string::npos);
    EXPECT_EQ(r.albedo.channels, 3);
    EXPECT_EQ(r.mesh.triangles.size(), b.mesh.triangles.size());
    EXPECT_TRUE(r.mesh.has_texcoords());
    EXPECT_EQ(corner_uvs(r.mesh).size(), b.mesh.triangles.size() * 3);
}

TEST(Bundle, ErrorsNameTheFileAndTheField) {
    const test::BundlePieces p = test::make_pieces();
    TempDir dir("bundle");
    const auto file = dir / "e.glb";
    Bundle b = make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, p.lobe);
    b.cube_g = test::random_cube(4, 5);
    b.cube_h = test::random_cube(4, 6);
    write_bundle(file, b);
    const json good = test::glb_json(file);
    const std::string ext = "materials[0].extensions.SPECULA_lafortune";
    auto expect_field = [&](const json& doc, const std::string& field) {
        write_bundle(file, b);
        test::rewrite_glb_json(file, doc);
        try {
            (void)read_bundle(file);
            ADD_FAILURE() << "expected InputError on " << field;
        } catch (const InputError& e) {
            EXPECT_EQ(e.file(), file);
            EXPECT_EQ(e.field(), field) << e.what();
        }
    };
    json d = good;
    d["materials"][0]["extensions"]["SPECULA_lafortune"]["albedo"]["width"] = p.albedo.width + 1;
    expect_field(d, ext + ".albedo.bufferView");
    d = good;
    d["materials"][0]["extensions"]["SPECULA_lafortune"]["lobe"]["n"] = json::array({1, 2});
    expect_field(d, ext + ".lobe.n");
    d = good;
    d["materials"][0]["extensions"]["SPECULA_lafortune"]["cubeH"]["resolution"] = 5;
    expect_field(d, ext + ".cubeH.bufferView");
    d = good;
    d["materials"][0]["extensions"]["SPECULA_lafortune"].erase("cubeG");
    expect_field(d, ext + ".cubeG");
    d = good;
    d["materials"][0]["extensions"]["SPECULA_lafortune"]["version"] = 5;
    expect_field(d, ext + ".version");
    // The parametrization: "gshd", "mirrored" (version 3) or "warped" (version 4, with its warp
    // and the lobe), with cube-maps.
    d = good;
    d["materials"][0]["extensions"]["SPECULA_lafortune"]["version"] = 3;
    d["materials"][0]["extensions"]["SPECULA_lafortune"]["parametrization"] = "warped";
    d["materials"][0]["extensions"]["SPECULA_lafortune"]["warp"] = json::array({-1, 0.5, 0.5, 0.5});
    expect_field(d, ext + ".parametrization"); // needs version 4
    d["materials"][0]["extensions"]["SPECULA_lafortune"]["version"] = 4;
    write_bundle(file, b);
    test::rewrite_glb_json(file, d);
    EXPECT_NO_THROW((void)read_bundle(file)); // well formed
    d["materials"][0]["extensions"]["SPECULA_lafortune"]["warp"] = json::array({-1, 0.5, 0.5});
    expect_field(d, ext + ".warp");
    d["materials"][0]["extensions"]["SPECULA_lafortune"]["warp"] = json::array({0.5, 0.5, 0.5, 0.5});
    expect_field(d, ext + ".warp");
    d["materials"][0]["extensions"]["SPECULA_lafortune"]["warp"] = json::array({1, 0.5, 0.0, 0.5});
    expect_field(d, ext + ".warp");
    d["materials"][0]["extensions"]["SPECULA_lafortune"].erase("warp");
    expect_field(d, ext + ".warp");
    d["materials"][0]["extensions"]["SPECULA_lafortune"]["warp"] = json::array({-1, 0.5, 0.5, 0.5});
    d["materials"][0]["extensions"]["SPECULA_lafortune"].erase("lobe"); // the radial factor needs it
    expect_field(d, ext + ".parametrization");
    d = good;
    d["materials"][0]["extensions"]["SPECULA_lafortune"]["version"] = 4;
    d["materials"][0]["extensions"]["SPECULA_lafortune"]["warp"] = json::array({-1, 0.5, 0.5, 0.5});
    expect_field(d, ext + ".warp"); // without "parametrization": "warped"
    d = good;
    d["materials"][0]["extensions"]["SPECULA_lafortune"]["parametrization"] = "mirrored";
    expect_field(d, ext + ".parametrization");
    d["materials"][0]["extensions"]["SPECULA_lafortune"]["version"] = 3;
    d["materials"][0]["extensions"]["SPECULA_lafortune"]["parametrization"] = "spherical";
    expect_field(d, ext + ".parametrization");
    d["materials"][0]["extensions"]["SPECULA_lafortune"]["parametrization"] = 1;
    expect_field(d, ext + ".parametrization");
    d["materials"][0]["extensions"]["SPECULA_lafortune"]["parametrization"] = "mirrored";
    d["materials"][0]["extensions"]["SPECULA_lafortune"].erase("cubeG");
    d["materials"][0]["extensions"]["SPECULA_lafortune"].erase("cubeH");
    expect_field(d, ext + ".parametrization");
    // Further factorization terms: only in version 2, each with both cube-maps.
    d = good;
    d["materials"][0]["extensions"]["SPECULA_lafortune"]["cubeTerms"] =
        json::array({d["materials"][0]["extensions"]["SPECULA_lafortune"]["cubeG"]});
    expect_field(d, ext + ".cubeTerms");
    d = good;
    d["materials"][0]["extensions"]["SPECULA_lafortune"]["version"] = 2;
    d["materials"][0]["extensions"]["SPECULA_lafortune"]["cubeTerms"] =
        json::array({{{"cubeG", d["materials"][0]["extensions"]["SPECULA_lafortune"]["cubeG"]}}});
    expect_field(d, ext + ".cubeTerms[0].cubeH");
    d = good;
    d["accessors"][3]["count"] = 1u << 30;
    expect_field(d, "meshes[0].primitives[0].indices");
    // Truncated file.
    write_bundle(file, b);
    const std::string bytes = read_text_file(file);
    write_text_file(file, bytes.substr(0, bytes.size() / 2));
    EXPECT_THROW((void)read_bundle(file), InputError);
    // Missing file.
    EXPECT_THROW((void)read_bundle(dir / "missing.glb"), InputError);
    // Writing an inconsistent bundle.
    Bundle bad = b;
    bad.cube_h->rgb.pop_back();
    EXPECT_THROW(write_bundle(dir / "bad.glb", bad), InputError);
    EXPECT_FALSE(std::filesystem::exists(dir / "bad.glb"));
}

// Set by tests/export/CMakeLists.txt (not through the environment: see the report on
// SPECULA_TEST_ENV, whose list gtest_discover_tests passes as separate properties).
#ifndef SPECULA_NODE_MODULES_DIR
#define SPECULA_NODE_MODULES_DIR ""
#endif
#ifndef SPECULA_GLTF_VALIDATE_JS
#define SPECULA_GLTF_VALIDATE_JS "tools/gltf-validate.js"
#endif

TEST(Bundle, KhronosValidatorReportsNoErrors) {
    if (std::system("command -v node >/dev/null 2>&1") != 0)
        GTEST_SKIP() << "node is not installed (tools/install-deps.sh installs nodejs and gltf-validator)";
    const test::BundlePieces p = test::make_pieces();
    Bundle b = make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, p.lobe);
    b.lobe_status = {"converged", "converged", "converged"};
    b.cube_g = test::random_cube(8, 1);
    b.cube_h = test::random_cube(8, 2);
    b.extra_terms = {{test::random_cube(8, 3), test::random_cube(8, 4)}}; // version 2, cubeTerms
    TempDir dir("bundle");
    for (const int kind : {0, 1, 2, 3}) { // lobe; mirrored (version 3); warped (version 4); diffuse only
        if (kind == 1) b.factor_param = FactorParam::Mirrored;
        if (kind == 2) {
            b.factor_param = FactorParam::Warped;
            b.factor_warp = warp_for_lobe(*b.lobe).value();
        }
        if (kind == 3) {
            b.factor_param = FactorParam::Gshd;
            b.lobe.reset();
        }
        const auto file = dir / (kind == 0 ? "lobe.glb" : kind == 1 ? "mirrored.glb" : kind == 2 ? "warped.glb" : "diffuse.glb");
        write_bundle(file, b);
        const std::string cmd = "SPECULA_GLTF_VALIDATOR_PATHS='" + std::string(SPECULA_NODE_MODULES_DIR) +
                                "' node '" + std::string(SPECULA_GLTF_VALIDATE_JS) + "' '" +
                                file.string() + "'";
        const int status = std::system(cmd.c_str());
        ASSERT_TRUE(WIFEXITED(status)) << cmd;
        if (WEXITSTATUS(status) == 77)
            GTEST_SKIP() << "the gltf-validator npm package is not installed (tools/install-deps.sh installs it)";
        EXPECT_EQ(WEXITSTATUS(status), 0) << cmd << ": the validator reported errors (printed above)";
    }
}

} // namespace
} // namespace specula
