// The stiff-case suite of the Lafortune fit (see lafortune_fit_cases.h).
#include "specular/lafortune_fit_cases.h"

#include "core/format.h"
#include "core/timer.h"
#include "shared/lafortune.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>

namespace specula {

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

/// Eq. 2.1 with rho_d = 0, as in shaders/shared/lafortune.h, in double so that the
/// truth of an N = 1e4 lobe is exact to the float the sample stores.
double lobe(double cx, double cz, double n, const glm::vec3& u, const glm::vec3& v) {
    return shared::f64::lafortune_eval(cx, cz, n, glm::dvec3(u), glm::dvec3(v));
}

/// A unit vector at angle `theta` from `axis`, azimuth `phi` around it.
glm::dvec3 around(const glm::dvec3& axis, double theta, double phi) {
    const glm::dvec3 helper = std::abs(axis.z) < 0.9 ? glm::dvec3(0, 0, 1) : glm::dvec3(1, 0, 0);
    const glm::dvec3 t = glm::normalize(glm::cross(helper, axis));
    const glm::dvec3 b = glm::cross(axis, t);
    return glm::normalize(std::cos(theta) * axis + std::sin(theta) * (std::cos(phi) * t + std::sin(phi) * b));
}

class Sampler {
public:
    Sampler(const LafortuneFitCase& c) : m_case(c), m_rng(c.seed) {}

    /// One (u, v) pair for the case's sampling kind (TailOnly is filtered by the caller).
    void draw(glm::vec3& u, glm::vec3& v) {
        const bool grazing = m_case.sampling == CaseSampling::Grazing;
        const double cos_lo = grazing ? std::cos(88 * kDeg) : std::cos(75 * kDeg);
        const double cos_hi = grazing ? std::cos(70 * kDeg) : 1.0;
        for (;;) {
            const double ct = uniform(cos_lo, cos_hi);
            const double az = uniform(0.0, 2.0 * std::numbers::pi);
            const double st = std::sqrt(std::max(0.0, 1.0 - ct * ct));
            const glm::dvec3 vv(st * std::cos(az), st * std::sin(az), ct);
            glm::dvec3 uu;
            if (m_case.sampling == CaseSampling::RigNoHighlights || uniform(0.0, 1.0) < 0.8) {
                // Within 60 deg of the view, uniform on the spherical cap.
                const double cu = uniform(std::cos(60 * kDeg), 1.0);
                uu = around(vv, std::acos(cu), uniform(0.0, 2.0 * std::numbers::pi));
            } else {
                // Near the lobe's peak direction for this view: u along (Cx vx, Cx vy, Cz vz)
                // (the generalized mirror, Lafortune et al. 1997), lifted to 5 deg above the
                // horizon when it points below (Cz < 0: the peak is at grazing).
                glm::dvec3 p(m_case.cx * vv.x, m_case.cx * vv.y, m_case.cz * vv.z);
                const double pt = std::hypot(p.x, p.y);
                if (p.z < std::sin(5 * kDeg) * glm::length(p)) p.z = pt * std::tan(5 * kDeg);
                p = glm::normalize(p);
                const double angle = std::exp(uniform(std::log(0.01 * kDeg), std::log(20 * kDeg)));
                uu = around(p, angle, uniform(0.0, 2.0 * std::numbers::pi));
            }
            if (uu.z < 0.02) continue;
            if (grazing && (uu.z > cos_hi || uu.z < cos_lo)) continue;
            u = glm::vec3(glm::normalize(uu));
            v = glm::vec3(glm::normalize(vv));
            return;
        }
    }
    double uniform(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(m_rng); }
    double gauss() { return m_normal(m_rng); }

private:
    const LafortuneFitCase& m_case;
    std::mt19937_64 m_rng;
    std::normal_distribution<double> m_normal{0.0, 1.0};
};

double rel(double got, double truth) { return std::abs(got - truth) / std::max(std::abs(truth), 1e-12); }

double largest_true(const std::vector<LafortuneSample>& s, const LafortuneFitCase& c) {
    double m = 0.0;
    for (const LafortuneSample& x : s) m = std::max(m, lobe(c.cx, c.cz, c.n, x.u, x.v));
    return m;
}

} // namespace

