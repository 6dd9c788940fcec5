// The output bundle (engine/export): make_bundle / corner_uvs, the exact round trip
// through write_bundle / read_bundle, the viewer approximation in the material,
// foreign .glb files, errors naming the file and the field, and the Khronos glTF
// validator on a written bundle (skipped when node or the validator is not installed).
#include "../capture/gltf_builder.h"
#include "../capture/png_bytes.h"
#include "bundle_fixtures.h"
#include "export/normal_map.h"
#include "geometry/particles.h"
#include "core/file_util.h"

#include <glm/gtc/matrix_transform.hpp>
#include "expect_error.h"
#include "legacy_bundles.h"
#include "test_dirs.h"

#include <gtest/gtest.h>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <future>
#include <limits>
#include <numbers>
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

/// The bundle's Lafortune lobe (the test bundles hold no other family).
const LafortuneRgb& lobe_of(const Bundle& b) { return std::get<LafortuneRgb>(*b.material.specular); }

/// A material with the lobe and no factorization.
Material with_lobe(const LafortuneRgb& lobe) { return Material{.specular = lobe}; }

/// Term k's cube-maps (k = 0: the thesis's term, "cubeG"/"cubeH").
const FactorTerm& term(const Bundle& b, std::size_t k) { return b.material.factorized->terms.at(k); }
FactorTerm& term(Bundle& b, std::size_t k) { return b.material.factorized->terms.at(k); }
/// The number of terms after the first (the extension's "cubeTerms").
std::size_t further_terms(const Bundle& b) { return b.material.factorized ? b.material.factorized->terms.size() - 1 : 0; }

TEST(MakeBundle, SplitsVerticesAndCornerUvsInvertsIt) {
    const test::BundlePieces p = test::make_pieces();
    const Bundle b = make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, with_lobe(p.lobe));
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
    ASSERT_TRUE(b.material.specular.has_value());
    EXPECT_EQ(lobe_of(b).n, p.lobe.n);
}

TEST(MakeBundle, MergesSharedCornersOnlyWhenTheirUvIsIdentical) {
    Mesh m;
    m.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
    m.triangles = {{0, 1, 2}, {0, 2, 3}};
    const Image albedo(2, 2, 3, 0.5f);
    const std::vector<glm::vec2> same = {{0, 0}, {1, 0}, {1, 1}, {0, 0}, {1, 1}, {0, 1}};
    const Bundle a = make_bundle(m, same, albedo, Material{});
    EXPECT_EQ(a.mesh.positions.size(), 4u);
    EXPECT_EQ(a.mesh.normals.size(), 4u); // computed: the mesh had none
    EXPECT_EQ(a.mesh.normals[0], glm::vec3(0, 0, 1));
    const std::vector<glm::vec2> seam = {{0, 0}, {0.5f, 0}, {0.5f, 0.5f}, {0.6f, 0.6f}, {1, 1}, {0.6f, 1}};
    const Bundle b = make_bundle(m, seam, albedo, Material{});
    EXPECT_EQ(b.mesh.positions.size(), 6u);
    EXPECT_TRUE(same_bits(corner_uvs(b.mesh), seam));
    EXPECT_THROW((void)make_bundle(m, std::span(seam).first(5), albedo, Material{}), Error);
    EXPECT_THROW((void)corner_uvs(m), Error);
}

TEST(Bundle, RoundTripWithLobeAndCubeMapsIsExact) {
    const test::BundlePieces p = test::make_pieces();
    Bundle b = make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, with_lobe(p.lobe));
    b.material.status = {"converged", "converged", "max_iterations"};
    b.material.factorized = FactorizedSpecular{.terms = {{test::random_cube(8, 1), test::random_cube(16, 2)}}};
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
    ASSERT_TRUE(r.material.specular.has_value());
    EXPECT_EQ(lobe_of(r).cx, lobe_of(b).cx);
    EXPECT_EQ(lobe_of(r).cz, lobe_of(b).cz);
    EXPECT_EQ(lobe_of(r).n, lobe_of(b).n);
    EXPECT_EQ(r.material.status, b.material.status);
    ASSERT_TRUE(r.material.factorized.has_value());
    EXPECT_EQ(term(r, 0).g.resolution, 8u);
    EXPECT_EQ(term(r, 0).h.resolution, 16u);
    EXPECT_TRUE(same_bits(term(r, 0).g.texels, term(b, 0).g.texels));
    EXPECT_TRUE(same_bits(term(r, 0).h.texels, term(b, 0).h.texels));
    EXPECT_EQ(r.info, b.info);
    EXPECT_EQ(further_terms(r), 0u);
    EXPECT_EQ(test::glb_json(file)["materials"][0]["extensions"]["SPECULA_lafortune"]["version"], 1)
        << "a one-term bundle stays version 1 (older readers load it)";
    // Writing what was read gives the same file, byte for byte.
    write_bundle(dir / "again.glb", r);
    EXPECT_EQ(read_text_file(dir / "again.glb"), read_text_file(file));
}

TEST(Bundle, RoundTripWithSeveralFactorTermsIsExact) {
    const test::BundlePieces p = test::make_pieces();
    Bundle b = make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, with_lobe(p.lobe));
    b.material.factorized = FactorizedSpecular{.terms = {{test::random_cube(8, 1), test::random_cube(16, 2)},
                                                         {test::random_cube(8, 3), test::random_cube(16, 4)},
                                                         {test::random_cube(8, 5), test::random_cube(16, 6)}}};
    term(b, 2).g.texels[1].x = -0.25f; // float 3 of the cube-map: residual terms take either sign
    TempDir dir("bundle");
    const auto file = dir / "terms.glb";
    write_bundle(file, b);
    EXPECT_EQ(test::glb_json(file)["materials"][0]["extensions"]["SPECULA_lafortune"]["version"], 2);
    const Bundle r = read_bundle(file);
    ASSERT_EQ(further_terms(r), 2u);
    for (std::size_t k = 1; k <= 2; ++k) {
        EXPECT_EQ(term(r, k).g.resolution, 8u);
        EXPECT_EQ(term(r, k).h.resolution, 16u);
        EXPECT_TRUE(same_bits(term(r, k).g.texels, term(b, k).g.texels));
        EXPECT_TRUE(same_bits(term(r, k).h.texels, term(b, k).h.texels));
    }
    write_bundle(dir / "again.glb", r);
    EXPECT_EQ(read_text_file(dir / "again.glb"), read_text_file(file));
    // Inconsistent further terms are refused on writing.
    Bundle bad = b;
    term(bad, 1).h.texels.pop_back();
    EXPECT_THROW(write_bundle(dir / "bad.glb", bad), InputError);
    bad = b;
    bad.material.factorized->terms.clear(); // a factorization without its terms
    EXPECT_THROW(write_bundle(dir / "bad.glb", bad), InputError);
}

