#include "specular/core_fit.h"

#include "core/parallel.h"
#include "core/timer.h"
#include "shared/gltf_core.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <tuple>
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

// Hypothesis B, a clearcoat layer alone (KHR_materials_clearcoat, no base specular): for its roughness,
// the weight c in [0, 1] of b = rho s (1 - c Fcc(n.v)) + c F_c D V, s = 1 / (1 - 0.04 c) held and iterated.
struct CoatSolution {
    double c = 0.0, sse = std::numeric_limits<double>::infinity();
};

CoatSolution solve_coat_at(const std::vector<Prepared>& s, double roughness) {
    double c = 0.0;
    const auto sums = [&](double scale, double& yy, double& ay, double& aa) {
        yy = ay = aa = 0.0;
        for (const Prepared& p : s) {
            const double spec = (0.04 + 0.96 * p.x5) * shared::f64::core_ggx_dv(p.ci, p.co, p.cuv, roughness);
            const double x = 1.0 - p.co, fcc = 0.04 + 0.96 * x * x * x * x * x;
            for (int k = 0; k < 3; ++k) {
                const double base = p.rho_pi[k] * scale;
                const double y = p.b[k] - base, a = spec - base * fcc;
                yy += p.w * y * y, ay += p.w * a * y, aa += p.w * a * a;
            }
        }
    };
    double yy = 0, ay = 0, aa = 0;
    for (int it = 0; it < 4; ++it) {
        sums(1.0 / (1.0 - 0.04 * c), yy, ay, aa);
        c = aa > 0.0 && std::isfinite(ay / aa) ? std::clamp(ay / aa, 0.0, 1.0) : 0.0;
    }
    sums(1.0 / (1.0 - 0.04 * c), yy, ay, aa);
    return {c, yy - 2.0 * c * ay + c * c * aa};
}

/// The roughness in [lo, 1] minimising err(r): a grid, then golden-section search between the best
/// point's neighbours. Returns (r, err).
template <class Err>
std::pair<double, double> minimise_roughness(Err err, const CoreFitOptions& options) {
    const double lo = shared::kCoreMinRoughness, hi = 1.0;
    const std::size_t n = std::max<std::size_t>(options.roughness_steps, 3);
    std::vector<double> grid(n), at(n);
    std::size_t best = 0;
    for (std::size_t k = 0; k < n; ++k) {
        grid[k] = lo + (hi - lo) * static_cast<double>(k) / static_cast<double>(n - 1);
        at[k] = err(grid[k]);
        if (at[k] < at[best]) best = k;
    }
    double a = grid[best == 0 ? 0 : best - 1], b = grid[std::min(best + 1, n - 1)];
    std::pair<double, double> out{grid[best], at[best]};
    constexpr double kInvPhi = 0.6180339887498949;
    double x1 = b - kInvPhi * (b - a), x2 = a + kInvPhi * (b - a);
    double e1 = err(x1), e2 = err(x2);
    for (std::size_t it = 0; it < options.golden_iterations; ++it) {
        if (e1 < e2) {
            b = x2, x2 = x1, e2 = e1;
            x1 = b - kInvPhi * (b - a);
            e1 = err(x1);
        } else {
            a = x1, x1 = x2, e1 = e2;
            x2 = a + kInvPhi * (b - a);
            e2 = err(x2);
        }
    }
    for (const auto& [r, e] : {std::pair{x1, e1}, std::pair{x2, e2}})
        if (e < out.second) out = {r, e};
    return out;
}

} // namespace

CoreFit fit_core_material(std::span<const MaterialSample> samples, const CoreFitOptions& options) {
    const Stopwatch watch;
    CoreFit out;
    std::vector<Prepared> s;
    const std::size_t stride =
        options.max_samples == 0 ? 1 : std::max<std::size_t>(1, (samples.size() + options.max_samples - 1) / options.max_samples);
    s.reserve(samples.size() / stride + 1);
    double wsum = 0.0;
    for (std::size_t i = 0; i < samples.size(); i += stride) {
        const MaterialSample& m = samples[i];
        if (!(m.weight > 0.0f) || !(m.u.z > 0.0f) || !(m.v.z > 0.0f)) continue;
        const glm::dvec3 u = glm::normalize(glm::dvec3(m.u)), v = glm::normalize(glm::dvec3(m.v));
        const double cuv = glm::dot(u, v);
        double w = m.weight;
        if (options.srgb_display) { // the slope of the sRGB encoding at the observed value, squared
            const double pixel = std::sqrt(w) * (double(m.b.x) + double(m.b.y) + double(m.b.z)) / 3.0;
            const double slope = pixel <= 0.0031308 ? 12.92 : 1.055 / 2.4 * std::pow(pixel, 1.0 / 2.4 - 1.0);
            w *= slope * slope;
        }
        const Prepared p{u.z, v.z, cuv, shared::f64::core_schlick_weight(cuv), w, glm::dvec3(m.rho_over_pi), glm::dvec3(m.b)};
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

    // Hypothesis A: glTF's base specular layer (roughness, F0, F90). Hypothesis B: a clearcoat
    // layer alone over the diffuse base (what a coated dielectric is: its diffuse dimmed by the
    // coating's Fresnel at the viewer, which the base layer cannot do). Independent searches.
    double r_a = 0.0, sse_a = 0.0, r_b = 0.0, sse_b = 0.0;
    Solution sol_a;
    CoatSolution sol_b;
    parallel_for(2, options.threads, [&](std::size_t hypothesis) {
        if (hypothesis == 0) {
            std::tie(r_a, sse_a) = minimise_roughness([&](double r) { return solve_at(s, r).sse; }, options);
            sol_a = solve_at(s, r_a);
        } else {
            std::tie(r_b, sse_b) = minimise_roughness([&](double r) { return solve_coat_at(s, r).sse; }, options);
            sol_b = solve_coat_at(s, r_b);
        }
    });
    if (sse_b < sse_a && sol_b.c > 0.0) {
        out.material = {.roughness = 1.0, .f0 = 0.0, .f90 = 0.0, .clearcoat = sol_b.c, .clearcoat_roughness = r_b};
        out.rms = std::sqrt(std::max(0.0, sse_b * norm));
        out.fitted = true;
    } else if (sol_a.f90 > 0.0) {
        out.material = {.roughness = r_a, .f0 = sol_a.f0, .f90 = sol_a.f90};
        out.rms = std::sqrt(std::max(0.0, sse_a * norm));
        out.fitted = true;
    } else {
        out.note = "no specular term lowers the error: the core material is diffuse only";
        out.rms = out.diffuse_only_rms;
    }
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
