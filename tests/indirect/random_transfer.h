#pragma once
// Seeded random transfer matrices and radiosity for the gather's conformance test and
// bench/indirect_bench. Rows are built as transfer.h says a real one is: K rays, each hit adds
// 1/K to the entry of the particle it reaches (here a random one: sources drawn uniformly,
// the worst case for the radiosity reads, where a real object's rays mostly reach particles
// near the receiver), the misses add nothing; entries by increasing source.
#include "indirect/transfer.h"

#include <glm/glm.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <random>
#include <vector>

namespace specula::test {

struct RandomTransferOptions {
    std::uint32_t rows = 1000;
    std::uint32_t rays = 64;       ///< K
    double hit_fraction = 0.5;     ///< mean fraction of a row's rays that hit (0: every row empty)
    std::uint32_t min_hits = 0;    ///< each row's hits are drawn in [min_hits, max_hits] ...
    std::uint32_t max_hits = 64;   ///< ... around hit_fraction K
    double empty_rows = 0.0;       ///< fraction of rows with no entry at all (rays that all leave)
    std::uint32_t hub = UINT32_MAX; ///< a source that each row also reaches with probability hub_fraction
    double hub_fraction = 0.0;
    std::uint32_t seed = 1;
};

/// A row's hit count is binomial(K, hit_fraction) clamped to [min_hits, max_hits] (at most K).
inline IndirectTransfer random_transfer(const RandomTransferOptions& o) {
    std::mt19937 rng(o.seed);
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    std::uniform_int_distribution<std::uint32_t> pick(0, o.rows == 0 ? 0 : o.rows - 1);
    std::binomial_distribution<std::uint32_t> hits_of(o.rays, o.hit_fraction);
    IndirectTransfer t;
    t.rows = o.rows;
    t.rays_per_row = o.rays;
    t.row_begin.reserve(std::size_t{o.rows} + 1);
    t.row_begin.push_back(0);
    std::map<std::uint32_t, std::uint32_t> counts; // source -> rays that reached it
    for (std::uint32_t i = 0; i < o.rows; ++i) {
        counts.clear();
        if (uni(rng) >= o.empty_rows) {
            const std::uint32_t hits = std::min({std::max(hits_of(rng), o.min_hits), o.max_hits, o.rays});
            for (std::uint32_t r = 0; r < hits; ++r) {
                const bool to_hub = o.hub < o.rows && uni(rng) < o.hub_fraction;
                ++counts[to_hub ? o.hub : pick(rng)];
            }
        }
        for (const auto& [source, n] : counts)
            t.entries.push_back({source, static_cast<float>(n) / static_cast<float>(o.rays)});
        t.row_begin.push_back(static_cast<std::uint32_t>(t.entries.size()));
    }
    return t;
}

/// frames x rows radiosity values, rgb in [0, scale) with the frames' scales spread over
/// decades (w: a value the gather must ignore).
inline std::vector<glm::vec4> random_radiosity(std::uint32_t rows, std::uint32_t frames, std::uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> uni(0.0f, 1.0f);
    std::vector<glm::vec4> b(std::size_t{rows} * frames);
    for (std::uint32_t f = 0; f < frames; ++f) {
        const float scale = std::pow(10.0f, static_cast<float>(f % 5) - 2.0f);
        for (std::uint32_t j = 0; j < rows; ++j)
            b[std::size_t{f} * rows + j] = glm::vec4(scale * uni(rng), scale * uni(rng), scale * uni(rng), -7.0f);
    }
    return b;
}

} // namespace specula::test