// The mirrored parametrization (shared/gshd.h part 4) is recorded as version 3 with
// "parametrization": "mirrored"; a plain bundle is written exactly as before (no field,
// version 1 or 2) and read as plain GSHD.
TEST(Bundle, RoundTripWithTheMirroredParametrization) {
    const test::BundlePieces p = test::make_pieces();
    Bundle b = make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, with_lobe(p.lobe));
    b.material.factorized = FactorizedSpecular{.terms = {{test::random_cube(8, 1), test::random_cube(16, 2)}}};
    TempDir dir("bundle");
    write_bundle(dir / "plain.glb", b);
    const json plain = test::glb_json(dir / "plain.glb")["materials"][0]["extensions"]["SPECULA_lafortune"];
    EXPECT_EQ(plain["version"], 1);
    EXPECT_FALSE(plain.contains("parametrization"));
    EXPECT_EQ(read_bundle(dir / "plain.glb").material.factorized->param, FactorParam::Gshd);
    for (const std::size_t terms : {1u, 3u}) {
        b.material.factorized->terms.resize(1);
        b.material.factorized->terms.insert(b.material.factorized->terms.end(), terms - 1,
                                            {test::random_cube(8, 3), test::random_cube(16, 4)});
        b.material.factorized->param = FactorParam::Mirrored;
        const auto file = dir / ("mirrored" + std::to_string(terms) + ".glb");
        write_bundle(file, b);
        const json ext = test::glb_json(file)["materials"][0]["extensions"]["SPECULA_lafortune"];
        EXPECT_EQ(ext["version"], 3);
        EXPECT_EQ(ext["parametrization"], "mirrored");
        const Bundle r = read_bundle(file);
        EXPECT_EQ(r.material.factorized->param, FactorParam::Mirrored);
        EXPECT_EQ(further_terms(r), terms - 1);
        EXPECT_TRUE(same_bits(term(r, 0).h.texels, term(b, 0).h.texels));
        write_bundle(dir / "again.glb", r);
        EXPECT_EQ(read_text_file(dir / "again.glb"), read_text_file(file));
    }
    // Warped (shared/gshd.h part 5): version 4, the parametrization and its warp, bit for bit.
    b.material.factorized->terms.resize(1);
    b.material.factorized->param = FactorParam::Warped;
    b.material.factorized->warp = glm::vec4(-1.0f, 0.4661f, 0.473f, 0.48f);
    write_bundle(dir / "warped.glb", b);
    const json warped = test::glb_json(dir / "warped.glb")["materials"][0]["extensions"]["SPECULA_lafortune"];
    EXPECT_EQ(warped["version"], 4);
    EXPECT_EQ(warped["parametrization"], "warped");
    EXPECT_EQ(warped["warp"].size(), 4u);
    const Bundle rw = read_bundle(dir / "warped.glb");
    EXPECT_EQ(rw.material.factorized->param, FactorParam::Warped);
    EXPECT_EQ(rw.material.factorized->warp, b.material.factorized->warp);
    Bundle no_lobe = b;
    no_lobe.material.specular.reset(); // the radial factor needs the lobe
    EXPECT_THROW(write_bundle(dir / "bad.glb", no_lobe), InputError);
    // Without cube-maps the parametrization means nothing and is not written.
    b.material.factorized.reset();
    write_bundle(dir / "diffuse.glb", b);
    const json none = test::glb_json(dir / "diffuse.glb")["materials"][0]["extensions"]["SPECULA_lafortune"];
    EXPECT_EQ(none["version"], 1);
    EXPECT_FALSE(none.contains("parametrization"));
}

TEST(Bundle, MaterialCarriesTheViewerApproximationAndAnOptionalExtension) {
    const test::BundlePieces p = test::make_pieces();
    TempDir dir("bundle");
    write_bundle(dir / "b.glb", make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, with_lobe(p.lobe)));
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
    write_bundle(dir / "d.glb", make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, Material{}));
    const json doc = test::glb_json(dir / "d.glb");
    const json& ext = doc["materials"][0]["extensions"]["SPECULA_lafortune"];
    EXPECT_FALSE(ext.contains("lobe"));
    EXPECT_FALSE(ext.contains("cubeG"));
    EXPECT_EQ(doc["materials"][0]["pbrMetallicRoughness"]["roughnessFactor"].get<double>(), 1.0);
    const Bundle r = read_bundle(dir / "d.glb");
    EXPECT_FALSE(r.material.specular.has_value());
    EXPECT_TRUE(r.material.status.empty());
    EXPECT_FALSE(r.material.factorized.has_value());
    EXPECT_TRUE(same_bits(r.albedo.pixels, p.albedo.pixels));
    EXPECT_TRUE(r.warnings.empty());
}

// Issue 20's leaner bundle: the float albedo beside the .glb (what reconstruct writes by
// default), read back exactly; without the file, the 8-bit base colour with a warning;
// a file of another size or a name with a folder is refused naming albedo.uri.
TEST(Bundle, FloatAlbedoBesideTheGlbReadsBackExactlyOrFallsBackWithAWarning) {
    const test::BundlePieces p = test::make_pieces();
    TempDir dir("bundle");
    const Bundle b = make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, with_lobe(p.lobe));
    write_bundle(dir / "inside.glb", b);
    write_bundle(dir / "lean.glb", b, {.float_albedo_file = "lean_albedo.exr"});
    const json ext = test::glb_json(dir / "lean.glb")["materials"][0]["extensions"]["SPECULA_lafortune"];
    EXPECT_EQ(ext["albedo"]["uri"], "lean_albedo.exr");
    EXPECT_FALSE(ext["albedo"].contains("bufferView"));
    const std::uintmax_t float_bytes = p.albedo.pixels.size() * sizeof(float);
    EXPECT_LE(std::filesystem::file_size(dir / "lean.glb") + float_bytes, std::filesystem::file_size(dir / "inside.glb") + 8);
    const Bundle r = read_bundle(dir / "lean.glb");
    EXPECT_TRUE(same_bits(r.albedo.pixels, p.albedo.pixels));
    EXPECT_TRUE(r.warnings.empty());

    // Without the file: the base colour PNG, within its 8-bit sRGB step, and a warning.
    std::filesystem::rename(dir / "lean_albedo.exr", dir / "elsewhere.exr");
    const Bundle fallback = read_bundle(dir / "lean.glb");
    ASSERT_EQ(fallback.albedo.pixels.size(), p.albedo.pixels.size());
    for (std::size_t i = 0; i < p.albedo.pixels.size(); ++i)
        ASSERT_NEAR(fallback.albedo.pixels[i], std::clamp(p.albedo.pixels[i], 0.0f, 1.0f), 0.01f) << i;
    ASSERT_EQ(fallback.warnings.size(), 1u);
    EXPECT_NE(fallback.warnings[0].find("lean_albedo.exr is not beside"), std::string::npos) << fallback.warnings[0];

    // A file of another size is refused, naming the field.
    write_image(dir / "lean_albedo.exr", Image(p.albedo.width + 1, p.albedo.height, 3, 0.5f), ColorSpace::Linear);
    const InputError e = test::expect_input_error([&] { (void)read_bundle(dir / "lean.glb"); });
    EXPECT_NE(e.field().find("albedo.uri"), std::string::npos) << e.what();
    EXPECT_THROW(write_bundle(dir / "x.glb", b, {.float_albedo_file = "../x.exr"}), InputError);
}

