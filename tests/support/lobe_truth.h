#pragma once
// The reconstructed lobe (report.json specular.lobe) against the synthetic capture's truth
// (capture.json ground_truth.lobe), per channel: status converged, |Cx - Cx*| and |Cz - Cz*|
// within tol_c of the truth, |N - N*| within tol_n (relative). Prints each channel.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

namespace specula::test {

inline void expect_lobe_near_truth(const nlohmann::json& report, const std::filesystem::path& capture, double tol_c, double tol_n,
                                   const std::string& name) {
    const nlohmann::json& lobe = report["specular"]["lobe"];
    const nlohmann::json truth = nlohmann::json::parse(std::ifstream(capture / "capture.json"))["ground_truth"]["lobe"];
    ASSERT_TRUE(lobe.is_object()) << report["specular"].dump();
    for (int k = 0; k < 3; ++k) {
        const double cx = lobe["cx"][k], cz = lobe["cz"][k], n = lobe["n"][k];
        const double tcx = truth["cx"][k], tcz = truth["cz"][k], tn = truth["n"][k];
        std::printf("%s channel %d: Cx %.4f (%.4f, %+.2f%%)  Cz %.4f (%.4f, %+.2f%%)  N %.3f (%.3f, %+.2f%%)  %s\n", name.c_str(),
                    k, cx, tcx, 100 * (cx - tcx) / std::abs(tcx), cz, tcz, 100 * (cz - tcz) / std::abs(tcz), n, tn,
                    100 * (n - tn) / tn, lobe["status"][k].get<std::string>().c_str());
        EXPECT_EQ(lobe["status"][k], "converged") << "channel " << k;
        EXPECT_NEAR(cx, tcx, tol_c * std::abs(tcx)) << "Cx, channel " << k;
        EXPECT_NEAR(cz, tcz, tol_c * std::abs(tcz)) << "Cz, channel " << k;
        EXPECT_NEAR(n, tn, tol_n * tn) << "N, channel " << k;
    }
}

} // namespace specula::test
