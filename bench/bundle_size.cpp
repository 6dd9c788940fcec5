// The size of a reconstruction's bundle (run by hand, not a ctest; the pipeline does not
// write the bundle yet): rebuilds the atlas exactly as `specula reconstruct` does (same
// train cameras, same options: build_atlas is deterministic), takes OUT/albedo.exr and the
// lobe from OUT/report.json, and writes the bundle.
//   bundle_size CAPTURE RECONSTRUCT_OUT TEXTURE_SIZE BUNDLE.glb [CUBE_RESOLUTION]
#include "capture/capture.h"
#include "core/error.h"
#include "core/file_util.h"
#include "export/bundle.h"
#include "geometry/atlas.h"

#include <cstdio>
#include <cstdlib>
#include <string>

using namespace specula;

namespace {
const nlohmann::json* find_lobe(const nlohmann::json& j) {
    if (!j.is_object()) return nullptr;
    if (j.contains("lobe") && j["lobe"].is_object() && j["lobe"].contains("cx")) return &j["lobe"];
    for (const auto& [k, v] : j.items())
        if (const auto* l = find_lobe(v)) return l;
    return nullptr;
}
} // namespace

int main(int argc, char** argv) try {
    if (argc < 5) {
        std::fprintf(stderr, "usage: bundle_size CAPTURE RECONSTRUCT_OUT TEXTURE_SIZE BUNDLE.glb [CUBE_RESOLUTION]\n");
        return 2;
    }
    const std::filesystem::path out_dir = argv[2];
    const auto texture = static_cast<std::uint32_t>(std::stoul(argv[3]));
    const Capture capture = load_capture(argv[1]);
    std::vector<Camera> cams;
    for (const View& view : capture.views)
        for (std::size_t f : view.frames)
            if (capture.desc.frames[f].split == Split::Train) {
                cams.push_back(view.camera);
                break;
            }
    AtlasOptions options;
    options.max_width = options.max_height = texture;
    const Atlas atlas = build_atlas(capture.mesh, cams, options);
    Image albedo = read_image(out_dir / "albedo.exr", ColorSpace::Linear, "albedo");
    if (albedo.width != static_cast<int>(atlas.width) || albedo.height != static_cast<int>(atlas.height))
        throw Error("albedo.exr does not match the rebuilt atlas (different options?)");
    const nlohmann::json report = nlohmann::json::parse(read_text_file(out_dir / "report.json"));
    std::optional<LafortuneRgb> lobe;
    std::vector<std::string> status;
    if (const auto* l = find_lobe(report)) {
        LafortuneRgb v;
        for (int k = 0; k < 3; ++k) {
            v.cx[k] = (*l)["cx"][k].get<float>();
            v.cz[k] = (*l)["cz"][k].get<float>();
            v.n[k] = (*l)["n"][k].get<float>();
        }
        lobe = v;
        status = (*l)["status"].get<std::vector<std::string>>();
    }
    Material material;
    if (lobe) material.specular = *lobe;
    material.status = status;
    if (argc > 5) {
        const auto r = static_cast<std::uint32_t>(std::stoul(argv[5]));
        const CubeMap cube{r, std::vector<glm::vec3>(std::size_t{6} * r * r, glm::vec3(0.5f))};
        material.factorized = FactorizedSpecular{.terms = {{cube, cube}}};
    }
    Bundle b = make_bundle(capture.mesh, atlas.corner_uv, std::move(albedo), std::move(material));
    b.info = {{"capture", argv[1]}};
    write_bundle(argv[4], b);
    const auto bytes = std::filesystem::file_size(argv[4]);
    std::printf("%s: %zu triangles, %zu -> %zu vertices, atlas %dx%d, lobe %s, cubes %s: %.2f MiB (%ju bytes)\n", argv[4],
                b.mesh.triangles.size(), capture.mesh.positions.size(), b.mesh.positions.size(), b.albedo.width,
                b.albedo.height, lobe ? "yes" : "no", b.material.factorized ? argv[5] : "no", static_cast<double>(bytes) / (1 << 20),
                static_cast<std::uintmax_t>(bytes));
    return 0;
} catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
}