TEST(Bundle, ForeignGlbWithoutMaterialIsRefusedNamingTheField) {
    test::BundlePieces p = test::make_pieces();
    TempDir dir("bundle");
    // A plain mesh (write_mesh_glb) with texture coordinates but no material.
    const Bundle b = make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, Material{});
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
    Bundle b = make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, with_lobe(p.lobe));
    b.material.factorized = FactorizedSpecular{.terms = {{test::random_cube(4, 3), test::random_cube(4, 4)}}};
    write_bundle(dir / "f.glb", b);
    json doc = test::glb_json(dir / "f.glb");
    doc["materials"][0].erase("extensions");
    doc.erase("extensionsUsed");
    test::rewrite_glb_json(dir / "f.glb", doc);
    const Bundle r = read_bundle(dir / "f.glb");
    EXPECT_FALSE(r.material.specular.has_value());
    EXPECT_FALSE(r.material.factorized.has_value());
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
    Bundle b = make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, with_lobe(p.lobe));
    b.material.factorized = FactorizedSpecular{.terms = {{test::random_cube(4, 5), test::random_cube(4, 6)}}};
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
    d["materials"][0]["extensions"]["SPECULA_lafortune"]["version"] = 6; // beyond the reader's (5)
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
    term(bad, 0).h.texels.pop_back();
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
    Bundle b = make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, with_lobe(p.lobe));
    b.material.status = {"converged", "converged", "converged"};
    b.material.factorized = FactorizedSpecular{.terms = {{test::random_cube(8, 1), test::random_cube(8, 2)},
                                                         {test::random_cube(8, 3), test::random_cube(8, 4)}}}; // version 2, cubeTerms
    TempDir dir("bundle");
    // lobe; mirrored (version 3); warped (version 4); diffuse only; coated (version 5, with
    // KHR_materials_ior and KHR_materials_specular, which the validator checks); with a normal
    // map (normalTexture and the TANGENT attribute, whose unit length and sign it checks); the
    // fitted core material, a base layer (IOR 3 with a specular colour above 1) and a clearcoat
    // (KHR_materials_clearcoat).
    for (const int kind : {0, 1, 2, 3, 4, 5, 6, 7}) {
        if (kind == 1) b.material.factorized->param = FactorParam::Mirrored;
        if (kind == 2) {
            b.material.factorized->param = FactorParam::Warped;
            b.material.factorized->warp = warp_for_lobe(lobe_of(b)).value();
        }
        if (kind == 3) {
            b.material.factorized->param = FactorParam::Gshd;
            b.material.specular.reset();
        }
        if (kind == 4) b.material.specular = CoatedParams{.eta = 1.4537f, .alpha = 0.0837f, .tint = {0.91f, 1.0f, 1.23f}};
        if (kind == 5) b.normal_map = Image(b.albedo.width, b.albedo.height, 3, 0.5f);
        if (kind == 6) b.core = CoreMaterial{.roughness = 0.49, .f0 = 0.057, .f90 = 0.057};
        if (kind == 7) b.core = CoreMaterial{.roughness = 1.0, .clearcoat = 1.0, .clearcoat_roughness = 0.335};
        const auto file = dir / (kind == 0   ? "lobe.glb"
                                 : kind == 1 ? "mirrored.glb"
                                 : kind == 2 ? "warped.glb"
                                 : kind == 3 ? "diffuse.glb"
                                 : kind == 4 ? "coated.glb"
                                 : kind == 5 ? "normal_map.glb"
                                 : kind == 6 ? "core.glb"
                                             : "clearcoat.glb");
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


// A normal map (issue 17): written as normalTexture (8-bit linear PNG) with a TANGENT per
// vertex (unit, orthogonal to the written normal, w = +-1), read back to the 8-bit codes; a
// world normal stored through the bundle's frames decodes, as a viewer decodes it, within the
// 8-bit quantization (0.5 degree) on every texel of a sphere. A bundle without one has no
// normalTexture and no TANGENT.
TEST(Bundle, NormalMapRoundTripsThroughTheTangentFrames) {
    const test::BundlePieces p = test::make_pieces();
    Bundle b = make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, with_lobe(p.lobe));
    const std::vector<glm::vec3> normals = gltf_unit_normals(b.mesh);
    const std::vector<glm::vec4> tangents = vertex_tangents(b.mesh);
    ASSERT_EQ(tangents.size(), b.mesh.positions.size());
    for (std::size_t i = 0; i < tangents.size(); ++i) {
        EXPECT_NEAR(glm::length(glm::vec3(tangents[i])), 1.0f, 1e-5f) << i;
        EXPECT_NEAR(glm::dot(glm::vec3(tangents[i]), normals[i]), 0.0f, 1e-5f) << i;
        EXPECT_EQ(std::abs(tangents[i].w), 1.0f) << i;
    }
    // Every texel's world normal: the mesh normal tilted by 10 degrees about a fixed axis.
    const ParticleSet particles = build_particles(p.mesh, p.atlas);
    const glm::mat3 tilt = glm::mat3(glm::rotate(glm::mat4(1.0f), glm::radians(10.0f), glm::vec3(0.3f, 0.8f, 0.5f)));
    Image map(b.albedo.width, b.albedo.height, 3, 0.5f);
    std::vector<glm::vec3> truth(particles.particles.size());
    for (std::size_t i = 0; i < particles.particles.size(); ++i) {
        const Particle& q = particles.particles[i];
        truth[i] = glm::normalize(tilt * q.n());
        const TangentFrame f = tangent_frame_at(b.mesh, normals, tangents, q.triangle, q.bary);
        const glm::vec3 e = encode_tangent_normal(f, truth[i]);
        for (int c = 0; c < 3; ++c) map.at(static_cast<int>(q.texel_x()), static_cast<int>(q.texel_y()), c) = e[c];
    }
    b.normal_map = map;
    TempDir dir("bundle");
    write_bundle(dir / "n.glb", b);
    const Bundle r = read_bundle(dir / "n.glb");
    ASSERT_TRUE(r.normal_map.has_value());
    ASSERT_EQ(r.normal_map->pixels.size(), map.pixels.size());
    double worst = 0.0;
    for (std::size_t i = 0; i < map.pixels.size(); ++i) // 8-bit codes
        ASSERT_NEAR(r.normal_map->pixels[i], std::round(map.pixels[i] * 255.0f) / 255.0f, 1e-6f) << i;
    for (std::size_t i = 0; i < particles.particles.size(); ++i) {
        const Particle& q = particles.particles[i];
        const TangentFrame f = tangent_frame_at(r.mesh, gltf_unit_normals(r.mesh), tangents, q.triangle, q.bary);
        const glm::vec3 code(r.normal_map->at(static_cast<int>(q.texel_x()), static_cast<int>(q.texel_y()), 0),
                             r.normal_map->at(static_cast<int>(q.texel_x()), static_cast<int>(q.texel_y()), 1),
                             r.normal_map->at(static_cast<int>(q.texel_x()), static_cast<int>(q.texel_y()), 2));
        const glm::vec3 shaded = decode_tangent_normal(f, code);
        worst = std::max(worst, glm::degrees(std::acos(std::min(1.0, double(glm::dot(shaded, truth[i]))))));
    }
    std::printf("normal map through the bundle: worst decoded angle %.3f deg over %zu texels\n", worst, particles.particles.size());
    EXPECT_LT(worst, 0.5);

    b.normal_map.reset();
    write_bundle(dir / "plain.glb", b);
    EXPECT_FALSE(read_bundle(dir / "plain.glb").normal_map.has_value());
    const std::string text = read_text_file(dir / "plain.glb");
    EXPECT_EQ(text.find("TANGENT"), std::string::npos);
    EXPECT_EQ(text.find("normalTexture"), std::string::npos);
    EXPECT_NE(read_text_file(dir / "n.glb").find("TANGENT"), std::string::npos);
}

