// Lafortune lobe fit by Levenberg-Marquardt (pipeline.md section 5; thesis eq. 2.1,
// section 3.2.2). The parametrization and the statuses are explained in lafortune_fit.h.
//
// Levenberg-Marquardt as in Madsen, Nielsen and Tingleff, "Methods for non-linear least
// squares problems" (2004), algorithm 3.16: Marquardt's diagonal scaling D = diag(J^T J),
// gain ratio rho = actual / predicted decrease, damping update
// lambda *= max(1/3, 1 - (2 rho - 1)^3) on success, lambda *= nu, nu *= 2 on failure.
// With F = sum r_i^2 and a step delta solving (J^T J + lambda D) delta = -J^T r, the
// predicted decrease is -delta^T J^T r + lambda delta^T D delta.
#include "specular/lafortune_fit.h"

#include "core/error.h"
#include "core/parallel.h"
#include "core/timer.h"
#include "material/material.h"

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

namespace specula {

namespace {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kMaxExponent = 700.0;  // exp(700) ~ 1e304: beyond it a value is treated as overflow
constexpr double kSingularCondition = 1e300; // reported for a singular J^T J (never infinity)

std::string format(const char* fmt, double a = 0, double b = 0, double c = 0, double d = 0) {
    char buf[512];
    std::snprintf(buf, sizeof buf, fmt, a, b, c, d);
    return buf;
}

/// The samples of one channel with weight > 0, reduced to what the isotropic lobe sees:
/// a = ux vx + uy vy, b = uz vz (eq. 2.1), the value and the weight.
struct Data {
    std::vector<double> a, b, f, w;
    double saturation = kInf; ///< f >= saturation: censored
    [[nodiscard]] std::size_t size() const { return f.size(); }
    void reserve(std::size_t n) { a.reserve(n); b.reserve(n); f.reserve(n); w.reserve(n); }
    void push(double ai, double bi, double fi, double wi) { a.push_back(ai); b.push_back(bi); f.push_back(fi); w.push_back(wi); }
};

// ---------------------------------------------------------------------------------------
// Models. prepare(p) fixes the parameters (false: infeasible); value() gives the model and
// optionally its gradient at one sample (false: overflow). Both clamp the base at zero
// before the power (eq. 2.1): there the value and the gradient are 0.

/// Thesis form: p = (Cx, Cz, N), f = base^N.
///   df/dCx = N base^(N-1) a,  df/dCz = N base^(N-1) b,  df/dN = base^N ln base.
struct PlainModel {
    double cx = 0, cz = 0, n = 0;
    bool prepare(const Vec3& p) {
        cx = p[0]; cz = p[1]; n = p[2];
        return std::isfinite(cx) && std::isfinite(cz) && std::isfinite(n);
    }
    bool value(double a, double b, double& f, Vec3* grad) const {
        const double base = cx * a + cz * b;
        if (!(base > 0.0)) {
            f = 0.0;
            if (grad) grad->setZero();
            return true;
        }
        const double lb = std::log(base);
        const double e = n * lb;
        if (e > kMaxExponent) return false;
        f = std::exp(e);
        if (grad) {
            const double e1 = (n - 1.0) * lb;
            if (e1 > kMaxExponent) return false;
            const double dbase = n * std::exp(e1); // N base^(N-1)
            *grad = Vec3(dbase * a, dbase * b, f * lb);
        }
        return true;
    }
};

/// Reparametrized: p = (eta, phi, L), N = e^L, g = cos(phi) a + sin(phi) b,
/// f = exp(eta + N ln(g / g_ref)), g_ref = g at the reference sample (a*, b*).
///   df/deta = f,  df/dphi = f N (g'/g - g_ref'/g_ref),  df/dL = f N ln(g / g_ref),
/// with g' = -sin(phi) a + cos(phi) b.
struct RobustModel {
    double ref_a = 0, ref_b = 1;
    double eta = 0, c = 0, s = 0, n = 1, log_gref = 0, dref = 0;
    bool prepare(const Vec3& p) {
        if (!p.allFinite()) return false;
        eta = p[0];
        c = std::cos(p[1]);
        s = std::sin(p[1]);
        n = std::exp(p[2]);
        const double gref = c * ref_a + s * ref_b;
        if (!(gref > 1e-300)) return false; // the reference left the lobe: infeasible
        log_gref = std::log(gref);
        dref = (-s * ref_a + c * ref_b) / gref;
        return std::isfinite(n);
    }
    bool value(double a, double b, double& f, Vec3* grad) const {
        const double g = c * a + s * b;
        if (!(g > 0.0)) {
            f = 0.0;
            if (grad) grad->setZero();
            return true;
        }
        const double l = std::log(g) - log_gref;
        const double e = eta + n * l;
        if (e > kMaxExponent) return false;
        f = std::exp(e);
        if (grad) *grad = Vec3(f, f * n * ((-s * a + c * b) / g - dref), f * n * l);
        return true;
    }
    /// The thesis form of p (lafortune_fit.h): |C| = exp(eta / N) / g_ref.
    [[nodiscard]] Vec3 thesis(const Vec3& p) const {
        const double nn = std::exp(p[2]);
        const double gref = std::cos(p[1]) * ref_a + std::sin(p[1]) * ref_b;
        const double mag = std::exp(p[0] / nn) / gref;
        return {mag * std::cos(p[1]), mag * std::sin(p[1]), nn};
    }
};

struct Eval {
    bool ok = false;
    double cost = kInf;
    Mat3 jtj = Mat3::Zero();
    Vec3 jtr = Vec3::Zero();
};

/// Weighted cost sum w (model - f)^2 and, optionally, J^T J and J^T r. A censored sample
/// (f >= saturation) has residual min(0, model - saturation) and no gradient where it is 0.
template <class Model>
Eval evaluate(const Model& model, const Data& d, bool jacobian) {
    Eval out;
    double cost = 0.0;
    Mat3 jtj = Mat3::Zero();
    Vec3 jtr = Vec3::Zero();
    Vec3 grad;
    const std::size_t m = d.size();
    for (std::size_t i = 0; i < m; ++i) {
        double f = 0.0;
        if (!model.value(d.a[i], d.b[i], f, jacobian ? &grad : nullptr)) return out;
        double target = d.f[i];
        if (target >= d.saturation) {
            if (f >= d.saturation) continue; // consistent with the clipped value
            target = d.saturation;
        }
        const double r = f - target;
        cost += d.w[i] * r * r;
        if (jacobian) {
            if (f == 0.0) continue;
            jtj.selfadjointView<Eigen::Lower>().rankUpdate(grad, d.w[i]);
            jtr += (d.w[i] * r) * grad;
        }
    }
    if (!std::isfinite(cost)) return out;
    out.ok = true;
    out.cost = cost;
    if (jacobian) {
        out.jtj = jtj.selfadjointView<Eigen::Lower>();
        out.jtr = jtr;
        if (!out.jtj.allFinite() || !out.jtr.allFinite()) out.ok = false;
    }
    return out;
}

/// Closed-form height for the robust model at fixed (phi, L): the model is A q_i with
/// q_i = (g_i / g_ref)^N, so A = sum w f q / sum w q^2 (weighted linear least squares;
/// censored samples enter with their clip level). Computed with q scaled by its maximum
/// so that N = 1e5 neither overflows nor underflows. Returns false if there is no
/// positive height (the lobe does not overlap the data, or the data are not positive there).
bool solve_height(RobustModel& model, const Data& d, Vec3& p) {
    Vec3 q = p;
    q[0] = 0.0;
    if (!model.prepare(q)) return false;
    // One pass, rescaling the sums whenever a larger exponent appears.
    double max_e = -kInf, num = 0.0, den = 0.0;
    for (std::size_t i = 0; i < d.size(); ++i) {
        const double g = model.c * d.a[i] + model.s * d.b[i];
        if (!(g > 0.0)) continue;
        const double e = model.n * (std::log(g) - model.log_gref);
        if (e > max_e) {
            const double k = std::isfinite(max_e) ? std::exp(max_e - e) : 0.0;
            num *= k;
            den *= k * k;
            max_e = e;
        }
        const double qi = std::exp(e - max_e);
        const double fi = std::min(d.f[i], d.saturation);
        num += d.w[i] * fi * qi;
        den += d.w[i] * qi * qi;
    }
    if (!std::isfinite(max_e) || !(num > 0.0) || !(den > 0.0)) return false;
    p[0] = std::log(num / den) - max_e;
    return std::isfinite(p[0]);
}

struct LmResult {
    Vec3 p = Vec3::Zero();
    double cost = kInf;
    std::uint32_t iterations = 0;
    bool converged = false;
    bool finite = false; ///< the start was evaluable
    std::string stop;
};

struct LmSettings {
    std::uint32_t max_iterations = 200;
    double ftol = 1e-12, xtol = 1e-10, gtol = 1e-14;
    bool bounded = false;
    double min_l = 0, max_l = 0; // bounds on p[2] when bounded
};

/// Levenberg-Marquardt (Madsen et al. 2004, alg. 3.16) on a 3-parameter model;
/// `refine(model, p, cost)` may improve an accepted point of cost `cost` (the robust model
/// re-solves its height) and must not increase the cost.
template <class Model, class Refine>
LmResult levenberg_marquardt(Model model, const Data& d, Vec3 p, const LmSettings& s, Refine refine) {
    LmResult res;
    res.p = p;
    if (!model.prepare(p)) {
        res.stop = "the start point is not feasible";
        return res;
    }
    Eval cur = evaluate(model, d, true);
    if (!cur.ok) {
        res.stop = "the model is not finite at the start point";
        return res;
    }
    res.finite = true;
    res.cost = cur.cost;
    const double cost_floor = 1e-30 * std::max(1.0, cur.cost);
    double lambda = 1e-3;
    double nu = 2.0;
    for (std::uint32_t it = 0; it < s.max_iterations; ++it) {
        res.iterations = it + 1;
        if (cur.cost <= cost_floor) {
            res.converged = true;
            res.stop = "cost reached zero";
            return res;
        }
        if (cur.jtr.cwiseAbs().maxCoeff() <= s.gtol * cur.cost) {
            res.converged = true;
            res.stop = "gradient below tolerance";
            return res;
        }
        Vec3 diag = cur.jtj.diagonal();
        const double dmax = std::max(diag.maxCoeff(), 1e-300);
        diag = diag.cwiseMax(1e-12 * dmax);
        bool accepted = false;
        while (!accepted) {
            Mat3 a = cur.jtj;
            a.diagonal() += lambda * diag;
            const Vec3 step = a.ldlt().solve(-cur.jtr);
            Vec3 pn = p + step;
            if (s.bounded) pn[2] = std::clamp(pn[2], s.min_l, s.max_l);
            const Vec3 delta = pn - p;
            const double predicted = -delta.dot(cur.jtr) + lambda * delta.dot(diag.cwiseProduct(delta));
            Eval next;
            if (step.allFinite() && model.prepare(pn)) next = evaluate(model, d, false);
            const double gain = next.ok ? (cur.cost - next.cost) / std::max(predicted, 1e-300) : -1.0;
            if (next.ok && next.cost < cur.cost && gain > 0.0) {
                accepted = true;
                refine(model, pn, next.cost);
                model.prepare(pn);
                Eval full = evaluate(model, d, true);
                if (!full.ok) { // cannot happen after a finite cost, but never trust it
                    res.stop = "the Jacobian is not finite";
                    return res;
                }
                const double decrease = cur.cost - full.cost;
                const double rel_step = delta.norm() / (p.norm() + s.xtol);
                p = pn;
                cur = full;
                res.p = p;
                res.cost = cur.cost;
                lambda *= std::max(1.0 / 3.0, 1.0 - std::pow(2.0 * gain - 1.0, 3));
                nu = 2.0;
                if (decrease <= s.ftol * cur.cost) {
                    res.converged = true;
                    res.stop = "relative decrease of the cost below tolerance";
                    return res;
                }
                if (rel_step <= s.xtol) {
                    res.converged = true;
                    res.stop = "relative step below tolerance";
                    return res;
                }
            } else {
                lambda *= nu;
                nu *= 2.0;
                if (lambda > 1e20 || !std::isfinite(lambda)) {
                    // No step along any damping decreases the cost: a (possibly flat) minimum.
                    res.converged = true;
                    res.stop = "no decreasing step (damping exhausted)";
                    return res;
                }
            }
        }
    }
    res.stop = format("iteration limit (%.0f) reached", s.max_iterations);
    return res;
}

struct NoRefine {
    template <class M>
    void operator()(M&, Vec3&, double) const {}
};

/// Reduces the samples of one channel to Data (weight > 0 only).
Data prepare_data(std::span<const LafortuneSample> samples, int channel) {
    Data d;
    d.reserve(samples.size());
    for (const LafortuneSample& s : samples) {
        const double w = s.weight;
        const double f = s.f[channel];
        if (!(w > 0.0) || !std::isfinite(w) || !std::isfinite(f)) continue;
        d.push(double(s.u.x) * s.v.x + double(s.u.y) * s.v.y, double(s.u.z) * s.v.z, f, w);
    }
    return d;
}

Data stride_subsample(const Data& d, std::size_t count) {
    Data out;
    out.saturation = d.saturation;
    const std::size_t m = d.size();
    out.reserve(count);
    for (std::size_t k = 0; k < count; ++k) {
        const std::size_t i = (k * m) / count;
        out.push(d.a[i], d.b[i], d.f[i], d.w[i]);
    }
    return out;
}

/// Fills standard errors, conditions, the peak test and the status from the final point,
/// in the thesis's (Cx, Cz, N).
void analyse(LafortuneChannelFit& out, const Data& d, const LafortuneFitOptions& o, const Mat3& internal_jtj,
             double theta_max, Mat3* covariance = nullptr, bool* has_covariance = nullptr) {
    PlainModel thesis;
    thesis.prepare(Vec3(out.cx, out.cz, out.n));
    const Eval e = evaluate(thesis, d, true);
    const double m = double(d.size());
    double weight_sum = 0.0;
    for (double w : d.w) weight_sum += w;
    if (e.ok) {
        out.cost = e.cost;
        out.rms = std::sqrt(e.cost / weight_sum);
    }
    // Standard errors: sigma^2 (J^T J)^-1, sigma^2 = SSE / (m - p) (e.g. Press et al.,
    // Numerical Recipes, 3rd ed., section 15.5 / 15.6).
    bool singular = !e.ok;
    double rel_error = 0.0;
    if (e.ok) {
        Eigen::SelfAdjointEigenSolver<Mat3> eig(e.jtj);
        const double lmin = eig.eigenvalues()[0], lmax = eig.eigenvalues()[2];
        out.condition = (lmin > 0.0 && lmax > 0.0) ? std::min(lmax / lmin, kSingularCondition) : kSingularCondition;
        if (lmin > 0.0 && lmax > 0.0 && lmax / lmin < 1e30) {
            const double sigma2 = e.cost / std::max(1.0, m - 3.0);
            const Mat3 cov = sigma2 * e.jtj.inverse();
            if (covariance) *covariance = cov;
            if (has_covariance) *has_covariance = true;
            out.std_error_cx = std::sqrt(std::max(0.0, cov(0, 0)));
            out.std_error_cz = std::sqrt(std::max(0.0, cov(1, 1)));
            out.std_error_n = std::sqrt(std::max(0.0, cov(2, 2)));
            const double mag = std::hypot(out.cx, out.cz);
            rel_error = std::max({out.std_error_cx / mag, out.std_error_cz / mag, out.std_error_n / out.n});
        } else {
            singular = true;
        }
    }
    {
        // Condition of the column-scaled J^T J of the fit's own parameters.
        const Vec3 dg = internal_jtj.diagonal();
        if ((dg.array() > 0.0).all()) {
            const Vec3 inv = dg.cwiseSqrt().cwiseInverse();
            const Mat3 scaled = inv.asDiagonal() * internal_jtj * inv.asDiagonal();
            Eigen::SelfAdjointEigenSolver<Mat3> eig(scaled);
            const double lmin = eig.eigenvalues()[0], lmax = eig.eigenvalues()[2];
            out.condition_internal =
                (lmin > 0.0) ? std::min(lmax / lmin, kSingularCondition) : kSingularCondition;
        } else {
            out.condition_internal = kSingularCondition;
        }
        if (out.condition_internal > o.max_condition) singular = true;
    }
    // How much of the lobe's peak the samples see: (base_max / base_peak)^N.
    double base_max = 0.0;
    for (std::size_t i = 0; i < d.size(); ++i) base_max = std::max(base_max, out.cx * d.a[i] + out.cz * d.b[i]);
    const double peak_base = std::max({0.0, out.cz, std::abs(out.cx) * std::pow(std::sin(theta_max), 2) +
                                                         out.cz * std::pow(std::cos(theta_max), 2)});
    out.peak_seen = (peak_base > 0.0 && base_max > 0.0)
                        ? std::min(1.0, std::exp(out.n * (std::log(base_max) - std::log(peak_base))))
                        : 0.0;

    if (out.status != LafortuneFitStatus::Converged) return; // keep the LM's verdict
    if (singular) {
        out.status = LafortuneFitStatus::Underdetermined;
        out.reason = format("J^T J is singular (condition %.3g; scaled, in the fit's parameters %.3g): the samples do "
                            "not separate Cx, Cz and N",
                            out.condition, out.condition_internal);
        return;
    }
    if (out.peak_seen < 0.5 && rel_error > o.max_relative_error_unseen_peak) {
        out.status = LafortuneFitStatus::Underdetermined;
        out.reason = format("no sample reaches half of the lobe's peak (the best sees %.3g of it), so its height "
                            "|C|^N and width N are extrapolated and not separable: relative standard error %.3g",
                            out.peak_seen, rel_error);
        return;
    }
    if (rel_error > o.max_relative_error) {
        out.status = LafortuneFitStatus::Underdetermined;
        out.reason = format("the parameters are poorly determined: relative standard error %.3g (Cx +- %.3g, "
                            "Cz +- %.3g, N +- %.3g)",
                            rel_error, out.std_error_cx, out.std_error_cz, out.std_error_n);
        return;
    }
    out.reason = format("converged: rms %.3g, relative standard error %.3g, peak seen %.3g", out.rms, rel_error,
                        out.peak_seen);
}

/// True (with a reason) if the fit explains no more than the noise: with a known sigma,
/// the cost decrease over the zero model is below 25 sigma^2 (five sigma on one sample);
/// unknown, the F statistic of the lobe (`params` parameters) against the zero model is
/// below 10. `strict` lowers both thresholds (4 sigma^2, F 2) for the early exit from the restarts.
bool no_energy(const Data& d, double cost, const LafortuneFitOptions& o, std::string& reason, bool strict = false,
               double params = 3.0) {
    double cost0 = 0.0, wsum = 0.0;
    for (std::size_t i = 0; i < d.size(); ++i) {
        const double fi = std::min(d.f[i], d.saturation);
        cost0 += d.w[i] * fi * fi;
        wsum += d.w[i];
    }
    const double gain = cost0 - cost;
    const double m = double(d.size());
    if (o.noise_sigma > 0.0) {
        const double noise = o.noise_sigma * o.noise_sigma * (wsum / m); // one sample's weighted noise energy
        if (gain <= (strict ? 4.0 : 25.0) * noise) {
            reason = format("the lobe explains %.3g of weighted energy, below 25 sigma^2 = %.3g (sigma %.3g): no more "
                            "than the noise",
                            gain, 25.0 * noise, o.noise_sigma);
            return true;
        }
        return false;
    }
    const double dof = std::max(1.0, m - params);
    const double f_stat = cost > 0.0 ? (gain / params) / (cost / dof) : kInf;
    if (f_stat <= (strict ? 2.0 : 10.0)) {
        reason = format("the lobe is not significant against zero (F statistic %.3g <= 10; the residual rms %.3g is "
                        "the noise)",
                        f_stat, std::sqrt(cost / wsum));
        return true;
    }
    return false;
}

void sanitize(LafortuneChannelFit& out) {
    double* values[] = {&out.cx, &out.cz, &out.n, &out.std_error_cx, &out.std_error_cz, &out.std_error_n,
                        &out.cost, &out.rms, &out.condition, &out.condition_internal, &out.peak_seen,
                        &out.max_albedo, &out.light_view_spread_deg};
    bool bad = false;
    for (double* v : values) {
        if (!std::isfinite(*v)) {
            *v = 0.0;
            bad = true;
        }
    }
    if (bad && out.status != LafortuneFitStatus::NoSpecularEnergy) {
        out.status = LafortuneFitStatus::NotConverged;
        out.reason += " (a non-finite value was replaced by 0)";
    }
}

// ---------------------------------------------------------------------------------------
// After the free fit: is its lobe used, and the constrained fallback (lafortune_fit.h, top).

constexpr double kRadToDeg = 180.0 / std::numbers::pi;

/// One channel from the free fit to the fallback.
struct ChannelRun {
    int channel = 0;
    Data d;
    LafortuneChannelFit fit;
    bool energy_tested = false; ///< the free lobe's energy test ran (it found energy unless NoSpecularEnergy)
    bool fallback = false;      ///< the free lobe is not used: fit the constrained one
    std::string why;            ///< why the free lobe is not used
    Mat3 covariance = Mat3::Zero(); ///< of the free fit's (Cx, Cz, N)
    bool has_covariance = false;     ///< false: J^T J was singular
    Stopwatch clock;
};

/// Whether a directional albedo above 1 is what the samples say, not noise: ln(albedo) more
/// than 2 standard errors above 0, the standard error propagated from the parameters'
/// covariance through the gradient `g` of ln(albedo) (first order, e.g. Press et al.,
/// Numerical Recipes, 3rd ed., section 15.6).
template <class Vec, class Cov>
bool albedo_excess_significant(double albedo, const Vec& g, const Cov& cov, bool has_cov, double& std_error) {
    std_error = std::sqrt(std::max(0.0, g.dot(cov * g)));
    return has_cov && cov.allFinite() && std::log(albedo) > 2.0 * std_error;
}

/// The 5th, 50th and 95th weighted percentiles of the light-view angle acos(u.v) = acos(a + b)
/// (degrees), from a histogram of 0.1-degree bins over a stride subsample of at most
/// `max_samples` (0: all).
std::array<double, 3> light_view_angles(const Data& d, std::size_t max_samples) {
    constexpr int kBins = 1800;
    std::vector<double> hist(kBins, 0.0);
    double total = 0.0;
    const std::size_t stride = max_samples > 0 ? std::max<std::size_t>(1, d.size() / max_samples) : 1;
    for (std::size_t i = 0; i < d.size(); i += stride) {
        const double g = std::acos(std::clamp(d.a[i] + d.b[i], -1.0, 1.0)) * kRadToDeg;
        hist[std::size_t(std::clamp(int(g * 10.0), 0, kBins - 1))] += d.w[i];
        total += d.w[i];
    }
    std::array<double, 3> out{0.0, 0.0, 0.0};
    const double fractions[3] = {0.05, 0.5, 0.95};
    double acc = 0.0;
    std::size_t k = 0;
    for (int bin = 0; bin < kBins && k < 3; ++bin) {
        acc += hist[std::size_t(bin)];
        while (k < 3 && total > 0.0 && acc >= fractions[k] * total) out[k++] = (bin + 0.5) * 0.1;
    }
    return out;
}

/// Decides whether the robust free fit's lobe is used: it is not (run.fallback, run.why)
/// when underdetermined or not converged, or converged but seen at one light-view angle,
/// with its peak far outside the samples, or above the white-furnace bound with its height
/// extrapolated (lafortune_fit.h, top). NoSpecularEnergy and fewer than 4 samples stand.
void review_free_lobe(ChannelRun& run, const LafortuneFitOptions& o) {
    LafortuneChannelFit& f = run.fit;
    const std::array<double, 3> angles = light_view_angles(run.d, o.coarse_samples);
    f.light_view_spread_deg = angles[2] - angles[0];
    switch (f.status) {
    case LafortuneFitStatus::NoSpecularEnergy:
    case LafortuneFitStatus::Constrained: return;
    case LafortuneFitStatus::Underdetermined:
        if (run.d.size() < 4) return; // too few samples to test anything, the constrained lobe included
        [[fallthrough]];
    case LafortuneFitStatus::NotConverged:
        run.why = std::string("the free fit is ") + to_string(f.status) + " (" + f.reason + ")";
        run.fallback = o.constrained_fallback;
        return;
    case LafortuneFitStatus::Converged: break;
    }
    const std::string free_lobe = format("; the free fit gave Cx %.4g, Cz %.4g, N %.4g", f.cx, f.cz, f.n) +
                                  (f.cx > 0.0 ? " (retro-reflective)" : "");
    if (o.constrained_fallback) {
        if (f.light_view_spread_deg < o.min_light_view_spread_deg) {
            run.why = format("the samples see the lobe at one light-view angle (median %.1f deg, 5-95%% spread %.2g deg "
                             "< %.3g): the off-specular part Cx + Cz, which the light-view angle changes, is set only by "
                             "the model's exact shape, not by the data",
                             angles[1], f.light_view_spread_deg, o.min_light_view_spread_deg) +
                      free_lobe;
            run.fallback = true;
            return;
        }
        if (f.peak_seen * o.max_peak_ratio < 1.0) {
            run.why = format("the free lobe's peak is %.3g times the largest value it takes at any sample (more than "
                             "K = %.3g): its height is extrapolated far outside the samples",
                             f.peak_seen > 0.0 ? 1.0 / f.peak_seen : kInf, o.max_peak_ratio) +
                      free_lobe;
            run.fallback = true;
            return;
        }
    }
    // For a view v the lobe is a Phong lobe about w = C v, C = diag(Cx, Cx, Cz): f = |w|^N
    // max(0, u.w / |w|)^N, whose integral against u.n over the upper hemisphere is at most
    // |w|^N int max(0, u.w / |w|)^N du = |w|^N 2 pi / (N + 1). So the albedo is at most
    // max(|Cx|, |Cz|)^N 2 pi / (N + 1): below 1, the quadrature is not needed.
    const double bound = std::exp(f.n * std::log(std::max(std::abs(f.cx), std::abs(f.cz)))) * 2.0 * std::numbers::pi / (f.n + 1.0);
    if (!(bound > 1.0)) {
        f.max_albedo = bound;
        return;
    }
    double theta = 0.0;
    f.max_albedo = lafortune_max_albedo(f.cx, f.cz, f.n, &theta);
    if (!(f.max_albedo > 1.0)) return;
    // ln(albedo) at the outgoing angle theta is, to first order in the parameters, that of its
    // Phong form |w|^N 2 pi / (N + 2) cos(theta_w) with w = C v: the gradient of
    // N ln|w| - ln(N + 2), |w|^2 = Cx^2 sin^2 + Cz^2 cos^2 (the direction theta_w left out).
    const double s2 = std::pow(std::sin(theta / kRadToDeg), 2), c2 = 1.0 - s2;
    const double w2 = f.cx * f.cx * s2 + f.cz * f.cz * c2;
    const Vec3 g(f.n * f.cx * s2 / w2, f.n * f.cz * c2 / w2, 0.5 * std::log(w2) - 1.0 / (f.n + 2.0));
    double se = 0.0;
    const bool significant = albedo_excess_significant(f.max_albedo, g, run.covariance, run.has_covariance, se);
    if (o.constrained_fallback && o.white_furnace && !significant) {
        run.why = format("the free lobe's directional albedo reaches %.3g at %.3g deg from the normal, above the "
                         "white-furnace bound 1, but not by 2 standard errors (ln albedo %.3g +- %.3g): the samples "
                         "do not ask for the excess",
                         f.max_albedo, theta, std::log(f.max_albedo), se) +
                  free_lobe;
        run.fallback = true;
        return;
    }
    f.reason += format("; its directional albedo reaches %.3g at %.3g deg from the normal, above the white-furnace "
                       "bound 1 by more than 2 standard errors (ln albedo %.3g +- %.3g), kept: the samples ask for it "
                       "(the capture's radiometric scale, or a non-physical material)",
                       f.max_albedo, theta, std::log(f.max_albedo), se);
}

/// The constrained lobe's view of one channel: ln t, t = r.v = b - a (u mirrored about the
/// normal, dotted with v), -infinity where t <= 0 (outside every mirror lobe).
struct Mirror {
    const Data* d = nullptr;
    std::vector<double> lt;
    double lt_max = -kInf;
    bool bounded = false; ///< height bounded by the white-furnace bound
};

Mirror make_mirror(const Data& d) {
    Mirror m;
    m.d = &d;
    m.lt.resize(d.size());
    for (std::size_t i = 0; i < d.size(); ++i) {
        const double t = d.b[i] - d.a[i];
        m.lt[i] = t > 0.0 ? std::log(t) : -kInf;
        m.lt_max = std::max(m.lt_max, m.lt[i]);
    }
    return m;
}

/// The mirror lobe at exponent N: f = H t^N = h q with q = exp(N (ln t - ln t_max)) in
/// (0, 1] (so that N = 1e5 neither overflows nor underflows) and h = H t_max^N. The height
/// is linear: h = sum w f q / sum w q^2 (weighted least squares, clipped samples at their
/// clip level, as solve_height); bounded, H is at most (N + 2) / (2 pi), the white-furnace
/// bound of the Phong lobe (Lafortune and Willems 1994). The cost censors clipped samples
/// as evaluate() does.
struct MirrorFit {
    double h = 0.0;
    double cost = kInf;
};

MirrorFit mirror_fit(const Mirror& m, double n) {
    const Data& d = *m.d;
    MirrorFit r;
    if (std::isfinite(m.lt_max)) {
        double num = 0.0, den = 0.0;
        for (std::size_t i = 0; i < d.size(); ++i) {
            if (!std::isfinite(m.lt[i])) continue;
            const double q = std::exp(n * (m.lt[i] - m.lt_max));
            num += d.w[i] * std::min(d.f[i], d.saturation) * q;
            den += d.w[i] * q * q;
        }
        if (num > 0.0 && den > 0.0) r.h = num / den;
        if (m.bounded) r.h = std::min(r.h, (n + 2.0) / (2.0 * std::numbers::pi) * std::exp(n * m.lt_max));
    }
    double cost = 0.0;
    for (std::size_t i = 0; i < d.size(); ++i) {
        const double model = std::isfinite(m.lt[i]) ? r.h * std::exp(n * (m.lt[i] - m.lt_max)) : 0.0;
        double target = d.f[i];
        if (target >= d.saturation) {
            if (model >= d.saturation) continue;
            target = d.saturation;
        }
        cost += d.w[i] * (model - target) * (model - target);
    }
    r.cost = cost;
    return r;
}

/// The one exponent shared by the channels: a grid of 64 values of ln N over [ln min_n,
/// ln max_n] on stride subsamples, then golden-section search on all samples between the
/// best grid value's neighbours. Returns ln N; `evaluations` counts the cost evaluations.
double mirror_exponent(const std::vector<Mirror>& coarse, const std::vector<Mirror>& full, const LafortuneFitOptions& o,
                       std::uint32_t& evaluations) {
    const auto total = [&](const std::vector<Mirror>& ms, double l) {
        ++evaluations;
        double c = 0.0;
        for (const Mirror& m : ms) c += mirror_fit(m, std::exp(l)).cost;
        return c;
    };
    const double lo = std::log(o.min_n), hi = std::log(o.max_n);
    constexpr int kGrid = 64;
    const double step = (hi - lo) / (kGrid - 1);
    int best = 0;
    double best_cost = kInf;
    for (int k = 0; k < kGrid; ++k) {
        const double c = total(coarse, lo + k * step);
        if (c < best_cost) {
            best_cost = c;
            best = k;
        }
    }
    // Golden-section search (e.g. Press et al., Numerical Recipes, 3rd ed., section 10.2).
    const double g = (std::sqrt(5.0) - 1.0) / 2.0;
    double a = lo + std::max(0, best - 1) * step, b = lo + std::min(kGrid - 1, best + 1) * step;
    double x1 = b - g * (b - a), x2 = a + g * (b - a);
    double f1 = total(full, x1), f2 = total(full, x2);
    for (int it = 0; it < 60 && b - a > 1e-9; ++it) {
        if (f1 <= f2) {
            b = x2;
            x2 = x1;
            f2 = f1;
            x1 = b - g * (b - a);
            f1 = total(full, x1);
        } else {
            a = x1;
            x1 = x2;
            f1 = f2;
            x2 = a + g * (b - a);
            f2 = total(full, x2);
        }
    }
    return f1 <= f2 ? x1 : x2;
}

/// The mirror lobe of one channel at exponent N, in the thesis's form, with the covariance
/// of (Cz, N) (sigma^2 (J^T J)^-1 of this channel, N's coupling with the other channels left
/// out; not determined when singular): f = (Cz t)^N, df/dCz = N f / Cz, df/dN = f ln(Cz t).
struct MirrorResult {
    double cz = 0.0, n = 0.0, cost = 0.0, albedo = 0.0, peak_seen = 0.0, condition = kSingularCondition;
    Eigen::Matrix2d covariance = Eigen::Matrix2d::Zero();
    bool determined = false; ///< J^T J not singular
};

MirrorResult mirror_result(const Mirror& m, double n) {
    const Data& d = *m.d;
    const MirrorFit mf = mirror_fit(m, n);
    MirrorResult r;
    r.n = n;
    r.cost = mf.cost;
    if (!(mf.h > 0.0)) return r;
    const double log_height = std::log(mf.h) - n * m.lt_max; // ln H, H = Cz^N
    r.cz = std::exp(log_height / n);
    r.albedo = std::exp(log_height) * 2.0 * std::numbers::pi / (n + 2.0);
    r.peak_seen = std::exp(n * m.lt_max);
    Eigen::Matrix2d jtj = Eigen::Matrix2d::Zero();
    for (std::size_t i = 0; i < d.size(); ++i) {
        if (!std::isfinite(m.lt[i])) continue;
        const double v = mf.h * std::exp(n * (m.lt[i] - m.lt_max));
        if (d.f[i] >= d.saturation && v >= d.saturation) continue; // consistent with the clip: no gradient
        const Eigen::Vector2d gr(n * v / r.cz, v * (std::log(r.cz) + m.lt[i]));
        jtj += d.w[i] * gr * gr.transpose();
    }
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(jtj);
    const double lmin = eig.eigenvalues()[0], lmax = eig.eigenvalues()[1];
    if (!(lmin > 0.0) || !(lmax / lmin < 1e30) || !jtj.allFinite()) return r;
    r.condition = std::min(lmax / lmin, kSingularCondition);
    r.covariance = mf.cost / std::max(1.0, double(d.size()) - 2.0) * jtj.inverse();
    r.determined = true;
    return r;
}

/// The constrained fallback on the channels whose free lobe is not used: a mirror lobe
/// Cx = -Cz per channel, one N shared by all of them (lafortune_fit.h, top).
void fit_constrained(const std::vector<ChannelRun*>& runs, const LafortuneFitOptions& o) {
    if (runs.empty()) return;
    std::vector<Data> subs;
    subs.reserve(runs.size());
    std::vector<Mirror> full, coarse;
    for (ChannelRun* r : runs) {
        full.push_back(make_mirror(r->d));
        if (o.coarse_samples > 0 && r->d.size() > o.coarse_samples) {
            subs.push_back(stride_subsample(r->d, o.coarse_samples));
            coarse.push_back(make_mirror(subs.back()));
        } else {
            coarse.push_back(full.back());
        }
    }
    std::uint32_t evaluations = 0;
    double l = mirror_exponent(coarse, full, o, evaluations);
    // The white-furnace bound: a channel whose unbounded lobe exceeds it, not by 2 standard
    // errors of ln(albedo), is bounded, and the exponent searched again.
    std::vector<double> unbounded_albedo(runs.size(), 0.0), unbounded_se(runs.size(), 0.0);
    bool refit = false;
    for (std::size_t k = 0; k < runs.size(); ++k) {
        const MirrorResult mr = mirror_result(full[k], std::exp(l));
        if (!(mr.cz > 0.0) || !(mr.albedo > 1.0)) continue;
        // ln(albedo) = N ln Cz + ln(2 pi) - ln(N + 2): gradient (N / Cz, ln Cz - 1 / (N + 2)).
        const Eigen::Vector2d g(mr.n / mr.cz, std::log(mr.cz) - 1.0 / (mr.n + 2.0));
        if (o.white_furnace && !albedo_excess_significant(mr.albedo, g, mr.covariance, mr.determined, unbounded_se[k])) {
            unbounded_albedo[k] = mr.albedo;
            full[k].bounded = coarse[k].bounded = true;
            refit = true;
        }
    }
    if (refit) l = mirror_exponent(coarse, full, o, evaluations);

    const double n = std::exp(l);
    std::string shared;
    if (runs.size() > 1) {
        shared = ", one N shared by channels ";
        for (std::size_t k = 0; k < runs.size(); ++k) shared += std::string(k ? ", " : "") + "rgb"[runs[k]->channel];
    }
    for (std::size_t k = 0; k < runs.size(); ++k) {
        ChannelRun& run = *runs[k];
        LafortuneChannelFit& f = run.fit;
        const Data& d = run.d;
        const MirrorResult mr = mirror_result(full[k], n);
        f.iterations += evaluations;
        double wsum = 0.0;
        for (double w : d.w) wsum += w;

        std::string noise;
        const bool none = !(mr.cz > 0.0) || no_energy(d, mr.cost, o, noise, false, 2.0);
        if (none) {
            if (noise.empty()) noise = "the mirror lobe has no positive height at any sample";
            if (run.energy_tested) {
                f.status = LafortuneFitStatus::Underdetermined;
                f.reason = "the free lobe was not used (" + run.why + ") and the mirror lobe Cx = -Cz explains no "
                           "more than the noise (" + noise + "): the residual energy is not a lobe about the mirror direction";
            } else {
                f.status = LafortuneFitStatus::NoSpecularEnergy;
                f.reason = noise + "; the free lobe was not used: " + run.why;
            }
            continue;
        }
        const bool singular = !mr.determined;
        const double se_cz = std::sqrt(std::max(0.0, mr.covariance(0, 0)));
        const double se_n = std::sqrt(std::max(0.0, mr.covariance(1, 1)));
        const double rel = singular ? kInf : std::max(se_cz / mr.cz, se_n / n);
        if (singular || rel > o.max_relative_error) {
            f.status = LafortuneFitStatus::Underdetermined;
            f.reason = "the free lobe was not used (" + run.why + ") and the mirror lobe Cx = -Cz is not determined "
                       "either: " + (singular ? std::string("J^T J is singular")
                                              : format("relative standard error %.3g (Cz +- %.3g, N +- %.3g)", rel, se_cz, se_n));
            continue;
        }
        f.status = LafortuneFitStatus::Constrained;
        f.cx = -mr.cz;
        f.cz = mr.cz;
        f.n = n;
        f.std_error_cx = f.std_error_cz = se_cz;
        f.std_error_n = se_n;
        f.cost = mr.cost;
        f.rms = std::sqrt(mr.cost / wsum);
        f.condition = f.condition_internal = mr.condition;
        f.peak_seen = mr.peak_seen;
        f.max_albedo = mr.albedo;
        f.reason = "constrained to a mirror lobe (Cx = -Cz" + shared + "): the free lobe was not used: " + run.why +
                   format(". Mirror lobe: rms %.3g, relative standard error %.3g, peak seen %.3g, directional albedo "
                          "%.3g",
                          f.rms, rel, f.peak_seen, f.max_albedo);
        if (unbounded_albedo[k] > 0.0)
            f.reason += format("; unbounded, its directional albedo was %.3g, above the white-furnace bound 1 but not "
                               "by 2 standard errors (ln albedo %.3g +- %.3g): refitted with Cz^N 2 pi / (N + 2) <= 1 "
                               "(Lafortune and Willems 1994)",
                               unbounded_albedo[k], std::log(unbounded_albedo[k]), unbounded_se[k]);
        else if (f.max_albedo > 1.0)
            f.reason += "; above the white-furnace bound 1 by more than 2 standard errors, kept: the samples ask for it";
    }
}

void check_arguments(int channel, const LafortuneFitOptions& o) {
    if (channel < 0 || channel > 2) throw UsageError("fit_lafortune_channel: channel must be 0, 1 or 2");
    if (!(o.min_n > 0.0) || !(o.max_n >= o.min_n) || !std::isfinite(o.max_n))
        throw UsageError("fit_lafortune: need 0 < min_n <= max_n < infinity");
    if (!(o.max_peak_ratio >= 1.0) || !(o.min_light_view_spread_deg >= 0.0))
        throw UsageError("fit_lafortune: need max_peak_ratio >= 1 and min_light_view_spread_deg >= 0");
}

LafortuneChannelFit finish(ChannelRun& run) {
    sanitize(run.fit);
    run.fit.seconds = run.clock.seconds();
    return run.fit;
}

/// The free fit of one channel (robust or the thesis's plain recipe), then, for the robust
/// method, the review that decides whether its lobe is used (review_free_lobe).
ChannelRun fit_free(std::span<const LafortuneSample> samples, int channel, const LafortuneFitOptions& o) {
    check_arguments(channel, o);
    ChannelRun run;
    run.channel = channel;
    LafortuneChannelFit& out = run.fit;
    run.d = prepare_data(samples, channel);
    Data& d = run.d;
    out.samples = std::uint32_t(d.size());

    // The largest polar angle that both directions of a sample reach (for the peak test).
    double theta_max = 0.0;
    for (const LafortuneSample& s : samples) {
        if (!(s.weight > 0.0f)) continue;
        const double cz = std::min(std::abs(double(s.u.z)), std::abs(double(s.v.z)));
        theta_max = std::max(theta_max, std::acos(std::clamp(cz, 0.0, 1.0)));
    }

    const bool robust = o.method == LafortuneFitMethod::Robust;
    const auto review = [&] {
        if (robust) review_free_lobe(run, o);
    };
    if (d.size() < 4) {
        out.status = LafortuneFitStatus::Underdetermined;
        out.reason = format("only %.0f samples with weight > 0: the three parameters need at least 4 (and many more "
                            "to be trusted)",
                            double(d.size()));
        review();
        return run;
    }
    double fmax = -kInf;
    std::size_t ref = 0;
    for (std::size_t i = 0; i < d.size(); ++i)
        if (d.f[i] > fmax) { fmax = d.f[i]; ref = i; }
    if (!(fmax > 0.0)) {
        out.status = LafortuneFitStatus::NoSpecularEnergy;
        out.reason = "no sample has a positive value";
        review();
        return run;
    }

    if (robust) {
        // Clip level: given, or detected as a maximum that several samples share exactly.
        if (o.saturation > 0.0) {
            d.saturation = o.saturation;
        } else if (o.saturation < 0.0) {
            std::uint32_t at_max = 0;
            for (double f : d.f) at_max += (f >= fmax) ? 1u : 0u;
            if (at_max >= std::max(2u, o.clip_detect_count)) d.saturation = fmax;
        }
        for (double f : d.f) out.censored += (f >= d.saturation) ? 1u : 0u;
    }

    LmSettings lm;
    lm.max_iterations = o.max_iterations;
    lm.ftol = o.cost_tolerance;
    lm.xtol = o.step_tolerance;
    lm.gtol = o.gradient_tolerance;

    LmResult best;
    Mat3 internal_jtj = Mat3::Zero();
    if (!robust) {
        // Thesis section 3.2.2: LM in (Cx, Cz, N) from the given start, nothing else.
        PlainModel model;
        best = levenberg_marquardt(model, d, Vec3(o.start_cx, o.start_cz, o.start_n), lm, NoRefine{});
        out.iterations = best.iterations;
        out.cx = best.p[0];
        out.cz = best.p[1];
        out.n = best.p[2];
        if (best.finite && model.prepare(best.p)) internal_jtj = evaluate(model, d, true).jtj;
    } else {
        // Reference samples (the lobe's value is parametrized at one, lafortune_fit.h). A
        // reference must lie inside the lobe (g > 0 there), so a single outlier as the
        // brightest sample would confine the fit to lobes that contain it (e.g. Cx ~ 0 when
        // the outlier sits on the retro side). Candidates: the brightest sample, the
        // brightest on the mirror side (a < 0: where a Cx < 0 lobe lives, Cz < 0 included),
        // and the brightest on the retro side (a > 0: Cx > 0 lobes). Every start of every
        // candidate competes on cost.
        std::vector<std::size_t> refs{ref};
        {
            std::size_t mirror = d.size(), retro = d.size();
            for (std::size_t i = 0; i < d.size(); ++i) {
                if (d.a[i] < 0.0 && (mirror == d.size() || d.f[i] > d.f[mirror])) mirror = i;
                if (d.a[i] > 0.0 && (retro == d.size() || d.f[i] > d.f[retro])) retro = i;
            }
            for (std::size_t r : {mirror, retro})
                if (r < d.size() && d.f[r] > 0.0 && std::find(refs.begin(), refs.end(), r) == refs.end()) refs.push_back(r);
        }
        lm.bounded = true;
        lm.min_l = std::log(o.min_n);
        lm.max_l = std::log(o.max_n);
        const Data coarse = (o.coarse_samples > 0 && d.size() > o.coarse_samples)
                                ? stride_subsample(d, o.coarse_samples)
                                : Data{};
        const Data& work = coarse.size() > 0 ? coarse : d;
        auto refine = [&work](RobustModel& mdl, Vec3& p, double cost) {
            // Re-solve the height in closed form; keep it only if the cost (with censoring) drops.
            Vec3 q = p;
            if (!solve_height(mdl, work, q)) return;
            RobustModel b = mdl;
            if (!b.prepare(q)) return;
            const Eval eb = evaluate(b, work, false);
            if (eb.ok && eb.cost < cost) p = q;
        };

        // Starts: per reference, a log grid over N times a few shapes, plus the given start;
        // the height of each from the closed form. Shapes: the thesis's (-1, 1), Cz-dominant
        // and Cx-dominant specular, both negative (woodenpot-like), both positive (retro).
        std::vector<double> ns{1, 3, 10, 30, 100, 300, 1000, 3000, 10000};
        ns.push_back(o.start_n);
        const double phi0 = std::atan2(o.start_cz, o.start_cx);
        const double deg = std::numbers::pi / 180.0;
        const std::array<double, 7> phis{phi0, 115 * deg, 155 * deg, 170 * deg, 200 * deg, 225 * deg, 45 * deg};
        struct Start {
            RobustModel model;
            Vec3 p;
            double cost;
        };
        std::vector<Start> starts;
        const Data grid_sub = (o.grid_samples > 0 && work.size() > o.grid_samples)
                                  ? stride_subsample(work, o.grid_samples)
                                  : Data{};
        const Data& grid = grid_sub.size() > 0 ? grid_sub : work;
        for (std::size_t r : refs) {
            RobustModel model;
            model.ref_a = d.a[r];
            model.ref_b = d.b[r];
            for (double n0 : ns) {
                if (!(n0 > 0.0)) continue;
                for (double phi : phis) {
                    Vec3 p(0.0, phi, std::clamp(std::log(n0), lm.min_l, lm.max_l));
                    if (!solve_height(model, grid, p)) continue;
                    RobustModel mdl = model;
                    if (!mdl.prepare(p)) continue;
                    const Eval e = evaluate(mdl, grid, false);
                    if (e.ok) starts.push_back({model, p, e.cost});
                }
            }
        }
        if (starts.empty()) {
            out.status = LafortuneFitStatus::NoSpecularEnergy;
            out.reason = "no start lobe overlaps positive data (the closed-form height is never positive)";
            review();
            return run;
        }
        std::sort(starts.begin(), starts.end(), [](const Start& x, const Start& y) { return x.cost < y.cost; });
        const std::size_t runs = std::min<std::size_t>(starts.size(), std::size_t(o.restarts) + 1);
        RobustModel model = starts.front().model;
        for (std::size_t k = 0; k < runs; ++k) {
            if (&grid != &work) {
                Vec3 p = starts[k].p; // the height on the samples LM runs on
                if (solve_height(starts[k].model, work, p)) starts[k].p = p;
            }
            LmResult r = levenberg_marquardt(starts[k].model, work, starts[k].p, lm, refine);
            out.iterations += r.iterations;
            if (r.finite && (!best.finite || r.cost < best.cost)) {
                best = r;
                model = starts[k].model;
            }
            std::string ignored;
            if (k == 0 && best.finite && no_energy(work, best.cost, o, ignored, true)) break; // restarts cannot help
        }
        if (best.finite && coarse.size() > 0) {
            // Polish on all samples from the best coarse result (the height is a parameter of LM
            // too; its closed form is only needed far from the minimum).
            LmResult r = levenberg_marquardt(model, d, best.p, lm, NoRefine{});
            out.iterations += r.iterations;
            if (r.finite) best = r;
        }
        if (best.finite) {
            const Vec3 t = model.thesis(best.p);
            out.cx = t[0];
            out.cz = t[1];
            out.n = t[2];
            if (model.prepare(best.p)) internal_jtj = evaluate(model, d, true).jtj;
        }
    }

    if (!best.finite) {
        out.status = LafortuneFitStatus::NotConverged;
        out.reason = "LM could not start: " + best.stop;
        review();
        return run;
    }
    if (!std::isfinite(out.cx) || !std::isfinite(out.cz) || !std::isfinite(out.n)) {
        out.status = LafortuneFitStatus::NotConverged;
        out.reason = "the parameters became non-finite (" + best.stop + ")";
        out.cx = out.cz = out.n = 0.0;
        review();
        return run;
    }
    out.status = best.converged ? LafortuneFitStatus::Converged : LafortuneFitStatus::NotConverged;
    out.reason = best.stop;
    analyse(out, d, o, internal_jtj, theta_max, &run.covariance, &run.has_covariance);
    std::string why;
    if (no_energy(d, out.cost, o, why)) {
        out.status = LafortuneFitStatus::NoSpecularEnergy;
        out.reason = why;
    }
    if (!robust && out.status == LafortuneFitStatus::Converged && out.n <= 0.0) {
        out.status = LafortuneFitStatus::NotConverged;
        out.reason = format("converged to a non-physical N = %.3g", out.n);
    }
    run.energy_tested = true;
    review();
    return run;
}

} // namespace

const char* to_string(LafortuneFitStatus status) noexcept {
    switch (status) {
    case LafortuneFitStatus::Converged: return "converged";
    case LafortuneFitStatus::NotConverged: return "not converged";
    case LafortuneFitStatus::Underdetermined: return "underdetermined";
    case LafortuneFitStatus::NoSpecularEnergy: return "no specular energy";
    case LafortuneFitStatus::Constrained: return "constrained";
    }
    return "?";
}

const char* to_string(LafortuneFitMethod method) noexcept {
    switch (method) {
    case LafortuneFitMethod::Robust: return "robust";
    case LafortuneFitMethod::ThesisPlain: return "thesis-plain";
    }
    return "?";
}

double lafortune_reachable_peak(double cx, double cz, double n, double theta_max) noexcept {
    const double s2 = std::pow(std::sin(theta_max), 2);
    const double base = std::max({0.0, cz, std::abs(cx) * s2 + cz * (1.0 - s2)});
    return base > 0.0 ? std::pow(base, n) : 0.0;
}

double lafortune_max_albedo(double cx, double cz, double n, double* theta_deg) {
    if (theta_deg) *theta_deg = 0.0;
    if (!(n > 0.0) || !std::isfinite(cx) || !std::isfinite(cz) || !std::isfinite(n)) return 0.0;
    const int cells = std::clamp(int(std::ceil(3.0 * std::sqrt(n))), 32, 640);
    const SpecularModel model = LafortuneRgb{glm::vec3(float(cx), 0.0f, 0.0f), glm::vec3(float(cz), 0.0f, 0.0f),
                                             glm::vec3(float(n), 1.0f, 1.0f)};
    bool overflow = false;
    const auto albedo = [&](double t) {
        const double a = directional_albedo(model, glm::dvec3(0.0), std::cos(t * std::numbers::pi / 180.0), cells).x;
        if (!(a <= 1e300)) overflow = true; // overflow (or NaN): beyond any bound
        return overflow ? 1e300 : a;
    };
    // Every 5 degrees (and 88, 89.5), then golden-section search between the best one's
    // neighbours (Press et al., Numerical Recipes, 3rd ed., section 10.2): a narrow lobe's
    // albedo peaks within a few degrees.
    std::vector<double> ts;
    for (double t = 0.0; t <= 85.0; t += 5.0) ts.push_back(t);
    ts.push_back(88.0);
    ts.push_back(89.5);
    std::size_t k = 0;
    double best = -1.0;
    for (std::size_t i = 0; i < ts.size(); ++i) {
        const double a = albedo(ts[i]);
        if (a > best) {
            best = a;
            k = i;
        }
    }
    double at = ts[k];
    if (!overflow) {
        const double g = (std::sqrt(5.0) - 1.0) / 2.0;
        double lo = ts[k > 0 ? k - 1 : 0], hi = ts[std::min(k + 1, ts.size() - 1)];
        double x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo);
        double f1 = albedo(x1), f2 = albedo(x2);
        for (int it = 0; it < 14; ++it) {
            if (f1 >= f2) {
                hi = x2;
                x2 = x1;
                f2 = f1;
                x1 = hi - g * (hi - lo);
                f1 = albedo(x1);
            } else {
                lo = x1;
                x1 = x2;
                f1 = f2;
                x2 = lo + g * (hi - lo);
                f2 = albedo(x2);
            }
        }
        if (std::max(f1, f2) > best) {
            best = std::max(f1, f2);
            at = f1 >= f2 ? x1 : x2;
        }
    }
    if (theta_deg) *theta_deg = at;
    return best;
}

