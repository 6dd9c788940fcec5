// Where the masked error of a reconstruction lives, and what the albedo atlas could hold
// (run by hand, not a ctest; built with SPECULA_BUILD_BENCHMARKS):
//   psnr_diag CAPTURE BUNDLE.glb [--all] [--out DIR] [--no-shadows] [--shadow-map N]
//             [--truth PRESET | --truth-lobe PRESET | --oracle PRESET TPP [--sim bilinear|nearest [--lsq N] [--ibp N ...]]]
// For every test frame (--all: every frame), renders the bundle (both terms, and the
// specular term alone) and splits the masked squared error into pixel classes, first
// match wins:
//   silhouette   within 2 px of a pixel outside the mask
//   shadow edge  within 2 px of both a captured black (shadowed) and a lit object pixel
//   shadow       captured black (all channels 0) inside the mask
//   highlight    rendered specular term > 0.01 in some channel
//   texture      the rest (albedo resampling)
// and prints each class's share of the error and the frame's PSNR without that class's
// error. --out writes |error| x 16 images. Instead of the bundle (BUNDLE is then ignored):
//   --truth P          the preset's own mesh, texture and lobe: the ceiling the renderer allows
//                      (its shadow map against the captures' ray-traced shadows)
//   --truth-lobe P     the bundle with the preset's lobe: what the lobe's error costs
//   --oracle P TPP     the atlas reconstruct builds at TPP texels per pixel, each particle given
//                      the TRUE albedo at its surface point, and the true lobe: what the atlas can hold
//   --sim bilinear     ... each particle given instead what a noise-free diffuse solve reads: the
//                      best view's bilinear interpolation of exact albedo images (one ray per pixel
//                      centre); "nearest": the pixel of any train view whose ray hits closest
//   --ibp N            ... then N rounds of back-projection, A += mean over seeing views (weights
//                      cos^--ibp-power, default 1; --ibp-best: the best view only) of the bilinear
//                      residual (albedo image - A as rendered), step --ibp-step (default 1): the
//                      simulation behind refine/albedo_refine.h
//   --lsq N            ... then N Jacobi iterations of the least squares of the atlas's bilinear read at
//                      every train pixel's atlas point against that pixel's albedo (--lsq-step, default
//                      1; --lsq-reg, added to each texel's weight, default 0): the simulation behind
//                      refine/pixel_fit.h (applied before --ibp when both are given)
// --shadow-map N renders with an N x N shadow map (default 2048, the renderer's).
// --ray-shadows: render unshadowed and black out the pixels the ground-truth ray caster finds
// unlit (the captures' own shadows, exactly): what the reconstruction scores without the
// shadow map's edges.
// --display: the errors on display values (sRGB-encoded, clipped, 8-bit codes) instead of linear ones.
// --coated: the preset in the coated family (its eta and alpha) for --truth, --truth-lobe and --oracle.
// --write-bundle PATH: write the bundle rendered (e.g. the oracle's) for `specula evaluate`, which
// scores display values too.
#include "capture/capture.h"
#include "core/image.h"
#include "export/bundle.h"
#include "gpu/context.h"
#include "geometry/atlas.h"
#include "geometry/particles.h"
#include "geometry/ray_scene.h"
#include "render/renderer.h"
#include "synth/presets.h"
#include "synth/render.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <optional>
#include <string>