// ---- format compatibility -----------------------------------------------------------

// tests/export/data/legacy_v{1,4}.glb were written by write_bundle before the glTF I/O moved
// to capture/gltf_io, legacy_v{0,3}.glb (Lambertian; mirrored with two terms) before the
// extension's version 5 (the coated family) was added (legacy_bundles.h): they read back bit
// for bit, including an integer in "info" above 2^32, and writing what was read gives the same
// bytes: the format of every bundle without the coated family is unchanged.
TEST(Bundle, LegacyBundlesReadExactlyAndRewriteByteForByte) {
    TempDir dir("bundle");
    for (const int version : {0, 1, 3, 4}) {
        const auto file = test::source_dir() / "tests" / "export" / "data" / ("legacy_v" + std::to_string(version) + ".glb");
        const Bundle want = test::legacy_bundle(version);
        const Bundle r = read_bundle(file);
        EXPECT_TRUE(r.warnings.empty());
        EXPECT_TRUE(same_bits(r.mesh.positions, want.mesh.positions));
        EXPECT_TRUE(same_bits(r.mesh.normals, want.mesh.normals));
        EXPECT_TRUE(same_bits(r.mesh.texcoords, want.mesh.texcoords));
        EXPECT_TRUE(same_bits(r.mesh.triangles, want.mesh.triangles));
        EXPECT_EQ(r.albedo.width, 3);
        EXPECT_EQ(r.albedo.height, 2);
        EXPECT_TRUE(same_bits(r.albedo.pixels, want.albedo.pixels));
        EXPECT_EQ(r.material.status, want.material.status);
        if (version == 0) { // Lambertian: no lobe, no cube-maps
            EXPECT_FALSE(r.material.specular.has_value());
            EXPECT_FALSE(r.material.factorized.has_value());
        } else {
            ASSERT_TRUE(r.material.specular.has_value());
            EXPECT_EQ(lobe_of(r).cx, lobe_of(want).cx);
            EXPECT_EQ(lobe_of(r).cz, lobe_of(want).cz);
            EXPECT_EQ(lobe_of(r).n, lobe_of(want).n);
            ASSERT_TRUE(r.material.factorized.has_value());
            EXPECT_EQ(term(r, 0).g.resolution, 1u);
            EXPECT_EQ(term(r, 0).h.resolution, 2u);
            EXPECT_TRUE(same_bits(term(r, 0).g.texels, term(want, 0).g.texels));
            EXPECT_TRUE(same_bits(term(r, 0).h.texels, term(want, 0).h.texels));
            ASSERT_EQ(further_terms(r), further_terms(want));
            for (std::size_t k = 1; k <= further_terms(r); ++k) {
                EXPECT_TRUE(same_bits(term(r, k).g.texels, term(want, k).g.texels));
                EXPECT_TRUE(same_bits(term(r, k).h.texels, term(want, k).h.texels));
            }
            EXPECT_EQ(r.material.factorized->param, want.material.factorized->param);
            EXPECT_EQ(r.material.factorized->warp, want.material.factorized->warp);
        }
        EXPECT_EQ(r.info, want.info);
        ASSERT_TRUE(r.info["texels"].is_number_unsigned());
        EXPECT_EQ(r.info["texels"].get<std::uint64_t>(), 5000000000ull); // not narrowed to int
        const auto again = dir / ("again" + std::to_string(version) + ".glb");
        write_bundle(again, r);
        EXPECT_EQ(read_text_file(again), read_text_file(file)) << "version " << version;
        write_bundle(again, want);
        EXPECT_EQ(read_text_file(again), read_text_file(file)) << "version " << version;
    }
}

// ---- the loader's guards, through read_bundle (capture/gltf_io.h) ---------------------

/// Rewrites `file` with its extension object (as written now) edited by the function given.
std::function<void(const std::function<void(json&)>&)> extension_editor(const std::filesystem::path& file) {
    return [file, good = test::glb_json(file)](const std::function<void(json&)>& edit) {
        json d = good;
        edit(d["materials"][0]["extensions"]["SPECULA_lafortune"]);
        test::rewrite_glb_json(file, d);
    };
}

void expect_bundle_refusal(const std::filesystem::path& file, const std::string& field, const std::string& words) {
    try {
        (void)read_bundle(file);
        ADD_FAILURE() << "expected InputError on " << field;
    } catch (const InputError& e) {
        EXPECT_EQ(e.file(), file);
        EXPECT_EQ(e.field(), field) << e.what();
        EXPECT_NE(e.message().find(words), std::string::npos) << e.what();
    }
}

// The JSON text of a written bundle with `insert` placed right after `after` (its first match).
std::string bundle_text_with(const std::filesystem::path& file, const std::string& after, const std::string& insert) {
    std::string text = test::glb_json(file).dump();
    const std::size_t at = text.find(after);
    EXPECT_NE(at, std::string::npos) << after;
    text.insert(at + after.size(), insert);
    return text;
}

// ---- the coated family (extension version 5) ------------------------------------------

/// A coated material with parameters that are not round decimals (float bits matter).
CoatedParams coated_params() {
    CoatedParams c;
    c.eta = 1.4537f;
    c.alpha = 0.0837f;
    c.tint = {0.91f, 1.0f, 1.23f}; // above 1 in one channel: glTF allows it (KHR_materials_specular)
    return c;
}

