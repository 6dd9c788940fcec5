#include "synth/render.h"

#include "core/error.h"
#include "core/parallel.h"
#include "geometry/ray_scene.h"
#include "synth/noise.h"
#include "synth/path_sampling.h"

#include "shared/lafortune.h"
#include "shared/material.h"
#include "shared/tangent_frame.h"

#include <glm/gtc/constants.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <optional>
#include <string>

namespace specula::synth {

glm::vec3 sample_albedo(const Image& texture, const glm::vec2& uv) {
    const int w = texture.width, h = texture.height;
    const float x = uv.x * static_cast<float>(w) - 0.5f;
    const float y = std::clamp(uv.y * static_cast<float>(h) - 0.5f, 0.0f, static_cast<float>(h - 1));
    const float x0f = std::floor(x), y0f = std::floor(y);
    const float fx = x - x0f, fy = y - y0f;
    const auto wrap = [w](int i) { return ((i % w) + w) % w; };
    const int x0 = wrap(static_cast<int>(x0f)), x1 = wrap(static_cast<int>(x0f) + 1);
    const int y0 = static_cast<int>(y0f), y1 = std::min(y0 + 1, h - 1);
    glm::vec3 out(0.0f);
    for (int c = 0; c < 3; ++c) {
        const int cc = std::min(c, texture.channels - 1);
        const float top = (1.0f - fx) * texture.at(x0, y0, cc) + fx * texture.at(x1, y0, cc);
        const float bottom = (1.0f - fx) * texture.at(x0, y1, cc) + fx * texture.at(x1, y1, cc);
        out[c] = (1.0f - fy) * top + fy * bottom;
    }
    return out;
}

struct Renderer::Impl {
    Mesh mesh;
    Material material;
    shared::MaterialGpu gpu{}; // material_gpu(material.specular())
    SamplingLobe lobe;         // SamplingLobe::of(material.specular()): the interreflections' lobe
    std::unique_ptr<RayScene> scene; // the engine's one Embree owner (engine/geometry)
    float epsilon = 1e-4f;

    void build() {
        // One build thread: the BVH build is then sequential, so the hierarchy (and which of
        // two triangles sharing an edge a ray reports) is the same on every run.
        scene = std::make_unique<RayScene>(mesh, RaySceneOptions{.build_threads = 1});
    }

    // Primary hit through the centre of pixel (x, y), or nothing.
    std::optional<RayHit> trace_primary(const Camera& camera, int x, int y, glm::dvec3* dir_out) const {
        const glm::dvec3 dir = camera.ray_direction(x + 0.5, y + 0.5);
        if (dir_out) *dir_out = dir;
        return scene->intersect(glm::vec3(camera.center()), glm::vec3(dir), 0.0f, std::numeric_limits<float>::infinity());
    }

    bool occluded(const glm::vec3& org, const glm::vec3& dir, float tfar) const {
        return scene->occluded(org, dir, 0.0f, tfar);
    }

    struct Counts {
        std::size_t lit = 0, shadowed = 0;
    };

    // A point a ray hit, as the shading sees it.
    struct Surface {
        glm::dvec3 p{0.0};  // the hit along the ray (more precise than the barycentric sum far from the origin)
        glm::vec3 n{0.0f};  // interpolated unit shading normal, as the mesh has it
        glm::vec3 ng{0.0f}; // unit geometric normal, on the side the ray came from
        glm::uvec3 tri{0u};
        float b0 = 0.0f, b1 = 0.0f, b2 = 0.0f;
    };

