// Writes the hostile inputs of issue 21 for the command-line tests (tests/cli/CMakeLists.txt):
//   specula_hostile OUT
// Each case starts from `specula synth --preset can --size 64 --views 4 --lights 3` (made
// in-process into OUT/base) plus one edit, as the issue found them, in OUT/<case>/.
#include "capture/capture.h"
#include "capture/mesh.h"
#include "core/file_util.h"
#include "core/image.h"
#include "export/bundle.h"
#include "gltf_builder.h"
#include "png_bytes.h"
#include "synth/presets.h"
#include "synth/synth.h"

#include <nlohmann/json.hpp>

#include <cstdio>
#include <exception>
#include <filesystem>
#include <functional>
#include <limits>
#include <string>

namespace fs = std::filesystem;
using nlohmann::json;
using namespace specula;

namespace {

using test::png_claiming;

json read_json(const fs::path& p) { return json::parse(read_text_file(p)); }
void write_json(const fs::path& p, const json& j) { write_text_file(p, j.dump(1)); }

// OUT/<name>: a copy of OUT/base with capture.json edited by `edit` (which may also write files).
void make_case(const fs::path& out, const std::string& name, const std::function<void(json&, const fs::path&)>& edit) {
    const fs::path dir = out / name;
    fs::remove_all(dir);
    fs::copy(out / "base", dir, fs::copy_options::recursive);
    json j = read_json(dir / "capture.json");
    edit(j, dir);
    write_json(dir / "capture.json", j);
}

} // namespace

