#include "material/material.h"

#include <cmath>
#include <type_traits>

namespace specula {

std::optional<MaterialFamily> material_family_from_string(const std::string& s) noexcept {
    for (std::size_t i = 0; i < kMaterialFamilyCount; ++i) {
        const auto f = static_cast<MaterialFamily>(i);
        if (s == to_string(f)) return f;
    }
    return std::nullopt;
}

bool is_zero(const SpecularModel& m) noexcept {
    return std::visit([](const auto& model) { return model.is_zero(); }, m);
}

namespace {

bool finite(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

} // namespace

std::optional<std::string> invalid_parameters(const SpecularModel& m) {
    if (const auto* l = std::get_if<LafortuneRgb>(&m)) {
        if (!finite(l->cx)) return "cx: not finite";
        if (!finite(l->cz)) return "cz: not finite";
        if (!finite(l->n) || !(l->n.x > 0.0f && l->n.y > 0.0f && l->n.z > 0.0f)) return "n: not finite and positive";
        return std::nullopt;
    }
    const auto& c = std::get<CoatedParams>(m);
    if (!(c.eta >= shared::kCoatedMinEta && c.eta <= shared::kCoatedMaxEta))
        return "eta: " + std::to_string(c.eta) + " is outside [" + std::to_string(shared::kCoatedMinEta) + ", " +
               std::to_string(shared::kCoatedMaxEta) + "]";
    if (!(c.alpha >= shared::kCoatedMinAlpha && c.alpha <= shared::kCoatedMaxAlpha))
        return "alpha: " + std::to_string(c.alpha) + " is outside [" + std::to_string(shared::kCoatedMinAlpha) + ", " +
               std::to_string(shared::kCoatedMaxAlpha) + "]";
    if (!finite(c.tint) || c.tint.x < 0.0f || c.tint.y < 0.0f || c.tint.z < 0.0f) return "tint: not finite and non-negative";
    return std::nullopt;
}

shared::MaterialGpu material_gpu(const std::optional<SpecularModel>& m) noexcept {
    shared::MaterialGpu g{};
    g.family = glm::uvec4(shared::kMaterialLafortune, 0u, 0u, 0u);
    if (!m) return g; // zero Lafortune lobe: no specular, Lambertian diffuse
    std::visit(
        [&](const auto& model) {
            using T = std::decay_t<decltype(model)>;
            if constexpr (std::is_same_v<T, LafortuneRgb>) {
                g.a = glm::vec4(model.cx, 0.0f);
                g.b = glm::vec4(model.cz, 0.0f);
                g.c = glm::vec4(model.n, 0.0f);
            } else {
                g.family.x = shared::kMaterialCoated;
                g.a = glm::vec4(model.eta, model.alpha, 0.0f, 0.0f);
                g.b = glm::vec4(model.tint, 0.0f);
            }
        },
        *m);
    return g;
}

glm::dvec3 directional_albedo(const SpecularModel& m, const glm::dvec3& rho, double cos_o, int n) {
    const shared::MaterialGpu g = material_gpu(m);
    const double so = std::sqrt(std::max(0.0, 1.0 - cos_o * cos_o));
    // Midpoint cells uniform in the polar angle theta and in phi (dw = sin(theta) dtheta dphi):
    // fine at the pole too, where a narrow lobe of a view along the normal peaks.
    const int nphi = 4 * n;
    const double dtheta = 0.5 * kPi / n, dphi = 2.0 * kPi / nphi;
    glm::dvec3 sum(0.0);
    for (int i = 0; i < n; ++i) {
        const double theta = (i + 0.5) * dtheta;
        const double ci = std::cos(theta), si = std::sin(theta);
        for (int j = 0; j < nphi; ++j) {
            const double cuv = ci * cos_o + si * so * std::cos((j + 0.5) * dphi); // u.v, v at azimuth 0
            const glm::dvec3 f = rho / kPi * shared::f64::material_diffuse_factor(g, ci, cos_o) +
                                 shared::f64::material_specular(g, ci, cos_o, cuv);
            sum += f * (ci * si);
        }
    }
    return sum * (dtheta * dphi);
}

double coated_internal_reflectance(double eta) {
    // Inside the coating the relative index is 1/eta: F(c, 1/eta) is 1 beyond the critical angle.
    constexpr int kSteps = 4096;
    double sum = 0.0;
    for (int i = 0; i < kSteps; ++i) {
        const double c = (i + 0.5) / kSteps;
        sum += shared::f64::coated_fresnel(c, 1.0 / eta) * c;
    }
    return 2.0 * sum / kSteps;
}

double coated_max_albedo(double eta) {
    const double t1 = shared::f64::coated_transmittance(1.0, eta);
    return t1 * t1 / (eta * eta * (1.0 - coated_internal_reflectance(eta)));
}

} // namespace specula
