// Reference for brdf_matrix: the shader's steps (shared/gshd.h) instantiated in double.
#include "factorization/brdf_matrix.h"

#include "core/error.h"

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
}

BrdfMatrix brdf_matrix_cpu(const BrdfMatrixInputs& in) {
    namespace f64 = shared::f64;
    brdf_matrix_validate(in);
    BrdfMatrix m{.res_h = in.res_h, .res_d = in.res_d, .param = in.param, .warp = in.warp, .values = {}};
    const std::size_t rows = m.rows();
    const std::size_t cols = m.cols();
    m.values.assign(3 * rows * cols, shared::kGshdInvalid);
    std::vector<glm::dvec3> dgrid(cols);
    for (std::size_t col = 0; col < cols; ++col) dgrid[col] = f64::gshd_grid_dir(static_cast<uint32_t>(col), in.res_d);
    const uint32_t param = static_cast<uint32_t>(in.param);
    const bool warped = in.param == FactorParam::Warped;
    for (std::size_t row = 0; row < rows; ++row) {
        const glm::dvec3 h = f64::gshd_grid_dir(static_cast<uint32_t>(row), in.res_h);
        for (std::size_t col = 0; col < cols; ++col) {
            // Each channel's pair in its own warp (warped); one pair for every channel otherwise.
            f64::GshdPair p = f64::gshd_to_uv_param(h, dgrid[col], warped ? shared::kGshdPlain : param);
            for (int c = 0; c < 3; ++c) {
                if (warped) p = f64::gshd_to_uv_warped(h, dgrid[col], param, glm::dvec2(channel_warp(in.warp, c)));
                if (!(p.u.z > shared::kGshdMinCos && p.v.z > shared::kGshdMinCos)) continue;
                const double f = warped ? shared::f64::lafortune_normalized(in.lobe.cx[c], in.lobe.cz[c], in.lobe.n[c], p.u, p.v)
                                        : shared::f64::lafortune_eval(in.lobe.cx[c], in.lobe.cz[c], in.lobe.n[c], p.u, p.v);
                m.values[(c * rows + row) * cols + col] = static_cast<float>(f64::gshd_clamp_value(glm::dvec3(f)).x);
            }
        }
    }
    return m;
}

} // namespace specula::factorization
