// Re-factorize a bundle's lobe (not a test; run by hand): the same bundle with the cube-maps of
// another parametrization or grid, so `specula evaluate --specular factorized` compares
// factorizations of one lobe without reconstructing again.
//   refactor_bundle IN.glb OUT.glb [--param auto|gshd|mirrored|warped] [--grid H,D] [--cube G,H] [--terms K]
// Prints the factorization's choices (parametrization, grids, K) and errors.
#include "export/bundle.h"
#include "factorization/factorization.h"

#include <cstdio>
#include <cstring>
#include <string>

using namespace specula;
using namespace specula::factorization;

int main(int argc, char** argv) try {
    if (argc < 3) {
        std::fprintf(stderr, "usage: refactor_bundle IN.glb OUT.glb [--param auto|gshd|mirrored|warped] [--grid H,D] [--cube G,H] [--terms K]\n");
        return 2;
    }
    FactorizationOptions o;
    for (int i = 3; i + 1 < argc; i += 2) {
        const std::string v = argv[i + 1];
        if (std::strcmp(argv[i], "--param") == 0) {
            o.param = factor_param_from_string(v);
            if (!o.param && v != "auto") throw Error("--param: " + v);
        } else if (std::strcmp(argv[i], "--grid") == 0) {
            const std::size_t comma = v.find(',');
            o.grid_h = static_cast<uint32_t>(std::stoul(v.substr(0, comma)));
            o.grid_d = comma == std::string::npos ? o.grid_h : static_cast<uint32_t>(std::stoul(v.substr(comma + 1)));
        } else if (std::strcmp(argv[i], "--cube") == 0) {
            const std::size_t comma = v.find(',');
            o.cube_g = static_cast<uint32_t>(std::stoul(v.substr(0, comma)));
            o.cube_h = comma == std::string::npos ? o.cube_g : static_cast<uint32_t>(std::stoul(v.substr(comma + 1)));
        } else if (std::strcmp(argv[i], "--terms") == 0) {
            o.terms = static_cast<uint32_t>(std::stoul(v));
        } else {
            throw Error(std::string("unknown option ") + argv[i]);
        }
    }
    Bundle b = read_bundle(argv[1]);
    if (!b.material.specular) throw Error(std::string(argv[1]) + ": no specular model");
    const Factorization f = factorize_cpu(*b.material.specular, o); // any family
    b.material.factorized = f.cubes;
    write_bundle(argv[2], b);
    std::printf("%s: %s, h %u x d %u (cube faces %u, %u), K = %u; against the lobe through the cube-maps %.4f\n  %s\n  %s\n",
                argv[2], to_string(f.cubes.param), f.resolution.grid_h, f.resolution.grid_d, f.resolution.cube_g,
                f.resolution.cube_h, f.term_count(), f.param_choice.of(f.cubes.param).direct_rms, f.terms.reason.c_str(),
                f.param_choice.reason.c_str());
    return 0;
} catch (const std::exception& e) {
    std::fprintf(stderr, "refactor_bundle: %s\n", e.what());
    return 1;
}
