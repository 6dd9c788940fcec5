// The coated family's fit: see coated_fit.h for the model, the parameters and the method.
#include "specular/coated_fit.h"

#include "core/format.h"
#include "core/parallel.h"
#include "core/timer.h"
#include "shared/material.h"

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <optional>
#include <thread>

namespace specula {
namespace {

namespace f64 = shared::f64;

/// The per-sample quantities that do not depend on the parameters.
struct Prepared {
    double ci, co, cuv; // n.u, n.v, u.v
    glm::dvec3 b, rho_pi;
    double w; // Ebar^2 times the robust weight
};

std::vector<Prepared> prepare(std::span<const MaterialSample> samples, std::size_t stride) {
    std::vector<Prepared> out;
    out.reserve(samples.size() / stride + 1);
    for (std::size_t i = 0; i < samples.size(); i += stride) {
        const MaterialSample& s = samples[i];
        if (!(s.weight > 0.0f) || !(s.u.z > 0.0f) || !(s.v.z > 0.0f)) continue;
        out.push_back({double(s.u.z), double(s.v.z), double(glm::dot(s.u, s.v)), glm::dvec3(s.b), glm::dvec3(s.rho_over_pi),
                       double(s.weight)});
    }
    return out;
}

/// Parameters in the fit's own coordinates.
struct Point {
    double log_alpha, eta;
};

/// A parameter's range in the fit's coordinates: the steps are clamped to it, and a parameter
/// at an end of it is held where the descent points out (levenberg_marquardt).
struct Range {
    double lo, hi;
    [[nodiscard]] double clamp(double x) const { return std::clamp(x, lo, hi); }
    /// At an end, with `descent` pointing out of the range.
    [[nodiscard]] bool pressed(double x, double descent) const { return (x <= lo && descent < 0.0) || (x >= hi && descent > 0.0); }
};
const Range kLogAlphaRange{std::log(double(shared::kCoatedMinAlpha)), std::log(double(shared::kCoatedMaxAlpha))};
const Range kEtaRange{double(shared::kCoatedMinEta), double(shared::kCoatedMaxEta)};

/// The model's two parts at one sample: the diffuse factor times rho / pi, and the untinted
/// specular (the tint multiplies it).
struct Parts {
    glm::dvec3 diffuse;
    double specular;
};
Parts parts(const Prepared& s, const Point& p) {
    const double alpha = std::exp(p.log_alpha);
    return {s.rho_pi * f64::coated_diffuse_factor(s.ci, s.co, p.eta), f64::coated_specular(s.ci, s.co, s.cuv, alpha, p.eta)};
}

/// The sum over the samples i < n of add(acc, i), in fixed chunks of kSumChunk samples on up
/// to `threads` workers, the chunks' partial sums then added in order: the same total for any
/// thread count (Acc has +=).
constexpr std::size_t kSumChunk = 8192;
template <class Acc, class F>
Acc chunked_sum(std::size_t n, unsigned threads, F&& add) {
    std::vector<Acc> part((n + kSumChunk - 1) / kSumChunk);
    parallel_for_chunks(n, std::max(threads, 1u), kSumChunk, [&](unsigned, std::size_t begin, std::size_t end) {
        Acc& acc = part[begin / kSumChunk];
        for (std::size_t i = begin; i < end; ++i) add(acc, i);
    });
    Acc total{};
    for (const Acc& a : part) total += a;
    return total;
}

/// The parameters that enter linearly: the tint, and the scale of the diffuse term the samples'
/// rho / pi is read with (coated_fit.h).
struct Linear {
    double scale = 1.0;
    glm::dvec3 tint{1.0};
    /// Which of (scale, tint r, g, b) the solve left free (fitted and off its bound): the
    /// Jacobian's curvature in (ln alpha, eta) is taken with these projected out.
    std::array<bool, 4> free{};
};

/// The model at one sample for given linear parameters.
glm::dvec3 model(const Parts& q, const Linear& l) { return l.scale * q.diffuse + l.tint * q.specular; }

/// The weighted sums of the linear least-squares problem in (scale, tint): D the diffuse part,
/// S the untinted specular, b the observation.
struct LinearSums {
    double dd = 0.0, ss = 0.0, db = 0.0;
    glm::dvec3 ds{0.0}, sb{0.0};
    LinearSums& operator+=(const LinearSums& o) {
        dd += o.dd;
        ss += o.ss;
        db += o.db;
        ds += o.ds;
        sb += o.sb;
        return *this;
    }
};

/// The linear parameters for fixed (alpha, eta), each either fixed (scale 1, tint 1) or the
/// weighted least-squares value given the others: the scale clamped to [kMinDiffuseScale,
/// kMaxDiffuseScale], the tint at 0 (a negative tint is no reflection). With both free, the
/// tint's channels and the scale are solved jointly (4 x 4 normal equations); a clamped value
/// is then held and the others solved again given it.
constexpr double kMinDiffuseScale = 0.5, kMaxDiffuseScale = 2.0;
Linear solve_linear(const std::vector<Prepared>& s, const std::vector<Parts>& at, const CoatedFitOptions& o, unsigned threads) {
    Linear l;
    if (!o.fit_tint && !o.fit_diffuse_scale) return l;
    const LinearSums t = chunked_sum<LinearSums>(s.size(), threads, [&](LinearSums& acc, std::size_t i) {
        const Prepared& x = s[i];
        const Parts& q = at[i];
        acc.dd += x.w * glm::dot(q.diffuse, q.diffuse);
        acc.ss += x.w * q.specular * q.specular;
        acc.db += x.w * glm::dot(q.diffuse, x.b);
        acc.ds += x.w * q.specular * q.diffuse;
        acc.sb += x.w * q.specular * x.b;
    });
    const auto scale_given = [&](const glm::dvec3& tint) {
        if (!(t.dd > 0.0)) return 1.0;
        return std::clamp((t.db - glm::dot(tint, t.ds)) / t.dd, kMinDiffuseScale, kMaxDiffuseScale);
    };
    const auto tint_given = [&](double scale) {
        return t.ss > 0.0 ? glm::max((t.sb - scale * t.ds) / t.ss, glm::dvec3(0.0)) : glm::dvec3(0.0);
    };
    const auto mark_free = [&] {
        l.free[0] = o.fit_diffuse_scale && l.scale > kMinDiffuseScale && l.scale < kMaxDiffuseScale;
        for (int c = 0; c < 3; ++c) l.free[c + 1] = o.fit_tint && l.tint[c] > 0.0;
    };
    if (!o.fit_tint) {
        l.scale = scale_given(l.tint);
        mark_free();
        return l;
    }
    if (!o.fit_diffuse_scale) {
        l.tint = tint_given(1.0);
        mark_free();
        return l;
    }
    Eigen::Matrix4d a = Eigen::Matrix4d::Zero();
    Eigen::Vector4d rhs;
    a(0, 0) = t.dd;
    rhs(0) = t.db;
    for (int c = 0; c < 3; ++c) {
        a(0, c + 1) = a(c + 1, 0) = t.ds[c];
        a(c + 1, c + 1) = t.ss;
        rhs(c + 1) = t.sb[c];
    }
    const Eigen::Vector4d x = a.ldlt().solve(rhs);
    const glm::dvec3 tint(x(1), x(2), x(3));
    if (x.allFinite() && x(0) >= kMinDiffuseScale && x(0) <= kMaxDiffuseScale && glm::all(glm::greaterThanEqual(tint, glm::dvec3(0.0)))) {
        l.scale = x(0);
        l.tint = tint;
        mark_free();
        return l;
    }
    // A bound is active: the tint at 0 where it went negative, the scale given it, the tint again.
    l.scale = scale_given(x.allFinite() ? glm::max(tint, glm::dvec3(0.0)) : glm::dvec3(0.0));
    l.tint = tint_given(l.scale);
    mark_free();
    return l;
}

double cost_at(const std::vector<Prepared>& s, const std::vector<Parts>& at, const Linear& l, unsigned threads) {
    return chunked_sum<double>(s.size(), threads, [&](double& acc, std::size_t i) {
        const glm::dvec3 r = model(at[i], l) - s[i].b;
        acc += s[i].w * glm::dot(r, r);
    });
}

/// The linear parameters projected out at p (variable projection) and the cost there. The model's
/// parts are evaluated once per sample into `scratch` (the linear solve and the cost both read them).
struct Projected {
    Linear linear;
    double cost;
};
void parts_at(const std::vector<Prepared>& s, const Point& p, unsigned threads, std::vector<Parts>& out) {
    out.resize(s.size());
    parallel_for_chunks(s.size(), std::max(threads, 1u), kSumChunk, [&](unsigned, std::size_t begin, std::size_t end) {
        for (std::size_t i = begin; i < end; ++i) out[i] = parts(s[i], p);
    });
}
Projected project(const std::vector<Prepared>& s, const Point& p, const CoatedFitOptions& o, unsigned threads,
                  std::vector<Parts>& scratch) {
    parts_at(s, p, threads, scratch);
    const Linear l = solve_linear(s, scratch, o, threads);
    return {l, cost_at(s, scratch, l, threads)};
}

/// The Jacobian J of the 3m residuals sqrt(w) (model - b) in (ln alpha, eta) at fixed linear
/// parameters, by forward differences from the parts at the point (the model's derivatives
/// through Fresnel and Smith are long; a difference costs one more part, for alpha the
/// specular alone: the diffuse factor does not depend on it), accumulated as J^T J and J^T r;
/// and with it the Jacobian P in the linear parameters (scale, tint), as J^T P and P^T P.
struct Normal {
    Eigen::Matrix2d jtj = Eigen::Matrix2d::Zero();
    Eigen::Vector2d jtr = Eigen::Vector2d::Zero();
    Eigen::Matrix<double, 2, 4> jtp = Eigen::Matrix<double, 2, 4>::Zero();
    Eigen::Matrix4d ptp = Eigen::Matrix4d::Zero();
    double cost = 0.0;
    Normal& operator+=(const Normal& o) {
        jtj += o.jtj;
        jtr += o.jtr;
        jtp += o.jtp;
        ptp += o.ptp;
        cost += o.cost;
        return *this;
    }
    /// The Gauss-Newton matrix of the cost with the free linear parameters projected out at
    /// every point (variable projection, Kaufman's approximation): J^T J less J^T P (P^T P)^-1
    /// P^T J over the free ones, the Schur complement. J^T r needs no projection: the free
    /// linear parameters' own gradient P^T r is 0 where they are solved. The correlation
    /// between eta and the diffuse scale (both scale the diffuse term) makes the plain J^T J a
    /// poor model of the projected cost: 40 to 100 iterations a fit instead of a few.
    /// The complement as it comes (it measures what the samples determine of (ln alpha, eta)
    /// with the linear parameters free: the standard errors at the minimum); `projected` keeps
    /// the plain matrix for the steps where rounding leaves it not positive definite.
    [[nodiscard]] Eigen::Matrix2d complement(const std::array<bool, 4>& free) const {
        std::array<int, 4> idx{};
        int k = 0;
        for (int j = 0; j < 4; ++j)
            if (free[j]) idx[k++] = j;
        if (k == 0) return jtj;
        Eigen::MatrixXd b(2, k), c(k, k);
        for (int a = 0; a < k; ++a) {
            b.col(a) = jtp.col(idx[a]);
            for (int d = 0; d < k; ++d) c(a, d) = ptp(idx[a], idx[d]);
        }
        const Eigen::LDLT<Eigen::MatrixXd> ldlt(c);
        if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return jtj;
        return jtj - b * ldlt.solve(b.transpose());
    }
    [[nodiscard]] Eigen::Matrix2d projected(const std::array<bool, 4>& free) const {
        const Eigen::Matrix2d h = complement(free);
        // Rounding can leave the complement a hair below 0 where the columns are nearly
        // dependent: keep the plain matrix there (its step is short, never wrong in sign).
        if (!h.allFinite() || !(h(0, 0) > 0.0) || !(h(1, 1) > 0.0) || h.determinant() < 0.0) return jtj;
        return h;
    }
};
/// `at`: the parts at p (parts_at).
Normal normal_equations(const std::vector<Prepared>& s, const std::vector<Parts>& at, const Point& p, const Linear& l,
                        unsigned threads = 1) {
    constexpr double h = 1e-7;
    const double alpha_h = std::exp(p.log_alpha + h);
    Normal n = chunked_sum<Normal>(s.size(), threads, [&](Normal& acc, std::size_t i) {
        const Prepared& x = s[i];
        const Parts& q0 = at[i];
        const double specular_a = f64::coated_specular(x.ci, x.co, x.cuv, alpha_h, p.eta);
        const Parts qe = parts(x, {p.log_alpha, p.eta + h});
        const glm::dvec3 r = model(q0, l) - x.b;
        const glm::dvec3 ja = l.tint * ((specular_a - q0.specular) / h);
        const glm::dvec3 je = (model(qe, l) - model(q0, l)) / h;
        acc.jtj(0, 0) += x.w * glm::dot(ja, ja);
        acc.jtj(0, 1) += x.w * glm::dot(ja, je);
        acc.jtj(1, 1) += x.w * glm::dot(je, je);
        acc.jtr(0) += x.w * glm::dot(ja, r);
        acc.jtr(1) += x.w * glm::dot(je, r);
        acc.cost += x.w * glm::dot(r, r);
        // The linear parameters' columns: d model / d scale = the diffuse part, d model / d tint_c
        // = the untinted specular in channel c.
        const std::array<glm::dvec3, 2> jc{ja, je};
        for (int a = 0; a < 2; ++a) {
            acc.jtp(a, 0) += x.w * glm::dot(jc[a], q0.diffuse);
            for (int c = 0; c < 3; ++c) acc.jtp(a, c + 1) += x.w * jc[a][c] * q0.specular;
        }
        acc.ptp(0, 0) += x.w * glm::dot(q0.diffuse, q0.diffuse);
        for (int c = 0; c < 3; ++c) {
            acc.ptp(0, c + 1) += x.w * q0.diffuse[c] * q0.specular;
            acc.ptp(c + 1, c + 1) += x.w * q0.specular * q0.specular;
        }
    });
    n.jtj(1, 0) = n.jtj(0, 1);
    for (int c = 0; c < 3; ++c) n.ptp(c + 1, 0) = n.ptp(0, c + 1);
    return n;
}

struct LmResult {
    Point p;
    Linear linear;
    double cost;
    std::uint32_t iterations;
    bool converged;
};

/// Levenberg-Marquardt in (ln alpha, eta), the linear parameters re-solved after each accepted
/// step; its sums on up to `threads` workers.
LmResult levenberg_marquardt(const std::vector<Prepared>& s, Point p, const CoatedFitOptions& o, unsigned threads) {
    std::vector<Parts> at, scratch; // the parts at p, and at a trial point
    const Projected start = project(s, p, o, threads, at);
    Linear lin = start.linear;
    double cost = start.cost;
    // The damping of each parameter, (ln alpha, eta). One shared damping let a parameter the
    // samples barely see (alpha where eta is near 1 and the coating reflects almost nothing:
    // J^T J's alpha entry 1e-14 to 1e-6 against eta's 60) drive it to 1e3..1e6, and the other
    // then moved by a thousandth of its Newton step an iteration (the woodenpot, thesis rig:
    // four runs of 100 iterations, none converged, the candidate lost).
    Eigen::Vector2d lambda(1e-3, 1e-3);
    LmResult r{p, lin, cost, 0, false};
    for (std::uint32_t it = 0; it < o.max_iterations; ++it) {
        ++r.iterations;
        const Normal n = normal_equations(s, at, p, lin, threads);
        const Eigen::Matrix2d h = n.projected(lin.free);
        // A parameter at a bound whose descent direction points out of the range is held for this
        // step (an active set): the coupled step would spend itself on the clamped parameter and
        // leave the other to creep along the bound (100 iterations without converging, eta at
        // the top of its range on a Lafortune capture, against a few held).
        const bool hold_alpha = kLogAlphaRange.pressed(p.log_alpha, -n.jtr(0));
        const bool hold_eta = o.fixed_eta || kEtaRange.pressed(p.eta, -n.jtr(1));
        if (hold_alpha && hold_eta) {
            r.converged = std::isfinite(cost); // both pressed against their bounds: a minimum on the box
            break;
        }
        const Eigen::Vector2d diag = h.diagonal().cwiseMax(1e-30);
        // Tries `step`; where it lowers the cost, moves there and returns true.
        const auto attempt = [&](const Eigen::Vector2d& step) {
            if (!step.allFinite()) return false;
            const Point q{kLogAlphaRange.clamp(p.log_alpha + step(0)), kEtaRange.clamp(p.eta + step(1))};
            const Projected trial = project(s, q, o, threads, scratch);
            if (!(std::isfinite(trial.cost) && trial.cost < cost)) return false;
            if ((cost - trial.cost) / std::max(cost, 1e-300) < o.cost_tolerance) r.converged = true;
            p = q;
            lin = trial.linear;
            cost = trial.cost;
            at.swap(scratch);
            return true;
        };
        // One parameter alone, k = 0 (ln alpha) or 1 (eta), damped by its own lambda.
        const auto alone = [&](int k) {
            Eigen::Vector2d step = Eigen::Vector2d::Zero();
            step(k) = -n.jtr(k) / (h(k, k) + lambda(k) * diag(k));
            return step;
        };
        bool accepted = false;
        for (int tries = 0; tries < 12 && !accepted; ++tries) {
            if (hold_eta || hold_alpha) {
                const int k = hold_eta ? 0 : 1; // the free one
                accepted = attempt(alone(k));
                lambda(k) = accepted ? std::max(lambda(k) / 10.0, 1e-12) : lambda(k) * 10.0;
                continue;
            }
            Eigen::Matrix2d a = h;
            a.diagonal() += lambda.cwiseProduct(diag);
            if (attempt(a.ldlt().solve(-n.jtr))) {
                lambda = (lambda / 10.0).cwiseMax(1e-12);
                accepted = true;
                continue;
            }
            // The coupled step does not lower the cost: each parameter alone, eta first (the
            // better determined on the captures measured). The one that moves relaxes its
            // damping, the other's grows.
            for (const int k : {1, 0}) {
                if (!attempt(alone(k))) continue;
                lambda(k) = std::max(lambda(k) / 10.0, 1e-12);
                lambda(1 - k) *= 10.0;
                accepted = true;
                break;
            }
            if (!accepted) lambda *= 10.0;
        }
        if (!accepted) r.converged = std::isfinite(cost); // no step lowers the cost: a minimum (or a bound)
        r.p = p;
        r.linear = lin;
        r.cost = cost;
        if (r.converged) break;
    }
    return r;
}

/// Huber weights (k = 1.345 robust sigmas) from the residuals at p, folded into the weights.
void reweight(std::vector<Prepared>& s, const std::vector<double>& base_w, const Point& p, const Linear& l) {
    std::vector<double> abs_r(s.size());
    for (std::size_t i = 0; i < s.size(); ++i) {
        const glm::dvec3 r = model(parts(s[i], p), l) - s[i].b;
        abs_r[i] = std::sqrt(base_w[i] * glm::dot(r, r) / 3.0);
    }
    std::vector<double> sorted = abs_r;
    std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
    const double sigma = 1.4826 * sorted[sorted.size() / 2];
    const double k = 1.345 * std::max(sigma, 1e-12);
    for (std::size_t i = 0; i < s.size(); ++i) s[i].w = base_w[i] * (abs_r[i] <= k ? 1.0 : k / abs_r[i]);
}

// A used residual sample as a total BRDF sample (to_material_samples).
MaterialSample to_material_sample(const ResidualSample& s) noexcept {
    const glm::vec3 rho_pi(s.d);
    return {.u = glm::vec3(s.u), .v = glm::vec3(s.v), .b = s.f + rho_pi * s.d.w, .rho_over_pi = rho_pi, .weight = s.u.w};
}

// material_mean_square_error's sums: sq += w |model - b|^2 / 3, wsum += w (weight > 0 only).
void add_square_error(const shared::MaterialGpu& m, const MaterialSample& s, double& sq, double& wsum) noexcept {
    if (!(s.weight > 0.0f)) return;
    const double ci = s.u.z, co = s.v.z, cuv = glm::dot(s.u, s.v);
    const glm::dvec3 f = glm::dvec3(s.rho_over_pi) * f64::material_diffuse_factor(m, ci, co) + f64::material_specular(m, ci, co, cuv);
    const glm::dvec3 r = f - glm::dvec3(s.b);
    sq += double(s.weight) * glm::dot(r, r) / 3.0;
    wsum += double(s.weight);
}

} // namespace

std::vector<MaterialSample> to_material_samples(std::span<const ResidualSample> samples, std::size_t max_samples) {
    const std::size_t stride = used_sample_stride(samples, max_samples);
    std::vector<MaterialSample> out;
    out.reserve(samples.size() / stride + 1);
    std::size_t k = 0;
    for (const ResidualSample& s : samples) {
        if (s.status != shared::kResidualUsed || k++ % stride != 0) continue;
        out.push_back(to_material_sample(s));
    }
    return out;
}

const char* to_string(CoatedFitStatus s) noexcept {
    switch (s) {
    case CoatedFitStatus::Converged: return "converged";
    case CoatedFitStatus::Underdetermined: return "underdetermined";
    case CoatedFitStatus::NotConverged: return "not_converged";
    case CoatedFitStatus::TooFewSamples: return "too_few_samples";
    }
    return "?";
}

namespace {

CoatedFit fit_once(std::span<const MaterialSample> samples, const CoatedFitOptions& o) {
    const Stopwatch watch;
    CoatedFit fit;
    std::vector<Prepared> all = prepare(samples, 1);
    fit.samples = static_cast<std::uint32_t>(all.size());
    const std::size_t params = (o.fixed_eta ? 1 : 2) + (o.fit_tint ? 3 : 0) + (o.fit_diffuse_scale ? 1 : 0);
    if (all.size() <= params * 3) {
        fit.reason = std::to_string(all.size()) + " usable samples for " + std::to_string(params) + " parameters";
        fit.seconds = watch.seconds();
        return fit;
    }

    // Grid over (ln alpha, eta) on a subsample: alpha 0.005..1 in 24 log steps, eta 1.1..2.5.
    const std::size_t stride = o.coarse_samples > 0 ? std::max<std::size_t>(1, all.size() / o.coarse_samples) : 1;
    const std::vector<Prepared> coarse = prepare(samples, stride);
    struct Cell {
        Point p;
        double cost;
    };
    std::vector<Cell> cells;
    constexpr int kAlphaSteps = 24;
    const int eta_steps = o.fixed_eta ? 1 : 15;
    for (int i = 0; i < kAlphaSteps; ++i)
        for (int j = 0; j < eta_steps; ++j) {
            const double la = std::log(0.005) + (std::log(1.0) - std::log(0.005)) * i / (kAlphaSteps - 1);
            cells.push_back({{la, o.fixed_eta ? kEtaRange.clamp(*o.fixed_eta) : 1.1 + 0.1 * j}, 0.0});
        }
    const unsigned threads = o.threads != 0 ? o.threads : std::max(1u, std::thread::hardware_concurrency());
    parallel_for(cells.size(), threads, [&](std::size_t c) {
        std::vector<Parts> scratch;
        cells[c].cost = project(coarse, cells[c].p, o, 1, scratch).cost;
    });
    std::sort(cells.begin(), cells.end(), [](const Cell& a, const Cell& b) { return a.cost < b.cost; });

    // LM from the best cells (distinct starts), robustly reweighted on all samples.
    std::vector<double> base_w(all.size());
    for (std::size_t i = 0; i < all.size(); ++i) base_w[i] = all[i].w;
    LmResult best{{0.0, 0.0}, Linear{}, std::numeric_limits<double>::infinity(), 0, false};
    const std::size_t starts = std::min<std::size_t>(cells.size(), std::max<std::uint32_t>(1, o.restarts));
    // The starts' LM runs are independent: side by side, then taken in order (the same best for any thread count).
    std::vector<std::optional<LmResult>> runs(starts);
    parallel_for(starts, threads, [&](std::size_t k) {
        if (std::isfinite(cells[k].cost)) runs[k] = levenberg_marquardt(coarse, cells[k].p, o, 1);
    });
    for (const std::optional<LmResult>& r : runs) {
        if (!r) continue;
        fit.iterations += r->iterations;
        if (r->cost < best.cost) best = *r;
    }
    if (!std::isfinite(best.cost)) {
        fit.status = CoatedFitStatus::NotConverged;
        fit.reason = "the cost is not finite at any start";
        fit.seconds = watch.seconds();
        return fit;
    }
    for (std::uint32_t pass = 0; pass <= o.robust_passes; ++pass) {
        if (pass > 0) reweight(all, base_w, best.p, best.linear);
        const LmResult r = levenberg_marquardt(all, best.p, o, threads);
        fit.iterations += r.iterations;
        best = r;
    }

    // Uncertainty at the minimum (the robust weights kept), with the free linear parameters
    // projected out: eta and the diffuse scale trade against each other, and eta's error with
    // the scale held would understate what the samples leave open.
    std::vector<Parts> at;
    parts_at(all, best.p, threads, at);
    const Normal n = normal_equations(all, at, best.p, best.linear, threads);
    const Eigen::Matrix2d h = n.complement(best.linear.free);
    const double m = 3.0 * double(all.size());
    const double s2 = n.cost / std::max(1.0, m - double(params));
    const Eigen::Vector2d scale = h.diagonal().cwiseMax(1e-300).cwiseSqrt().cwiseInverse();
    const Eigen::Matrix2d scaled = scale.asDiagonal() * h * scale.asDiagonal();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(scaled);
    const double lo = eig.eigenvalues().minCoeff(), hi = eig.eigenvalues().maxCoeff();
    fit.condition = lo > 0.0 ? hi / lo : std::numeric_limits<double>::infinity();
    const double alpha = std::exp(best.p.log_alpha);
    if (o.fixed_eta) {
        // eta given: ln alpha's variance alone, and no error on eta.
        fit.condition = 1.0;
        fit.std_error_alpha = h(0, 0) > 0.0 ? alpha * std::sqrt(s2 / h(0, 0)) : std::numeric_limits<double>::infinity();
        fit.std_error_eta = 0.0;
    } else if (lo > 0.0) {
        const Eigen::Matrix2d cov = s2 * h.inverse();
        fit.std_error_alpha = alpha * std::sqrt(std::max(0.0, cov(0, 0))); // d alpha = alpha d ln alpha
        fit.std_error_eta = std::sqrt(std::max(0.0, cov(1, 1)));
    } else {
        fit.std_error_alpha = fit.std_error_eta = std::numeric_limits<double>::infinity();
    }
    if (o.fit_tint) {
        // The tint is linear: its variance given (alpha, eta) is s^2 / sum w s_spec^2.
        double den = 0.0;
        for (std::size_t i = 0; i < all.size(); ++i) den += all[i].w * at[i].specular * at[i].specular;
        fit.std_error_tint = glm::dvec3(den > 0.0 ? std::sqrt(s2 / den) : std::numeric_limits<double>::infinity());
    }
    fit.params = CoatedParams{.eta = float(best.p.eta), .alpha = float(alpha), .tint = glm::vec3(best.linear.tint)};
    fit.diffuse_scale = best.linear.scale;
    fit.cost = best.cost;
    double sq = 0.0, wsum = 0.0;
    for (std::size_t i = 0; i < all.size(); ++i) {
        const glm::dvec3 r = model(at[i], best.linear) - all[i].b;
        sq += base_w[i] * glm::dot(r, r) / 3.0;
        wsum += base_w[i];
    }
    fit.rms = wsum > 0.0 ? std::sqrt(sq / wsum) : 0.0;
    fit.alpha_determined = fit.std_error_alpha < o.max_relative_error * alpha;
    fit.eta_determined = fit.std_error_eta < o.max_relative_error * best.p.eta;
    if (!best.converged) {
        fit.status = CoatedFitStatus::NotConverged;
        fit.reason = "iteration limit (" + std::to_string(o.max_iterations) + ") reached";
    } else if (!fit.alpha_determined || !fit.eta_determined) {
        fit.status = CoatedFitStatus::Underdetermined;
        fit.reason = std::string("the samples do not determine ") +
                     (!fit.alpha_determined && !fit.eta_determined ? "alpha nor eta"
                      : !fit.alpha_determined                      ? "alpha"
                                                                   : "eta") +
                     " (relative standard error above " + std::to_string(o.max_relative_error) +
                     "): the rig's light and view directions do not vary " +
                     (!fit.eta_determined ? "the Fresnel terms (grazing or wide half-angles)" : "the half-vector angle") +
                     " enough";
    } else {
        fit.status = CoatedFitStatus::Converged;
        fit.reason = "converged";
    }
    fit.seconds = watch.seconds();
    return fit;
}

} // namespace

CoatedFit fit_coated(std::span<const MaterialSample> samples, const CoatedFitOptions& o) {
    CoatedFit fit = fit_once(samples, o);
    // eta ran to the top of its range (within 5% of the upper bound, converged there or not): the
    // samples hold no Fresnel rise to fix it (the cologne's first solve on the thesis rig at 512
    // px, the highlight's views rejected as outliers, went to eta 3, alpha 0.016 against the
    // truth's 1.52, 0.05). Fitted again with eta held at a common coating's index (alpha 0.047
    // there), and said. Not at the bottom: eta near 1 is a coating that reflects nothing, the
    // right answer for a surface without one (a Lambertian truth forced to fit a specular).
    const float eta = fit.params.eta;
    const bool at_bound = eta >= 0.95f * shared::kCoatedMaxEta;
    if (o.fixed_eta || !o.eta_at_bound || fit.status == CoatedFitStatus::TooFewSamples || !at_bound) return fit;
    CoatedFitOptions held = o;
    held.fixed_eta = *o.eta_at_bound;
    CoatedFit h = fit_once(samples, held);
    if (!h.usable()) return fit;
    h.status = CoatedFitStatus::Underdetermined;
    h.eta_determined = false;
    h.reason = format_text("eta ran to the top of its range (%.3g): the samples hold no Fresnel rise to fix it, so it is held at %.3g "
                           "and alpha alone is fitted",
                           double(eta), *o.eta_at_bound);
    h.iterations += fit.iterations;
    h.seconds += fit.seconds;
    return h;
}

double material_mean_square_error(const SpecularModel& model, std::span<const MaterialSample> samples) {
    const shared::MaterialGpu m = material_gpu(model);
    double sq = 0.0, wsum = 0.0;
    for (const MaterialSample& s : samples) add_square_error(m, s, sq, wsum);
    return wsum > 0.0 ? sq / wsum : 0.0;
}

double material_mean_square_error(const SpecularModel& model, std::span<const ResidualSample> samples) {
    const shared::MaterialGpu m = material_gpu(model);
    double sq = 0.0, wsum = 0.0;
    for (const ResidualSample& s : samples)
        if (s.status == shared::kResidualUsed) add_material_square_error(m, s, sq, wsum);
    return wsum > 0.0 ? sq / wsum : 0.0;
}

void add_material_square_error(const shared::MaterialGpu& m, const ResidualSample& s, double& sq, double& wsum) noexcept {
    add_square_error(m, to_material_sample(s), sq, wsum);
}

} // namespace specula