LafortuneChannelFit fit_lafortune_channel(std::span<const LafortuneSample> samples, int channel,
                                          const LafortuneFitOptions& o) {
    ChannelRun run = fit_free(samples, channel, o);
    if (run.fallback) fit_constrained({&run}, o);
    return finish(run);
}

LafortuneRgb LafortuneFitRgb::converged_lobe() const noexcept {
    LafortuneRgb l;
    for (int k = 0; k < 3; ++k)
        if (has_lobe(channel[k].status)) {
            l.cx[k] = static_cast<float>(channel[k].cx);
            l.cz[k] = static_cast<float>(channel[k].cz);
            l.n[k] = static_cast<float>(channel[k].n);
        }
    return l;
}

LafortuneFitRgb fit_lafortune(std::span<const LafortuneSample> samples, const LafortuneFitOptions& options) {
    std::array<ChannelRun, 3> runs;
    // The channels' free fits are independent: one worker each (the same runs for any count). With
    // more than one worker allowed, a thread a channel: three threads on two cores end after 1.5
    // channels' time, where two end after two.
    parallel_for(3, options.threads > 1 ? 3u : 1u, [&](std::size_t c) { runs[c] = fit_free(samples, static_cast<int>(c), options); });
    std::vector<ChannelRun*> fallback;
    for (ChannelRun& run : runs)
        if (run.fallback) fallback.push_back(&run);
    fit_constrained(fallback, options);
    LafortuneFitRgb out;
    for (int c = 0; c < 3; ++c) out.channel[c] = finish(runs[std::size_t(c)]);
    return out;
}

} // namespace specula