int main(int argc, char** argv) {
    if (argc != 2) {
        std::fprintf(stderr, "usage: specula_hostile OUT\n");
        return 2;
    }
    try {
        const fs::path out = fs::absolute(argv[1]);
        fs::create_directories(out);
        synth::SynthOptions o;
        o.size = 64;
        o.views = 4;
        o.lights = 3;
        o.force = true;
        (void)synth::write_synthetic_capture(synth::to_object(synth::make_preset("can")), out / "base", o);

        // Case 1: a light position finite as a double, infinite as a float.
        make_case(out, "case01_light_1e39", [](json& j, const fs::path&) { j["frames"][0]["light"]["position"] = {1e39, 0, 0}; });
        // Case 2: a translation of 1e20 on every frame of view 0.
        make_case(out, "case02_translation_1e20", [](json& j, const fs::path&) {
            for (json& f : j["frames"])
                if (f["view_index"] == 0) f["transform_matrix"][0][3] = 1e20;
        });
        // Case 3: a denormal focal length (0 as a float).
        make_case(out, "case03_focal_denormal", [](json& j, const fs::path&) { j["fl_x"] = 5e-324; });
        // Case 7: 150 frames all naming one 4096 x 4096 PNG (a few hundred KB on disk).
        make_case(out, "case07_one_png_150_frames", [](json& j, const fs::path& dir) {
            Image big(4096, 4096, 1);
            for (int y = 0; y < 4096; ++y)
                for (int x = 0; x < 4096; ++x) big.at(x, y) = static_cast<float>((x ^ y) & 255) / 255.0f;
            write_image(dir / "images/big.png", big, ColorSpace::Srgb);
            const double scale = 4096.0 / j["w"].get<double>();
            for (const char* k : {"fl_x", "fl_y", "cx", "cy"}) j[k] = j[k].get<double>() * scale;
            j["w"] = 4096;
            j["h"] = 4096;
            json frames = json::array();
            for (std::size_t k = 0; k < 150; ++k) {
                json f = j["frames"][k % j["frames"].size()];
                f["file_path"] = "images/big.png";
                f.erase("mask_path");
                frames.push_back(f);
            }
            j["frames"] = frames;
        });
        // Case 8: a small PNG file of 20000 x 20000, w and h matching.
        make_case(out, "case08_png_20000", [](json& j, const fs::path& dir) {
            write_text_file(dir / "images/huge.png", png_claiming(20000, 20000));
            j["w"] = 20000;
            j["h"] = 20000;
            for (json& f : j["frames"]) {
                f["file_path"] = "images/huge.png";
                f.erase("mask_path");
            }
        });
        // Case 9: a foreign glTF (no SPECULA_lafortune) whose base colour is a 30000 x 30000 PNG.
        {
            const fs::path dir = out / "case09_gltf_30000";
            fs::create_directories(dir);
            test::GltfBuilder b;
            json prim = {{"attributes",
                          {{"POSITION", b.positions({-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0})},
                           {"TEXCOORD_0", b.texcoords({0, 0, 1, 0, 1, 1, 0, 1})}}},
                         {"indices", b.indices_u16({0, 1, 2, 0, 2, 3})},
                         {"material", 0}};
            b.node({{"mesh", b.mesh(json::array({prim}))}});
            b.doc()["materials"] = {{{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}}};
            b.doc()["textures"] = {{{"source", 0}}};
            write_text_file(dir / "huge.png", png_claiming(30000, 30000));
            b.doc()["images"] = {{{"uri", "huge.png"}}};
            b.write(dir / "foreign.gltf");
        }
        // Case 15: every mask zero.
        make_case(out, "case15_masks_zero", [](json& j, const fs::path& dir) {
            for (const json& f : j["frames"]) {
                const fs::path mask = dir / f["mask_path"].get<std::string>();
                write_image(mask, Image(j["w"].get<int>(), j["h"].get<int>(), 1, 0.0f), ColorSpace::Linear);
            }
        });
        // Case 15: the mesh scaled by 1e30, outside every view.
        make_case(out, "case15_mesh_1e30", [](json&, const fs::path& dir) {
            Mesh m = load_mesh(dir / "mesh.glb").mesh;
            for (glm::vec3& p : m.positions) p *= 1e30f;
            write_mesh_glb(dir / "mesh.glb", m);
        });
        // Case 16: a JPEG cut in half.
        make_case(out, "case16_jpeg_cut", [](json& j, const fs::path& dir) {
            const std::string png = j["frames"][0]["file_path"];
            const Image img = read_image(dir / png, ColorSpace::Srgb);
            write_image(dir / "images/v00_l0.jpg", img, ColorSpace::Srgb);
            const std::string bytes = read_text_file(dir / "images/v00_l0.jpg");
            write_text_file(dir / "images/v00_l0.jpg", bytes.substr(0, bytes.size() / 2));
            j["frames"][0]["file_path"] = "images/v00_l0.jpg";
        });
        // Case 18: light.intensity = 1e308 (infinite as a float).
        make_case(out, "case18_intensity_1e308", [](json& j, const fs::path&) {
            j["frames"][0]["light"]["intensity"] = {1e308, 1e308, 1e308};
        });
        // A NUL inside a path: would open images/v00_l0.png.
        make_case(out, "nul_in_path", [](json& j, const fs::path&) {
            j["frames"][1]["file_path"] = j["frames"][0]["file_path"].get<std::string>() + std::string(1, '\0') + ".txt";
        });
        // A path that leaves the capture's folder.
        make_case(out, "path_leaves_folder", [](json& j, const fs::path&) { j["mesh_path"] = "../base/mesh.glb"; });
        // A duplicate key: "intensity" twice in frames[2].light (nlohmann keeps the last).
        make_case(out, "duplicate_key", [](json&, const fs::path&) {});
        {
            const fs::path p = out / "duplicate_key" / "capture.json";
            json j = read_json(p);
            const std::string light = j["frames"][2]["light"].dump();
            std::string text = j.dump();
            const std::size_t at = text.find(light);
            text.replace(at, light.size(), light.substr(0, light.size() - 1) + ",\"intensity\":[100.0,100.0,100.0]}");
            write_text_file(p, text);
        }
        // A bundle whose albedo is NaN everywhere.
        {
            Bundle b;
            b.mesh.positions = {{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}};
            b.mesh.texcoords = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
            b.mesh.triangles = {{0, 1, 2}, {0, 2, 3}};
            b.mesh.normals = compute_vertex_normals(b.mesh.positions, b.mesh.triangles);
            b.albedo = Image(4, 4, 3, std::numeric_limits<float>::quiet_NaN());
            write_bundle(out / "nan_albedo.glb", b);
        }
        std::printf("specula_hostile: wrote the hostile inputs into %s\n", out.string().c_str());
        return 0;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "specula_hostile: %s\n", e.what());
        return 1;
    }
}