TEST(BundleCoated, RoundTripIsExactAndWritesVersion5WithTheModel) {
    const test::BundlePieces p = test::make_pieces();
    const CoatedParams c = coated_params();
    Bundle b = make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, Material{.specular = c});
    b.material.status = {"converged"};
    b.material.factorized = FactorizedSpecular{.terms = {{test::random_cube(4, 1), test::random_cube(4, 2)}}};
    b.material.factorized->param = FactorParam::Mirrored; // a coated bundle may carry cube-maps too
    b.info = {{"specula_version", "test"}};
    TempDir dir("bundle");
    const auto file = dir / "coated.glb";
    write_bundle(file, b);
    const json ext = test::glb_json(file)["materials"][0]["extensions"]["SPECULA_lafortune"];
    EXPECT_EQ(ext["version"], 5);
    EXPECT_EQ(ext["model"], "coated");
    EXPECT_FALSE(ext.contains("lobe"));
    ASSERT_TRUE(ext["coated"].is_object());
    EXPECT_EQ(ext["coated"]["eta"].get<double>(), static_cast<double>(c.eta));
    EXPECT_EQ(ext["coated"]["alpha"].get<double>(), static_cast<double>(c.alpha));
    EXPECT_EQ(ext["coated"]["tint"], json::array({static_cast<double>(c.tint.x), static_cast<double>(c.tint.y),
                                                  static_cast<double>(c.tint.z)}));
    EXPECT_EQ(ext["parametrization"], "mirrored");

    const Bundle r = read_bundle(file);
    EXPECT_TRUE(r.warnings.empty());
    ASSERT_TRUE(r.material.specular.has_value());
    ASSERT_TRUE(std::holds_alternative<CoatedParams>(*r.material.specular));
    const CoatedParams& rc = std::get<CoatedParams>(*r.material.specular);
    // Bit for bit: float -> shortest double decimal -> float.
    EXPECT_EQ(std::memcmp(&rc.eta, &c.eta, sizeof(float)), 0);
    EXPECT_EQ(std::memcmp(&rc.alpha, &c.alpha, sizeof(float)), 0);
    EXPECT_EQ(rc.tint, c.tint);
    EXPECT_EQ(r.material.status, b.material.status);
    ASSERT_TRUE(r.material.factorized.has_value());
    EXPECT_EQ(r.material.factorized->param, FactorParam::Mirrored);
    EXPECT_TRUE(same_bits(term(r, 0).g.texels, term(b, 0).g.texels));
    EXPECT_TRUE(same_bits(r.albedo.pixels, b.albedo.pixels));
    EXPECT_EQ(r.info, b.info);
    write_bundle(dir / "again.glb", r);
    EXPECT_EQ(read_text_file(dir / "again.glb"), read_text_file(file));

    // Without cube-maps: still version 5 (the model needs it).
    b.material.factorized.reset();
    write_bundle(dir / "plain.glb", b);
    EXPECT_EQ(test::glb_json(dir / "plain.glb")["materials"][0]["extensions"]["SPECULA_lafortune"]["version"], 5);
    EXPECT_TRUE(std::holds_alternative<CoatedParams>(*read_bundle(dir / "plain.glb").material.specular));
}

// The core material a viewer renders: the glTF 2.0 specification, appendix B (specular_brdf:
// GGX with alpha = roughness^2), KHR_materials_ior (ior) and KHR_materials_specular
// (dielectric_f0 = min(((ior - 1) / (ior + 1))^2 specularColorFactor, 1) specularFactor),
// computed here from the written JSON as a viewer would, and compared with the coated model's own
// GGX distribution and tinted Fresnel reflectance at normal incidence (shaders/shared/coated.h).
TEST(BundleCoated, CoreMaterialCarriesRoughnessIorAndSpecularExactly) {
    const test::BundlePieces p = test::make_pieces(3, 4);
    const CoatedParams c = coated_params();
    TempDir dir("bundle");
    write_bundle(dir / "c.glb", make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, Material{.specular = c}));
    const json doc = test::glb_json(dir / "c.glb");
    EXPECT_EQ(doc["extensionsUsed"], json::array({"SPECULA_lafortune", "KHR_materials_ior", "KHR_materials_specular"}));
    EXPECT_FALSE(doc.contains("extensionsRequired")); // a plain viewer still loads it
    const json& mat = doc["materials"][0];
    const json& pbr = mat["pbrMetallicRoughness"];
    EXPECT_EQ(pbr["metallicFactor"].get<double>(), 0.0);
    const double roughness = pbr["roughnessFactor"].get<double>();
    EXPECT_EQ(roughness, std::sqrt(static_cast<double>(c.alpha)));
    EXPECT_NEAR(roughness * roughness, static_cast<double>(c.alpha), 1e-15);
    const double ior = mat["extensions"]["KHR_materials_ior"]["ior"].get<double>();
    EXPECT_EQ(ior, static_cast<double>(c.eta));
    const json& spec = mat["extensions"]["KHR_materials_specular"];
    EXPECT_EQ(spec.value("specularFactor", 1.0), 1.0);
    ASSERT_EQ(spec["specularColorFactor"].size(), 3u);

    // The viewer's GGX distribution (glTF appendix B, alpha = roughness^2) is the model's.
    const double a = roughness * roughness;
    for (const double nh : {1.0, 0.99, 0.9, 0.6, 0.2}) {
        const double t = nh * nh * (a * a - 1.0) + 1.0;
        const double d_gltf = a * a / (std::numbers::pi * t * t);
        EXPECT_NEAR(d_gltf / shared::f64::coated_ggx_d(nh, static_cast<double>(c.alpha)), 1.0, 1e-12) << nh;
    }
    // The viewer's F0 (both extensions) is the coated reflection's tint times its exact Fresnel
    // reflectance at normal incidence.
    for (int ch = 0; ch < 3; ++ch) {
        const double f0_gltf = std::min(std::pow((ior - 1.0) / (ior + 1.0), 2.0) * spec["specularColorFactor"][ch].get<double>(), 1.0) *
                               spec.value("specularFactor", 1.0);
        const double f0_model = static_cast<double>(c.tint[ch]) * shared::f64::coated_fresnel(1.0, static_cast<double>(c.eta));
        EXPECT_NEAR(f0_gltf, f0_model, 1e-12) << ch;
    }
    // A Lafortune bundle keeps its single extension and no KHR_materials_* object.
    write_bundle(dir / "l.glb", make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, with_lobe(p.lobe)));
    const json ldoc = test::glb_json(dir / "l.glb");
    EXPECT_EQ(ldoc["extensionsUsed"], json::array({"SPECULA_lafortune"}));
    EXPECT_EQ(ldoc["materials"][0]["extensions"].size(), 1u);
}

