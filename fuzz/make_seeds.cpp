// Writes the seed corpus of the fuzz targets (a few KB, generated rather than committed):
//   make_seeds OUT  ->  OUT/capture_json/, OUT/gltf_mesh/, OUT/bundle/, OUT/image_decode/
// Valid inputs of each reader, small, covering its main branches (per-frame intrinsics,
// unknown fields; .glb and .gltf with a data URI; a bundle with and without the extension;
// PNG 8/16-bit, grey and RGBA, JPEG, OpenEXR).
#include "capture/capture.h"
#include "capture/mesh.h"
#include "core/file_util.h"
#include "core/image.h"
#include "export/bundle.h"
#include "gltf_builder.h"
#include "unit_cube.h"

#include <nlohmann/json.hpp>

#include <cstdio>
#include <exception>
#include <filesystem>
#include <string>

namespace fs = std::filesystem;
using nlohmann::json;
using namespace specula;

namespace {

void write_bytes(const fs::path& path, const std::vector<std::uint8_t>& bytes) {
    write_text_file(path, std::string(bytes.begin(), bytes.end()));
}

Image gradient(int w, int h, int channels) {
    Image img(w, h, channels);
    for (std::size_t i = 0; i < img.pixels.size(); ++i) img.pixels[i] = static_cast<float>(i % 17) / 16.0f;
    return img;
}


json frame(const std::string& file, int view, double tz, double lx) {
    return {{"file_path", file},
            {"view_index", view},
            {"transform_matrix", {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, tz}, {0, 0, 0, 1}}},
            {"light", {{"type", "point"}, {"position", {lx, 0.5, 3.0}}, {"intensity", {10.0, 10.0, 10.0}}}}};
}

} // namespace

