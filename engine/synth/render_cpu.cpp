#include "synth/render.h"

#include "core/error.h"
#include "core/parallel.h"
#include "geometry/ray_scene.h"

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

    void shade_row(const Camera& camera, const PointLight& light, int y, RenderedFrame& out, Counts& counts) const {
        const int w = camera.intrinsics.w;
        const glm::dvec3 eye = camera.center();
        for (int x = 0; x < w; ++x) {
            glm::dvec3 ray_dir;
            const std::optional<RayHit> rh = trace_primary(camera, x, y, &ray_dir);
            if (!rh) continue;
            out.mask[static_cast<std::size_t>(y) * w + x] = 255;

            const glm::uvec3 tri = mesh.triangles[rh->triangle];
            const float b1 = rh->u, b2 = rh->v, b0 = 1.0f - b1 - b2; // Embree: p = (1-u-v) p0 + u p1 + v p2
            const glm::vec3 p0 = mesh.positions[tri.x], p1 = mesh.positions[tri.y], p2 = mesh.positions[tri.z];
            // The hit along the ray (more precise than the barycentric sum far from the origin).
            const glm::dvec3 hit = eye + static_cast<double>(rh->t) * ray_dir;
            const glm::vec3 n = glm::normalize(b0 * mesh.normals[tri.x] + b1 * mesh.normals[tri.y] + b2 * mesh.normals[tri.z]);
            glm::vec3 ng = glm::normalize(glm::cross(p1 - p0, p2 - p0));
            if (glm::dot(glm::dvec3(ng), ray_dir) > 0.0) ng = -ng; // the side the camera sees

            // A directional light exactly (not its stand-in): parallel rays, the same irradiance everywhere.
            const glm::dvec3 to_light = light.directional ? light.directional->direction : light.position - hit;
            const double d = light.directional ? 1.0 : glm::length(to_light);
            const glm::dvec3 u = to_light / d;
            const double cos_theta = glm::dot(glm::dvec3(n), u);
            if (!(cos_theta > 0.0)) continue;
            // A light behind the geometric surface seen from the camera cannot reach this side.
            const float reach = light.directional ? std::numeric_limits<float>::infinity() : static_cast<float>(d) - epsilon;
            if (glm::dot(glm::dvec3(ng), u) <= 0.0 || occluded(glm::vec3(hit) + epsilon * ng, glm::vec3(u), reach)) {
                ++counts.shadowed;
                continue;
            }
            ++counts.lit;

            glm::vec3 albedo = material.albedo_value;
            if (!material.albedo_texture.empty()) {
                const glm::vec2 uv = b0 * mesh.texcoords[tri.x] + b1 * mesh.texcoords[tri.y] + b2 * mesh.texcoords[tri.z];
                albedo = sample_albedo(material.albedo_texture, uv);
            }
            // f = (rho / pi) k_d + f_s (shared/material.h).
            const glm::dvec3 v = -ray_dir;
            const double co = glm::dot(glm::dvec3(n), v);
            glm::vec3 f = albedo / glm::pi<float>() * shared::material_diffuse_factor(gpu, static_cast<float>(cos_theta), static_cast<float>(co));
            if (material.coated) {
                // In double: the truth is as exact as the formula (shared/coated.h's f64 instance).
                f += glm::vec3(shared::f64::material_specular(gpu, cos_theta, co, glm::dot(u, v)));
            } else if (!material.lobe.is_zero()) {
                // The lobe in the tangent frame (lafortune_eval_rgb, the same lafortune_eval_ab that
                // material_specular calls): its float products round differently from material_specular's
                // u.v - (n.u)(n.v), and this form keeps the lafortune captures byte for byte as they were.
                const glm::vec3 u_local = shared::to_tangent_frame(n, glm::vec3(u));
                const glm::vec3 v_local = shared::to_tangent_frame(n, glm::vec3(v));
                f += shared::lafortune_eval_rgb(material.lobe.cx, material.lobe.cz, material.lobe.n, u_local, v_local);
            }
            const glm::dvec3 radiance = light.directional ? glm::dvec3(f) * light.directional->irradiance * cos_theta
                                                          : glm::dvec3(f) * light.intensity * (cos_theta / (d * d));
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

RenderedFrame Renderer::render(const Camera& camera, const PointLight& light, int threads) const {
    const int w = camera.intrinsics.w, h = camera.intrinsics.h;
    if (w <= 0 || h <= 0) throw Error("synth renderer: the camera has no pixels");
    RenderedFrame out;
    out.color = Image(w, h, 3, 0.0f);
    out.mask.assign(static_cast<std::size_t>(w) * h, 0);
    // Rows are handed out dynamically, but each pixel's value depends only on its own rays,
    // so the image is the same whatever the thread count or schedule.
    const unsigned workers = static_cast<unsigned>(std::max(threads, 1));
    std::vector<Impl::Counts> counts(parallel_workers(static_cast<std::size_t>(h), workers));
    parallel_for_chunks(static_cast<std::size_t>(h), workers, 1, [&](unsigned worker, std::size_t begin, std::size_t end) {
        for (std::size_t y = begin; y < end; ++y) m_impl->shade_row(camera, light, static_cast<int>(y), out, counts[worker]);
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

RenderedFrame render_frame(const Mesh& mesh, const Material& material, const Camera& camera, const PointLight& light, int threads) {
    return Renderer(mesh, material).render(camera, light, threads);
}

} // namespace specula::synth
