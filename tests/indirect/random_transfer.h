#pragma once
// Seeded random transfer matrices and radiosity for the gather's conformance test and
// bench/indirect_bench, and the directed lobe's inputs for its own (random_lobe_inputs). Rows
// are built as transfer.h says a real one is: K rays, each hit adds 1/K to the entry of the
// particle it reaches (here a random one: sources drawn uniformly, the worst case for the
// radiosity reads, where a real object's rays mostly reach particles near the receiver), the
// misses add nothing; entries by increasing source.
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

/// The directed lobe's inputs (indirect/lobe.h) besides the transfer and the material.
struct RandomLobeInputs {
    std::vector<glm::vec3> row_normal;    ///< per row
    std::vector<glm::vec4> light_geometry; ///< rows x frames, r * frames + f
    std::vector<glm::vec3> intensity;     ///< per frame
};

struct RandomLobeOptions {
    double below = 0.1;  ///< fraction of entries leaving their source from under its surface (v.w <= 0; a tenth of them 0)
    double behind = 0.2; ///< fraction of (source, frame) lights behind the source (N.u < 0)
    double unlit = 0.1;  ///< fraction of (source, frame) with no lit particle (geometry 0)
    /// |N.u| at least this: the float and double paths then agree on which lights are behind
    /// (N.u is a float dot product within ~3 2^-24 of the double one).
    float min_abs_cos = 1e-3f;
};

/// Sets t's entry directions and draws the rest of the directed lobe's inputs: random unit
/// normals; per entry a unit direction v in its source's upper hemisphere (or, for a fraction
/// `below`, its lower one) with v.w = N_j.v; per (source, frame) a unit direction toward the
/// light in front of the source (or behind, for a fraction `behind`) and a geometry factor
/// spread over two decades (0 for a fraction `unlit`); per frame an rgb intensity spread over
/// decades, as random_radiosity's scales.
inline RandomLobeInputs random_lobe_inputs(IndirectTransfer& t, std::uint32_t frames, const RandomLobeOptions& o,
                                           std::uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> uni(0.0f, 1.0f);
    std::normal_distribution<float> gauss(0.0f, 1.0f);
    const auto sphere = [&] {
        for (;;) {
            const glm::vec3 d(gauss(rng), gauss(rng), gauss(rng));
            const float length = glm::length(d);
            if (length > 1e-3f) return d / length;
        }
    };
    RandomLobeInputs in;
    in.row_normal.resize(t.rows);
    for (glm::vec3& n : in.row_normal) n = sphere();
    t.entry_direction.resize(t.entries.size());
    for (std::size_t k = 0; k < t.entries.size(); ++k) {
        const glm::vec3& n = in.row_normal[t.entries[k].source];
        glm::vec3 v = sphere();
        const bool below = uni(rng) < o.below;
        if ((glm::dot(n, v) > 0.0f) == below) v = -v;
        const float c = glm::clamp(glm::dot(n, v), -1.0f, 1.0f);
        t.entry_direction[k] = glm::vec4(v, below && uni(rng) < 0.1f ? 0.0f : c);
    }
    in.light_geometry.resize(std::size_t{t.rows} * frames);
    for (std::uint32_t j = 0; j < t.rows; ++j)
        for (std::uint32_t f = 0; f < frames; ++f) {
            const glm::vec3& n = in.row_normal[j];
            const bool behind = uni(rng) < o.behind;
            glm::vec3 u;
            do {
                u = sphere();
                if ((glm::dot(n, u) > 0.0f) == behind) u = -u;
            } while (std::abs(glm::dot(n, u)) < o.min_abs_cos);
            const float g = uni(rng) < o.unlit ? 0.0f : std::pow(10.0f, -2.0f * uni(rng));
            in.light_geometry[std::size_t{j} * frames + f] = glm::vec4(u, g);
        }
    in.intensity.resize(frames);
    for (std::uint32_t f = 0; f < frames; ++f) {
        const float scale = std::pow(10.0f, static_cast<float>(f % 4));
        in.intensity[f] = scale * glm::vec3(0.5f + uni(rng), 0.5f + uni(rng), 0.5f + uni(rng));
    }
    return in;
}

} // namespace specula::test
