// Reference for lsq3_solve: the same shared math as the shader (shared/solve3.h),
// instantiated in double, so the GPU's float32 result is compared with a result
// whose own rounding error is negligible.
#include "gpu/kernels/lsq3_solve.h"

#include "core/error.h"

namespace specula::gpu {

const char* lsq3_status_name(uint32_t status) noexcept {
    switch (status) {
    case shared::kLsq3Ok: return "ok";
    case shared::kLsq3IllConditioned: return "ill-conditioned";
    case shared::kLsq3TooFewRows: return "too few rows";
    case shared::kLsq3InvalidInput: return "invalid input";
    default: return "unknown";
    }
}

void lsq3_validate(const Lsq3Inputs& in) {
    if (in.row_offsets.empty()) {
        if (!in.rows.empty()) throw Error("lsq3_solve: rows given without row_offsets");
        return;
    }
    if (in.row_offsets.front() != 0) throw Error("lsq3_solve: row_offsets[0] must be 0");
    for (std::size_t e = 0; e + 1 < in.row_offsets.size(); ++e)
        if (in.row_offsets[e + 1] < in.row_offsets[e])
            throw Error("lsq3_solve: row_offsets decrease at element " + std::to_string(e));
    if (in.row_offsets.back() != in.rows.size())
        throw Error("lsq3_solve: row_offsets.back() = " + std::to_string(in.row_offsets.back()) + " but " +
                    std::to_string(in.rows.size()) + " rows were given");
}

std::vector<Lsq3Result> lsq3_solve_cpu(const Lsq3Inputs& in) {
    namespace f64 = shared::f64;
    lsq3_validate(in);
    const std::size_t count = in.element_count();
    std::vector<Lsq3Result> out(count);
    for (std::size_t e = 0; e < count; ++e) {
        const auto rows = in.rows.subspan(in.row_offsets[e], in.row_offsets[e + 1] - in.row_offsets[e]);
        f64::Lsq3Normal n = f64::lsq3_normal_zero();
        for (const Lsq3Row& r : rows) f64::lsq3_accumulate(n, glm::dvec3(r.a_x, r.a_y, r.a_z), r.b, r.w);
        const f64::Lsq3Solution s = f64::lsq3_solve_normal(n);
        double rss = 0.0;
        if (s.status == shared::kLsq3Ok)
            for (const Lsq3Row& r : rows) rss += f64::lsq3_residual_term(glm::dvec3(r.a_x, r.a_y, r.a_z), r.b, r.w, s.g);
        out[e] = Lsq3Result{.g_x = static_cast<float>(s.g.x),
                            .g_y = static_cast<float>(s.g.y),
                            .g_z = static_cast<float>(s.g.z),
                            .rcond = static_cast<float>(s.rcond),
                            .rss = static_cast<float>(rss),
                            .status = s.status,
                            .rows = n.rows,
                            .reserved = 0};
    }
    return out;
}

} // namespace specula::gpu
