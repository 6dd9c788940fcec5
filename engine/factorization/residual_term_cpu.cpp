// Reference for residual_term: the shader's loops in double (same skipping, same blocking,
// same pass order), so the differences are float rounding only.
#include "factorization/residual_term.h"

#include "core/error.h"
#include "core/parallel.h"

#include <cmath>
#include <limits>
#include <string>

namespace specula::factorization {

namespace {

struct BlockedSum2 { // numerator and denominator blocked together, as in the shader
    double total = 0.0, block = 0.0, wtotal = 0.0, wblock = 0.0;
    uint32_t in_block = 0, count = 0;
    void add(double x, double w) {
        ++count;
        block += x;
        wblock += w;
        if (++in_block == shared::kGshdSumBlock) {
            total += block;
            wtotal += wblock;
            block = wblock = 0.0;
            in_block = 0;
        }
    }
    [[nodiscard]] double num() const { return total + block; }
    [[nodiscard]] double den() const { return wtotal + wblock; }
};

} // namespace

void residual_terms_validate(const ResidualTermsInputs& in) {
    decomposition_validate({.matrix = in.matrix});
    if (in.first == nullptr) throw Error("residual_terms: no first term");
    if (in.first->res_h != in.matrix->res_h || in.first->res_d != in.matrix->res_d ||
        in.first->g.size() != in.matrix->rows() || in.first->h.size() != in.matrix->cols())
        throw Error("residual_terms: the first term's grids do not match the matrix");
    if (in.terms < 2 || in.terms > kMaxFactorTerms)
        throw Error("residual_terms: terms must be in [2, " + std::to_string(kMaxFactorTerms) + "] (got " +
                    std::to_string(in.terms) + ")");
    if (in.iterations < 1 || in.iterations > 1000) throw Error("residual_terms: iterations must be in [1, 1000]");
}

namespace {

/// Fits term k of `all` to F - sum_{j < active, j != k} G_j H_j: from the column RMS (cold) or
/// from the term's current H (warm), then `iterations` (G, H) pairs. Every G entry is a sum over
/// its row's columns and every H entry a sum over its column's rows, each added in the shader's
/// order by one worker: the same result for any thread count.
void fit_term(const BrdfMatrix& m, std::vector<Decomposition>& all, uint32_t k, uint32_t active, bool warm,
              uint32_t iterations, unsigned threads) {
    const std::size_t rows = m.rows();
    const std::size_t cols = m.cols();
    // The residual of one channel, a float as the shader holds it (exact in double); NaN marks
    // invalid entries.
    std::vector<float> r(rows * cols);
    std::vector<double> g(rows), h(cols);
    std::vector<BlockedSum2> sums(cols); // one per column
    constexpr std::size_t kRowChunk = 8, kColChunk = 1024;
    // Each column's sum over the rows in row order, as the shader adds them, taken row by row
    // over a range of columns (the matrix is row-major: a column at a time strode through all of it).
    const auto column_sums = [&](auto&& add) {
        parallel_for_chunks(cols, threads, kColChunk, [&](unsigned, std::size_t begin, std::size_t end) {
            for (std::size_t col = begin; col < end; ++col) sums[col] = BlockedSum2{};
            for (std::size_t row = 0; row < rows; ++row) {
                const float* rr = r.data() + row * cols;
                for (std::size_t col = begin; col < end; ++col)
                    if (!std::isnan(rr[col])) add(sums[col], double(rr[col]), row);
            }
        });
    };
    Decomposition& t = all[k];
    for (uint32_t c = 0; c < 3; ++c) {
        const int ci = static_cast<int>(c);
        parallel_for_chunks(rows, threads, kRowChunk, [&](unsigned, std::size_t begin, std::size_t end) {
            for (std::size_t row = begin; row < end; ++row)
                for (std::size_t col = 0; col < cols; ++col) {
                    const float v = m.at(c, row, col);
                    if (v < 0.0f) {
                        r[row * cols + col] = std::numeric_limits<float>::quiet_NaN();
                        continue;
                    }
                    // Same order as the shader: F - G_0 H_0 - G_1 H_1 ..., products of floats.
                    float acc = v;
                    for (uint32_t j = 0; j < active; ++j)
                        if (j != k) acc -= all[j].g[row][ci] * all[j].h[col][ci];
                    r[row * cols + col] = acc;
                }
        });
        // The shader reads back its own float G and H between passes: round the same way.
        if (warm) {
            for (std::size_t col = 0; col < cols; ++col) h[col] = t.h[col][ci];
        } else {
            column_sums([](BlockedSum2& s, double x, std::size_t) { s.add(x * x, 0.0); });
            for (std::size_t col = 0; col < cols; ++col) {
                const BlockedSum2& s = sums[col];
                h[col] = static_cast<float>(s.count > 0 ? std::sqrt(s.num() / s.count) : 0.0);
            }
        }
        for (uint32_t it = 0; it < iterations; ++it) {
            parallel_for_chunks(rows, threads, kRowChunk, [&](unsigned, std::size_t begin, std::size_t end) {
                for (std::size_t row = begin; row < end; ++row) {
                    BlockedSum2 s;
                    const float* rr = r.data() + row * cols;
                    for (std::size_t col = 0; col < cols; ++col)
                        if (!std::isnan(rr[col])) s.add(double(rr[col]) * h[col], h[col] * h[col]);
                    g[row] = static_cast<float>(s.den() > 0.0 ? s.num() / s.den() : 0.0);
                }
            });
            column_sums([&g](BlockedSum2& s, double x, std::size_t row) { s.add(x * g[row], g[row] * g[row]); });
            for (std::size_t col = 0; col < cols; ++col) {
                const BlockedSum2& s = sums[col];
                h[col] = static_cast<float>(s.den() > 0.0 ? s.num() / s.den() : 0.0);
            }
        }
        for (std::size_t row = 0; row < rows; ++row) t.g[row][ci] = static_cast<float>(g[row]);
        for (std::size_t col = 0; col < cols; ++col) t.h[col][ci] = static_cast<float>(h[col]);
    }
}

} // namespace

std::vector<Decomposition> residual_terms_cpu(const ResidualTermsInputs& in) {
    residual_terms_validate(in);
    const BrdfMatrix& m = *in.matrix;
    std::vector<Decomposition> all(in.terms, Decomposition{.res_h = m.res_h, .res_d = m.res_d,
                                                           .g = std::vector<glm::vec3>(m.rows(), glm::vec3(0.0f)),
                                                           .h = std::vector<glm::vec3>(m.cols(), glm::vec3(0.0f)),
                                                           .param = m.param, .warp = m.warp});
    all[0] = *in.first;
    // Only the greedy, cold form is used for terms 2..K: back-fitting (refitting every term to
    // F minus all the others, warm, also term 1) was measured and gains little: pepsi K = 4
    // matrix RMS 0.155 greedy, 0.144 with 6 cycles of terms 2..K, 0.132 with 10 cycles
    // including term 1 (plain GSHD; term 1 alone: refine_first_term_cpu).
    for (uint32_t k = 1; k < in.terms; ++k) fit_term(m, all, k, k, false, in.iterations, in.threads); // greedy deflation
    return {std::make_move_iterator(all.begin() + 1), std::make_move_iterator(all.end())};
}

Decomposition refine_first_term_cpu(const BrdfMatrix& m, const Decomposition& first, uint32_t iterations, unsigned threads) {
    residual_terms_validate({.matrix = &m, .first = &first, .terms = 2, .iterations = iterations});
    std::vector<Decomposition> all{first};
    fit_term(m, all, 0, 1, true, iterations, threads);
    return std::move(all[0]);
}

} // namespace specula::factorization