std::vector<LafortuneFitCase> lafortune_fit_cases() {
    std::vector<LafortuneFitCase> cs;
    auto add = [&](LafortuneFitCase c) { cs.push_back(std::move(c)); };
    // Widths: N = 1 .. 1e4 on a specular lobe (Cx = -Cz); |C| so that the peak is 1 .. 150.
    add({.name = "N=1", .cx = -0.8, .cz = 0.8, .n = 1, .seed = 11});
    add({.name = "N=3", .cx = -1.1, .cz = 1.1, .n = 3, .seed = 12});
    add({.name = "N=10", .cx = -1.2, .cz = 1.2, .n = 10, .seed = 13});
    add({.name = "N=100", .cx = -1.03, .cz = 1.03, .n = 100, .seed = 14});
    add({.name = "N=1000", .cx = -1.004, .cz = 1.004, .n = 1000, .seed = 15});
    add({.name = "N=10000", .cx = -1.0005, .cz = 1.0005, .n = 10000, .seed = 16});
    // The thesis's fitted lobes (table 5.2), noise-free and with 1% noise.
    struct Preset {
        const char* name;
        double cx, cz, n;
    };
    const Preset presets[] = {{"pepsi", -0.8962, 0.7587, 10.1119},
                              {"cologne", -0.8874, 1.1162, 18.0888},
                              {"vase", -1.2127, 0.5653, 20.3645},
                              {"woodenpot (Cz<0)", -1.4299, -0.7763, 9.7362}};
    std::uint64_t seed = 21;
    for (const Preset& p : presets)
        add({.name = std::string("table5.2 ") + p.name, .cx = p.cx, .cz = p.cz, .n = p.n, .seed = seed++});
    for (const Preset& p : presets)
        add({.name = std::string("table5.2 ") + p.name + " 1%", .cx = p.cx, .cz = p.cz, .n = p.n, .noise = 0.01,
             .tol_c = 0.05, .tol_n = 0.10, .seed = seed++});
    // Off-specular: |Cx| != |Cz| (peak at normal incidence, or towards grazing).
    add({.name = "off-specular Cz>|Cx|", .cx = -0.95, .cz = 1.05, .n = 200, .seed = 31});
    add({.name = "off-specular |Cx|>Cz", .cx = -1.06, .cz = 0.98, .n = 100, .seed = 32});
    // Retro-reflective (Cx > 0): the lobe is around u = v.
    add({.name = "retro-reflective Cx>0", .cx = 1.05, .cz = 1.0, .n = 50, .seed = 33});
    add({.name = "retro-reflective, grazing only", .cx = 1.05, .cz = 1.0, .n = 50,
         .sampling = CaseSampling::Grazing, .seed = 34});
    // A very bright, very narrow lobe (peak 4.8e8): the start's height is off by 1e8.
    add({.name = "N=10000, peak 5e8", .cx = -1.002, .cz = 1.002, .n = 10000, .seed = 35});
    // Coverage.
    add({.name = "woodenpot, grazing only", .cx = -1.4299, .cz = -0.7763, .n = 9.7362,
         .sampling = CaseSampling::Grazing, .seed = 44});
    add({.name = "N=1000, no highlight samples", .cx = -1.004, .cz = 1.004, .n = 1000,
         .sampling = CaseSampling::RigNoHighlights, .expect = CaseExpect::RecoverOrUnderdetermined, .seed = 45});
    add({.name = "N=1000, no highlights, 1%", .cx = -1.004, .cz = 1.004, .n = 1000,
         .sampling = CaseSampling::RigNoHighlights, .noise = 0.01, .tol_c = 0.05, .tol_n = 0.10,
         .expect = CaseExpect::RecoverOrUnderdetermined, .seed = 46});
    add({.name = "N=10000, no highlights, 1%", .cx = -1.0005, .cz = 1.0005, .n = 10000,
         .sampling = CaseSampling::RigNoHighlights, .noise = 0.01, .tol_c = 0.05, .tol_n = 0.10,
         .expect = CaseExpect::RecoverOrUnderdetermined, .seed = 47});
    add({.name = "grazing only (70-88 deg)", .cx = -1.05, .cz = 1.05, .n = 30, .sampling = CaseSampling::Grazing,
         .seed = 41});
    add({.name = "tail only (<10% of peak)", .cx = -1.05, .cz = 1.05, .n = 30, .sampling = CaseSampling::TailOnly,
         .expect = CaseExpect::RecoverOrUnderdetermined, .seed = 42,
         .note = "noise-free tails still determine the lobe"});
    add({.name = "tail only, 5% noise", .cx = -1.05, .cz = 1.05, .n = 30, .sampling = CaseSampling::TailOnly,
         .noise = 0.05, .tol_c = 0.10, .tol_n = 0.25, .expect = CaseExpect::RecoverOrUnderdetermined, .seed = 43,
         .note = "noise is 5% of the largest (tail) value"});
    add({.name = "tail only (<1% of peak), 5% noise", .cx = -1.02, .cz = 1.02, .n = 100,
         .sampling = CaseSampling::TailOnly, .tail_fraction = 0.01, .noise = 0.05, .tol_c = 0.10, .tol_n = 0.25,
         .expect = CaseExpect::RecoverOrUnderdetermined, .seed = 48});
    add({.name = "tail only (<1%), 20% noise, 300", .cx = -1.02, .cz = 1.02, .n = 100, .samples = 300,
         .sampling = CaseSampling::TailOnly, .tail_fraction = 0.01, .noise = 0.20, .tol_c = 0.10, .tol_n = 0.25,
         .expect = CaseExpect::RecoverOrUnderdetermined, .seed = 49,
         .note = "the peak is 100x above anything seen: height and width are extrapolated"});
    // Noise.
    add({.name = "N=100 1% noise", .cx = -1.03, .cz = 1.03, .n = 100, .noise = 0.01, .tol_c = 0.05, .tol_n = 0.10,
         .seed = 51});
    add({.name = "N=100 5% noise", .cx = -1.03, .cz = 1.03, .n = 100, .noise = 0.05, .tol_c = 0.05, .tol_n = 0.10,
         .seed = 52});
    add({.name = "N=1000 5% noise", .cx = -1.004, .cz = 1.004, .n = 1000, .noise = 0.05, .tol_c = 0.05,
         .tol_n = 0.10, .seed = 53});
    add({.name = "N=10000 5% noise", .cx = -1.0005, .cz = 1.0005, .n = 10000, .noise = 0.05, .tol_c = 0.05,
         .tol_n = 0.10, .seed = 54});
    // Clipped highlights: values capped at 30% of the largest.
    add({.name = "clipped at 30%", .cx = -1.03, .cz = 1.03, .n = 100, .clip = 0.3, .seed = 61});
    add({.name = "clipped at 30%, 1% noise", .cx = -1.03, .cz = 1.03, .n = 100, .noise = 0.01, .clip = 0.3,
         .tol_c = 0.05, .tol_n = 0.10, .seed = 62});
    // Few samples.
    add({.name = "10 samples", .cx = -1.2, .cz = 1.2, .n = 10, .samples = 10,
         .expect = CaseExpect::RecoverOrUnderdetermined, .seed = 71});
    add({.name = "10 samples, 1% noise", .cx = -1.2, .cz = 1.2, .n = 10, .samples = 10, .noise = 0.01,
         .tol_c = 0.05, .tol_n = 0.10, .expect = CaseExpect::RecoverOrUnderdetermined, .seed = 72});
    add({.name = "3 samples", .cx = -1.2, .cz = 1.2, .n = 10, .samples = 3, .expect = CaseExpect::Underdetermined,
         .seed = 73});
    // No specular energy: a lobe of height 6e-6 under noise of sigma 0.01.
    add({.name = "noise only, sigma known", .cx = -0.3, .cz = 0.3, .n = 10, .noise_abs = 0.01, .tell_noise = true,
         .expect = CaseExpect::NoSpecularEnergy, .seed = 81});
    add({.name = "noise only, sigma unknown", .cx = -0.3, .cz = 0.3, .n = 10, .noise_abs = 0.01,
         .expect = CaseExpect::NoSpecularEnergy, .seed = 82});
    // Ten million samples (the fit runs on a 50k subsample, then polishes on all).
    add({.name = "10M samples, 1% noise", .cx = -1.03, .cz = 1.03, .n = 100, .samples = 10'000'000, .noise = 0.01,
         .tol_c = 0.02, .tol_n = 0.05, .compare_plain = false, .long_running = true, .seed = 91});
    return cs;
}

