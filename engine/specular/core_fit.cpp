#include "specular/core_fit.h"

#include "core/timer.h"
#include "shared/gltf_core.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

namespace specula {

namespace {

struct Prepared {
    double ci, co, cuv, x5, w;
    glm::dvec3 rho_pi, b;
};

struct Solution {
    double f0 = 0.0, f90 = 0.0, sse = std::numeric_limits<double>::infinity();
};

// Weighted sums for the model b = rho s + f0 A + f90 B (per channel), A = (1 - x5)(dv - rho s),
// B = x5 (dv - rho s), y = b - rho s.
struct Sums {
    double yy = 0, ay = 0, by = 0, aa = 0, ab = 0, bb = 0;
    [[nodiscard]] double sse(double f0, double f90) const noexcept {
        return yy - 2.0 * (f0 * ay + f90 * by) + f0 * f0 * aa + 2.0 * f0 * f90 * ab + f90 * f90 * bb;
    }
};

Sums sums_at(const std::vector<Prepared>& s, double roughness, double scale) {
    Sums t;
    for (const Prepared& p : s) {
        const double dv = shared::f64::core_ggx_dv(p.ci, p.co, p.cuv, roughness);
        for (int c = 0; c < 3; ++c) {
            const double base = p.rho_pi[c] * scale;
            const double y = p.b[c] - base;
            const double a = (1.0 - p.x5) * (dv - base), b = p.x5 * (dv - base);
            t.yy += p.w * y * y;
            t.ay += p.w * a * y;
            t.by += p.w * b * y;
            t.aa += p.w * a * a;
            t.ab += p.w * a * b;
            t.bb += p.w * b * b;
        }
    }
    return t;
}

// The least-squares (f0, f90) with 0 <= f0 <= f90 <= 1: the free optimum when it is feasible,
// else the best over the boundary lines (f0 = 0, f0 = f90, f90 = 1), each a clamped 1-D optimum.
Solution solve_bounded(const Sums& t) {
    Solution best;
    const auto consider = [&](double f0, double f90) {
        if (!(f0 >= 0.0) || !(f90 >= f0) || !(f90 <= 1.0)) return;
        const double e = t.sse(f0, f90);
        if (e < best.sse) best = {f0, f90, e};
    };
    const double det = t.aa * t.bb - t.ab * t.ab;
    if (det > 1e-300 * std::max(1.0, t.aa * t.bb)) consider((t.ay * t.bb - t.by * t.ab) / det, (t.by * t.aa - t.ay * t.ab) / det);
    const auto clamp01 = [](double x) { return std::isfinite(x) ? std::clamp(x, 0.0, 1.0) : 0.0; };
    if (t.bb > 0.0) consider(0.0, clamp01(t.by / t.bb)); // f0 = 0
    const double cc = t.aa + 2.0 * t.ab + t.bb;          // f0 = f90 = x
    if (cc > 0.0) {
        const double x = clamp01((t.ay + t.by) / cc);
        consider(x, x);
    }
    if (t.aa > 0.0) consider(clamp01((t.ay - t.ab) / t.aa), 1.0); // f90 = 1
    consider(0.0, 0.0);
    return best;
}

// The best (f0, f90) for a roughness, the base colour's scale 1 / (1 - f0) iterated.
Solution solve_at(const std::vector<Prepared>& s, double roughness) {
    Solution sol{0.0, 0.0, 0.0};
    double scale = 1.0;
    for (int it = 0; it < 4; ++it) {
        sol = solve_bounded(sums_at(s, roughness, scale));
        scale = 1.0 / (1.0 - std::min(sol.f0, 0.95));
    }
    // The error with the scale the solution implies.
    sol.sse = sums_at(s, roughness, 1.0 / (1.0 - sol.f0)).sse(sol.f0, sol.f90);
    return sol;
}

} // namespace

CoreFit fit_core_material(std::span<const MaterialSample> samples, const CoreFitOptions& options) {
    const Stopwatch watch;
    CoreFit out;
    std::vector<Prepared> s;
    s.reserve(samples.size());
    double wsum = 0.0;
    for (const MaterialSample& m : samples) {
        if (!(m.weight > 0.0f) || !(m.u.z > 0.0f) || !(m.v.z > 0.0f)) continue;
        const glm::dvec3 u = glm::normalize(glm::dvec3(m.u)), v = glm::normalize(glm::dvec3(m.v));
        const double cuv = glm::dot(u, v);
        const Prepared p{u.z, v.z, cuv, shared::f64::core_schlick_weight(cuv), double(m.weight), glm::dvec3(m.rho_over_pi), glm::dvec3(m.b)};
        if (!std::isfinite(p.b.x + p.b.y + p.b.z + p.rho_pi.x + p.rho_pi.y + p.rho_pi.z + p.w)) continue;
        s.push_back(p);
        wsum += p.w;
    }
    out.samples = s.size();
    if (s.empty() || !(wsum > 0.0)) {
        out.note = "no usable sample: the core material has no specular term";
        out.seconds = watch.seconds();
        return out;
    }
    const double norm = 1.0 / (3.0 * wsum);
    out.diffuse_only_rms = std::sqrt(std::max(0.0, sums_at(s, 1.0, 1.0).yy * norm));

    const double lo = shared::kCoreMinRoughness, hi = 1.0;
    const std::size_t n = std::max<std::size_t>(options.roughness_steps, 3);
    std::vector<double> grid(n);
    std::vector<Solution> at(n);
    std::size_t best = 0;
    for (std::size_t k = 0; k < n; ++k) {
        grid[k] = lo + (hi - lo) * static_cast<double>(k) / static_cast<double>(n - 1);
        at[k] = solve_at(s, grid[k]);
        if (at[k].sse < at[best].sse) best = k;
    }
    double a = grid[best == 0 ? 0 : best - 1], b = grid[std::min(best + 1, n - 1)];
    double r_best = grid[best];
    Solution s_best = at[best];
    constexpr double kInvPhi = 0.6180339887498949;
    double x1 = b - kInvPhi * (b - a), x2 = a + kInvPhi * (b - a);
    Solution s1 = solve_at(s, x1), s2 = solve_at(s, x2);
    for (std::size_t it = 0; it < options.golden_iterations; ++it) {
        if (s1.sse < s2.sse) {
            b = x2, x2 = x1, s2 = s1;
            x1 = b - kInvPhi * (b - a);
            s1 = solve_at(s, x1);
        } else {
            a = x1, x1 = x2, s1 = s2;
            x2 = a + kInvPhi * (b - a);
            s2 = solve_at(s, x2);
        }
    }
    for (const auto& [r, sol] : {std::pair{x1, s1}, std::pair{x2, s2}})
        if (sol.sse < s_best.sse) r_best = r, s_best = sol;

    out.fitted = s_best.f90 > 0.0;
    out.material = {.roughness = r_best, .f0 = s_best.f0, .f90 = s_best.f90};
    if (!out.fitted) {
        out.material = {};
        out.note = "no specular term lowers the error: the core material is diffuse only";
    }
    out.rms = std::sqrt(std::max(0.0, s_best.sse * norm));
    if (!out.fitted) out.rms = out.diffuse_only_rms;
    out.seconds = watch.seconds();
    return out;
}

nlohmann::json to_json(const CoreFit& f) {
    return {{"fitted", f.fitted},
            {"material", to_json(f.material)},
            {"rms", f.rms},
            {"diffuse_only_rms", f.diffuse_only_rms},
            {"samples", f.samples},
            {"seconds", f.seconds},
            {"note", f.note}};
}

} // namespace specula