TEST(BundleCoated, WritingRefusesParametersOutOfRangeNamingTheField) {
    const test::BundlePieces p = test::make_pieces(3, 4);
    TempDir dir("bundle");
    const auto file = dir / "bad.glb";
    auto expect_write_refusal = [&](const CoatedParams& c, const std::string& field) {
        Bundle b = make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, Material{.specular = c});
        try {
            write_bundle(file, b);
            ADD_FAILURE() << "expected InputError on " << field;
        } catch (const InputError& e) {
            EXPECT_EQ(e.file(), file);
            EXPECT_EQ(e.field(), field) << e.what();
        }
        EXPECT_FALSE(std::filesystem::exists(file));
    };
    CoatedParams c = coated_params();
    c.eta = 1.0f; // no interface: below shared::kCoatedMinEta
    expect_write_refusal(c, "material.specular.coated.eta");
    c = coated_params();
    c.alpha = std::numeric_limits<float>::quiet_NaN();
    expect_write_refusal(c, "material.specular.coated.alpha");
    c = coated_params();
    c.tint.y = -0.5f;
    expect_write_refusal(c, "material.specular.coated.tint");
    // Warped cube-maps hold a Lafortune lobe over its radial factor: not a coated model's.
    Bundle b = make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, Material{.specular = coated_params()});
    b.material.factorized = FactorizedSpecular{.param = FactorParam::Warped, .warp = glm::vec4(-1.0f, 0.5f, 0.5f, 0.5f),
                                               .terms = {{test::random_cube(2, 1), test::random_cube(2, 2)}}};
    EXPECT_THROW(write_bundle(file, b), InputError);
}

TEST(BundleCoated, ReadingRefusesUnknownModelsVersionsAndBadParametersNamingTheField) {
    const test::BundlePieces p = test::make_pieces(3, 4);
    TempDir dir("bundle");
    const auto file = dir / "c.glb";
    write_bundle(file, make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, Material{.specular = coated_params()}));
    const std::string ext = "materials[0].extensions.SPECULA_lafortune";
    const auto with = extension_editor(file);
    with([](json&) {}); // the control: the unedited file reads
    EXPECT_NO_THROW((void)read_bundle(file));

    with([](json& e) { e["model"] = "velvet"; });
    expect_bundle_refusal(file, ext + ".model", "unknown model \"velvet\"");
    with([](json& e) { e["model"] = 1; });
    expect_bundle_refusal(file, ext + ".model", "unknown model");
    with([](json& e) { e["version"] = 6; }); // a future version
    expect_bundle_refusal(file, ext + ".version", "unsupported version");
    with([](json& e) { e["version"] = 4; }); // the model needs version 5
    expect_bundle_refusal(file, ext + ".model", "needs version 5");
    with([](json& e) { e["coated"]["eta"] = 0.5; });
    expect_bundle_refusal(file, ext + ".coated.eta", "outside");
    with([](json& e) { e["coated"]["eta"] = 3.5; });
    expect_bundle_refusal(file, ext + ".coated.eta", "outside");
    with([](json& e) { e["coated"]["eta"] = 1e300; }); // beyond float: refused, not narrowed
    expect_bundle_refusal(file, ext + ".coated.eta", "finite");
    with([](json& e) { e["coated"]["alpha"] = 0.0; });
    expect_bundle_refusal(file, ext + ".coated.alpha", "outside");
    with([](json& e) { e["coated"]["alpha"] = 1.5; });
    expect_bundle_refusal(file, ext + ".coated.alpha", "outside");
    with([](json& e) { e["coated"]["tint"] = json::array({1.0, -0.25, 1.0}); });
    expect_bundle_refusal(file, ext + ".coated.tint", "non-negative");
    with([](json& e) { e["coated"]["tint"] = json::array({1.0, 1.0}); });
    expect_bundle_refusal(file, ext + ".coated.tint", "missing or not an array of 3 numbers");
    for (const char* key : {"eta", "alpha", "tint"}) {
        with([&](json& e) { e["coated"].erase(key); });
        expect_bundle_refusal(file, ext + ".coated." + key, "missing");
    }
    with([](json& e) { e["coated"]["eta"] = "1.5"; });
    expect_bundle_refusal(file, ext + ".coated.eta", "not a number");
    with([](json& e) { e.erase("coated"); });
    expect_bundle_refusal(file, ext + ".coated", "missing");
    with([](json& e) { e["coated"] = json::array({1.5, 0.1}); });
    expect_bundle_refusal(file, ext + ".coated", "not an object");
    with([](json& e) { e.erase("model"); }); // coated parameters without the model
    expect_bundle_refusal(file, ext + ".coated", "without \"model\": \"coated\"");
    with([](json& e) { e["lobe"] = {{"cx", {-1, -1, -1}}, {"cz", {1, 1, 1}}, {"n", {10, 10, 10}}}; });
    expect_bundle_refusal(file, ext + ".lobe", "in a \"coated\" model");
    // An explicit "lafortune" model in version 5 reads as the lobe it carries.
    with([](json& e) {
        e["model"] = "lafortune";
        e.erase("coated");
        e["lobe"] = {{"cx", {-1, -1, -1}}, {"cz", {1, 1, 1}}, {"n", {10, 10, 10}}};
    });
    const Bundle r = read_bundle(file);
    ASSERT_TRUE(r.material.specular && std::holds_alternative<LafortuneRgb>(*r.material.specular));
    EXPECT_EQ(lobe_of(r).n, glm::vec3(10.0f));
}

TEST(BundleGuard, JsonNestingInTheExtensionIsRefusedWithoutCrashing) {
    const test::BundlePieces p = test::make_pieces(3, 4);
    TempDir dir("bundle");
    const auto file = dir / "deep.glb";
    write_bundle(file, make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, with_lobe(p.lobe)));
    const std::string deep = "\"deep\":" + std::string(100000, '[') + std::string(100000, ']') + ",";
    test::rewrite_glb_text(file, bundle_text_with(file, "\"info\":{", deep));
    expect_bundle_refusal(file, "materials[0].extensions.SPECULA_lafortune.info.deep", "deeper than 256");
}

TEST(BundleGuard, DuplicateKeyInTheExtensionIsRefused) {
    const test::BundlePieces p = test::make_pieces(3, 4);
    TempDir dir("bundle");
    const auto file = dir / "dup.glb";
    write_bundle(file, make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, with_lobe(p.lobe)));
    // Two versions: a reader keeping the first and one keeping the last would read different bundles.
    test::rewrite_glb_text(file, bundle_text_with(file, "\"SPECULA_lafortune\":{", "\"version\":4,"));
    expect_bundle_refusal(file, "materials[0].extensions.SPECULA_lafortune.version", "duplicate JSON key");
}

