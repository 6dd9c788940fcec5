#include "synth/path_sampling.h"

#include "shared/coated.h"
#include "shared/tangent_frame.h"

#include <glm/gtc/constants.hpp>

#include <algorithm>
#include <cmath>
#include <variant>

namespace specula::synth {

SamplingLobe SamplingLobe::of(const SpecularModel& model) {
    SamplingLobe lobe;
    if (is_zero(model)) return lobe;
    const auto mean = [](const glm::vec3& x) { return (static_cast<double>(x.x) + x.y + x.z) / 3.0; };
    if (const auto* l = std::get_if<LafortuneRgb>(&model)) {
        lobe.kind = Kind::Lafortune;
        lobe.cx = mean(l->cx), lobe.cz = mean(l->cz), lobe.exponent = mean(l->n);
    } else {
        const CoatedParams& c = std::get<CoatedParams>(model);
        lobe.kind = Kind::Ggx;
        lobe.alpha = c.alpha, lobe.eta = c.eta, lobe.tint = mean(c.tint);
    }
    return lobe;
}

glm::dvec3 direction_about(const glm::dvec3& axis, double c, double b) {
    const glm::dvec3 x = shared::f64::tangent_frame_x(axis);
    const glm::dvec3 y = glm::cross(axis, x);
    const double s = std::sqrt(std::max(0.0, 1.0 - c * c)), phi = glm::two_pi<double>() * b;
    return glm::normalize(s * std::cos(phi) * x + s * std::sin(phi) * y + c * axis);
}

DirectionSampler::DirectionSampler(const SamplingLobe& lobe, const glm::dvec3& n, const glm::dvec3& v, double diffuse,
                                   bool use_lobe)
    : m_lobe(lobe), m_n(n), m_v(v) {
    if (!use_lobe) m_lobe.kind = SamplingLobe::Kind::None;
    const double co = glm::dot(n, v);
    double lobe_albedo = 0.0; // roughly: the lobe's share of light reflected toward v
    if (m_lobe.kind == SamplingLobe::Kind::Lafortune) {
        const glm::dvec3 a = m_lobe.cx * (v - co * n) + m_lobe.cz * co * n;
        const double s = glm::length(a);
        if (s > 1e-12) {
            m_axis = a / s;
            // A peak below the horizon (woodenpot's Cz < 0; grazing views) leaves above it only
            // the lobe's flank nearest the horizon: aim there, kMinLobeLift above it.
            const double lift = glm::dot(m_axis, n);
            if (lift < kMinLobeLift) m_axis = glm::normalize(m_axis + (kMinLobeLift - lift) * n);
            // The integral of (s cos a)^N cos(theta) over the lobe, with cos(theta) taken at its peak.
            lobe_albedo = std::pow(s, m_lobe.exponent) * glm::two_pi<double>() / (m_lobe.exponent + 1.0) *
                          std::max(glm::dot(m_axis, n), 0.0);
        } else {
            m_lobe.kind = SamplingLobe::Kind::None;
        }
    } else if (m_lobe.kind == SamplingLobe::Kind::Ggx) {
        // The coating reflects about F(n.v) of the light; the base gets the rest.
        const double f = shared::f64::coated_fresnel(std::max(co, 0.0), m_lobe.eta);
        lobe_albedo = m_lobe.tint * f;
        diffuse *= 1.0 - f;
    }
    if (m_lobe.kind != SamplingLobe::Kind::None)
        m_q = std::clamp(diffuse / std::max(diffuse + lobe_albedo, 1e-12), kMinCosineShare, 1.0);
    if (!(m_q < 1.0)) m_lobe.kind = SamplingLobe::Kind::None, m_q = 1.0;
}

glm::dvec3 DirectionSampler::sample(double a, double b) const {
    if (a < m_q) {
        // Malley: uniform on the unit disc (radius sqrt(a'), angle 2 pi b), lifted to the hemisphere.
        const double u = a / m_q;
        return direction_about(m_n, std::sqrt(std::max(0.0, 1.0 - u)), b);
    }
    const double u = std::min((a - m_q) / (1.0 - m_q), 1.0 - 1e-16);
    if (m_lobe.kind == SamplingLobe::Kind::Lafortune)
        return direction_about(m_axis, std::pow(u, 1.0 / (m_lobe.exponent + 1.0)), b);
    // GGX: tan^2 of the half-vector's angle = alpha^2 u / (1 - u) (Walter et al. eq. 35).
    const double t2 = m_lobe.alpha * m_lobe.alpha * u / (1.0 - u);
    const glm::dvec3 h = direction_about(m_n, 1.0 / std::sqrt(1.0 + t2), b);
    const double vh = glm::dot(m_v, h);
    if (!(vh > 0.0)) return glm::dvec3(0.0);
    return glm::normalize(2.0 * vh * h - m_v);
}

double DirectionSampler::pdf(const glm::dvec3& w) const {
    const double cosine = std::max(glm::dot(m_n, w), 0.0) / glm::pi<double>();
    if (m_lobe.kind == SamplingLobe::Kind::None) return cosine;
    double lobe = 0.0;
    if (m_lobe.kind == SamplingLobe::Kind::Lafortune) {
        const double c = glm::dot(m_axis, w);
        if (c > 0.0) lobe = (m_lobe.exponent + 1.0) / glm::two_pi<double>() * std::pow(c, m_lobe.exponent);
    } else {
        const glm::dvec3 sum = w + m_v;
        const double len = glm::length(sum);
        if (len > 1e-12) {
            const glm::dvec3 h = sum / len;
            const double nh = glm::dot(m_n, h), wh = glm::dot(w, h);
            if (nh > 0.0 && wh > 0.0) lobe = shared::f64::coated_ggx_d(nh, m_lobe.alpha) * nh / (4.0 * wh);
        }
    }
    return m_q * cosine + (1.0 - m_q) * lobe;
}

} // namespace specula::synth
