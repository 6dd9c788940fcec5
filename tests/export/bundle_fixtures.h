#pragma once
// Shared pieces of the bundle tests: a small atlas-mapped sphere with a random float
// albedo, a lobe and two cube-maps, and GLB surgery (rewrite the JSON chunk) for the
// foreign-file and error tests.
#include "../geometry/test_meshes.h"
#include "core/error.h"
#include "core/file_util.h"
#include "export/bundle.h"
#include "geometry/atlas.h"

#include <nlohmann/json.hpp>

#include <cstring>
#include <random>
#include <string>

namespace specula::test {

struct BundlePieces {
    Mesh mesh;
    Atlas atlas;
    Image albedo;
    LafortuneRgb lobe{{-0.9f, -0.8f, -0.7f}, {0.95f, 0.85f, 0.75f}, {24.0f, 30.0f, 36.5f}};
};

inline BundlePieces make_pieces(int rings = 6, int segments = 10) {
    BundlePieces p;
    p.mesh = sphere(1.0f, rings, segments);
    p.atlas = build_atlas(p.mesh, {}, {.max_width = 128, .max_height = 128});
    p.albedo = Image(static_cast<int>(p.atlas.width), static_cast<int>(p.atlas.height), 3);
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> u(0.0f, 1.2f); // > 1 on purpose: the float copy keeps it, the PNG clamps
    for (float& v : p.albedo.pixels) v = u(rng);
    return p;
}

/// 6 * res^2 texels, r, g, b of each drawn in turn from a seeded generator.
inline CubeMap random_cube(std::uint32_t res, unsigned seed) {
    CubeMap c{res, std::vector<glm::vec3>(std::size_t{6} * res * res)};
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(0.0f, 3.0f);
    for (glm::vec3& t : c.texels)
        for (int ch = 0; ch < 3; ++ch) t[ch] = u(rng);
    return c;
}

/// The JSON chunk of a .glb, and a rewrite of it (BIN chunk kept).
inline nlohmann::json glb_json(const std::filesystem::path& file) {
    const std::string s = read_text_file(file);
    std::uint32_t len = 0;
    std::memcpy(&len, s.data() + 12, 4);
    return nlohmann::json::parse(s.substr(20, len));
}
/// The same with the JSON chunk given as text (for JSON nlohmann would not write: duplicate
/// keys, 100,000 levels of nesting).
inline void rewrite_glb_text(const std::filesystem::path& file, std::string text) {
    const std::string s = read_text_file(file);
    std::uint32_t len = 0;
    std::memcpy(&len, s.data() + 12, 4);
    const std::string rest = s.substr(20 + len); // BIN chunk header + data
    while (text.size() % 4 != 0) text.push_back(' ');
    std::string out(20, '\0');
    const std::uint32_t head[5] = {0x46546C67u, 2u, static_cast<std::uint32_t>(20 + text.size() + rest.size()),
                                   static_cast<std::uint32_t>(text.size()), 0x4E4F534Au};
    std::memcpy(out.data(), head, 20);
    write_text_file(file, out + text + rest);
}
inline void rewrite_glb_json(const std::filesystem::path& file, const nlohmann::json& doc) {
    rewrite_glb_text(file, doc.dump());
}

} // namespace specula::test
