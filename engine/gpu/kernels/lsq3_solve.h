#pragma once
// lsq3_solve: per element, the weighted 3x3 least-squares solve
//     g = argmin sum_i w_i (a_i . g - b_i)^2
// with a status and a reciprocal condition estimate per element. The math,
// thresholds and statuses are in shaders/shared/solve3.h (one source for GLSL and
// C++); the diffuse solve's photometric mode reuses this kernel.
//
// Inputs are CSR: element e owns rows[row_offsets[e] .. row_offsets[e + 1]).
// The layouts below are the std430 layouts the shader reads (checked by static_assert).
#include "gpu/buffer.h"
#include "gpu/pipeline.h"
#include "gpu/sequence.h"
#include "shared/solve3.h"

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

namespace specula::gpu {

using Lsq3Row = shared::Lsq3Row;       // a_x, a_y, a_z, b, w: 20 bytes
using Lsq3Result = shared::Lsq3Result; // g, rcond, rss, status, rows: 32 bytes
static_assert(sizeof(Lsq3Row) == 20 && offsetof(Lsq3Row, b) == 12 && offsetof(Lsq3Row, w) == 16);
static_assert(sizeof(Lsq3Result) == 32 && offsetof(Lsq3Result, rcond) == 12 && offsetof(Lsq3Result, status) == 20 &&
              offsetof(Lsq3Result, rows) == 24);

enum class Lsq3Status : uint32_t {
    Ok = shared::kLsq3Ok,
    IllConditioned = shared::kLsq3IllConditioned,
    TooFewRows = shared::kLsq3TooFewRows,
    InvalidInput = shared::kLsq3InvalidInput,
};
[[nodiscard]] const char* lsq3_status_name(uint32_t status) noexcept;

struct Lsq3Inputs {
    std::span<const uint32_t> row_offsets; // element_count + 1 entries, non-decreasing, front() == 0
    std::span<const Lsq3Row> rows;         // row_offsets.back() rows
    [[nodiscard]] std::size_t element_count() const noexcept {
        return row_offsets.empty() ? 0 : row_offsets.size() - 1;
    }
};

/// Throws InputError-like specula::Error when the CSR offsets are inconsistent.
void lsq3_validate(const Lsq3Inputs& in);

/// The reference: accumulates and solves in double (shared::f64), rounds the result to float.
[[nodiscard]] std::vector<Lsq3Result> lsq3_solve_cpu(const Lsq3Inputs& in);

struct Lsq3SolveVkOptions {
    /// Upper bound on the bytes of one binding; 0 = the device's maxStorageBufferRange.
    /// Problems larger than this are solved in chunks (tests lower it to exercise chunking).
    uint64_t max_binding_bytes = 0;
    uint32_t workgroup_size = 64;
};

/// The Vulkan kernel. Owns its pipeline and grows its buffers as needed (they are
/// reused between run() calls of similar size).
class Lsq3SolveVk {
public:
    explicit Lsq3SolveVk(Context& ctx, Lsq3SolveVkOptions options = {});
    [[nodiscard]] std::vector<Lsq3Result> run(const Lsq3Inputs& in);
    /// Sum of the GPU times of the last run's dispatches, in ns (nullopt without timestamps).
    [[nodiscard]] std::optional<double> last_gpu_ns() const noexcept { return m_last_gpu_ns; }
    /// Number of chunks the last run needed (1 when everything fit one binding).
    [[nodiscard]] uint32_t last_chunk_count() const noexcept { return m_last_chunks; }

private:
    Context* m_ctx;
    Lsq3SolveVkOptions m_options;
    ComputePipeline m_pipeline;
    Sequence m_sequence;
    std::optional<Buffer> m_offsets;
    std::optional<Buffer> m_rows;
    std::optional<Buffer> m_results;
    std::optional<double> m_last_gpu_ns;
    uint32_t m_last_chunks = 0;
};

} // namespace specula::gpu
