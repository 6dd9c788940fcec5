// libFuzzer target: a .glb or .gltf (told apart by the GLB magic) through load_mesh, the
// capture's mesh loader (capture/gltf_io.h's guards, then the triangle assembly). A refusal is
// an InputError; anything else that escapes is a finding.
#include "capture/mesh.h"
#include "core/error.h"
#include "fuzz_input.h"

#include <cstddef>
#include <cstdint>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const auto path = specula::fuzz::write_input(data, size, "mesh.glb");
    try {
        const specula::MeshLoadResult m = specula::load_mesh(path, "mesh_path");
        (void)specula::mesh_bounds(m.mesh);
    } catch (const specula::InputError&) {
    }
    return 0;
}
