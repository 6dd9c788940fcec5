// Reference for normalized_decomposition: the shader's loops in double (same skipping,
// same blocking), so the only differences are float rounding and pow's accuracy.
#include "factorization/normalized_decomposition.h"

#include "core/error.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace specula::factorization {

namespace {

// Blocked sum, as in the shader (kGshdSumBlock terms per block).
struct BlockedSum {
    double total = 0.0;
    double block = 0.0;
    uint32_t in_block = 0;
    uint32_t count = 0;
    void add(double x) {
        ++count;
        block += x;
        if (++in_block == shared::kGshdSumBlock) {
            total += block;
            block = 0.0;
            in_block = 0;
        }
    }
    [[nodiscard]] double sum() const { return total + block; }
};

double power_term(double x, double p) { return p == 2.0 ? x * x : p == 1.0 ? x : std::pow(x, p); }
double power_root(double x, double p) { return p == 2.0 ? std::sqrt(x) : p == 1.0 ? x : std::pow(x, 1.0 / p); }

} // namespace

const char* to_string(DecompositionWeighting w) noexcept {
    return w == DecompositionWeighting::Uniform ? "uniform" : "energy";
}

void decomposition_validate(const DecompositionInputs& in) {
    if (in.matrix == nullptr) throw Error("normalized_decomposition: no matrix");
    const BrdfMatrix& m = *in.matrix;
    if (m.res_h < 2 || m.res_d < 2) throw Error("normalized_decomposition: grid resolutions must be >= 2");
    if (m.values.size() != 3 * m.rows() * m.cols())
        throw Error("normalized_decomposition: matrix holds " + std::to_string(m.values.size()) + " values, expected " +
                    std::to_string(3 * m.rows() * m.cols()));
    if (!(in.p >= 1.0f && in.p <= 64.0f))
        throw Error("normalized_decomposition: p must be in [1, 64] (got " + std::to_string(in.p) + ")");
}

Decomposition normalized_decomposition_cpu(const DecompositionInputs& in) {
    decomposition_validate(in);
    const BrdfMatrix& m = *in.matrix;
    const std::size_t rows = m.rows();
    const std::size_t cols = m.cols();
    const double p = in.p;
    Decomposition out{.res_h = m.res_h, .res_d = m.res_d, .g = {}, .h = {}, .param = m.param, .warp = m.warp};
    out.g.assign(rows, glm::vec3(0.0f));
    out.h.assign(cols, glm::vec3(0.0f));
    std::vector<double> g(3 * rows, 0.0);
    for (uint32_t c = 0; c < 3; ++c) {
        for (std::size_t row = 0; row < rows; ++row) {
            const float* f = &m.values[(c * rows + row) * cols];
            double mx = 0.0;
            for (std::size_t d = 0; d < cols; ++d) mx = std::max(mx, static_cast<double>(f[d]));
            if (mx < shared::kGshdMinValue) continue;
            BlockedSum s;
            for (std::size_t d = 0; d < cols; ++d)
                if (f[d] >= 0.0f) s.add(power_term(f[d] / mx, p));
            g[3 * row + c] = mx * power_root(s.sum() / s.count, p);
            out.g[row][static_cast<int>(c)] = static_cast<float>(g[3 * row + c]);
        }
        const bool energy = in.weighting == DecompositionWeighting::Energy;
        double gmax = 0.0;
        for (std::size_t row = 0; row < rows; ++row) gmax = std::max(gmax, g[3 * row + c]);
        for (std::size_t col = 0; col < cols; ++col) {
            BlockedSum s, w2;
            for (std::size_t row = 0; row < rows; ++row) {
                const float v = m.values[(c * rows + row) * cols + col];
                const double gv = g[3 * row + c];
                if (v < 0.0f || gv <= 0.0) continue;
                if (energy) {
                    const double w = gv / gmax;
                    s.add(w * (v / gmax));
                    w2.add(w * w);
                } else {
                    s.add(v / gv);
                }
            }
            double hv = 0.0;
            if (energy) hv = w2.sum() > 0.0 ? s.sum() / w2.sum() : 0.0;
            else hv = s.count > 0 ? s.sum() / s.count : 0.0;
            out.h[col][static_cast<int>(c)] = static_cast<float>(hv);
        }
    }
    return out;
}

void unweight_decomposition(Decomposition& d, float q) {
    if (q == 0.0f) return;
    if (d.g.size() != std::size_t{d.res_h} * d.res_h || d.h.size() != std::size_t{d.res_d} * d.res_d)
        throw Error("unweight_decomposition: the grids do not match their resolutions");
    const auto unweight = [q](std::vector<glm::vec3>& grid, uint32_t res) {
        for (std::size_t i = 0; i < grid.size(); ++i) {
            const double w = std::pow(shared::f64::gshd_grid_dir(static_cast<uint32_t>(i), res).z, static_cast<double>(q));
            grid[i] = glm::vec3(glm::dvec3(grid[i]) / w);
        }
    };
    unweight(d.g, d.res_h);
    unweight(d.h, d.res_d);
}

} // namespace specula::factorization
