// Reference of the Lambert solve: the method of shared/lambert.h, step for step as
// shaders/diffuse/lambert_gather.comp, lambert_solve.comp and lambert_solve_combine.comp do it
// (the gather step's records are this pair step's `samples`), with the shared
// helpers instantiated in double (shared::f64) and every sum accumulated in double.
// Results are rounded to the float layouts the GPU writes.
#include "diffuse/lambert_solve.h"
#include "diffuse/lambert_solve_detail.h"
#include "diffuse/view_batches.h"

#include "core/error.h"
#include "core/parallel.h"
#include "core/timer.h"
#include "shared/prelude.h"
#include "shared/solve3.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>

namespace specula {

namespace {

namespace f64 = shared::f64;

struct Sample {
    glm::dvec3 c;   // bilinear pixel value
    glm::dvec3 e;   // E = I max(0, n.u) / d^2
    glm::dvec3 i;   // I
    glm::dvec3 a;   // u / d^2
    bool kept = false;
};

glm::dvec3 pixel(const FrameImage& im, int x, int y) {
    const float* p = &im.color.pixels[im.color.index(x, y)];
    return {p[0], p[1], p[2]};
}

bool finite3(const glm::dvec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

// Tap i of 4 (00, 10, 01, 11), as lambert_tap_index in lambert_sample.glsl.
glm::ivec2 tap(const f64::LambertTaps& t, int i) { return {(i & 1) == 0 ? t.x0 : t.x1, (i & 2) == 0 ? t.y0 : t.y1}; }

double lower_median(std::span<const double> values) { // rank (n - 1) / 2 in ascending order
    thread_local std::vector<double> v;
    v.assign(values.begin(), values.end());
    const std::size_t k = (v.size() - 1) / 2;
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
    return v[k];
}

// Lower median weighted by the used samples (shared/lambert.h): in (value, position) order,
// the element where the cumulative weight first reaches half of the total. Unit weights give
// the element of rank (n - 1) / 2, the plain lower median.
double weighted_lower_median(const std::vector<std::pair<double, std::uint32_t>>& v) {
    std::vector<std::size_t> order(v.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
        return v[a].first < v[b].first || (v[a].first == v[b].first && a < b);
    });
    std::uint64_t total = 0;
    for (const auto& e : v) total += e.second;
    std::uint64_t cum = 0;
    for (std::size_t i : order) {
        cum += v[i].second;
        if (2 * cum >= total) return v[i].first;
    }
    return v[order.back()].first;
}

} // namespace

namespace detail {

TapSurface lambert_tap_surface(const SurfaceMap& surface, const f64::LambertTaps& t) {
    TapSurface s;
    for (int i = 0; i < 4; ++i) {
        const glm::ivec2 q = tap(t, i);
        glm::vec3 x, nt;
        if (!surface.at(q.x, q.y, x, nt)) {
            s.missing = true;
            return s;
        }
        s.x[i] = glm::dvec3(x);
        s.n[i] = glm::dvec3(nt);
    }
    return s;
}

SampleRead lambert_read_sample(const FrameImage& im, const f64::LambertTaps& t, const TapSurface* surface,
                               const glm::dvec3& light, double e_particle, double min_cos) {
    SampleRead r;
    const std::size_t w = static_cast<std::size_t>(im.color.width);
    glm::dvec3 c[4];
    std::uint32_t fl = 0;
    bool finite = true;
    for (int i = 0; i < 4; ++i) {
        const glm::ivec2 q = tap(t, i);
        c[i] = pixel(im, q.x, q.y);
        fl |= im.flags[std::size_t(q.y) * w + std::size_t(q.x)];
        finite = finite && finite3(c[i]);
    }
    if ((fl & (shared::kLambertPixMissing | shared::kLambertPixOutside)) || !finite) {
        r.status = SampleStatus::Missing;
        return r;
    }
    const double sat = static_cast<double>(std::isfinite(im.saturation) ? im.saturation : 3.0e38f);
    bool clip = (fl & shared::kLambertPixClipped) != 0;
    for (const auto& v : c) clip = clip || v.x >= sat || v.y >= sat || v.z >= sat;
    if (clip) {
        r.status = SampleStatus::Clipped;
        return r;
    }
    if (surface != nullptr) {
        if (surface->missing) {
            r.status = SampleStatus::Missing;
            return r;
        }
        for (int i = 0; i < 4; ++i) {
            const double g = f64::lambert_tap_gain(surface->x[i], surface->n[i], light, e_particle, min_cos);
            if (g < 0.0) {
                r.status = SampleStatus::Grazing;
                return r;
            }
            c[i] *= g;
        }
    }
    r.c = f64::lambert_bilinear(t, c[0], c[1], c[2], c[3]);
    return r;
}

double lambert_band_test(std::span<const double> q, std::span<const double> es, double tau, double k_sigma,
                         std::uint32_t iterations, std::vector<std::uint8_t>& kept) {
    kept.assign(q.size(), 1);
    if (q.empty()) return 0.0;
    double est = lower_median(q);
    for (std::uint32_t it = 0; it < iterations; ++it) {
        bool changed = false;
        double num = 0.0, den = 0.0;
        for (std::size_t i = 0; i < q.size(); ++i) {
            const std::uint8_t keep =
                f64::lambert_keep(q[i], es[i], est, tau, k_sigma) && !f64::lambert_low(q[i], es[i], est, tau, k_sigma) ? 1 : 0;
            changed = changed || keep != kept[i];
            kept[i] = keep;
            if (keep) {
                num += q[i] * es[i] * es[i]; // = cs es
                den += es[i] * es[i];
            }
        }
        if (den > 0.0) est = num / den;
        if (!changed && it > 0) break;
    }
    return est;
}

shared::LambertPairResult lambert_pair_cpu(const LambertInputs& in, const LambertOptions& o, std::uint32_t particle,
                                           std::uint32_t view_index) {
    const Particle& part = in.particles[particle];
    const LambertView& view = in.views[view_index];
    const Visibility& vis = *in.visibility;
    const glm::dvec3 P(part.p());
    const glm::dvec3 n(part.n());
    const Intrinsics& k = view.camera.intrinsics;
    // The float camera the GPU gets: world_to_camera, centre, intrinsics and lights rounded to float.
    const glm::dmat4 w2c = glm::dmat4(glm::mat4(view.camera.world_to_camera));
    const glm::dvec3 xc(w2c * glm::dvec4(P, 1.0));
    const glm::dvec4 kf(glm::vec4(static_cast<float>(k.fl_x), static_cast<float>(k.fl_y), static_cast<float>(k.cx),
                                  static_cast<float>(k.cy)));
    const glm::dvec2 pos(kf.z + kf.x * xc.x / (-xc.z), kf.w - kf.y * xc.y / (-xc.z));
    const f64::LambertTaps t = f64::lambert_taps(pos, k.w, k.h);
    const glm::dvec3 center(glm::vec3(view.camera.center()));

    shared::LambertPairResult r{};
    r.view = view_index;
    const glm::dvec3 vdir = glm::normalize(center - P);
    const double nv = glm::dot(n, vdir);
    r.albedo = glm::vec4(0.0f, 0.0f, 0.0f, static_cast<float>(nv));
    r.normal = glm::vec4(glm::vec3(n), 0.0f);
    std::uint32_t shadow = 0, clipped = 0, missing = 0, grazing = 0;
    // Scratch kept per thread: a pair is a few microseconds, its allocations were a tenth of that.
    thread_local std::vector<Sample> samples;
    thread_local std::vector<double> q, es;
    samples.clear();
    q.clear();
    es.clear();
    const std::vector<SurfaceMap>* surfaces = tap_surfaces(in, o.tap_irradiance);
    const std::optional<TapSurface> surface =
        surfaces != nullptr ? std::optional(lambert_tap_surface((*surfaces)[view_index], t)) : std::nullopt;
    const shared::MaterialGpu known = material_gpu(o.material);
    for (std::uint32_t f : view.frames) {
        if (!vis.lights(particle, f)) { ++shadow; continue; }
        const PointLight& light = in.lights[f];
        const glm::dvec3 L = glm::dvec3(glm::vec3(light.position)) - P;
        const double d2 = glm::dot(L, L);
        const glm::dvec3 u = L / std::sqrt(d2);
        const double cosl = glm::dot(n, u);
        if (!(cosl >= static_cast<double>(o.min_light_cos))) { ++grazing; continue; }
        const SampleRead read = lambert_read_sample(in.images[f], t, surface ? &*surface : nullptr,
                                                    glm::dvec3(glm::vec3(light.position)), cosl / d2,
                                                    static_cast<double>(o.min_light_cos));
        if (read.status == SampleStatus::Missing) { ++missing; continue; }
        if (read.status == SampleStatus::Clipped) { ++clipped; continue; }
        if (read.status == SampleStatus::Grazing) { ++grazing; continue; }
        Sample s;
        s.i = glm::dvec3(glm::vec3(light.intensity));
        s.e = s.i * (cosl / d2);
        const double kd = f64::material_diffuse_factor(known, cosl, nv);
        if (!(kd > 0.0)) { ++grazing; continue; } // the known diffuse term is dark here: nothing to solve
        s.c = read.c - f64::material_specular(known, cosl, nv, glm::dot(u, vdir)) * s.e;
        s.e *= kd;
        s.a = (u / d2) * kd;
        samples.push_back(s);
    }

    // Highlights: robust fit on the channel sums (shared/lambert.h).
    std::size_t kept = 0;
    std::uint32_t low = 0;
    if (!samples.empty()) {
        for (const Sample& s : samples) {
            es.push_back(s.e.x + s.e.y + s.e.z);
            q.push_back((s.c.x + s.c.y + s.c.z) / es.back());
        }
        thread_local std::vector<std::uint8_t> keep;
        const double est = lambert_band_test(q, es, static_cast<double>(o.highlight_tau),
                                             static_cast<double>(o.highlight_k) * static_cast<double>(o.noise_sigma),
                                             o.highlight_iterations, keep);
        for (std::size_t i = 0; i < samples.size(); ++i) {
            samples[i].kept = keep[i] != 0;
            kept += samples[i].kept ? 1u : 0u;
            if (!samples[i].kept && q[i] < est) ++low;
        }
    }
    const std::uint32_t highlight = static_cast<std::uint32_t>(samples.size() - kept) - low;

    if (kept > 0) {
        r.status |= shared::kLambertPairHasSample;
        glm::dvec3 rho(0.0);
        bool solved = false;
        if (o.mode == LambertMode::Photometric) {
            if (kept >= shared::kLsq3MinRows) {
                std::array<f64::Lsq3Normal, 3> ne{f64::lsq3_normal_zero(), f64::lsq3_normal_zero(), f64::lsq3_normal_zero()};
                for (const Sample& s : samples)
                    if (s.kept)
                        for (int c = 0; c < 3; ++c) f64::lsq3_accumulate(ne[std::size_t(c)], s.i[c] * s.a, s.c[c], 1.0);
                bool ok = true;
                glm::dvec3 g[3];
                for (int c = 0; c < 3; ++c) {
                    const f64::Lsq3Solution sol = f64::lsq3_solve_normal(ne[std::size_t(c)]);
                    ok = ok && sol.status == shared::kLsq3Ok && sol.rcond >= static_cast<double>(o.min_rcond);
                    g[c] = sol.g;
                }
                const glm::dvec3 sum = g[0] + g[1] + g[2];
                const double len = glm::length(sum);
                if (ok && len > 0.0 && glm::dot(sum, n) > 0.0) {
                    const glm::dvec3 nr = sum / len;
                    rho = kPi * glm::dvec3(glm::length(g[0]), glm::length(g[1]), glm::length(g[2]));
                    r.normal = glm::vec4(glm::vec3(nr), static_cast<float>(f64::lambert_angle_deg(nr, n)));
                    r.status |= shared::kLambertPairPhotometric;
                    solved = true;
                }
            }
            if (!solved) r.status |= shared::kLambertPairFallback;
        }
        if (!solved) {
            glm::dvec3 num(0.0), den(0.0);
            for (const Sample& s : samples)
                if (s.kept) {
                    num += s.c * s.e;
                    den += s.e * s.e;
                }
            for (int c = 0; c < 3; ++c) rho[c] = den[c] > 0.0 ? kPi * num[c] / den[c] : 0.0;
        }
        r.albedo = glm::vec4(glm::vec3(rho), r.albedo.w);
    }
    r.used = static_cast<std::uint32_t>(kept);
    r.shadow = shadow;
    r.clipped = clipped;
    r.missing = missing;
    r.grazing = grazing;
    r.highlight = highlight;
    r.frames = static_cast<std::uint32_t>(view.frames.size());
    r.low = low;
    return r;
}

LambertParticleResult lambert_combine_cpu(std::span<const shared::LambertPairResult> pairs, const LambertOptions& o,
                                          const Particle& particle) {
    LambertParticleResult r{};
    r.albedo_best = glm::vec4(0.0f, 0.0f, 0.0f, -1.0f);
    r.albedo_robust = glm::vec4(0.0f);
    r.normal = glm::vec4(particle.n(), 0.0f);
    r.best_view = shared::kLambertNoView;
    r.views = static_cast<std::uint32_t>(pairs.size());
    std::vector<std::pair<double, std::uint32_t>> lum; // (luminance, used samples), in view order
    for (const auto& p : pairs) {
        r.rejected_shadow += p.shadow;
        r.rejected_clipped += p.clipped;
        r.rejected_missing += p.missing;
        r.rejected_grazing += p.grazing;
        r.rejected_highlight += p.highlight;
        r.rejected_low += p.low;
        if (p.status & shared::kLambertPairHasSample)
            lum.push_back({double(p.albedo.x) + double(p.albedo.y) + double(p.albedo.z), p.used});
    }
    if (pairs.empty()) {
        r.status = shared::kLambertNotSeen;
        return r;
    }
    if (lum.empty()) {
        r.status = shared::kLambertNoSample;
        return r;
    }
    const double ref = weighted_lower_median(lum);
    glm::dvec3 sum(0.0);
    double weight = 0.0;
    double best_cos = -2.0;
    std::uint32_t kept_views = 0;
    const shared::LambertPairResult* best = nullptr;
    for (const auto& p : pairs) {
        if (!(p.status & shared::kLambertPairHasSample)) continue;
        const double l = double(p.albedo.x) + double(p.albedo.y) + double(p.albedo.z);
        const std::uint32_t used = p.used;
        if (f64::lambert_view_outlier(l, ref, static_cast<double>(o.view_tau), static_cast<double>(o.view_abs))) {
            r.rejected_view += used;
            r.status |= shared::kLambertViewsRejected;
            continue;
        }
        ++kept_views;
        r.used += used;
        sum += double(used) * glm::dvec3(glm::vec3(p.albedo));
        weight += double(used);
        if (double(p.albedo.w) > best_cos) { // pairs come in view order: ties keep the lower index
            best_cos = double(p.albedo.w);
            best = &p;
        }
    }
    // ref is one of the kept views, so best != nullptr and weight > 0 (unless a value is not
    // finite: then the particle has no usable sample, never a crash or a NaN albedo).
    if (best == nullptr || !(weight > 0.0)) {
        r.status |= shared::kLambertNoSample; // as the shader's combine step
        return r;
    }
    r.status |= shared::kLambertOk;
    r.best_view = best->view;
    r.albedo_best = glm::vec4(glm::vec3(best->albedo), static_cast<float>(best->view));
    r.albedo_robust = glm::vec4(glm::vec3(sum / weight), static_cast<float>(kept_views));
    r.normal = best->normal;
    if (best->status & shared::kLambertPairFallback) r.status |= shared::kLambertFallback;
    return r;
}

} // namespace detail

LambertOutputs lambert_solve_cpu(const LambertInputs& in, const LambertOptions& options) {
    const Stopwatch sw;
    lambert_validate(in);
    const Visibility& vis = *in.visibility;
    LambertOutputs out;
    out.mode = options.mode;
    out.choice = options.choice;
    out.particles.resize(in.particles.size());
    // Particles are independent: each thread takes chunks of them (the result is the same for any
    // count). Within a chunk the pairs go view by view, so that neighbouring particles read
    // neighbouring pixels of the same frames (demo can: the 7 solves 6.8 -> 5.7 s), each into its
    // particle's slots (the views that see it, in view order); then each particle combines them.
    const std::size_t views = in.views.size();
    const auto seen = [&](std::size_t p, std::uint32_t v) { return !in.views[v].frames.empty() && vis.sees(p, v); };
    parallel_for_chunks(in.particles.size(), std::max(options.threads, 1u), 4096, [&](unsigned, std::size_t begin, std::size_t end) {
        thread_local std::vector<shared::LambertPairResult> pairs;
        thread_local std::vector<std::size_t> first, next; // per particle of the chunk: its first slot, its next free one
        first.assign(end - begin + 1, 0);
        for (std::size_t i = begin; i < end; ++i) {
            std::size_t k = 0;
            for (std::uint32_t v = 0; v < views; ++v) k += seen(i, v) ? 1u : 0u;
            first[i - begin + 1] = first[i - begin] + k;
        }
        pairs.resize(first.back());
        next.assign(first.begin(), first.end() - 1);
        for (std::uint32_t v = 0; v < views; ++v)
            for (std::size_t i = begin; i < end; ++i)
                if (seen(i, v)) pairs[next[i - begin]++] = detail::lambert_pair_cpu(in, options, static_cast<std::uint32_t>(i), v);
        for (std::size_t i = begin; i < end; ++i)
            out.particles[i] = detail::lambert_combine_cpu(
                std::span(pairs).subspan(first[i - begin], first[i - begin + 1] - first[i - begin]), options, in.particles[i]);
    });
    out.summary.seconds = sw.seconds();
    summarize(out);
    out.summary.tap_irradiance = tap_surfaces(in, options.tap_irradiance) != nullptr;
    return out;
}

} // namespace specula
