// The albedo fitted to the train pixels through the renderer's atlas read (pixel_fit.h).
#include "refine/pixel_fit.h"

#include "core/error.h"
#include "core/parallel.h"
#include "core/timer.h"
#include "diffuse/lambert_solve_detail.h"
#include "material/material.h"
#include "shared/prelude.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <optional>
#include <string>

namespace specula {

namespace {

namespace f64 = shared::f64;

constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();

// One train pixel with an albedo: its atlas point's 4 texels (particles, kNone where none was
// solved) with their bilinear weights renormalised over the solved ones, its albedo and weight.
struct PixelDatum {
    std::array<std::uint32_t, 4> particle;
    std::array<float, 4> weight;
    glm::vec3 albedo;
    float w;
};

// What the ray through a pixel's centre hits: the atlas point (texel coordinates), the surface
// point and its interpolated normal.
struct PixelPoint {
    glm::vec2 texel{-1.0f};
    glm::vec3 x{0.0f};
    glm::vec3 n{0.0f};
};

} // namespace

AlbedoRefineResult fit_albedo_to_pixels(const Mesh& mesh, const RayScene& scene, const Atlas& atlas,
                                        std::span<const Particle> particles, const LambertInputs& in,
                                        const LambertOutputs& solve, const LambertOptions& o, const PixelFitOptions& fit,
                                        PixelFitStats* stats_out) {
    lambert_validate(in);
    if (solve.particles.size() != particles.size())
        throw Error("albedo pixel fit: the diffuse solution has " + std::to_string(solve.particles.size()) +
                    " particles, the particle set " + std::to_string(particles.size()));
    const unsigned threads = std::max(fit.threads, 1u);
    PixelFitStats stats;
    const Visibility& vis = *in.visibility;

    AlbedoRefineResult out;
    out.albedo.resize(particles.size(), glm::vec3(0.0f));
    out.valid.resize(particles.size(), 0);
    for (std::size_t p = 0; p < particles.size(); ++p)
        if (solve.particles[p].status & shared::kLambertOk) {
            out.albedo[p] = glm::vec3(solve.albedo(p));
            out.valid[p] = 1;
        }
    // The particle of each texel, where it has a solved one.
    std::vector<std::uint32_t> texel_particle(std::size_t(atlas.width) * atlas.height, kNone);
    for (std::size_t p = 0; p < particles.size(); ++p)
        if (out.valid[p]) texel_particle[std::size_t(particles[p].texel_y()) * atlas.width + particles[p].texel_x()] = std::uint32_t(p);

    const shared::MaterialGpu known = material_gpu(o.material);
    const double min_cos = static_cast<double>(o.min_light_cos);
    const double k_sigma = static_cast<double>(o.highlight_k) * static_cast<double>(o.noise_sigma);
    const double tau = static_cast<double>(o.highlight_tau);

    std::vector<PixelDatum> data;
    for (std::uint32_t vi = 0; vi < in.views.size(); ++vi) {
        const LambertView& view = in.views[vi];
        if (view.frames.empty()) continue;
        const Camera& cam = view.camera;
        const int w = cam.intrinsics.w, h = cam.intrinsics.h;
        Stopwatch sw;
        std::vector<PixelPoint> hits(std::size_t(w) * std::size_t(h));
        const glm::vec3 eye(cam.center());
        std::optional<PixelHits> cast;
        const PixelHits& view_hits =
            vi < fit.view_hits.size() ? fit.view_hits[vi] : cast.emplace(cast_pixel_hits(scene, cam, threads));
        if (!view_hits.fits(cam))
            throw Error("albedo pixel fit: view " + std::to_string(vi) + "'s pixel hits are not its camera's");
        parallel_for(static_cast<std::size_t>(h), threads, [&](std::size_t y) {
            for (int x = 0; x < w; ++x) {
                const std::size_t k = y * std::size_t(w) + std::size_t(x);
                const std::uint32_t triangle = view_hits.triangle[k];
                if (triangle == PixelHits::kMiss) continue;
                PixelPoint& ph = hits[k];
                const glm::dvec2 c0 = atlas.corner_texel(triangle, 0), c1 = atlas.corner_texel(triangle, 1),
                                 c2 = atlas.corner_texel(triangle, 2);
                const double u = view_hits.uv[k].x, v = view_hits.uv[k].y;
                ph.texel = glm::vec2((1.0 - u - v) * c0 + u * c1 + v * c2);
                const SurfacePoint sp = surface_point(mesh, triangle, glm::dvec2(u, v));
                ph.x = sp.position;
                ph.n = sp.normal;
            }
        });
        stats.ray_seconds += sw.seconds();
        const Stopwatch ss;
        // Rows of pixels in parallel, each row's data in order, then appended row by row.
        std::vector<std::vector<PixelDatum>> rows(static_cast<std::size_t>(h));
        std::vector<std::uint64_t> row_pixels(static_cast<std::size_t>(h), 0), row_samples(static_cast<std::size_t>(h), 0);
        parallel_for(static_cast<std::size_t>(h), threads, [&](std::size_t yy) {
            const int y = static_cast<int>(yy);
            std::vector<glm::dvec3> cs, es;
            std::vector<double> q, esum;
            std::vector<std::uint8_t> kept;
            for (int x = 0; x < w; ++x) {
                const PixelPoint& ph = hits[std::size_t(y) * std::size_t(w) + std::size_t(x)];
                if (ph.texel.x < 0.0f) continue;
                ++row_pixels[yy];
                // Not on a silhouette: every 8-neighbour shows the surface too.
                bool inner = x > 0 && y > 0 && x + 1 < w && y + 1 < h;
                for (int dy = -1; dy <= 1 && inner; ++dy)
                    for (int dx = -1; dx <= 1 && inner; ++dx)
                        inner = hits[std::size_t(y + dy) * std::size_t(w) + std::size_t(x + dx)].texel.x >= 0.0f;
                if (!inner) continue;
                // The atlas point's 4 texels, as the renderer reads them.
                const float fx = std::clamp(ph.texel.x - 0.5f, 0.0f, float(atlas.width - 1));
                const float fy = std::clamp(ph.texel.y - 0.5f, 0.0f, float(atlas.height - 1));
                const int x0 = int(fx), y0 = int(fy);
                const int x1 = std::min(x0 + 1, int(atlas.width) - 1), y1 = std::min(y0 + 1, int(atlas.height) - 1);
                const float ax = fx - float(x0), ay = fy - float(y0);
                PixelDatum d{};
                const int tx[4] = {x0, x1, x0, x1}, ty[4] = {y0, y0, y1, y1};
                const float tw[4] = {(1 - ax) * (1 - ay), ax * (1 - ay), (1 - ax) * ay, ax * ay};
                float wsum = 0.0f;
                for (int k = 0; k < 4; ++k) {
                    d.particle[std::size_t(k)] = texel_particle[std::size_t(ty[k]) * atlas.width + std::size_t(tx[k])];
                    d.weight[std::size_t(k)] = d.particle[std::size_t(k)] == kNone ? 0.0f : tw[k];
                    wsum += d.weight[std::size_t(k)];
                }
                if (!(wsum > 0.0f)) continue;
                for (float& wk : d.weight) wk /= wsum;
                const glm::dvec3 P(ph.x), n(ph.n);
                const glm::dvec3 vdir = glm::normalize(glm::dvec3(eye) - P);
                const double nv = glm::dot(n, vdir);
                if (!(nv > 0.0)) continue;
                cs.clear();
                es.clear();
                q.clear();
                esum.clear();
                for (std::uint32_t f : view.frames) {
                    // Lit: every texel particle this view sees is lit by the frame.
                    bool lit = true, any = false;
                    for (int k = 0; k < 4 && lit; ++k) {
                        const std::uint32_t p = d.particle[std::size_t(k)];
                        if (p == kNone || !vis.sees(p, vi)) continue;
                        any = true;
                        lit = vis.lights(p, f);
                    }
                    if (!any || !lit) continue;
                    const FrameImage& im = in.images[f];
                    const std::uint32_t fl = im.flags[std::size_t(y) * std::size_t(im.color.width) + std::size_t(x)];
                    if (fl & (shared::kLambertPixMissing | shared::kLambertPixOutside | shared::kLambertPixClipped)) continue;
                    const float* px = &im.color.pixels[im.color.index(x, y)];
                    const glm::dvec3 c(px[0], px[1], px[2]);
                    const double sat = static_cast<double>(std::isfinite(im.saturation) ? im.saturation : 3.0e38f);
                    if (!(std::isfinite(c.x) && std::isfinite(c.y) && std::isfinite(c.z))) continue;
                    if (c.x >= sat || c.y >= sat || c.z >= sat) continue;
                    const PointLight& light = in.lights[f];
                    const glm::dvec3 L = glm::dvec3(glm::vec3(light.position)) - P;
                    const double d2 = glm::dot(L, L);
                    const glm::dvec3 u = L / std::sqrt(d2);
                    const double cosl = glm::dot(n, u);
                    if (!(cosl >= min_cos)) continue;
                    const double kd = f64::material_diffuse_factor(known, cosl, nv);
                    if (!(kd > 0.0)) continue;
                    const glm::dvec3 E = glm::dvec3(glm::vec3(light.intensity)) * (cosl / d2);
                    cs.push_back(c - f64::material_specular(known, cosl, nv, glm::dot(u, vdir)) * E);
                    es.push_back(E * kd);
                    esum.push_back(es.back().x + es.back().y + es.back().z);
                    q.push_back((cs.back().x + cs.back().y + cs.back().z) / esum.back());
                }
                if (cs.empty()) continue;
                // The solve's band test on the channel sums (shared/lambert.h): highlights above,
                // shadow edges below.
                (void)detail::lambert_band_test(q, esum, tau, k_sigma, o.highlight_iterations, kept);
                glm::dvec3 num(0.0), den(0.0);
                double wsq = 0.0;
                std::uint64_t used = 0;
                for (std::size_t i = 0; i < cs.size(); ++i) {
                    if (!kept[i]) continue;
                    num += cs[i] * es[i];
                    den += es[i] * es[i];
                    const double eb = esum[i] / 3.0;
                    wsq += eb * eb;
                    ++used;
                }
                if (used == 0 || !(den.x > 0.0 && den.y > 0.0 && den.z > 0.0)) continue;
                d.albedo = glm::vec3(kPi * num / den);
                d.w = static_cast<float>(wsq);
                row_samples[yy] += used;
                rows[yy].push_back(d);
            }
        });
        for (std::size_t y = 0; y < rows.size(); ++y) {
            data.insert(data.end(), rows[y].begin(), rows[y].end());
            stats.pixels += row_pixels[y];
            stats.samples_used += row_samples[y];
        }
        stats.sample_seconds += ss.seconds();
    }
    stats.pixels_used = data.size();

    // Each particle's (datum, tap) entries, in datum order: the gather of the iterations.
    const Stopwatch fs;
    std::vector<std::uint64_t> first(particles.size() + 1, 0);
    for (const PixelDatum& d : data)
        for (int k = 0; k < 4; ++k)
            if (d.weight[std::size_t(k)] > 0.0f) ++first[d.particle[std::size_t(k)] + 1];
    for (std::size_t p = 0; p < particles.size(); ++p) first[p + 1] += first[p];
    std::vector<std::uint32_t> entry_datum(first.back());
    std::vector<float> entry_weight(first.back());
    {
        std::vector<std::uint64_t> next(first.begin(), first.end() - 1);
        for (std::size_t i = 0; i < data.size(); ++i)
            for (int k = 0; k < 4; ++k) {
                const float wk = data[i].weight[std::size_t(k)];
                if (!(wk > 0.0f)) continue;
                const std::uint64_t e = next[data[i].particle[std::size_t(k)]]++;
                entry_datum[e] = static_cast<std::uint32_t>(i);
                entry_weight[e] = wk * data[i].w;
            }
    }
    const std::vector<glm::vec3> a0 = out.albedo;
    // Each particle's data weight d_p, and its bounds: the least and the largest albedo of the
    // pixels that read it.
    std::vector<double> weight(particles.size(), 0.0);
    std::vector<glm::vec3> lo(particles.size()), hi(particles.size());
    parallel_for_chunks(particles.size(), threads, 4096, [&](unsigned, std::size_t b, std::size_t e) {
        for (std::size_t p = b; p < e; ++p) {
            glm::vec3 l(std::numeric_limits<float>::max()), h(0.0f);
            for (std::uint64_t k = first[p]; k < first[p + 1]; ++k) {
                weight[p] += double(entry_weight[k]);
                l = glm::min(l, data[entry_datum[k]].albedo);
                h = glm::max(h, data[entry_datum[k]].albedo);
            }
            lo[p] = glm::max(l, glm::vec3(0.0f));
            hi[p] = h;
        }
    });
    std::vector<glm::vec3> residual(data.size());
    const double mu = static_cast<double>(fit.prior);
    const auto residuals = [&] {
        parallel_for_chunks(data.size(), threads, 65536, [&](unsigned, std::size_t b, std::size_t e) {
            for (std::size_t i = b; i < e; ++i) {
                const PixelDatum& d = data[i];
                glm::vec3 pred(0.0f);
                for (int k = 0; k < 4; ++k)
                    if (d.weight[std::size_t(k)] > 0.0f) pred += d.weight[std::size_t(k)] * out.albedo[d.particle[std::size_t(k)]];
                residual[i] = d.albedo - pred;
            }
        });
        double rss = 0.0, ws = 0.0;
        for (std::size_t i = 0; i < data.size(); ++i) {
            rss += double(data[i].w) * glm::dot(glm::dvec3(residual[i]), glm::dvec3(residual[i])) / 3.0;
            ws += double(data[i].w);
        }
        return ws > 0.0 ? std::sqrt(rss / ws) : 0.0;
    };
    for (std::uint32_t it = 0; it < fit.iterations; ++it) {
        stats.rms.push_back(residuals());
        std::vector<glm::vec3> next = out.albedo;
        std::vector<double> change(particles.size(), 0.0);
        parallel_for_chunks(particles.size(), threads, 4096, [&](unsigned, std::size_t b, std::size_t e) {
            for (std::size_t p = b; p < e; ++p) {
                const double dp = weight[p];
                if (!(dp > 0.0)) continue;
                glm::dvec3 g(0.0);
                for (std::uint64_t k = first[p]; k < first[p + 1]; ++k)
                    g += double(entry_weight[k]) * glm::dvec3(residual[entry_datum[k]]);
                const glm::dvec3 step = (g - mu * dp * (glm::dvec3(out.albedo[p]) - glm::dvec3(a0[p]))) / ((1.0 + mu) * dp);
                next[p] = glm::clamp(glm::vec3(glm::dvec3(out.albedo[p]) + step), lo[p], hi[p]);
                change[p] = glm::dot(glm::abs(glm::dvec3(next[p]) - glm::dvec3(out.albedo[p])), glm::dvec3(1.0 / 3.0));
            }
        });
        AlbedoRefineRound round;
        double sum = 0.0;
        for (std::size_t p = 0; p < particles.size(); ++p)
            if (first[p] != first[p + 1]) {
                sum += change[p];
                ++round.corrected;
            }
        round.mean_abs_change = round.corrected > 0 ? sum / double(round.corrected) : 0.0;
        out.albedo = std::move(next);
        out.rounds.push_back(round);
    }
    stats.rms.push_back(residuals());
    stats.fit_seconds = fs.seconds();
    if (stats_out != nullptr) *stats_out = std::move(stats);
    return out;
}

} // namespace specula
