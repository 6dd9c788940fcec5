#include "diffuse_scene.h"

#include "core/timer.h"
#include "geometry/ray_scene.h"
#include "visibility/visibility.h"

#include <algorithm>
#include <cmath>

namespace specula::test {

namespace {

float quantize(float v, synth::ImageFormat format) {
    if (format == synth::ImageFormat::Exr) return v;
    const float levels = format == synth::ImageFormat::Png8 ? 255.0f : 65535.0f;
    const float s = linear_to_srgb(std::clamp(v, 0.0f, 1.0f));
    return srgb_to_linear(std::round(s * levels) / levels);
}

glm::vec2 particle_uv(const Mesh& mesh, const Particle& p) {
    const glm::uvec3 t = mesh.triangles[p.triangle];
    const float s = p.bary.x, u = p.bary.y;
    return (1.0f - s - u) * mesh.texcoords[t.x] + s * mesh.texcoords[t.y] + u * mesh.texcoords[t.z];
}

} // namespace

DiffuseScene make_scene(const SceneOptions& o) {
    const Stopwatch sw;
    DiffuseScene s;
    s.preset = synth::make_preset(o.preset, o.lambertian);
    if (o.edit_preset) o.edit_preset(s.preset);
    synth::RigOptions ro;
    ro.size = o.size;
    ro.views = o.views;
    ro.lights = o.lights;
    if (!o.light_angles_deg.empty()) ro.light_angles_deg = o.light_angles_deg;
    ro.test_views = 0;
    ro.exposure = o.exposure;
    synth::Rig rig = synth::make_rig(s.preset.mesh, ro);
    if (o.edit_rig) o.edit_rig(rig);
    const synth::Renderer renderer(s.preset.mesh, s.preset.material);
    const bool is_float = o.format == synth::ImageFormat::Exr;
    const float sat = is_float ? std::numeric_limits<float>::infinity() : 1.0f;

    Capture& c = s.capture;
    c.mesh = s.preset.mesh;
    c.desc.color_space = is_float ? ColorSpace::Linear : ColorSpace::Srgb;
    if (!is_float) c.desc.saturation = 1.0;
    std::size_t frame_index = 0;
    for (const synth::RigView& rv : rig.views) {
        View view;
        view.view_index = rv.view_index;
        view.camera = rv.camera;
        for (std::size_t l = 0; l < rv.lights.size(); ++l) {
            synth::RenderedFrame fr = renderer.render(rv.camera, rv.lights[l], 2);
            synth::apply_noise(fr.color, {o.noise_sigma, 0.0}, 1, frame_index);
            FrameImage im;
            im.saturation = sat;
            im.color = std::move(fr.color);
            im.flags.assign(fr.mask.size(), 0);
            for (std::size_t p = 0; p < fr.mask.size(); ++p) {
                std::uint8_t flag = 0;
                for (int ch = 0; ch < 3; ++ch) {
                    float& v = im.color.pixels[3 * p + std::size_t(ch)];
                    v = quantize(v, o.format);
                    if (v >= sat) flag |= static_cast<std::uint8_t>(kClippedR << ch);
                }
                if (!fr.mask[p]) flag |= kOutsideMask;
                if (flag & kClippedAny) ++s.clipped_pixels;
                im.flags[p] = flag;
            }
            FrameDesc f;
            f.view_index = rv.view_index;
            f.transform = rv.camera.camera_to_world;
            f.intrinsics = rv.camera.intrinsics;
            f.light = rv.lights[l];
            f.split = Split::Train;
            c.desc.frames.push_back(f);
            view.frames.push_back(frame_index++);
            c.images.push_back(std::move(im));
        }
        c.views.push_back(std::move(view));
    }

    build_scene_stages(s, o.texels_per_pixel, o.force_rays);
    s.seconds = sw.seconds();
    return s;
}

void build_scene_stages(DiffuseScene& s, double texels_per_pixel, bool force_rays) {
    const Capture& c = s.capture;
    std::vector<Camera> cameras; // the views with train frames, as reconstruct sizes the atlas
    for (const View& v : c.views)
        if (std::any_of(v.frames.begin(), v.frames.end(), [&](std::size_t f) { return c.desc.frames[f].split == Split::Train; }))
            cameras.push_back(v.camera);
    AtlasOptions ao;
    ao.texels_per_pixel = texels_per_pixel;
    s.atlas = build_atlas(c.mesh, cameras, ao);
    s.particles = build_particles(c.mesh, s.atlas);
    const RayScene scene(c.mesh);
    const VisibilityInputs vi = visibility_inputs(c);
    VisibilityOptions vo;
    vo.force_rays = force_rays;
    vo.frame_view = vi.frame_view;
    s.visibility = compute_visibility(s.particles.particles, c.mesh, scene, vi.views, vi.lights, vo);
    s.truth.resize(s.particles.particles.size());
    for (std::size_t p = 0; p < s.truth.size(); ++p)
        s.truth[p] = synth::sample_albedo(s.preset.material.albedo_texture, particle_uv(c.mesh, s.particles.particles[p]));
}

AlbedoError albedo_error(const DiffuseScene& scene, const LambertOutputs& out, const std::vector<std::uint8_t>& select) {
    std::vector<glm::vec3> estimate(out.particles.size());
    for (std::size_t p = 0; p < estimate.size(); ++p) estimate[p] = out.albedo(p);
    return albedo_error(estimate, scene.truth, select);
}

AlbedoError albedo_error(std::span<const glm::vec3> estimate, std::span<const glm::vec3> truth,
                         const std::vector<std::uint8_t>& select) {
    AlbedoError e;
    double sum = 0.0;
    for (std::size_t p = 0; p < truth.size(); ++p) {
        if (!select[p]) continue;
        const glm::vec3 d = estimate[p] - truth[p];
        sum += double(d.x) * d.x + double(d.y) * d.y + double(d.z) * d.z;
        e.max_abs = std::max<double>(e.max_abs, std::max({std::abs(d.x), std::abs(d.y), std::abs(d.z)}));
        ++e.count;
    }
    e.rmse = e.count ? std::sqrt(sum / (3.0 * double(e.count))) : 0.0;
    return e;
}

ShadowedTexelError shadowed_texel_error(const DiffuseScene& scene, const LambertOutputs& out,
                                        const std::vector<std::uint8_t>& select) {
    const Visibility& vis = scene.visibility;
    std::vector<double> abs_err;
    double signed_sum = 0.0, sq = 0.0;
    ShadowedTexelError e;
    for (std::size_t p = 0; p < scene.truth.size(); ++p) {
        const LambertParticleResult& r = out.particles[p];
        if (!select[p] || !(r.status & shared::kLambertOk) || r.rejected_shadow == 0) continue;
        bool lit_some = false;
        for (std::uint32_t f = 0; f < vis.frame_count && !lit_some; ++f) lit_some = vis.lights(p, f);
        if (!lit_some) continue;
        ++e.count;
        const glm::vec3 d = out.albedo(p) - scene.truth[p];
        for (int c = 0; c < 3; ++c) {
            abs_err.push_back(std::abs(double(d[c])));
            signed_sum += double(d[c]);
            sq += double(d[c]) * double(d[c]);
        }
    }
    if (abs_err.empty()) return e;
    const std::size_t mid = abs_err.size() / 2;
    std::nth_element(abs_err.begin(), abs_err.begin() + static_cast<std::ptrdiff_t>(mid), abs_err.end());
    e.median_abs = abs_err[mid];
    e.signed_mean = signed_sum / double(abs_err.size());
    e.rmse = std::sqrt(sq / double(abs_err.size()));
    return e;
}

std::vector<glm::vec3> texel_box_truth(const DiffuseScene& scene, int samples) {
    const Mesh& mesh = scene.capture.mesh;
    const Image& tex = scene.preset.material.albedo_texture;
    std::vector<glm::vec3> out(scene.particles.particles.size());
    for (std::size_t p = 0; p < out.size(); ++p) {
        const Particle& part = scene.particles.particles[p];
        const glm::uvec3 t = mesh.triangles[part.triangle];
        // Atlas texel offset d -> barycentric offset M^-1 d -> uv offset U M^-1 d.
        const glm::dvec2 c0 = scene.atlas.corner_texel(part.triangle, 0);
        const glm::dmat2 m(scene.atlas.corner_texel(part.triangle, 1) - c0, scene.atlas.corner_texel(part.triangle, 2) - c0);
        const glm::dmat2 u(glm::dvec2(mesh.texcoords[t.y] - mesh.texcoords[t.x]), glm::dvec2(mesh.texcoords[t.z] - mesh.texcoords[t.x]));
        const glm::dmat2 j = u * glm::inverse(m);
        const glm::dvec2 centre(particle_uv(mesh, part));
        glm::dvec3 sum(0.0);
        for (int y = 0; y < samples; ++y)
            for (int x = 0; x < samples; ++x) {
                const glm::dvec2 d((x + 0.5) / samples - 0.5, (y + 0.5) / samples - 0.5);
                sum += glm::dvec3(synth::sample_albedo(tex, glm::vec2(centre + j * d)));
            }
        out[p] = glm::vec3(sum / double(samples * samples));
    }
    return out;
}

AlbedoError surface_error(const DiffuseScene& scene, const Image& texture, const std::vector<std::uint8_t>& select,
                          int samples) {
    const Mesh& mesh = scene.capture.mesh;
    const Image& tex = scene.preset.material.albedo_texture;
    const auto bilinear = [&](glm::dvec2 q) {
        const double fx = q.x - 0.5, fy = q.y - 0.5;
        const int x0 = static_cast<int>(std::floor(fx)), y0 = static_cast<int>(std::floor(fy));
        const double ax = fx - x0, ay = fy - y0;
        glm::dvec3 v(0.0);
        for (int k = 0; k < 4; ++k) {
            const int x = std::clamp(x0 + (k & 1), 0, texture.width - 1), y = std::clamp(y0 + (k >> 1), 0, texture.height - 1);
            const double w = ((k & 1) ? ax : 1.0 - ax) * ((k >> 1) ? ay : 1.0 - ay);
            for (int c = 0; c < 3; ++c) v[c] += w * texture.at(x, y, c);
        }
        return v;
    };
    AlbedoError e;
    double sum = 0.0, n = 0.0;
    for (std::size_t p = 0; p < scene.particles.particles.size(); ++p) {
        if (!select[p]) continue;
        const Particle& part = scene.particles.particles[p];
        const glm::uvec3 t = mesh.triangles[part.triangle];
        ++e.count;
        for (int j = 0; j < samples; ++j)
            for (int i = 0; i < samples; ++i) {
                const glm::dvec2 q(part.texel_x() + (i + 0.5) / samples, part.texel_y() + (j + 0.5) / samples);
                const glm::dvec2 st = scene.atlas.patch_bary(part.triangle, q);
                if (st.x < 0.0 || st.y < 0.0 || st.x + st.y > 1.0) continue;
                const glm::vec2 uv = float(1.0 - st.x - st.y) * mesh.texcoords[t.x] + float(st.x) * mesh.texcoords[t.y] +
                                     float(st.y) * mesh.texcoords[t.z];
                const glm::dvec3 d = bilinear(q) - glm::dvec3(synth::sample_albedo(tex, uv));
                sum += glm::dot(d, d);
                n += 3.0;
                e.max_abs = std::max({e.max_abs, std::abs(d.x), std::abs(d.y), std::abs(d.z)});
            }
    }
    e.rmse = n > 0.0 ? std::sqrt(sum / n) : 0.0;
    return e;
}

std::vector<std::uint8_t> flat_truth(const DiffuseScene& scene, double radius_pixels, float tol) {
    // Image pixels sample the texture at their centres; a particle's bilinear value mixes the
    // pixels within sqrt(2) pixels of it. The texture footprint of one image pixel, per
    // particle: sqrt(uv area in texels / projected area in pixels) of its triangle, in the
    // view that SEES the particle with the largest projected area. (The largest area over all
    // cameras the triangle faces, occlusion ignored, overstates the resolution on a
    // self-occluding mesh: a knot texel hidden from every view but a grazing one was judged
    // in a view that cannot see it, and counted as resolved where the grazing view's pixels,
    // each spread over several texels, blur the texture.)
    const Image& tex = scene.preset.material.albedo_texture;
    const Mesh& mesh = scene.capture.mesh;
    const Visibility& vis = scene.visibility;
    const std::size_t views = scene.capture.views.size();
    std::vector<double> area(mesh.triangles.size() * views, -1.0); // per (triangle, view), computed on first use
    const auto projected_area = [&](std::uint32_t triangle, std::size_t v) {
        double& a = area[std::size_t(triangle) * views + v];
        if (a < 0.0) {
            const Camera& cam = scene.capture.views[v].camera;
            const glm::uvec3 t = mesh.triangles[triangle];
            const auto q0 = cam.project(glm::dvec3(mesh.positions[t.x])), q1 = cam.project(glm::dvec3(mesh.positions[t.y])),
                       q2 = cam.project(glm::dvec3(mesh.positions[t.z]));
            a = 0.0;
            if (q0 && q1 && q2) {
                const glm::dvec2 e1 = *q1 - *q0, e2 = *q2 - *q0;
                a = 0.5 * std::abs(e1.x * e2.y - e1.y * e2.x);
            }
        }
        return a;
    };
    std::vector<std::uint8_t> flat(scene.truth.size(), 0);
    for (std::size_t p = 0; p < flat.size(); ++p) {
        const Particle& part = scene.particles.particles[p];
        const glm::uvec3 t = mesh.triangles[part.triangle];
        const glm::vec2 e1 = (mesh.texcoords[t.y] - mesh.texcoords[t.x]) * glm::vec2(tex.width, tex.height);
        const glm::vec2 e2 = (mesh.texcoords[t.z] - mesh.texcoords[t.x]) * glm::vec2(tex.width, tex.height);
        const double uv_area = 0.5 * std::abs(double(e1.x) * e2.y - double(e1.y) * e2.x);
        double pa = 0.0;
        for (std::size_t v = 0; v < views; ++v)
            if (vis.sees(p, v)) pa = std::max(pa, projected_area(part.triangle, v));
        const double texels_per_pixel = pa > 0.0 ? std::sqrt(uv_area / pa) : 1e9;
        const int r = static_cast<int>(std::ceil(radius_pixels * texels_per_pixel + 1.0));
        if (r > 64) continue;
        const glm::vec2 uv = particle_uv(mesh, part);
        const int cx = static_cast<int>(std::floor(uv.x * float(tex.width))), cy = static_cast<int>(std::floor(uv.y * float(tex.height)));
        bool ok = true;
        for (int dy = -r; dy <= r && ok; ++dy)
            for (int dx = -r; dx <= r && ok; ++dx) {
                const int x = ((cx + dx) % tex.width + tex.width) % tex.width;
                const int y = std::clamp(cy + dy, 0, tex.height - 1);
                for (int ch = 0; ch < 3; ++ch) ok = ok && std::abs(tex.at(x, y, ch) - scene.truth[p][ch]) <= tol;
            }
        flat[p] = ok ? 1 : 0;
    }
    return flat;
}

const DiffuseScene& conformance_scene() {
    // 3 texels per pixel: the chart atlas has no gutters inside its charts, so at one it
    // gives a third of the patchwork's particles here, too few to split the batching tests'
    // bindings.
    static const DiffuseScene s = make_scene({.preset = "cologne", .lambertian = false, .size = 96, .views = 6,
                                              .exposure = 2.0, .format = synth::ImageFormat::Png8, .texels_per_pixel = 3.0});
    return s;
}

} // namespace specula::test