std::vector<LafortuneSample> make_case_samples(const LafortuneFitCase& c) {
    Sampler sampler(c);
    std::vector<LafortuneSample> out;
    out.reserve(c.samples);
    const double peak = lafortune_reachable_peak(c.cx, c.cz, c.n, 88 * kDeg);
    std::uint64_t tries = 0;
    while (out.size() < c.samples) {
        LafortuneSample s;
        sampler.draw(s.u, s.v);
        const double f = lobe(c.cx, c.cz, c.n, s.u, s.v);
        if (c.sampling == CaseSampling::TailOnly && f > c.tail_fraction * peak && ++tries < 1000 * c.samples) continue;
        s.f = glm::vec3(float(f));
        s.weight = s.u.z; // like the irradiance cosine (pipeline.md section 4): unequal weights
        out.push_back(s);
    }
    const double fmax = largest_true(out, c);
    const double sigma = c.noise * fmax + c.noise_abs;
    const double cap = c.clip > 0.0 ? c.clip * fmax : 0.0;
    for (LafortuneSample& s : out) {
        double f = s.f.x;
        if (sigma > 0.0) f += sigma * sampler.gauss();
        if (cap > 0.0) f = std::min(f, cap);
        s.f = glm::vec3(float(f));
    }
    return out;
}

LafortuneFitOptions case_options(const LafortuneFitCase& c, LafortuneFitMethod method,
                                 const std::vector<LafortuneSample>& samples) {
    LafortuneFitOptions o;
    o.method = method;
    if (c.tell_noise) o.noise_sigma = c.noise * largest_true(samples, c) + c.noise_abs;
    return o;
}

