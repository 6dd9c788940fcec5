#pragma once
// The bundles behind tests/export/data/legacy_v1.glb and legacy_v4.glb: small, explicit
// bundles (no atlas, no random numbers) written by write_bundle before the glTF I/O moved to
// engine/capture/gltf_io (commit 55e0ad6). The test reads the files and compares them, bit
// for bit, with these; and writes them again to check the format did not change.
#include "export/bundle.h"

#include <cstdint>
#include <limits>
#include <string>

namespace specula::test {

/// Float i of the cube-map (texel i / 3, channel i % 3) is start + step * i.
inline CubeMap ramp_cube(std::uint32_t res, float start, float step) {
    CubeMap c{res, std::vector<glm::vec3>(std::size_t{6} * res * res)};
    for (std::size_t i = 0; i < 3 * c.texels.size(); ++i) c.texels[i / 3][static_cast<int>(i % 3)] = start + step * static_cast<float>(i);
    return c;
}

/// version 1: one factorization term; version 4: the warped parametrization with a second term.
inline Bundle legacy_bundle(int version) {
    Bundle b;
    b.mesh.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0.25f}, {0, 1, 0}, {0.5f, 0.5f, -0.125f}};
    b.mesh.normals = {{0, 0, 1}, {0, 0, 1}, {0, 0.6f, 0.8f}, {0, 0, 1}, {0.6f, 0, 0.8f}};
    b.mesh.texcoords = {{0, 0}, {1, 0}, {1, 1}, {0, 1}, {0.5f, 0.5f}};
    b.mesh.triangles = {{0, 1, 4}, {1, 2, 4}, {2, 3, 4}, {3, 0, 4}};
    b.albedo = Image(3, 2, 3);
    for (std::size_t i = 0; i < b.albedo.pixels.size(); ++i) b.albedo.pixels[i] = 0.0625f * static_cast<float>(i);
    b.albedo.pixels[4] = 1.5f;                                       // above 1: the float copy keeps it
    b.albedo.pixels[5] = std::numeric_limits<float>::denorm_min();   // raw bits, not decimal
    b.material.specular = LafortuneRgb{{-0.9f, -0.8f, -0.7f}, {0.95f, 0.85f, 0.75f}, {24.0f, 30.0f, 36.5f}};
    b.material.status = {"converged", "converged", "max_iterations"};
    b.material.factorized = FactorizedSpecular{.terms = {{ramp_cube(1, 0.5f, 0.125f), ramp_cube(2, 2.0f, -0.03125f)}}};
    b.info = {{"specula_version", "legacy-fixture"}, {"texels", 5000000000ull}, {"summary", {{"psnr_db", 41.25}}}};
    if (version == 4) {
        b.material.factorized->terms.push_back({ramp_cube(1, -0.25f, 0.0625f), ramp_cube(2, 1.0f, 0.015625f)});
        b.material.factorized->param = FactorParam::Warped;
        b.material.factorized->warp = glm::vec4(-1.0f, 0.5f, 0.75f, 1.25f);
    }
    return b;
}

} // namespace specula::test