    Surface surface_at(const RayHit& rh, const glm::dvec3& origin, const glm::dvec3& dir) const {
        Surface s;
        s.tri = mesh.triangles[rh.triangle];
        s.b1 = rh.u, s.b2 = rh.v, s.b0 = 1.0f - s.b1 - s.b2; // Embree: p = (1-u-v) p0 + u p1 + v p2
        const glm::vec3 p0 = mesh.positions[s.tri.x], p1 = mesh.positions[s.tri.y], p2 = mesh.positions[s.tri.z];
        s.p = origin + static_cast<double>(rh.t) * dir;
        s.n = glm::normalize(s.b0 * mesh.normals[s.tri.x] + s.b1 * mesh.normals[s.tri.y] + s.b2 * mesh.normals[s.tri.z]);
        s.ng = glm::normalize(glm::cross(p1 - p0, p2 - p0));
        if (glm::dot(glm::dvec3(s.ng), dir) > 0.0) s.ng = -s.ng;
        return s;
    }

    glm::vec3 albedo_at(const Surface& s) const {
        if (material.albedo_texture.empty()) return material.albedo_value;
        const glm::vec2 uv = s.b0 * mesh.texcoords[s.tri.x] + s.b1 * mesh.texcoords[s.tri.y] + s.b2 * mesh.texcoords[s.tri.z];
        return sample_albedo(material.albedo_texture, uv);
    }

    // The light as seen from a surface point with shading normal n.
    enum class Lighting { Away, Shadowed, Lit };
    struct LightPath {
        Lighting state = Lighting::Away;
        glm::dvec3 u{0.0}; // unit, toward the light
        double d = 1.0;    // distance to the light (1 for a directional light)
        double cos_theta = 0.0;
    };

    LightPath light_at(const Surface& s, const glm::vec3& n, const PointLight& light) const {
        LightPath l;
        // A directional light exactly (not its stand-in): parallel rays, the same irradiance everywhere.
        const glm::dvec3 to_light = light.directional ? light.directional->direction : light.position - s.p;
        l.d = light.directional ? 1.0 : glm::length(to_light);
        l.u = to_light / l.d;
        l.cos_theta = glm::dot(glm::dvec3(n), l.u);
        if (!(l.cos_theta > 0.0)) return l;
        // A light behind the geometric surface seen from the ray's side cannot reach this side.
        const float reach = light.directional ? std::numeric_limits<float>::infinity() : static_cast<float>(l.d) - epsilon;
        const bool blocked = glm::dot(glm::dvec3(s.ng), l.u) <= 0.0 ||
                             occluded(glm::vec3(s.p) + epsilon * s.ng, glm::vec3(l.u), reach);
        l.state = blocked ? Lighting::Shadowed : Lighting::Lit;
        return l;
    }

    // f(u, v) = (rho / pi) k_d + f_s (shared/material.h) with incoming u and outgoing v.
    glm::vec3 brdf(const glm::vec3& albedo, const glm::vec3& n, const glm::dvec3& u, const glm::dvec3& v) const {
        const double ci = glm::dot(glm::dvec3(n), u);
        const double co = glm::dot(glm::dvec3(n), v);
        glm::vec3 f = albedo / glm::pi<float>() *
                      shared::material_diffuse_factor(gpu, static_cast<float>(ci), static_cast<float>(co));
        if (material.coated) {
            // In double: the truth is as exact as the formula (shared/coated.h's f64 instance).
            f += glm::vec3(shared::f64::material_specular(gpu, ci, co, glm::dot(u, v)));
        } else if (!material.lobe.is_zero()) {
            // The lobe in the tangent frame (lafortune_eval_rgb, the same lafortune_eval_ab that
            // material_specular calls): its float products round differently from material_specular's
            // u.v - (n.u)(n.v), and this form keeps the lafortune captures byte for byte as they were.
            const glm::vec3 u_local = shared::to_tangent_frame(n, glm::vec3(u));
            const glm::vec3 v_local = shared::to_tangent_frame(n, glm::vec3(v));
            f += shared::lafortune_eval_rgb(material.lobe.cx, material.lobe.cz, material.lobe.n, u_local, v_local);
        }
        return f;
    }