TEST(BundleGuard, RequiredExtensionsAreHonouredOrRefused) {
    const test::BundlePieces p = test::make_pieces(3, 4);
    TempDir dir("bundle");
    const auto file = dir / "req.glb";
    const Bundle b = make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, with_lobe(p.lobe));
    write_bundle(file, b);
    json doc = test::glb_json(file);
    doc["extensionsRequired"] = {"SPECULA_lafortune"}; // its own extension: honoured
    test::rewrite_glb_json(file, doc);
    const Bundle r = read_bundle(file);
    ASSERT_TRUE(r.material.specular.has_value());
    EXPECT_TRUE(same_bits(r.albedo.pixels, b.albedo.pixels));
    doc["extensionsRequired"] = {"SPECULA_lafortune", "KHR_draco_mesh_compression"};
    test::rewrite_glb_json(file, doc);
    expect_bundle_refusal(file, "extensionsRequired[1]", "KHR_draco_mesh_compression");
}

// A .gltf bundle with its buffer in a file beside it reads as the .glb does; the buffer's
// URI must stay in the folder and name a regular file (a FIFO is refused, not waited on).
TEST(BundleGuard, ExternalBufferReadsTheSameAndStaysInItsFolder) {
    const test::BundlePieces p = test::make_pieces(3, 4);
    TempDir dir("bundle");
    Bundle b = make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, with_lobe(p.lobe));
    b.material.factorized = FactorizedSpecular{.terms = {{test::random_cube(4, 1), test::random_cube(4, 2)}}};
    write_bundle(dir / "b.glb", b);
    const std::string glb = read_text_file(dir / "b.glb");
    std::uint32_t json_len = 0, bin_len = 0;
    std::memcpy(&json_len, glb.data() + 12, 4);
    std::memcpy(&bin_len, glb.data() + 20 + json_len, 4);
    std::filesystem::create_directories(dir / "model");
    write_text_file(dir / "model" / "b.bin", glb.substr(28 + json_len, bin_len));
    write_text_file(dir / "b.bin", glb.substr(28 + json_len, bin_len));
    json doc = test::glb_json(dir / "b.glb");
    const auto file = dir / "model" / "b.gltf";
    doc["buffers"][0]["uri"] = "b.bin";
    write_text_file(file, doc.dump());
    const Bundle r = read_bundle(file);
    EXPECT_TRUE(same_bits(r.mesh.positions, b.mesh.positions));
    EXPECT_TRUE(same_bits(r.albedo.pixels, b.albedo.pixels));
    EXPECT_TRUE(same_bits(term(r, 0).h.texels, term(b, 0).h.texels));
    doc["buffers"][0]["uri"] = "../b.bin";
    write_text_file(file, doc.dump());
    expect_bundle_refusal(file, "buffers[0].uri", "leaves the glTF file's folder");
    ASSERT_EQ(::mkfifo((dir / "model" / "pipe.bin").c_str(), 0600), 0);
    doc["buffers"][0]["uri"] = "pipe.bin";
    write_text_file(file, doc.dump());
    auto result = std::async(std::launch::async, [&] { expect_bundle_refusal(file, "buffers[0].uri", "a FIFO"); });
    if (result.wait_for(std::chrono::seconds(20)) != std::future_status::ready) {
        ADD_FAILURE() << "read_bundle blocked on the FIFO";
        const int fd = ::open((dir / "model" / "pipe.bin").c_str(), O_WRONLY | O_NONBLOCK); // frees it
        if (fd >= 0) ::close(fd);
    }
    result.get();
}

// The forged PNG header as bytes (tests/capture/png_bytes.h).
std::vector<std::uint8_t> png_claiming(std::uint32_t w, std::uint32_t h) {
    const std::string png = test::png_claiming(w, h);
    return {png.begin(), png.end()};
}

// A foreign .gltf (no extension): a textured quad whose base colour is images[0], which the
// caller adds.
test::GltfBuilder foreign_quad() {
    test::GltfBuilder b;
    json prim = {{"attributes",
                  {{"POSITION", b.positions({0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0})},
                   {"TEXCOORD_0", b.texcoords({0, 0, 1, 0, 1, 1, 0, 1})}}},
                 {"indices", b.indices_u16({0, 1, 2, 0, 2, 3})},
                 {"material", 0}};
    b.node({{"mesh", b.mesh(json::array({prim}))}});
    b.doc()["materials"] = {{{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}}};
    b.doc()["textures"] = {{{"source", 0}}};
    return b;
}

TEST(BundleGuard, BaseColourSizeIsReadFromTheHeaderAndRefusedAboveTheLimit) {
    TempDir dir("bundle");
    const auto file = dir / "f.gltf";
    // The control: a real 2 x 2 PNG in a bufferView decodes to the albedo.
    Image texture(2, 2, 3);
    for (std::size_t i = 0; i < texture.pixels.size(); ++i) texture.pixels[i] = 0.05f * static_cast<float>(i + 1);
    const std::vector<std::uint8_t> real = encode_image(texture, ImageCodec::Png, ColorSpace::Srgb);
    test::GltfBuilder b = foreign_quad();
    b.doc()["images"] = {{{"bufferView", b.view(real)}, {"mimeType", "image/png"}}};
    b.write(file);
    const Bundle r = read_bundle(file);
    ASSERT_EQ(r.albedo.width, 2);
    for (std::size_t i = 0; i < r.albedo.pixels.size(); ++i)
        EXPECT_NEAR(linear_to_srgb(r.albedo.pixels[i]), linear_to_srgb(texture.pixels[i]), 0.5f / 255.0f + 1e-5f);

    // 30000 x 30000: the header is readable, and the image is refused from it.
    const std::vector<std::uint8_t> huge = png_claiming(30000, 30000);
    const ImageFileInfo info = read_image_info(huge, file, "images[0]");
    EXPECT_EQ(info.width, 30000);
    EXPECT_EQ(info.height, 30000);
    b = foreign_quad(); // embedded in a bufferView
    b.doc()["images"] = {{{"bufferView", b.view(huge)}, {"mimeType", "image/png"}}};
    b.write(file);
    expect_bundle_refusal(file, "images[0].bufferView", "30000 x 30000");
    b = foreign_quad(); // linked
    write_text_file(dir / "huge.png", std::string(huge.begin(), huge.end()));
    b.doc()["images"] = {{{"uri", "huge.png"}}};
    b.write(file);
    expect_bundle_refusal(file, "images[0].uri", "30000 x 30000");
    b.doc()["images"] = {{{"uri", "data:image/png;base64," + test::base64(huge)}}}; // a data URI
    b.write(file);
    expect_bundle_refusal(file, "images[0].uri", "30000 x 30000");
    // One side above the limit is enough.
    const std::vector<std::uint8_t> wide = png_claiming(kMaxDecodedImageDimension + 1, 1);
    b.doc()["images"] = {{{"uri", "data:image/png;base64," + test::base64(wide)}}};
    b.write(file);
    expect_bundle_refusal(file, "images[0].uri", "above the largest accepted width or height");
}

// ---- the in-memory image codec (core/image.h), which the bundle's base colour uses ------

