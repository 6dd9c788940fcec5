// The recovered albedo against a synthetic capture's truth, over the seen surface and its concave
// parts (tests/support/concave_albedo.h): concave_albedo CAPTURE OBJECT.GLB [CONCAVE_FRACTION] [POINTS.CSV|-]
// [FLAT_ATLAS_TEXELS]
#include "concave_albedo.h"

#include <cstdio>
#include <exception>
#include <functional>
#include <stdexcept>
#include <string>

int main(int argc, char** argv) try {
    if (argc < 3) {
        std::fprintf(stderr, "usage: concave_albedo CAPTURE OBJECT.GLB [CONCAVE_FRACTION (0.25)] [POINTS.CSV|-]\n"
                             "                      [FLAT_ATLAS_TEXELS (2)]\n"
                             "  POINTS.CSV: every compared point (x, y, z, area, the fraction of its hemisphere that sees\n"
                             "  the object, truth r g b, error r g b); -: none\n"
                             "  FLAT_ATLAS_TEXELS: the truth must be flat over this many atlas texels too (0: 2 truth texels only)\n");
        return 2;
    }
    const double fraction = argc > 3 ? std::stod(argv[3]) : 0.25;
    std::FILE* points = nullptr;
    if (argc > 4 && std::string(argv[4]) != "-") {
        points = std::fopen(argv[4], "w");
        if (points == nullptr) throw std::runtime_error(std::string("cannot write ") + argv[4]);
        std::fprintf(points, "x,y,z,area,hemisphere,truth_r,truth_g,truth_b,error_r,error_g,error_b\n");
    }
    const auto each = [&](const specula::test::PointError& p) {
        std::fprintf(points, "%g,%g,%g,%g,%g,%g,%g,%g,%g,%g,%g\n", p.position.x, p.position.y, p.position.z, p.area, p.hemisphere,
                     p.truth.x, p.truth.y, p.truth.z, p.error.x, p.error.y, p.error.z);
    };
    const specula::test::AlbedoComparison c = specula::test::compare_albedo(
        argv[1], argv[2], fraction, points != nullptr ? std::function<void(const specula::test::PointError&)>(each) : nullptr,
        argc > 5 ? std::stof(argv[5]) : specula::test::kFlatAtlasTexels);
    if (points != nullptr && std::fclose(points) != 0) throw std::runtime_error(std::string("cannot write ") + argv[4]);
    std::printf("albedo RMSE over seen points %.3f%% (%zu points); concave (>= %.0f%% of the hemisphere sees the object, "
                "%.1f%% of the seen area, %zu points): RMSE %.3f%%, mean error %+.3f%%\n",
                100.0 * c.rmse_all, c.points, 100.0 * fraction, 100.0 * c.concave_area, c.concave_points, 100.0 * c.rmse_concave,
                100.0 * c.bias_concave);
    return 0;
} catch (const std::exception& e) {
    std::fprintf(stderr, "concave_albedo: %s\n", e.what());
    return 1;
}