    // Radiance reflected toward v by a lit point: f(u, v) I max(0, n.u) / d^2.
    static glm::dvec3 reflected(const glm::vec3& f, const LightPath& l, const PointLight& light) {
        return light.directional ? glm::dvec3(f) * light.directional->irradiance * l.cos_theta
                                 : glm::dvec3(f) * light.intensity * (l.cos_theta / (l.d * l.d));
    }

    // The shading normal on the side a ray arrived from: flipped where the surface is seen from
    // behind (the geometric normal, already on the ray's side, decides; the interpolated normal
    // alone would flip at silhouettes, where it may lean away from a ray that sees the front).
    static glm::vec3 facing_normal(const Surface& s) { return glm::dot(s.n, s.ng) < 0.0f ? -s.n : s.n; }

    // The key of a pixel's random numbers: (seed, frame, pixel) and nothing else. The tag keeps
    // these numbers apart from the sensor noise's (noise.cpp), which hashes the same seed and frame.
    static std::uint64_t pixel_key(const Interreflection& ir, std::uint64_t pixel) {
        constexpr std::uint64_t kTag = 0x62f1e7d3a5c94b17ull;
        return mix64(mix64(ir.seed ^ kTag) ^ mix64(ir.frame + 0x632be59bd9b4e019ull) ^ mix64(pixel * 0x2545f4914f6cdd1dull));
    }
    static double random01(std::uint64_t key, std::uint64_t counter) { return uniform01(mix64(key ^ mix64(counter))); }

    // The light reflected at x toward v after 1..bounces further reflections (render.h): the
    // mean over ir.samples paths. Each vertex draws its next direction from the mixture of
    // path_sampling.h (cosine-weighted and the specular lobe) and weighs the step by
    // f(w, v) max(0, n.w) / pdf(w). Sample s's first direction is point s of a Hammersley set,
    // ((s + 1/2) / S, radical inverse of s in base 2), moved by a random offset per pixel
    // (Cranley-Patterson rotation), so the first bounce, most of the light, is stratified; the
    // later ones are independent.
    glm::dvec3 indirect(const Surface& x, const glm::vec3& albedo_x, const glm::dvec3& v, const PointLight& light,
                        const Interreflection& ir, std::uint64_t key) const {
        const double shift_a = random01(key, 0), shift_b = random01(key, 1);
        const double samples = static_cast<double>(ir.samples);
        const glm::vec3 n_x = facing_normal(x);
        const DirectionSampler first(lobe, glm::dvec3(n_x), v, mean(albedo_x), ir.lobe_sampling);
        glm::dvec3 sum(0.0);
        for (int s = 0; s < ir.samples; ++s) {
            const double radical = static_cast<double>(bit_reverse(static_cast<std::uint32_t>(s))) * 0x1.0p-32;
            double a = (s + 0.5) / samples + shift_a, b = radical + shift_b;
            a -= std::floor(a), b -= std::floor(b);
            Surface at = x;
            glm::vec3 n = n_x, albedo = albedo_x;
            glm::dvec3 out = v;         // toward the previous vertex
            glm::dvec3 throughput(1.0); // T_k of render.h
            for (int bounce = 1; bounce <= ir.bounces; ++bounce) {
                std::optional<DirectionSampler> later;
                if (bounce > 1) {
                    const std::uint64_t counter = 2 + 2 * (static_cast<std::uint64_t>(s) * (Interreflection::kMaxBounces + 1) +
                                                           bounce);
                    a = random01(key, counter), b = random01(key, counter + 1);
                    later.emplace(lobe, glm::dvec3(n), out, mean(albedo), ir.lobe_sampling);
                }
                const DirectionSampler& sampler = later ? *later : first;
                const glm::dvec3 w = sampler.sample(a, b);
                const double cos_w = glm::dot(glm::dvec3(n), w);
                // Below the shading or the geometric surface (or a failed lobe sample): no light from there.
                if (!(cos_w > 0.0) || glm::dot(glm::dvec3(at.ng), w) <= 0.0) break;
                const double density = sampler.pdf(w);
                if (!(density > 0.0)) break;
                const glm::vec3 origin = glm::vec3(at.p) + epsilon * at.ng;
                const glm::vec3 wf(w);
                const std::optional<RayHit> rh = scene->intersect(origin, wf, 0.0f, std::numeric_limits<float>::infinity());
                if (!rh) break; // off the object: black
                throughput *= glm::dvec3(brdf(albedo, n, w, out)) * (cos_w / density);
                at = surface_at(*rh, glm::dvec3(origin), glm::dvec3(wf));
                n = facing_normal(at);
                albedo = albedo_at(at);
                out = -w;
                const LightPath l = light_at(at, n, light);
                if (l.state == Lighting::Lit) sum += throughput * reflected(brdf(albedo, n, l.u, out), l, light);
            }
        }
        return sum / samples;
    }

