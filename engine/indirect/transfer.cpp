// The transfer matrix's checks and the C++ reference of the per-frame gather (transfer.h).
#include "indirect/transfer.h"

#include "core/error.h"
#include "core/parallel.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace specula {

namespace {

// Rows per chunk of the parallel loop: ~30 entries a row, so a chunk is ~100k entries times
// the frames, long enough that handing chunks out costs nothing.
constexpr std::size_t kRowsPerChunk = 4096;

// Rows whose weights sum above 1 + this are refused (transfer.h). Each weight is the count of
// the row's rays that reach its source over K, rounded to float, so a row whose every ray hits
// sums to 1 within one float rounding (6e-8 relative) per entry: ~1e-5 for hundreds of entries.
constexpr double kRowSumSlack = 1e-4;

[[noreturn]] void refuse(const std::string& what) { throw Error("indirect transfer: " + what); }

std::string entry_name(std::uint32_t row, std::size_t k) {
    return "row " + std::to_string(row) + ", entry " + std::to_string(k);
}

} // namespace

void validate_transfer(const IndirectTransfer& t) {
    if (t.row_begin.size() != std::size_t{t.rows} + 1)
        refuse("row_begin holds " + std::to_string(t.row_begin.size()) + " offsets, " + std::to_string(t.rows) +
               " rows need " + std::to_string(std::size_t{t.rows} + 1));
    if (t.row_begin.front() != 0) refuse("row_begin[0] is " + std::to_string(t.row_begin.front()) + ", not 0");
    if (t.row_begin.back() != t.entries.size())
        refuse("row_begin[" + std::to_string(t.rows) + "] is " + std::to_string(t.row_begin.back()) + ", but there are " +
               std::to_string(t.entries.size()) + " entries");
    // The offsets first: with them rising from 0 to the entry count, every row's entries are in range.
    for (std::uint32_t i = 0; i < t.rows; ++i)
        if (t.row_begin[i + 1] < t.row_begin[i])
            refuse("row_begin falls at row " + std::to_string(i) + " (" + std::to_string(t.row_begin[i]) + " then " +
                   std::to_string(t.row_begin[i + 1]) + ")");
    for (std::uint32_t i = 0; i < t.rows; ++i) {
        const std::uint32_t begin = t.row_begin[i], end = t.row_begin[i + 1];
        double sum = 0.0;
        for (std::size_t k = begin; k < end; ++k) {
            const TransferEntry& e = t.entries[k];
            if (e.source >= t.rows)
                refuse(entry_name(i, k) + ": source " + std::to_string(e.source) + " out of range (" +
                       std::to_string(t.rows) + " rows)");
            if (k > begin && e.source <= t.entries[k - 1].source)
                refuse(entry_name(i, k) + ": source " + std::to_string(e.source) + " not above the previous entry's " +
                       std::to_string(t.entries[k - 1].source) + " (a row's sources rise)");
            if (!std::isfinite(e.weight) || e.weight < 0.0f)
                refuse(entry_name(i, k) + ": weight " + std::to_string(e.weight) + " is not a finite value >= 0");
            sum += e.weight;
        }
        if (sum > 1.0 + kRowSumSlack)
            refuse("row " + std::to_string(i) + ": weights sum to " + std::to_string(sum) +
                   ", above 1 (a row is a fraction of its particle's rays)");
    }
    if (!t.entry_direction.empty()) {
        if (t.entry_direction.size() != t.entries.size())
            refuse(std::to_string(t.entry_direction.size()) + " entry directions for " + std::to_string(t.entries.size()) +
                   " entries");
        for (std::uint32_t i = 0; i < t.rows; ++i)
            for (std::size_t k = t.row_begin[i]; k < t.row_begin[i + 1]; ++k) {
                const glm::vec4& d = t.entry_direction[k];
                const float length = glm::length(glm::vec3(d));
                if (!std::isfinite(length) || std::abs(length - 1.0f) > 1e-3f || !(std::abs(d.w) <= 1.0f + 1e-5f))
                    refuse(entry_name(i, k) + ": direction (" + std::to_string(d.x) + ", " + std::to_string(d.y) + ", " +
                           std::to_string(d.z) + ") with cosine " + std::to_string(d.w) +
                           " is not a unit vector with a cosine in [-1, 1]");
            }
    }
    for (std::size_t p = 0; p < t.row_of.size(); ++p)
        if (t.row_of[p] >= t.rows)
            refuse("particle " + std::to_string(p) + ": row " + std::to_string(t.row_of[p]) + " out of range (" +
                   std::to_string(t.rows) + " rows)");
}