int main(int argc, char** argv) {
    if (argc != 2) {
        std::fprintf(stderr, "usage: make_seeds OUT\n");
        return 2;
    }
    try {
        const fs::path out = argv[1];
        for (const char* d : {"capture_json", "gltf_mesh", "bundle", "image_decode"}) fs::create_directories(out / d);

        // capture.json: the format's example shape; per-frame intrinsics, a mask, a test split,
        // unknown fields and ground_truth.
        json j = {{"format", "specula-capture"}, {"version", 1}, {"mesh_path", "mesh.glb"}, {"color_space", "srgb"},
                  {"saturation", 1.0}, {"w", 4}, {"h", 3}, {"fl_x", 5.0}, {"fl_y", 5.5}, {"cx", 2.0}, {"cy", 1.5},
                  {"frames", json::array()}};
        for (int v = 0; v < 2; ++v)
            for (int l = 0; l < 2; ++l) {
                json f = frame("images/v" + std::to_string(v) + "_l" + std::to_string(l) + ".png", v, 3.0 + v, l ? -1.0 : 1.0);
                if (v == 0) f["mask_path"] = "masks/v0.png";
                if (v == 1 && l == 1) f["split"] = "test";
                j["frames"].push_back(f);
            }
        write_text_file(out / "capture_json/basic.json", j.dump(1));
        json k = j;
        k.erase("fl_x");
        for (json& f : k["frames"]) f["fl_x"] = 5.0;
        k["frames"][0]["extra"] = {{"exposure", 0.5}};
        k["frames"][1]["light"]["note"] = "calibrated";
        k["rig"] = {{"name", "turntable"}};
        k["ground_truth"] = {{"preset", "cube"}, {"lobe", {{"cx", {-0.5, -0.5, -0.5}}, {"cz", {0.5, 0.5, 0.5}}, {"n", {20, 20, 20}}}}};
        k["color_space"] = "linear";
        write_text_file(out / "capture_json/per_frame.json", k.dump());
        json d = j; // version 1.1: directional lights beside point lights
        d["version"] = 1.1;
        d["frames"][0]["light"] = {{"type", "directional"}, {"direction", {0.2, 0.5, 1.0}}, {"irradiance", {0.5, 0.5, 0.5}}};
        d["frames"][2]["light"] = {{"type", "directional"}, {"direction", {-1.0, 0.0, 0.5}}, {"irradiance", {0.0, 1e-3, 2.0}}};
        write_text_file(out / "capture_json/directional.json", d.dump(1));

        // Meshes: a .glb as Specula writes it, and a .gltf with a node transform and 16-bit indices.
        write_mesh_glb(out / "gltf_mesh/cube.glb", test::unit_cube_mesh());
        test::GltfBuilder b;
        const int pos = b.positions({0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0});
        const int idx = b.indices_u16({0, 1, 2, 0, 2, 3});
        b.node({{"mesh", b.mesh(json::array({{{"attributes", {{"POSITION", pos}}}, {"indices", idx}}}))},
                {"translation", {0.0, 0.0, 1.0}}});
        b.doc()["scenes"] = {{{"nodes", {0}}}};
        b.doc()["scene"] = 0;
        write_text_file(out / "gltf_mesh/quad.gltf", b.text());

        // Bundles: with the extension (albedo, a lobe or the coated family), and a foreign glTF with a base colour PNG.
        Bundle bundle;
        bundle.mesh.positions = {{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}};
        bundle.mesh.texcoords = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
        bundle.mesh.triangles = {{0, 1, 2}, {0, 2, 3}};
        bundle.mesh.normals = compute_vertex_normals(bundle.mesh.positions, bundle.mesh.triangles);
        bundle.albedo = gradient(4, 4, 3);
        bundle.material.specular = LafortuneRgb{{-0.5f, -0.5f, -0.5f}, {0.5f, 0.5f, 0.5f}, {20.0f, 20.0f, 20.0f}};
        write_bundle(out / "bundle/specula.glb", bundle);
        // The coated family (extension version 5, and the core glTF material's ior and specular).
        bundle.material.specular = CoatedParams{.eta = 1.5f, .alpha = 0.2f, .tint = {1.0f, 1.0f, 1.0f}};
        write_bundle(out / "bundle/coated.glb", bundle);
        test::GltfBuilder f;
        json prim = {{"attributes", {{"POSITION", f.positions({0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0})},
                                     {"TEXCOORD_0", f.texcoords({0, 0, 1, 0, 1, 1, 0, 1})}}},
                     {"indices", f.indices_u16({0, 1, 2, 0, 2, 3})},
                     {"material", 0}};
        f.node({{"mesh", f.mesh(json::array({prim}))}});
        f.doc()["materials"] = {{{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}}};
        f.doc()["textures"] = {{{"source", 0}}};
        f.doc()["images"] = {{{"uri", "data:image/png;base64," +
                                          test::base64(encode_image(gradient(2, 2, 3), ImageCodec::Png, ColorSpace::Srgb))}}};
        write_text_file(out / "bundle/foreign.gltf", f.text());

        // Images.
        write_bytes(out / "image_decode/rgb8.png", encode_image(gradient(8, 6, 3), ImageCodec::Png, ColorSpace::Srgb));
        write_bytes(out / "image_decode/rgba16.png", encode_image(gradient(5, 3, 4), ImageCodec::Png, ColorSpace::Linear, 16));
        write_bytes(out / "image_decode/grey.png", encode_image(gradient(7, 2, 1), ImageCodec::Png, ColorSpace::Linear));
        write_bytes(out / "image_decode/rgb.jpg", encode_image(gradient(16, 8, 3), ImageCodec::Jpeg, ColorSpace::Srgb));
        write_bytes(out / "image_decode/rgb.exr", encode_image(gradient(4, 4, 3), ImageCodec::Exr, ColorSpace::Linear));
        std::printf("make_seeds: wrote the seed corpus into %s\n", out.string().c_str());
        return 0;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "make_seeds: %s\n", e.what());
        return 1;
    }
}
