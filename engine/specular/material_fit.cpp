#include "specular/material_fit.h"

#include "core/timer.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace specula {

std::optional<SpecularModel> MaterialFit::model() const {
    if (lafortune) {
        const LafortuneRgb l = lafortune->converged_lobe();
        return l.is_zero() ? std::nullopt : std::optional<SpecularModel>(l);
    }
    if (coated && coated->usable()) return SpecularModel(coated->params);
    return std::nullopt;
}

std::vector<std::string> MaterialFit::status() const {
    std::vector<std::string> out;
    if (lafortune)
        for (const LafortuneChannelFit& c : lafortune->channel) out.emplace_back(to_string(c.status));
    if (coated) out.emplace_back(to_string(coated->status));
    return out;
}

std::string MaterialFit::describe() const {
    std::ostringstream s;
    s << to_string(family) << ": ";
    if (lafortune)
        for (int k = 0; k < 3; ++k) {
            const LafortuneChannelFit& c = lafortune->channel[k];
            s << "rgb"[k] << " Cx " << c.cx << " Cz " << c.cz << " N " << c.n << " (" << to_string(c.status) << ")"
              << (k < 2 ? "; " : "");
        }
    if (coated)
        s << "eta " << coated->params.eta << " +- " << coated->std_error_eta << ", alpha " << coated->params.alpha << " +- "
          << coated->std_error_alpha << ", tint " << coated->params.tint.x << " " << coated->params.tint.y << " "
          << coated->params.tint.z << " (" << to_string(coated->status) << (coated->reason != "converged" ? ": " + coated->reason : "")
          << ")";
    return s.str();
}

MaterialFit fit_material(MaterialFamily family, std::span<const ResidualSample> samples, const MaterialFitOptions& options) {
    const Stopwatch watch;
    MaterialFit fit;
    fit.family = family;
    if (family == MaterialFamily::Lafortune) {
        const std::vector<LafortuneSample> sub = to_lafortune_samples(samples, options.max_samples);
        fit.samples = sub.size();
        fit.lafortune = fit_lafortune(sub, options.lafortune);
    } else {
        const std::vector<MaterialSample> sub = to_material_samples(samples, options.max_samples);
        fit.samples = sub.size();
        fit.coated = fit_coated(sub, options.coated);
    }
    fit.seconds = watch.seconds();
    return fit;
}

double max_relative_change(const SpecularModel& next, const SpecularModel& previous) noexcept {
    if (next.index() != previous.index()) return 1.0;
    const auto rel = [](double a, double b) { return std::abs(a - b) / std::max(1e-6, std::abs(b)); };
    double change = 0.0;
    if (const auto* n = std::get_if<LafortuneRgb>(&next)) {
        const auto& p = std::get<LafortuneRgb>(previous);
        for (int k = 0; k < 3; ++k)
            change = std::max({change, rel(n->cx[k], p.cx[k]), rel(n->cz[k], p.cz[k]), rel(n->n[k], p.n[k])});
        return change;
    }
    const auto& n = std::get<CoatedParams>(next);
    const auto& p = std::get<CoatedParams>(previous);
    change = std::max(rel(n.eta, p.eta), rel(n.alpha, p.alpha));
    for (int k = 0; k < 3; ++k) change = std::max(change, rel(n.tint[k], p.tint[k]));
    return change;
}

} // namespace specula
