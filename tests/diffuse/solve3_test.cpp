// The weighted 3x3 least-squares solve of shared/solve3.h (the photometric mode of the
// diffuse solve), in both its instantiations: float (the one glslang compiles too) and
// double (the CPU reference). Known truth on photometric systems, and every status on
// systems built to hit it. (These cases come from the former lsq3_solve kernel's tests,
// which were the only direct tests of this header.)
//
// Tolerance (solve3.h): for K rows with float inputs and the reciprocal condition rcond
// of the Jacobi-scaled normal matrix C, the float solve's error in data units x = D^1/2 g
// (D = diag(M)) is at most about cond_2(C) (K + 8) eps32 with cond_2(C) <= 3 / rcond;
// allowed: kSafety * (K + 8) * eps32 * 3 / rcond * |D^1/2 g|, kSafety = 4 for the
// rounding of inputs and outputs. The double solve is far inside the same bound.
#include "shared/solve3.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <vector>

namespace specula {
namespace {

constexpr double kEps32 = 5.96e-8; // 2^-24
constexpr double kSafety = 4.0;
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();

// One row as the GPU reads it: float a, b, w.
struct Row {
    glm::vec3 a;
    float b;
    float w;
};

Row row(glm::dvec3 a, double b, double w = 1.0) { return {glm::vec3(a), static_cast<float>(b), static_cast<float>(w)}; }

struct Solved {
    glm::dvec3 g;
    double rcond;
    std::uint32_t status;
    std::uint32_t rows;
};

// The two instantiations behind one interface.
enum class Precision { Float, Double };

Solved solve(Precision precision, const std::vector<Row>& rows) {
    if (precision == Precision::Float) {
        shared::Lsq3Normal n = shared::lsq3_normal_zero();
        for (const Row& r : rows) shared::lsq3_accumulate(n, r.a, r.b, r.w);
        const shared::Lsq3Solution s = shared::lsq3_solve_normal(n);
        return {glm::dvec3(s.g), s.rcond, s.status, n.rows};
    }
    shared::f64::Lsq3Normal n = shared::f64::lsq3_normal_zero();
    for (const Row& r : rows) shared::f64::lsq3_accumulate(n, glm::dvec3(r.a), r.b, r.w);
    const shared::f64::Lsq3Solution s = shared::f64::lsq3_solve_normal(n);
    return {s.g, s.rcond, s.status, n.rows};
}

// D^1/2 of an element, from its rows in double.
glm::dvec3 sqrt_diag(const std::vector<Row>& rows) {
    glm::dvec3 d(0.0);
    for (const Row& r : rows)
        if (r.w > 0.0f) d += static_cast<double>(r.w) * glm::dvec3(r.a) * glm::dvec3(r.a);
    return glm::sqrt(d);
}

bool all_finite(const Solved& s) {
    return std::isfinite(s.g.x) && std::isfinite(s.g.y) && std::isfinite(s.g.z) && std::isfinite(s.rcond);
}

glm::dvec3 random_unit(std::mt19937& rng) {
    std::normal_distribution<double> n(0.0, 1.0);
    return glm::normalize(glm::dvec3(n(rng), n(rng), n(rng)));
}

class Solve3Test : public ::testing::TestWithParam<Precision> {};

// Well-conditioned photometric systems (lights around the normal) with exact b: g comes back.
TEST_P(Solve3Test, RecoversKnownSolutions) {
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    std::size_t ok = 0;
    const std::size_t count = 5000;
    double worst = 0.0;
    for (std::size_t e = 0; e < count; ++e) {
        const glm::dvec3 n = random_unit(rng);
        const glm::dvec3 g = (0.05 + 0.9 * uni(rng)) / 3.14159265358979 * n;
        const int k = 3 + static_cast<int>(uni(rng) * 14);
        std::vector<Row> rows;
        for (int i = 0; i < k; ++i) {
            glm::dvec3 u = random_unit(rng);
            if (glm::dot(u, n) < 0.0) u = -u;
            const glm::dvec3 a = (0.2 + 4.8 * uni(rng)) * u;
            rows.push_back(row(a, glm::dot(a, g), 0.25 + 0.75 * uni(rng)));
        }
        const Solved s = solve(GetParam(), rows);
        ASSERT_TRUE(all_finite(s)) << "element " << e;
        if (s.status != shared::kLsq3Ok) continue; // random directions can be nearly coplanar
        ++ok;
        const glm::dvec3 d = sqrt_diag(rows);
        const double err = glm::length(d * (s.g - g));
        const double tol = kSafety * double(rows.size() + 8) * kEps32 * 3.0 / s.rcond * glm::length(d * g);
        worst = std::max(worst, err / tol);
        ASSERT_LE(err, tol) << "element " << e << " rcond " << s.rcond;
    }
    EXPECT_GT(ok, count * 9 / 10);
    std::printf("known truth: %zu of %zu solved, worst error / tolerance = %.3g\n", ok, count, worst);
}

// The statuses, on systems built to hit each one; every output is finite, g = 0 unless ok.
TEST_P(Solve3Test, ReportsStatusesAndNeverNaN) {
    const glm::dvec3 g(0.1, -0.2, 0.3);
    const glm::dvec3 x(1, 0, 0), y(0, 1, 0), z(0, 0, 1);
    const auto exact = [&](glm::dvec3 a, double w = 1.0) { return row(a, glm::dot(a, g), w); };
    const std::vector<std::vector<Row>> elements = {
        {},                                                                               // 0: no rows
        {exact(x), exact(y)},                                                             // 1: two rows
        {exact(x), exact(y), exact(z, 0.0)},                                              // 2: zero weight does not count
        {exact(x), exact(y), exact(x + y)},                                               // 3: rank 2 (coplanar)
        {exact(x), exact(2.0 * x), exact(3.0 * x), exact(-x)},                            // 4: rank 1
        {exact(x + z), exact(y + z), exact(x + y + 2.001 * z)},                           // 5: nearly coplanar
        {exact(x), exact(y), exact(z)},                                                   // 6: identity
        {exact(1e12 * x), exact(1e12 * y), exact(1e12 * z)},                              // 7: huge scale
        {exact(1e-12 * x), exact(1e-12 * y), exact(1e-12 * z)},                           // 8: tiny scale
        {exact(glm::dvec3(1e6, 1, 0)), exact(glm::dvec3(0, 1, 1)), exact(glm::dvec3(1e6, 0, 1))}, // 9: unit mix
        {exact(x), exact(y), exact(z), row(glm::dvec3(kNaN, 0, 0), 1.0)},                 // 10: NaN
        {exact(x), exact(y), exact(z), row(z, kInf)},                                     // 11: infinite b
        {exact(x), exact(y), exact(z), exact(x + y, -1.0)},                               // 12: negative weight
        {exact(x), exact(y), exact(x), exact(y)},                                         // 13: z unconstrained
    };
    const std::uint32_t expected[] = {shared::kLsq3TooFewRows,     shared::kLsq3TooFewRows,     shared::kLsq3TooFewRows,
                                      shared::kLsq3IllConditioned, shared::kLsq3IllConditioned, shared::kLsq3IllConditioned,
                                      shared::kLsq3Ok,             shared::kLsq3Ok,             shared::kLsq3Ok,
                                      shared::kLsq3Ok,             shared::kLsq3InvalidInput,   shared::kLsq3InvalidInput,
                                      shared::kLsq3InvalidInput,   shared::kLsq3IllConditioned};
    ASSERT_EQ(elements.size(), std::size(expected));
    std::vector<Solved> out;
    for (const std::vector<Row>& rows : elements) out.push_back(solve(GetParam(), rows));
    for (std::size_t e = 0; e < out.size(); ++e) {
        EXPECT_EQ(out[e].status, expected[e]) << "element " << e;
        EXPECT_TRUE(all_finite(out[e])) << "element " << e;
        if (out[e].status != shared::kLsq3Ok) {
            EXPECT_EQ(out[e].g, glm::dvec3(0.0)) << "element " << e;
        } else { // error in data units: inputs are float, so b carries a relative error of eps32
            const glm::dvec3 d = sqrt_diag(elements[e]);
            EXPECT_LT(glm::length(d * (out[e].g - g)), 1e-5 * glm::length(d * g)) << "element " << e;
        }
    }
    // Scale invariance: the unit matrix at any scale, and a 1e6 unit mix, keep their conditioning.
    // Element 9's scaled matrix is [[1,.5,.5],[.5,1,.5],[.5,.5,1]]: rcond = 1.5 / (sqrt(4.5) sqrt(2.0625)).
    for (std::size_t e : {6u, 7u, 8u}) EXPECT_NEAR(out[e].rcond, 1.0, 1e-6) << "element " << e;
    EXPECT_NEAR(out[9].rcond, 1.5 / (std::sqrt(4.5) * std::sqrt(2.0625)), 1e-5);
    EXPECT_EQ(out[2].rows, 2u);
    EXPECT_EQ(out[4].rows, 4u);
    EXPECT_LT(out[5].rcond, shared::kLsq3MinRcond);
}

INSTANTIATE_TEST_SUITE_P(Instantiations, Solve3Test, ::testing::Values(Precision::Float, Precision::Double),
                         [](const auto& info) { return info.param == Precision::Float ? "Float" : "Double"; });

} // namespace
} // namespace specula
