// Reference for brdf_matrix: the shader's steps (shared/gshd.h, shared/material.h) instantiated in double.
#include "factorization/brdf_matrix.h"

#include "core/error.h"
#include "core/parallel.h"

#include <cmath>
#include <string>

namespace specula::factorization {

void brdf_matrix_validate(const BrdfMatrixInputs& in) {
    if (in.res_h < 2 || in.res_d < 2)
        throw Error("brdf_matrix: grid resolutions must be >= 2 (got " + std::to_string(in.res_h) + ", " +
                    std::to_string(in.res_d) + ")");
    const uint64_t entries = uint64_t{in.res_h} * in.res_h * in.res_d * in.res_d * 3u;
    if (entries >= (uint64_t{1} << 32))
        throw Error("brdf_matrix: " + std::to_string(entries) + " entries exceed 32-bit indexing");
    if (in.param == FactorParam::Warped && !valid_warp(in.warp))
        throw Error("brdf_matrix: the warp must be (+-1, k_r, k_g, k_b) with every k in [1/64, 64]");
    if (!(in.weight_q >= 0.0f && in.weight_q <= 8.0f))
        throw Error("brdf_matrix: weight_q must be in [0, 8] (got " + std::to_string(in.weight_q) + ")");
    if (in.param == FactorParam::Warped && family_of(in.model) != MaterialFamily::Lafortune)
        throw Error(std::string("brdf_matrix: the warped parametrization divides by the Lafortune lobe's radial factor; "
                                "the model is ") +
                    to_string(family_of(in.model)));
}

BrdfMatrix brdf_matrix_cpu(const BrdfMatrixInputs& in) {
    namespace f64 = shared::f64;
    brdf_matrix_validate(in);
    BrdfMatrix m{.res_h = in.res_h, .res_d = in.res_d, .param = in.param, .warp = in.warp, .weight_q = in.weight_q, .values = {}};
    const std::size_t rows = m.rows();
    const std::size_t cols = m.cols();
    m.values.assign(3 * rows * cols, shared::kGshdInvalid);
    std::vector<glm::dvec3> dgrid(cols);
    for (std::size_t col = 0; col < cols; ++col) dgrid[col] = f64::gshd_grid_dir(static_cast<uint32_t>(col), in.res_d);
    const uint32_t param = static_cast<uint32_t>(in.param);
    const bool warped = in.param == FactorParam::Warped;
    const shared::MaterialGpu material = material_gpu(in.model); // the parameters in float, as the kernel reads them
    const double q = in.weight_q;
    parallel_for(rows, in.threads, [&](std::size_t row) {
        const glm::dvec3 h = f64::gshd_grid_dir(static_cast<uint32_t>(row), in.res_h);
        for (std::size_t col = 0; col < cols; ++col) {
            const double weight = q != 0.0 ? std::pow(h.z * dgrid[col].z, q) : 1.0;
            if (!warped) { // one pair for every channel
                const f64::GshdPair p = f64::gshd_to_uv_param(h, dgrid[col], param);
                if (!(p.u.z > shared::kGshdMinCos && p.v.z > shared::kGshdMinCos)) continue;
                const glm::dvec3 f =
                    f64::gshd_clamp_value(f64::material_specular(material, p.u.z, p.v.z, glm::dot(p.u, p.v)) * weight);
                for (int c = 0; c < 3; ++c) m.values[(c * rows + row) * cols + col] = static_cast<float>(f[c]);
                continue;
            }
            for (int c = 0; c < 3; ++c) { // each channel's pair in its own warp
                const f64::GshdPair p = f64::gshd_to_uv_warped(h, dgrid[col], param, glm::dvec2(channel_warp(in.warp, c)));
                if (!(p.u.z > shared::kGshdMinCos && p.v.z > shared::kGshdMinCos)) continue;
                const double f = f64::lafortune_normalized(material.a[c], material.b[c], material.c[c], p.u, p.v) * weight;
                m.values[(c * rows + row) * cols + col] = static_cast<float>(f64::gshd_clamp_value(glm::dvec3(f)).x);
            }
        }
    });
    return m;
}

} // namespace specula::factorization