    static double mean(const glm::vec3& c) { return (static_cast<double>(c.x) + c.y + c.z) / 3.0; }

    static std::uint32_t bit_reverse(std::uint32_t v) {
        v = ((v >> 1) & 0x55555555u) | ((v & 0x55555555u) << 1);
        v = ((v >> 2) & 0x33333333u) | ((v & 0x33333333u) << 2);
        v = ((v >> 4) & 0x0f0f0f0fu) | ((v & 0x0f0f0f0fu) << 4);
        v = ((v >> 8) & 0x00ff00ffu) | ((v & 0x00ff00ffu) << 8);
        return (v >> 16) | (v << 16);
    }

    void shade_row(const Camera& camera, const PointLight& light, const Interreflection& ir, int y, RenderedFrame& out,
                   Counts& counts) const {
        const int w = camera.intrinsics.w;
        const glm::dvec3 eye = camera.center();
        for (int x = 0; x < w; ++x) {
            glm::dvec3 ray_dir;
            const std::optional<RayHit> rh = trace_primary(camera, x, y, &ray_dir);
            if (!rh) continue;
            const std::size_t pixel = static_cast<std::size_t>(y) * w + x;
            out.mask[pixel] = 255;

            const Surface hit = surface_at(*rh, eye, ray_dir);
            const glm::dvec3 v = -ray_dir;
            const LightPath l = light_at(hit, hit.n, light);
            if (l.state == Lighting::Shadowed) ++counts.shadowed;
            if (l.state == Lighting::Lit) ++counts.lit;
            std::optional<glm::vec3> albedo;
            glm::dvec3 radiance(0.0);
            if (l.state == Lighting::Lit) {
                albedo = albedo_at(hit);
                radiance = reflected(brdf(*albedo, hit.n, l.u, v), l, light);
            }
            if (ir.bounces > 0) {
                if (!albedo) albedo = albedo_at(hit);
                radiance += indirect(hit, *albedo, v, light, ir, pixel_key(ir, pixel));
            } else if (l.state != Lighting::Lit) {
                continue; // exactly 0, as the image was made
            }
            for (int c = 0; c < 3; ++c) out.color.at(x, y, c) = static_cast<float>(radiance[c]);
        }
    }
};

Renderer::Renderer(Mesh mesh, Material material) : m_impl(std::make_unique<Impl>()) {
    if (mesh.positions.empty() || mesh.triangles.empty()) throw Error("synth renderer: the mesh is empty");
    if (mesh.normals.size() != mesh.positions.size()) mesh.normals = compute_vertex_normals(mesh.positions, mesh.triangles);
    for (glm::vec3& n : mesh.normals) n = glm::normalize(n);
    for (const glm::uvec3& t : mesh.triangles)
        if (t.x >= mesh.positions.size() || t.y >= mesh.positions.size() || t.z >= mesh.positions.size())
            throw Error("synth renderer: a triangle index is out of range");
    if (!material.albedo_texture.empty()) {
        if (!mesh.has_texcoords()) throw Error("synth renderer: an albedo texture needs texture coordinates (TEXCOORD_0) on the mesh");
        if (material.albedo_texture.channels < 1) throw Error("synth renderer: the albedo texture has no channels");
    }
    if (material.coated) {
        if (!material.lobe.is_zero())
            throw Error("synth renderer: a coated material cannot also have a Lafortune lobe (one family per material)");
        if (const std::optional<std::string> why = invalid_parameters(*material.coated))
            throw Error("synth renderer: coated material: " + *why);
    }
    m_impl->gpu = material_gpu(material.specular());
    m_impl->lobe = SamplingLobe::of(material.specular());
    const Bounds b = mesh_bounds(mesh);
    // Scale-relative: well above float rounding at the hit, well below any feature of the object.
    m_impl->epsilon = std::max(1e-4f * b.radius(), 1e-7f);
    m_impl->mesh = std::move(mesh);
    m_impl->material = std::move(material);
    m_impl->build();
}

Renderer::~Renderer() = default;
Renderer::Renderer(Renderer&&) noexcept = default;
Renderer& Renderer::operator=(Renderer&&) noexcept = default;

const Mesh& Renderer::mesh() const noexcept { return m_impl->mesh; }
const Material& Renderer::material() const noexcept { return m_impl->material; }
float Renderer::shadow_epsilon() const noexcept { return m_impl->epsilon; }

RenderedFrame Renderer::render(const Camera& camera, const PointLight& light, int threads,
                               const Interreflection& indirect) const {
    const int w = camera.intrinsics.w, h = camera.intrinsics.h;
    if (w <= 0 || h <= 0) throw Error("synth renderer: the camera has no pixels");
    if (indirect.bounces < 0 || indirect.bounces > Interreflection::kMaxBounces)
        throw Error("synth renderer: bounces must be between 0 and " + std::to_string(Interreflection::kMaxBounces) + ", not " +
                    std::to_string(indirect.bounces));
    if (indirect.bounces > 0 && (indirect.samples < 1 || indirect.samples > Interreflection::kMaxSamples))
        throw Error("synth renderer: interreflection samples per pixel must be between 1 and " +
                    std::to_string(Interreflection::kMaxSamples) + ", not " + std::to_string(indirect.samples));
    RenderedFrame out;
    out.color = Image(w, h, 3, 0.0f);
    out.mask.assign(static_cast<std::size_t>(w) * h, 0);
    // Rows are handed out dynamically, but each pixel's value depends only on its own rays,
    // so the image is the same whatever the thread count or schedule.
    const unsigned workers = static_cast<unsigned>(std::max(threads, 1));
    std::vector<Impl::Counts> counts(parallel_workers(static_cast<std::size_t>(h), workers));
    parallel_for_chunks(static_cast<std::size_t>(h), workers, 1, [&](unsigned worker, std::size_t begin, std::size_t end) {
        for (std::size_t y = begin; y < end; ++y)
            m_impl->shade_row(camera, light, indirect, static_cast<int>(y), out, counts[worker]);
    });
    for (const Impl::Counts& c : counts) {
        out.lit_pixels += c.lit;
        out.shadowed_pixels += c.shadowed;
    }
    return out;
}

std::vector<std::uint8_t> Renderer::render_mask(const Camera& camera, int threads) const {
    const int w = camera.intrinsics.w, h = camera.intrinsics.h;
    std::vector<std::uint8_t> mask(static_cast<std::size_t>(w) * h, 0);
    parallel_for(static_cast<std::size_t>(std::max(h, 0)), static_cast<unsigned>(std::max(threads, 1)), [&](std::size_t row) {
        const int y = static_cast<int>(row);
        for (int x = 0; x < w; ++x)
            if (m_impl->trace_primary(camera, x, y, nullptr))
                mask[static_cast<std::size_t>(y) * w + x] = 255;
    });
    return mask;
}

RenderedFrame render_frame(const Mesh& mesh, const Material& material, const Camera& camera, const PointLight& light, int threads,
                           const Interreflection& indirect) {
    return Renderer(mesh, material).render(camera, light, threads, indirect);
}

} // namespace specula::synth