TEST(ImageCodec, PngAndExrRoundTripInMemory) {
    Image image(5, 3, 3);
    for (std::size_t i = 0; i < image.pixels.size(); ++i) image.pixels[i] = 0.021f * static_cast<float>(i);
    image.pixels[4] = 1.75f; // above 1: EXR keeps it, PNG clamps
    const std::filesystem::path name = "memory";
    for (const int bits : {8, 16}) {
        const std::vector<std::uint8_t> png = encode_image(image, ImageCodec::Png, ColorSpace::Srgb, bits);
        const ImageFileInfo info = read_image_info(png, name, "png");
        EXPECT_EQ(info.width, 5);
        EXPECT_EQ(info.height, 3);
        EXPECT_EQ(info.bits_per_channel, bits);
        EXPECT_FALSE(info.is_float);
        const Image back = decode_image(png, ColorSpace::Srgb, name, "png");
        ASSERT_EQ(back.pixels.size(), image.pixels.size());
        const float step = bits == 8 ? 1.0f / 255.0f : 1.0f / 65535.0f;
        for (std::size_t i = 0; i < image.pixels.size(); ++i)
            ASSERT_NEAR(linear_to_srgb(back.pixels[i]), linear_to_srgb(std::min(image.pixels[i], 1.0f)), 0.5f * step + 1e-6f) << i;
    }
    const std::vector<std::uint8_t> exr = encode_image(image, ImageCodec::Exr, ColorSpace::Linear);
    EXPECT_TRUE(read_image_info(exr, name, "exr").is_float);
    const Image back = decode_image(exr, ColorSpace::Srgb, name, "exr"); // float data is never sRGB-decoded
    EXPECT_TRUE(same_bits(back.pixels, image.pixels));
    // Refusals name the file and the field: not an image; above a given size.
    const std::vector<std::uint8_t> junk = {'n', 'o', 't', ' ', 'a', 'n', ' ', 'i', 'm', 'a', 'g', 'e'};
    try {
        (void)decode_image(junk, ColorSpace::Srgb, name, "images[3]");
        ADD_FAILURE() << "junk decoded";
    } catch (const InputError& e) {
        EXPECT_EQ(e.file(), name);
        EXPECT_EQ(e.field(), "images[3]");
    }
    try {
        (void)decode_image(exr, ColorSpace::Linear, name, "exr", 4);
        ADD_FAILURE() << "a 5 x 3 image decoded under a limit of 4";
    } catch (const InputError& e) {
        EXPECT_NE(e.message().find("5 x 3"), std::string::npos) << e.what();
    }
}

TEST(Bundle, RoundTripWithTheCoreMaterialIsExact) {
    const test::BundlePieces p = test::make_pieces();
    Bundle b = make_bundle(p.mesh, p.atlas.corner_uv, p.albedo, with_lobe(p.lobe));
    b.core = CoreMaterial{.roughness = 0.4923, .f0 = 0.0581, .f90 = 0.0581, .clearcoat = 0.5, .clearcoat_roughness = 0.31};
    TempDir dir("bundle");
    const auto file = dir / "out.glb";
    write_bundle(file, b);
    const Bundle r = read_bundle(file);
    ASSERT_TRUE(r.core.has_value());
    EXPECT_EQ(r.core->roughness, b.core->roughness);
    EXPECT_EQ(r.core->f0, b.core->f0);
    EXPECT_EQ(r.core->f90, b.core->f90);
    EXPECT_EQ(r.core->clearcoat, b.core->clearcoat);
    EXPECT_EQ(r.core->clearcoat_roughness, b.core->clearcoat_roughness);
    EXPECT_EQ(test::glb_json(file)["materials"][0]["extensions"]["KHR_materials_clearcoat"]["clearcoatFactor"], 0.5);
    // The viewer's fields give the same material; the base colour is the albedo times 1 / (1 - F0).
    const auto m = test::glb_json(file)["materials"][0];
    const CoreMaterial viewed = core_from_gltf_fields({.roughness_factor = m["pbrMetallicRoughness"]["roughnessFactor"],
                                                       .ior = m["extensions"]["KHR_materials_ior"]["ior"],
                                                       .specular_factor = m["extensions"]["KHR_materials_specular"]["specularFactor"],
                                                       .specular_color_factor =
                                                           m["extensions"]["KHR_materials_specular"]["specularColorFactor"][0]});
    EXPECT_NEAR(viewed.f0, b.core->f0, 1e-12);
    EXPECT_NEAR(viewed.f90, b.core->f90, 1e-12);
    EXPECT_NEAR(viewed.roughness, b.core->roughness, 1e-12);
    // Without the float albedo file the albedo comes from the base colour, divided by the scale again.
    write_bundle(dir / "lean.glb", b, {.float_albedo_file = "albedo.exr"});
    std::filesystem::remove(dir / "albedo.exr");
    const Bundle lean = read_bundle(dir / "lean.glb");
    ASSERT_EQ(lean.albedo.pixels.size(), b.albedo.pixels.size());
    for (std::size_t i = 0; i < b.albedo.pixels.size(); ++i) {
        const float want = std::clamp(b.albedo.pixels[i], 0.0f, 1.0f);
        const float scale = static_cast<float>(b.core->base_color_scale());
        if (want * scale > 1.0f) continue; // clipped in the 8-bit base colour
        // Half an 8-bit sRGB code at the scaled value, back in albedo units.
        const float code = linear_to_srgb(want * scale);
        const float half_code = (srgb_to_linear(std::min(1.0f, code + 0.5f / 255.0f)) - want * scale) / scale;
        ASSERT_NEAR(lean.albedo.pixels[i], want, half_code + 1e-6f) << i;
    }
    b.core->f0 = 0.2; // above F90: refused, naming the field
    EXPECT_THROW(write_bundle(dir / "bad.glb", b), InputError);

    // A core object a reader must refuse, naming the field.
    const std::string ext = "materials[0].extensions.SPECULA_lafortune";
    const auto with = extension_editor(file);
    with([](json&) {}); // the control
    EXPECT_NO_THROW((void)read_bundle(file));
    with([](json& e) { e["core"]["f0"] = 0.5; });
    expect_bundle_refusal(file, ext + ".core.f0", "outside");
    with([](json& e) { e["core"]["roughness"] = -0.1; });
    expect_bundle_refusal(file, ext + ".core.roughness", "outside");
    with([](json& e) { e["core"]["clearcoat"] = 1.5; });
    expect_bundle_refusal(file, ext + ".core.clearcoat", "outside");
    with([](json& e) { e["core"].erase("clearcoat_roughness"); }); // both or neither
    expect_bundle_refusal(file, ext + ".core.clearcoat_roughness", "missing");
    with([](json& e) { e["core"]["f90"] = "1"; });
    expect_bundle_refusal(file, ext + ".core.f90", "not a number");
    with([](json& e) { e["core"] = json::array(); });
    expect_bundle_refusal(file, ext + ".core", "not an object");
}

} // namespace
} // namespace specula
