#pragma once
// Where the ground-truth renderer's interreflection paths go next (render.h, Interreflection):
// at a path vertex with unit shading normal n, seen from unit direction v, a mixture of two
// ways to pick the incoming direction w:
//   - cosine-weighted about n (density n.w / pi): matches the diffuse term;
//   - the specular lobe: lafortune, (Cx (u.v - (n.u)(n.v)) + Cz (n.u)(n.v))^N = (s cos a)^N
//     with a the angle of w to the lobe's peak direction p = norm(Cx (v - (n.v) n) + Cz (n.v) n)
//     and s = |Cx (v - (n.v) n) + Cz (n.v) n|: w about p with density (N + 1) / (2 pi) cos^N a
//     (the channels' mean Cx, Cz and N; p lifted above the horizon when it lies below); coated, GGX half-vectors h about n with density
//     D(n.h) (n.h) and w = v mirrored about h, density D(n.h) (n.h) / (4 w.h) (Walter,
//     Marschner, Li and Torrance 2007, eqs. 35 and 14).
// The lobe is taken with probability 1 - q, q = (diffuse albedo) / (diffuse albedo + the lobe's
// approximate directional albedo) but at least kMinCosineShare, so neither term goes unsampled.
// The estimate of a path's next step is f(w, v) max(0, n.w) / pdf(w) with pdf the mixture's
// density (the balance heuristic of Veach and Guibas 1995, one sample): unbiased whatever q is,
// and with no glossy spike left to a cosine sample's luck. A lobe sample that lands below the
// surface, or a GGX half-vector facing away from v, carries no light (pdf() is the density of
// the directions sample() does return).
#include "material/material.h"

#include <glm/glm.hpp>

namespace specula::synth {

/// The specular lobe a material's directions are drawn from (one per material).
struct SamplingLobe {
    enum class Kind { None, Lafortune, Ggx };
    Kind kind = Kind::None;
    double cx = 0.0, cz = 0.0, exponent = 0.0; // lafortune: the channels' means
    double alpha = 0.0, eta = 1.5, tint = 0.0; // coated: roughness, index, the tint's mean
    /// The lobe of a material's specular model; Kind::None for a zero one.
    [[nodiscard]] static SamplingLobe of(const SpecularModel& model);
};

class DirectionSampler {
public:
    static constexpr double kMinCosineShare = 0.1;
    /// Lafortune: the sampled lobe's axis at least this cosine above the horizon (measured
    /// on the presets: 0.1 gave the woodenpot's glossy bowl the least noise of 0, 0.1, 0.2, 0.35).
    static constexpr double kMinLobeLift = 0.1;

    /// At a vertex with unit shading normal n, toward unit v, diffuse albedo `diffuse` (the
    /// channels' mean); `use_lobe` false: cosine-weighted only.
    DirectionSampler(const SamplingLobe& lobe, const glm::dvec3& n, const glm::dvec3& v, double diffuse, bool use_lobe = true);

    /// The direction of (a, b) in [0, 1)^2: a < q is a cosine sample (a / q stretched back to
    /// [0, 1): a stratified set stays stratified within each technique), else a lobe sample.
    /// Unit; may lie below the surface (then it carries no light). Zero when the sample fails
    /// (a GGX half-vector facing away from v).
    [[nodiscard]] glm::dvec3 sample(double a, double b) const;
    /// Density per steradian of sample() returning unit w.
    [[nodiscard]] double pdf(const glm::dvec3& w) const;
    /// q: the probability of a cosine sample.
    [[nodiscard]] double cosine_share() const noexcept { return m_q; }

private:
    SamplingLobe m_lobe;
    glm::dvec3 m_n, m_v, m_axis{0.0}; // m_axis: lafortune's peak direction p
    double m_q = 1.0;
};

/// Unit direction about unit `axis` at cosine `c` from it and azimuth 2 pi `b`
/// (in shared/tangent_frame.h's frame of the axis).
[[nodiscard]] glm::dvec3 direction_about(const glm::dvec3& axis, double c, double b);

} // namespace specula::synth
