// The recovered albedo against a synthetic capture's truth, over the seen surface and its concave
// parts (tests/support/concave_albedo.h): concave_albedo CAPTURE OBJECT.GLB [CONCAVE_FRACTION]
#include "concave_albedo.h"

#include <cstdio>
#include <exception>
#include <string>

int main(int argc, char** argv) try {
    if (argc < 3) {
        std::fprintf(stderr, "usage: concave_albedo CAPTURE OBJECT.GLB [CONCAVE_FRACTION (0.25)]\n");
        return 2;
    }
    const double fraction = argc > 3 ? std::stod(argv[3]) : 0.25;
    const specula::test::AlbedoComparison c = specula::test::compare_albedo(argv[1], argv[2], fraction);
    std::printf("albedo RMSE over seen points %.3f%% (%zu points); concave (>= %.0f%% of the hemisphere sees the object, "
                "%.1f%% of the seen area, %zu points): RMSE %.3f%%, mean error %+.3f%%\n",
                100.0 * c.rmse_all, c.points, 100.0 * fraction, 100.0 * c.concave_area, c.concave_points, 100.0 * c.rmse_concave,
                100.0 * c.bias_concave);
    return 0;
} catch (const std::exception& e) {
    std::fprintf(stderr, "concave_albedo: %s\n", e.what());
    return 1;
}