bool case_recovered(const LafortuneFitCase& c, const LafortuneChannelFit& f) {
    return rel(f.cx, c.cx) <= c.tol_c && rel(f.cz, c.cz) <= c.tol_c && rel(f.n, c.n) <= c.tol_n;
}

std::string case_verdict(const LafortuneFitCase& c, const LafortuneChannelFit& f) {
    if (!std::isfinite(f.cx) || !std::isfinite(f.cz) || !std::isfinite(f.n) || !std::isfinite(f.cost))
        return "NaN/inf";
    if (f.status != LafortuneFitStatus::Converged) {
        const bool lobe_there = c.expect == CaseExpect::Recover;
        const bool honest = case_pass(c, f) || (f.status == LafortuneFitStatus::NotConverged && !lobe_there);
        return std::string(to_string(f.status)) + (honest ? "" : " (false: the lobe is recoverable)");
    }
    if (case_recovered(c, f)) return "recovered";
    return format_text("wrong (dCx %+.0f%% dCz %+.0f%% dN %+.0f%%)", 100 * (f.cx - c.cx) / std::abs(c.cx),
               100 * (f.cz - c.cz) / std::abs(c.cz), 100 * (f.n - c.n) / c.n);
}

bool case_pass(const LafortuneFitCase& c, const LafortuneChannelFit& f) {
    if (!std::isfinite(f.cx) || !std::isfinite(f.cz) || !std::isfinite(f.n)) return false;
    switch (f.status) {
    case LafortuneFitStatus::Converged:
        return (c.expect == CaseExpect::Recover || c.expect == CaseExpect::RecoverOrUnderdetermined) &&
               case_recovered(c, f);
    case LafortuneFitStatus::Underdetermined:
        return c.expect == CaseExpect::RecoverOrUnderdetermined || c.expect == CaseExpect::Underdetermined;
    case LafortuneFitStatus::NoSpecularEnergy: return c.expect == CaseExpect::NoSpecularEnergy;
    case LafortuneFitStatus::NotConverged: return false;
    }
    return false;
}

LafortuneCaseResult run_lafortune_case(const LafortuneFitCase& c, bool with_plain) {
    LafortuneCaseResult r;
    const Stopwatch clock;
    const std::vector<LafortuneSample> samples = make_case_samples(c);
    r.sample_seconds = clock.seconds();
    r.robust = fit_lafortune_channel(samples, 0, case_options(c, LafortuneFitMethod::Robust, samples));
    r.robust_pass = case_pass(c, r.robust);
    r.robust_verdict = case_verdict(c, r.robust);
    if (with_plain && c.compare_plain) {
        r.plain_run = true;
        r.plain = fit_lafortune_channel(samples, 0, case_options(c, LafortuneFitMethod::ThesisPlain, samples));
        r.plain_verdict = case_verdict(c, r.plain);
    }
    return r;
}

std::string lafortune_case_table_header() {
    char buf[512];
    std::snprintf(buf, sizeof buf, "%-34s %8s %-28s %-31s %5s %8s %-18s %-4s | %-31s %5s %s", "case", "samples",
                  "truth (Cx, Cz, N)", "recovered (Cx, Cz, N)", "iter", "time", "status", "pass",
                  "plain recipe (Cx, Cz, N)", "iter", "plain outcome");
    return buf;
}

std::string lafortune_case_table_row(const LafortuneFitCase& c, const LafortuneCaseResult& r) {
    auto triple = [](double x, double z, double n) {
        char b[64];
        std::snprintf(b, sizeof b, "%.4f %.4f %.5g", x, z, n);
        return std::string(b);
    };
    std::string status = r.robust_verdict;
    char buf[1024];
    const std::string samples = c.samples >= 1000000 ? format_text("%.0fM", double(c.samples) / 1e6) : format_text("%.0f", double(c.samples));
    const std::string plain = r.plain_run ? triple(r.plain.cx, r.plain.cz, r.plain.n) : std::string("-");
    const std::string plain_iter = r.plain_run ? format_text("%.0f", r.plain.iterations) : std::string("-");
    const std::string plain_verdict = r.plain_run ? r.plain_verdict : std::string("not run");
    std::snprintf(buf, sizeof buf, "%-34s %8s %-28s %-31s %5u %7.3fs %-18s %-4s | %-31s %5s %s", c.name.c_str(),
                  samples.c_str(), triple(c.cx, c.cz, c.n).c_str(),
                  triple(r.robust.cx, r.robust.cz, r.robust.n).c_str(), r.robust.iterations, r.robust.seconds,
                  status.c_str(), r.robust_pass ? "yes" : "NO", plain.c_str(), plain_iter.c_str(),
                  plain_verdict.c_str());
    return buf;
}

} // namespace specula