void validate_gather(const IndirectTransfer& t, std::size_t radiosity, std::uint32_t frames, std::size_t out,
                     const char* who) {
    validate_transfer(t);
    const std::size_t want = std::size_t{frames} * t.rows;
    if (radiosity != want || out != want)
        throw Error(std::string(who) + ": " + std::to_string(frames) + " frames of " + std::to_string(t.rows) +
                    " particles need " + std::to_string(want) + " radiosity and output values, got " +
                    std::to_string(radiosity) + " and " + std::to_string(out));
}

namespace {

// The sources' values particle by particle, the frames of one particle side by side: an entry
// then reads one or two cache lines for all the frames, not one line per frame (frame-major,
// the sources are scattered over `frames` arrays of rows x 16 bytes). Empty for one frame.
// `out` keeps its storage from call to call (a caller's scratch: no fresh pages a batch).
void by_source(std::span<const glm::vec4> radiosity, std::size_t rows, std::uint32_t frames, unsigned threads,
               std::vector<glm::vec4>& out) {
    if (frames <= 1) return;
    out.resize(rows * frames);
    parallel_for_chunks(rows, threads, kRowsPerChunk, [&](unsigned, std::size_t first, std::size_t last) {
        for (std::size_t j = first; j < last; ++j)
            for (std::size_t f = 0; f < frames; ++f) out[j * frames + f] = radiosity[f * rows + j];
    });
}

// Both gathers: Sum (a glm vector of doubles or floats) accumulates each row's terms in entry order.
template <typename Sum>
void gather(const IndirectTransfer& t, std::span<const glm::vec4> radiosity, std::uint32_t frames, std::span<glm::vec4> out,
            unsigned threads, std::vector<glm::vec4>* scratch = nullptr) {
    const std::size_t rows = t.rows;
    std::vector<glm::vec4> own;
    std::vector<glm::vec4>& transposed = scratch != nullptr ? *scratch : own;
    by_source(radiosity, rows, frames, threads, transposed);
    const glm::vec4* source = frames > 1 ? transposed.data() : radiosity.data();
    parallel_for_chunks(rows, threads, kRowsPerChunk, [&](unsigned, std::size_t first, std::size_t last) {
        std::vector<Sum> sum(frames);
        for (std::size_t i = first; i < last; ++i) {
            std::fill(sum.begin(), sum.end(), Sum(0));
            for (std::uint32_t k = t.row_begin[i]; k < t.row_begin[i + 1]; ++k) {
                const TransferEntry e = t.entries[k];
                const glm::vec4* b = source + static_cast<std::size_t>(e.source) * frames;
                if (k + detail::kPrefetchAhead < t.entries.size())
                    detail::prefetch(source + std::size_t{t.entries[k + detail::kPrefetchAhead].source} * frames,
                                     frames * sizeof(glm::vec4));
                for (std::size_t f = 0; f < frames; ++f) sum[f] += static_cast<typename Sum::value_type>(e.weight) * Sum(b[f]);
            }
            // w: 0 whatever the radiosity's w held (transfer.h).
            for (std::size_t f = 0; f < frames; ++f) out[f * rows + i] = glm::vec4(glm::vec3(sum[f]), 0.0f);
        }
    });
}

} // namespace

void gather_indirect_cpu(const IndirectTransfer& t, std::span<const glm::vec4> radiosity, std::uint32_t frames,
                         std::span<glm::vec4> out, unsigned threads) {
    validate_gather(t, radiosity.size(), frames, out.size(), "gather_indirect_cpu");
    gather<glm::dvec3>(t, radiosity, frames, out, threads);
}

void gather_indirect_float(const IndirectTransfer& t, std::span<const glm::vec4> radiosity, std::uint32_t frames,
                           std::span<glm::vec4> out, unsigned threads) {
    validate_gather(t, radiosity.size(), frames, out.size(), "gather_indirect_float");
    gather<glm::vec4>(t, radiosity, frames, out, threads);
}

void detail::gather_indirect_float_unchecked(const IndirectTransfer& t, std::span<const glm::vec4> radiosity,
                                             std::uint32_t frames, std::span<glm::vec4> out, unsigned threads,
                                             std::vector<glm::vec4>* scratch) {
    gather<glm::vec4>(t, radiosity, frames, out, threads, scratch);
}

std::vector<detail::TransferRowChunk> detail::transfer_row_chunks(const IndirectTransfer& t, std::uint64_t max_entries) {
    std::vector<detail::TransferRowChunk> chunks;
    for (std::uint32_t first = 0; first < t.rows;) {
        std::uint32_t last = first + 1;
        while (last < t.rows && t.row_begin[last + 1] - t.row_begin[first] <= max_entries) ++last;
        chunks.push_back({first, last});
        first = last;
    }
    return chunks;
}

} // namespace specula