int main(int argc, char** argv) {
    using namespace specula;
    if (argc < 3) {
        std::fprintf(stderr, "usage: psnr_diag CAPTURE BUNDLE.glb [options] (see the source's first comment)\n");
        return 2;
    }
    std::string truth, out, oracle, truth_lobe;
    double oracle_tpp = 1.0;
    bool all = false, shadows = true;
    int shadow_map = 2048;
    int ibp_iterations = 0;
    int lsq_iterations = 0;
    double lsq_step = 1.0, lsq_reg = 0.0;
    float ibp_step = 1.0f;
    double ibp_weight_power = 1.0;
    bool ibp_best = false;
    bool coated = false;
    bool display = false;
    bool ray_shadows = false;
    std::string write_to;
    std::string sim; // with --oracle: estimate the albedo from simulated albedo images of the train views
                     // ("bilinear": best view, bilinear; "nearest": the pixel of any view whose centre ray
                     // hits closest to the particle)
    for (int i = 3; i < argc; ++i) {
        if (!std::strcmp(argv[i], "--truth") && i + 1 < argc) truth = argv[++i];
        else if (!std::strcmp(argv[i], "--oracle") && i + 2 < argc) { oracle = argv[++i]; oracle_tpp = std::atof(argv[++i]); }
        else if (!std::strcmp(argv[i], "--sim") && i + 1 < argc) sim = argv[++i];
        else if (!std::strcmp(argv[i], "--truth-lobe") && i + 1 < argc) truth_lobe = argv[++i];
        else if (!std::strcmp(argv[i], "--ibp") && i + 1 < argc) ibp_iterations = std::atoi(argv[++i]);
        else if (!std::strcmp(argv[i], "--lsq") && i + 1 < argc) lsq_iterations = std::atoi(argv[++i]);
        else if (!std::strcmp(argv[i], "--lsq-step") && i + 1 < argc) lsq_step = std::atof(argv[++i]);
        else if (!std::strcmp(argv[i], "--lsq-reg") && i + 1 < argc) lsq_reg = std::atof(argv[++i]);
        else if (!std::strcmp(argv[i], "--ibp-step") && i + 1 < argc) ibp_step = float(std::atof(argv[++i]));
        else if (!std::strcmp(argv[i], "--ibp-power") && i + 1 < argc) ibp_weight_power = std::atof(argv[++i]);
        else if (!std::strcmp(argv[i], "--ibp-best")) ibp_best = true;
        else if (!std::strcmp(argv[i], "--out") && i + 1 < argc) out = argv[++i];
        else if (!std::strcmp(argv[i], "--all")) all = true;
        else if (!std::strcmp(argv[i], "--shadow-map") && i + 1 < argc) shadow_map = std::atoi(argv[++i]);
        else if (!std::strcmp(argv[i], "--no-shadows")) shadows = false;
        else if (!std::strcmp(argv[i], "--coated")) coated = true;
        else if (!std::strcmp(argv[i], "--display")) display = true;
        else if (!std::strcmp(argv[i], "--ray-shadows")) ray_shadows = true;
        else if (!std::strcmp(argv[i], "--write-bundle") && i + 1 < argc) write_to = argv[++i];
    }
    const MaterialFamily family = coated ? MaterialFamily::Coated : MaterialFamily::Lafortune;
    const Capture cap = load_capture(argv[1]);
    Bundle b;
    if (!truth.empty()) {
        const synth::Preset p = synth::make_preset(truth, false, family);
        b.mesh = p.mesh;
        b.albedo = p.material.albedo_texture;
        b.material.specular = p.material.specular();
    } else if (!oracle.empty()) {
        // The atlas reconstruct builds (train cameras), every particle given the TRUE albedo
        // at its surface point: what the atlas itself can hold, with no estimation error.
        const synth::Preset p = synth::make_preset(oracle, false, family);
        std::vector<Camera> cams;
        for (const View& v : cap.views)
            for (const std::size_t f : v.frames)
                if (cap.desc.frames[f].split == Split::Train) { cams.push_back(v.camera); break; }
        AtlasOptions ao;
        ao.texels_per_pixel = oracle_tpp;
        const Atlas atlas = build_atlas(cap.mesh, cams, ao);
        const ParticleSet ps = build_particles(cap.mesh, atlas);
        Image img(int(atlas.width), int(atlas.height), 3, 0.0f);
        const auto truth_at = [&](std::uint32_t tri, float s1, float s2) {
            const glm::uvec3 t = p.mesh.triangles[tri];
            const float s0 = 1.0f - s1 - s2;
            const glm::vec2 uv = s0 * p.mesh.texcoords[t.x] + s1 * p.mesh.texcoords[t.y] + s2 * p.mesh.texcoords[t.z];
            return synth::sample_albedo(p.material.albedo_texture, uv);
        };
        if (sim.empty()) {
            for (const Particle& q : ps.particles) {
                const glm::vec3 a = truth_at(q.triangle, q.bary.x, q.bary.y);
                for (int k = 0; k < 3; ++k) img.at(int(q.texel_x()), int(q.texel_y()), k) = a[k];
            }
        } else {
            const RayScene scene(cap.mesh);
            struct Px { glm::vec3 hit; glm::vec3 albedo; glm::vec2 texel; bool ok = false; };
            std::vector<std::vector<Px>> views(cams.size());
            for (std::size_t v = 0; v < cams.size(); ++v) {
                const Camera& cam = cams[v];
                const int w = cam.intrinsics.w, h = cam.intrinsics.h;
                views[v].resize(std::size_t(w) * h);
                for (int y = 0; y < h; ++y)
                    for (int x = 0; x < w; ++x) {
                        const glm::dvec3 d = cam.ray_direction(x + 0.5, y + 0.5);
                        const auto hit = scene.intersect(glm::vec3(cam.center()), glm::vec3(d), 0.0f, 1e30f);
                        if (!hit) continue;
                        Px& px = views[v][std::size_t(y) * w + x];
                        px.hit = glm::vec3(cam.center() + double(hit->t) * d);
                        px.albedo = truth_at(hit->triangle, hit->u, hit->v);
                        const glm::dvec2 c0 = atlas.corner_texel(hit->triangle, 0), c1 = atlas.corner_texel(hit->triangle, 1),
                                         c2 = atlas.corner_texel(hit->triangle, 2);
                        px.texel = glm::vec2((1.0 - hit->u - hit->v) * c0 + double(hit->u) * c1 + double(hit->v) * c2);
                        px.ok = true;
                    }
            }
            std::size_t unset = 0;
            for (const Particle& q : ps.particles) {
                glm::vec3 best_a(0.0f);
                double best_score = -1e30;
                bool found = false;
                for (std::size_t v = 0; v < cams.size(); ++v) {
                    const Camera& cam = cams[v];
                    const glm::dvec3 pc = glm::dvec3(q.p());
                    const glm::dvec3 to_cam = cam.center() - pc;
                    const double cos_v = glm::dot(glm::dvec3(q.n()), glm::normalize(to_cam));
                    if (cos_v <= 0.05) continue;
                    const auto pr = cam.project(pc);
                    if (!pr || !cam.inside(*pr)) continue;
                    const double foot = glm::length(to_cam) / cam.intrinsics.fl_x; // world units per pixel
                    const int w = cam.intrinsics.w, h = cam.intrinsics.h;
                    const auto px_at = [&](int x, int y) -> const Px* {
                        if (x < 0 || y < 0 || x >= w || y >= h) return nullptr;
                        const Px& px = views[v][std::size_t(y) * w + x];
                        if (!px.ok || glm::length(glm::dvec3(px.hit) - pc) > 3.0 * foot / cos_v) return nullptr;
                        return &px;
                    };
                    if (sim == "bilinear") {
                        const double fx = pr->x - 0.5, fy = pr->y - 0.5;
                        const int x0 = int(std::floor(fx)), y0 = int(std::floor(fy));
                        const double ax = fx - x0, ay = fy - y0;
                        const Px *a00 = px_at(x0, y0), *a10 = px_at(x0 + 1, y0), *a01 = px_at(x0, y0 + 1), *a11 = px_at(x0 + 1, y0 + 1);
                        if (!a00 || !a10 || !a01 || !a11) continue;
                        if (cos_v <= best_score) continue;
                        best_score = cos_v;
                        best_a = glm::vec3(float((1 - ax) * (1 - ay)) * a00->albedo + float(ax * (1 - ay)) * a10->albedo +
                                           float((1 - ax) * ay) * a01->albedo + float(ax * ay) * a11->albedo);
                        found = true;
                    } else {
                        const int xn = int(std::floor(pr->x)), yn = int(std::floor(pr->y));
                        for (int dy = -1; dy <= 1; ++dy)
                            for (int dx = -1; dx <= 1; ++dx) {
                                const Px* a = px_at(xn + dx, yn + dy);
                                if (!a) continue;
                                const double score = -glm::length(glm::dvec3(a->hit) - pc);
                                if (score <= best_score) continue;
                                best_score = score;
                                best_a = a->albedo;
                                found = true;
                            }
                    }
                }
                if (!found) ++unset;
                for (int k = 0; k < 3; ++k) img.at(int(q.texel_x()), int(q.texel_y()), k) = best_a[k];
            }
            std::printf("sim %s: %zu particles without a value\n", sim.c_str(), unset);
            // Iterative back-projection: A += mean over seeing views (weight cos) of bilinear(I_v - render_v(A)).
            const auto atlas_bilinear = [&](const glm::vec2& t) {
                const float fx = t.x - 0.5f, fy = t.y - 0.5f;
                const int x0 = int(std::floor(fx)), y0 = int(std::floor(fy));
                const float ax = fx - float(x0), ay = fy - float(y0);
                const auto at = [&](int x, int y) {
                    x = std::clamp(x, 0, int(atlas.width) - 1);
                    y = std::clamp(y, 0, int(atlas.height) - 1);
                    return glm::vec3(img.at(x, y, 0), img.at(x, y, 1), img.at(x, y, 2));
                };
                return (1 - ax) * (1 - ay) * at(x0, y0) + ax * (1 - ay) * at(x0 + 1, y0) + (1 - ax) * ay * at(x0, y0 + 1) +
                       ax * ay * at(x0 + 1, y0 + 1);
            };
            // Least squares: min over A of sum_i (bilinear_A(t_i) - a_i)^2 over every train pixel i (its
            // atlas point t_i, its albedo a_i), by Jacobi iterations preconditioned by each texel's weight.
            for (int it = 0; it < lsq_iterations; ++it) {
                std::vector<glm::dvec3> g(std::size_t(atlas.width) * atlas.height, glm::dvec3(0.0));
                std::vector<double> dsum(g.size(), 0.0);
                double rss = 0.0, rn = 0.0;
                for (std::size_t v = 0; v < cams.size(); ++v)
                    for (const Px& px : views[v]) {
                        if (!px.ok) continue;
                        const glm::vec3 r = px.albedo - atlas_bilinear(px.texel);
                        rss += glm::dot(r, r); rn += 3;
                        const float fx = px.texel.x - 0.5f, fy = px.texel.y - 0.5f;
                        const int x0 = int(std::floor(fx)), y0 = int(std::floor(fy));
                        const float ax = fx - float(x0), ay = fy - float(y0);
                        for (int k = 0; k < 4; ++k) {
                            const int x = std::clamp(x0 + (k & 1), 0, int(atlas.width) - 1), y = std::clamp(y0 + (k >> 1), 0, int(atlas.height) - 1);
                            const double wk = ((k & 1) ? ax : 1 - ax) * ((k >> 1) ? ay : 1 - ay);
                            g[std::size_t(y) * atlas.width + x] += wk * glm::dvec3(r);
                            dsum[std::size_t(y) * atlas.width + x] += wk;
                        }
                    }
                std::printf("lsq %d: train albedo-image RMS %.5f\n", it, std::sqrt(rss / rn));
                for (int y = 0; y < int(atlas.height); ++y)
                    for (int x = 0; x < int(atlas.width); ++x) {
                        const std::size_t i = std::size_t(y) * atlas.width + x;
                        if (dsum[i] <= 0.0) continue;
                        for (int k = 0; k < 3; ++k) img.at(x, y, k) += float(lsq_step * g[i][k] / (dsum[i] + lsq_reg));
                    }
            }
            for (int it = 0; it < ibp_iterations; ++it) {
                std::vector<std::vector<glm::vec3>> resid(cams.size());
                double rss = 0.0, rn = 0.0;
                for (std::size_t v = 0; v < cams.size(); ++v) {
                    resid[v].assign(views[v].size(), glm::vec3(0.0f));
                    for (std::size_t i = 0; i < views[v].size(); ++i)
                        if (views[v][i].ok) {
                            resid[v][i] = views[v][i].albedo - atlas_bilinear(views[v][i].texel);
                            rss += glm::dot(resid[v][i], resid[v][i]);
                            rn += 3;
                        }
                }
                std::printf("ibp %d: train albedo-image RMS %.5f\n", it, std::sqrt(rss / rn));
                std::vector<glm::vec3> delta(ps.particles.size(), glm::vec3(0.0f));
                for (std::size_t pi = 0; pi < ps.particles.size(); ++pi) {
                    const Particle& q = ps.particles[pi];
                    const glm::dvec3 pc = glm::dvec3(q.p());
                    glm::dvec3 sum(0.0);
                    double wsum = 0.0, best_cos = -1.0;
                    glm::dvec3 best(0.0);
                    for (std::size_t v = 0; v < cams.size(); ++v) {
                        const Camera& cam = cams[v];
                        const glm::dvec3 to_cam = cam.center() - pc;
                        const double cos_v = glm::dot(glm::dvec3(q.n()), glm::normalize(to_cam));
                        if (cos_v <= 0.05) continue;
                        const auto pr = cam.project(pc);
                        if (!pr || !cam.inside(*pr)) continue;
                        const double foot = glm::length(to_cam) / cam.intrinsics.fl_x;
                        const int w = cam.intrinsics.w, h = cam.intrinsics.h;
                        const double fx = pr->x - 0.5, fy = pr->y - 0.5;
                        const int x0 = int(std::floor(fx)), y0 = int(std::floor(fy));
                        const double ax = fx - x0, ay = fy - y0;
                        glm::dvec3 val(0.0);
                        bool ok = true;
                        for (int k = 0; k < 4 && ok; ++k) {
                            const int x = x0 + (k & 1), y = y0 + (k >> 1);
                            if (x < 0 || y < 0 || x >= w || y >= h) { ok = false; break; }
                            const std::size_t i = std::size_t(y) * w + x;
                            const Px& px = views[v][i];
                            if (!px.ok || glm::length(glm::dvec3(px.hit) - pc) > 3.0 * foot / cos_v) { ok = false; break; }
                            const double wk = ((k & 1) ? ax : 1 - ax) * ((k >> 1) ? ay : 1 - ay);
                            val += wk * glm::dvec3(resid[v][i]);
                        }
                        if (!ok) continue;
                        const double wv = ibp_weight_power == 0 ? 1.0 : std::pow(cos_v, ibp_weight_power);
                        sum += wv * val;
                        wsum += wv;
                        if (cos_v > best_cos) { best_cos = cos_v; best = val; }
                    }
                    if (ibp_best) delta[pi] = glm::vec3(best);
                    else if (wsum > 0) delta[pi] = glm::vec3(sum / wsum);
                }
                for (std::size_t pi = 0; pi < ps.particles.size(); ++pi) {
                    const Particle& q = ps.particles[pi];
                    for (int k = 0; k < 3; ++k) img.at(int(q.texel_x()), int(q.texel_y()), k) += ibp_step * delta[pi][k];
                }
            }
        }
        std::printf("oracle atlas %ux%u at %.2f texels per pixel, %zu particles\n", atlas.width, atlas.height, oracle_tpp,
                    ps.particles.size());
        b = make_bundle(cap.mesh, atlas.corner_uv, img, Material{.specular = p.material.specular()});
    } else {
        b = read_bundle(argv[2]);
        if (!truth_lobe.empty()) b.material.specular = synth::make_preset(truth_lobe, false, family).material.specular();
    }
    if (!write_to.empty()) write_bundle(write_to, b);
    std::optional<synth::Renderer> caster; // --ray-shadows: a white Lambertian object, its scene built once
    if (ray_shadows) {
        synth::Material white;
        white.albedo_value = glm::vec3(1.0f);
        caster.emplace(cap.mesh, white);
    }
    gpu::Context ctx;
    const std::vector<glm::vec2> corner_uv = corner_uvs(b.mesh);
    render::Renderer r(ctx, render::Scene{.mesh = &b.mesh, .corner_uv = corner_uv, .albedo = &b.albedo,
                                         .material = {.specular = b.material.specular}},
                       render::Options{.shadow_map_size = std::uint32_t(shadow_map)});
    if (!out.empty()) std::filesystem::create_directories(out);
    constexpr int kClasses = 5;
    const char* names[kClasses] = {"silhouette", "shadow edge", "shadow", "highlight", "texture"};
    std::array<double, kClasses> tot_sse{}, tot_n{};
    double tot_all = 0.0, tot_pix = 0.0;
    std::printf("%5s %4s %5s %7s | %s\n", "frame", "view", "split", "PSNR", "per class: pixels, share of SSE, PSNR without it");
    for (std::size_t fi = 0; fi < cap.desc.frames.size(); ++fi) {
        const FrameDesc& fd = cap.desc.frames[fi];
        if (!all && fd.split != Split::Test) continue;
        const FrameImage& ci = cap.images[fi];
        const Image& c = ci.color;
        render::Frame both = r.render(fd.camera(), fd.light, {.mode = render::Mode::Both, .shadows = shadows && !ray_shadows});
        if (ray_shadows) {
            // The light's visibility as the captures have it: the ground-truth ray caster's lit
            // pixels (a white Lambertian render is > 0 exactly where a pixel's point is lit).
            const synth::RenderedFrame lit = caster->render(fd.camera(), fd.light);
            for (int y = 0; y < both.color.height; ++y)
                for (int x = 0; x < both.color.width; ++x)
                    if (!(lit.color.at(x, y, 0) > 0.0f))
                        for (int k = 0; k < 3; ++k) both.color.at(x, y, k) = 0.0f;
        }
        const render::Frame spec = r.render(fd.camera(), fd.light, {.mode = render::Mode::Specular, .shadows = shadows});
        const int w = c.width, h = c.height;
        auto in_mask = [&](int x, int y) {
            return x >= 0 && y >= 0 && x < w && y < h && (ci.flags[std::size_t(y) * w + x] & kOutsideMask) == 0;
        };
        auto black = [&](int x, int y) { return c.at(x, y, 0) == 0.0f && c.at(x, y, 1) == 0.0f && c.at(x, y, 2) == 0.0f; };
        std::array<double, kClasses> sse{}, n{};
        double all_sse = 0.0, pix = 0.0;
        Image err(w, h, 3, 0.0f);
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) {
                if (!in_mask(x, y)) continue;
                double e = 0.0;
                for (int k = 0; k < 3; ++k) {
                    const double rendered = std::min(both.color.at(x, y, k), ci.saturation);
                    // --display: both values sRGB-encoded, clipped and quantized to 8 bits, as
                    // `specula evaluate`'s display figures for an 8-bit sRGB capture
                    const auto shown = [&](double v) {
                        return display ? std::round(255.0 * linear_to_srgb(float(std::clamp(v, 0.0, 1.0)))) / 255.0 : v;
                    };
                    const double d = shown(rendered) - shown(c.at(x, y, k));
                    e += d * d;
                    err.at(x, y, k) = float(std::min(1.0, 16.0 * std::abs(d)));
                }
                bool sil = false, blk = false, lit = false;
                for (int dy = -2; dy <= 2; ++dy)
                    for (int dx = -2; dx <= 2; ++dx) {
                        if (!in_mask(x + dx, y + dy)) { sil = true; continue; }
                        (black(x + dx, y + dy) ? blk : lit) = true;
                    }
                int cls = 4;
                if (sil) cls = 0;
                else if (blk && lit) cls = 1;
                else if (black(x, y)) cls = 2;
                else if (std::max({spec.color.at(x, y, 0), spec.color.at(x, y, 1), spec.color.at(x, y, 2)}) > 0.01f) cls = 3;
                sse[cls] += e;
                n[cls] += 1;
                all_sse += e;
                pix += 1;
            }
        const auto psnr = [&](double s) { return s <= 0 ? 100.0 : 10.0 * std::log10(3.0 * pix / s); };
        std::printf("%5zu %4d %5s %7.2f |", fi, fd.view_index, fd.split == Split::Test ? "test" : "train", psnr(all_sse));
        for (int k = 0; k < kClasses; ++k)
            std::printf(" %s %6.0f %5.1f%% %6.2f;", names[k], n[k], 100.0 * sse[k] / all_sse, psnr(all_sse - sse[k]));
        std::printf("\n");
        for (int k = 0; k < kClasses; ++k) {
            tot_sse[k] += sse[k];
            tot_n[k] += n[k];
        }
        tot_all += all_sse;
        tot_pix += pix;
        if (!out.empty()) {
            char name[64];
            std::snprintf(name, sizeof name, "err_%04zu.png", fi);
            write_image(std::filesystem::path(out) / name, err, ColorSpace::Linear, 8);
        }
    }
    std::printf("all: RMS %.5f (PSNR of pooled MSE %.2f)\n", std::sqrt(tot_all / (3 * tot_pix)), 10 * std::log10(3 * tot_pix / tot_all));
    for (int k = 0; k < kClasses; ++k)
        std::printf("  %-12s %9.0f px (%5.2f%%)  %5.1f%% of SSE  class RMS %.5f\n", names[k], tot_n[k], 100 * tot_n[k] / tot_pix,
                    100 * tot_sse[k] / tot_all, tot_n[k] > 0 ? std::sqrt(tot_sse[k] / (3 * tot_n[k])) : 0.0);
    return 0;
}
