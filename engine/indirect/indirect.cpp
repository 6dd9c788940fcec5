#include "indirect/indirect.h"

#include "core/error.h"
#include "core/parallel.h"
#include "core/timer.h"

#include "shared/material.h"

#include <glm/gtc/constants.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>
#include <unordered_map>

namespace specula {

namespace {

// The mean cosine of a cosine-weighted hemisphere (indirect.h).
constexpr float kMeanCosine = 2.0f / 3.0f;

// splitmix64 (Steele, Lea and Flood 2014): a counter-based hash, so a ray's numbers depend on
// (seed, particle, ray) alone and not on the thread that casts it.
std::uint64_t mix(std::uint64_t z) {
    z += 0x9E3779B97F4A7C15ull;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}
float unit(std::uint64_t bits) { return static_cast<float>(bits >> 40) * (1.0f / 16777216.0f); } // [0, 1)

// An orthonormal basis around a unit normal (Duff et al. 2017, "Building an orthonormal basis,
// revisited", JCGT 6(1)).
void basis(const glm::vec3& n, glm::vec3& t, glm::vec3& b) {
    const float sign = std::copysign(1.0f, n.z);
    const float a = -1.0f / (sign + n.z);
    const float c = n.x * n.y * a;
    t = glm::vec3(1.0f + sign * n.x * n.x * a, sign * c, -sign * n.x);
    b = glm::vec3(c, sign + n.y * n.y * a, -n.y);
}

// The atlas point (texel coordinates) of barycentrics (u, v) of a triangle.
glm::vec2 atlas_point(const Atlas& atlas, std::uint32_t triangle, float u, float v) {
    const glm::dvec2 c0 = atlas.corner_texel(triangle, 0), c1 = atlas.corner_texel(triangle, 1), c2 = atlas.corner_texel(triangle, 2);
    return glm::vec2(c0 + static_cast<double>(u) * (c1 - c0) + static_cast<double>(v) * (c2 - c0));
}

// The specular lobe's directional albedo a_s(c) = integral of f_s(u, w) N.w dw over the
// hemisphere, u at cosine c to the normal: the share of a source's light that its lobe reflects
// (spread diffusely here: its later bounces, and its first without the transfer's directions),
// and by reciprocity what a receiver's lobe sends toward the camera at cosine c of light that
// arrives from all over its hemisphere.
// Tabulated at kSteps cosines by a stratified cosine-weighted quadrature (64 x 64 strata:
// integral = pi x the mean of f_s), clamped to [0, 1] (a fitted lobe need not conserve energy).
class LobeAlbedo {
public:
    explicit LobeAlbedo(const std::optional<SpecularModel>& material) {
        const shared::MaterialGpu m = material_gpu(material);
        m_zero = !material || is_zero(*material);
        if (m_zero) return;
        constexpr int kGrid = 64;
        for (int k = 0; k < kSteps; ++k) {
            const float c = std::max(1e-3f, static_cast<float>(k) / (kSteps - 1));
            const glm::vec3 u(std::sqrt(1.0f - c * c), 0.0f, c);
            glm::dvec3 sum(0.0);
            for (int i = 0; i < kGrid; ++i)
                for (int j = 0; j < kGrid; ++j) {
                    const float r2 = (static_cast<float>(i) + 0.5f) / kGrid, phi = glm::two_pi<float>() * (static_cast<float>(j) + 0.5f) / kGrid;
                    const float r = std::sqrt(r2);
                    const glm::vec3 w(r * std::cos(phi), r * std::sin(phi), std::sqrt(1.0f - r2));
                    sum += glm::dvec3(shared::material_specular(m, c, w.z, glm::dot(u, w)));
                }
            m_table[k] = glm::clamp(glm::vec3(glm::pi<double>() * sum / double(kGrid * kGrid)), 0.0f, 1.0f);
        }
    }
    [[nodiscard]] bool zero() const noexcept { return m_zero; }
    [[nodiscard]] glm::vec3 operator()(float c) const {
        if (m_zero) return glm::vec3(0.0f);
        const float x = std::clamp(c, 0.0f, 1.0f) * (kSteps - 1);
        const int k = std::min(static_cast<int>(x), kSteps - 2);
        return glm::mix(m_table[k], m_table[k + 1], x - static_cast<float>(k));
    }

private:
    static constexpr int kSteps = 33;
    bool m_zero = true;
    glm::vec3 m_table[kSteps]{};
};

// The bilinear taps of an atlas point (texel coordinates): texel (i, j) centred at (i + 0.5,
// j + 0.5), clamped at the atlas's edges.
struct Taps {
    int x0, y0, x1, y1;
    float ax, ay;
};
Taps taps_of(const Atlas& atlas, glm::vec2 q) {
    const float fx = std::clamp(q.x - 0.5f, 0.0f, static_cast<float>(atlas.width - 1));
    const float fy = std::clamp(q.y - 0.5f, 0.0f, static_cast<float>(atlas.height - 1));
    const int x0 = static_cast<int>(fx), y0 = static_cast<int>(fy);
    return {x0, y0, std::min(x0 + 1, static_cast<int>(atlas.width) - 1), std::min(y0 + 1, static_cast<int>(atlas.height) - 1),
            fx - static_cast<float>(x0), fy - static_cast<float>(y0)};
}

glm::vec3 face_normal(const Mesh& mesh, std::uint32_t triangle) {
    const glm::uvec3 t = mesh.triangles[triangle];
    return glm::normalize(glm::cross(mesh.positions[t.y] - mesh.positions[t.x], mesh.positions[t.z] - mesh.positions[t.x]));
}

// Each row's particles, in particle order: row r's are members[begin[r], begin[r + 1]).
struct RowMembers {
    std::vector<std::uint32_t> begin, members;
};
RowMembers row_members(std::span<const std::uint32_t> row_of, std::uint32_t rows, std::size_t particles) {
    RowMembers m;
    m.begin.assign(std::size_t{rows} + 1, 0);
    m.members.resize(particles);
    if (row_of.empty()) {
        std::iota(m.begin.begin(), m.begin.end(), 0u);
        std::iota(m.members.begin(), m.members.end(), 0u);
        return m;
    }
    for (const std::uint32_t r : row_of) ++m.begin[r + 1];
    std::partial_sum(m.begin.begin(), m.begin.end(), m.begin.begin());
    std::vector<std::uint32_t> next(m.begin.begin(), m.begin.end() - 1);
    for (std::size_t i = 0; i < particles; ++i) m.members[next[row_of[i]]++] = static_cast<std::uint32_t>(i);
    return m;
}

// Each row's mean position and mean unit normal (the particle's own for a row of one).
void row_frames(std::span<const Particle> particles, const RowMembers& rows, std::vector<glm::vec3>& position,
                std::vector<glm::vec3>& normal) {
    const std::size_t n = rows.begin.size() - 1;
    position.assign(n, glm::vec3(0.0f));
    normal.assign(n, glm::vec3(0.0f));
    for (std::size_t r = 0; r < n; ++r) {
        glm::vec3 p(0.0f), nsum(0.0f);
        for (std::uint32_t q = rows.begin[r]; q < rows.begin[r + 1]; ++q) {
            p += particles[rows.members[q]].p();
            nsum += particles[rows.members[q]].n();
        }
        const float count = static_cast<float>(rows.begin[r + 1] - rows.begin[r]);
        const float length = glm::length(nsum);
        position[r] = p / count;
        // Opposite normals in one block (a fold within a chart) cancel: the first particle's stands in.
        normal[r] = length > 1e-3f * count ? nsum / length : particles[rows.members[rows.begin[r]]].n();
    }
}

// The rows of a transfer with blocks of `block` x `block` texels: per particle its row, the rows
// numbered in the order of their first particle. Empty for block 1 (row i is particle i).
std::vector<std::uint32_t> block_rows(std::span<const Particle> particles, const Atlas& atlas, std::uint32_t block,
                                      std::uint32_t& rows) {
    rows = static_cast<std::uint32_t>(particles.size());
    if (block <= 1) return {};
    // A block never spans two charts (or two patches): their texels may neighbour in the atlas
    // while their surfaces lie apart.
    std::unordered_map<std::uint64_t, std::uint32_t> ids;
    ids.reserve(particles.size() / (std::size_t{block} * block) + 1);
    std::vector<std::uint32_t> row_of(particles.size());
    for (std::size_t i = 0; i < particles.size(); ++i) {
        const Particle& p = particles[i];
        const std::uint64_t group = atlas.chart_of.empty() ? p.triangle : atlas.chart_of[p.triangle];
        const std::uint64_t key = (group << 30) | (std::uint64_t{p.texel_y() / block} << 15) | (p.texel_x() / block);
        row_of[i] = ids.try_emplace(key, static_cast<std::uint32_t>(ids.size())).first->second;
    }
    rows = static_cast<std::uint32_t>(ids.size());
    return row_of;
}

} // namespace

std::uint32_t transfer_block_for(std::size_t particles) {
    const double side = std::round(std::sqrt(static_cast<double>(particles) / kTransferBlockRows));
    return static_cast<std::uint32_t>(std::clamp(side, static_cast<double>(kTransferBlock), 64.0));
}

std::vector<std::uint32_t> row_stand_ins(const IndirectTransfer& t) {
    std::vector<std::uint32_t> first(t.rows, Atlas::kEmpty), out(t.row_of.size());
    for (std::size_t p = 0; p < t.row_of.size(); ++p) {
        std::uint32_t& f = first[t.row_of[p]];
        if (f == Atlas::kEmpty) f = static_cast<std::uint32_t>(p);
        out[p] = f;
    }
    return out;
}

IndirectTransfer build_transfer(std::span<const Particle> particles, const Mesh& mesh, const RayScene& scene,
                                const Atlas& atlas, const TransferOptions& options, TransferStats* stats) {
    const Stopwatch clock;
    if (particles.size() >= std::numeric_limits<std::uint32_t>::max())
        throw Error("indirect light: " + std::to_string(particles.size()) + " particles exceed the transfer's 32-bit indices");
    if (options.rays == 0) throw Error("indirect light: a transfer needs at least one ray per particle");
    if (options.block == 0 || options.block > 64) throw Error("indirect light: a transfer's blocks are 1 to 64 texels wide");
    const std::uint32_t grid = static_cast<std::uint32_t>(std::ceil(std::sqrt(static_cast<double>(options.rays))));
    const std::uint32_t rays = grid * grid;
    IndirectTransfer out;
    out.rays_per_row = rays;
    out.row_of = block_rows(particles, atlas, options.block, out.rows);
    const RowMembers rm = row_members(out.row_of, out.rows, particles.size());
    std::vector<glm::vec3> row_position, row_normal;
    row_frames(particles, rm, row_position, row_normal);
    // Which row holds each texel (the particles own distinct texels, atlas.h).
    std::vector<std::uint32_t> holder(static_cast<std::size_t>(atlas.width) * atlas.height, Atlas::kEmpty);
    for (std::size_t i = 0; i < particles.size(); ++i)
        holder[static_cast<std::size_t>(particles[i].texel_y()) * atlas.width + particles[i].texel_x()] =
            out.row_of.empty() ? static_cast<std::uint32_t>(i) : out.row_of[i];

    std::vector<std::vector<TransferEntry>> rows(out.rows);
    std::vector<std::vector<glm::vec4>> directions(out.rows);
    const unsigned workers = parallel_workers(out.rows, std::max(options.threads, 1u), 256);
    std::vector<TransferStats> counts(workers);
    parallel_for_chunks(out.rows, std::max(options.threads, 1u), 256, [&](unsigned worker, std::size_t begin, std::size_t end) {
        TransferStats& st = counts[worker];
        // A hit: its source row and the direction from the source back toward the ray's origin.
        std::vector<std::pair<std::uint32_t, glm::vec3>> sources;
        // Where the row's particles cast from: the origin, the face normal, the shading frame.
        struct Start {
            glm::vec3 origin, ng, n, t, b;
        };
        std::vector<Start> starts;
        for (std::size_t i = begin; i < end; ++i) {
            const std::uint32_t first = rm.begin[i], count = rm.begin[i + 1] - first;
            starts.clear();
            for (std::uint32_t q = first; q < first + count; ++q) {
                const Particle& p = particles[rm.members[q]];
                Start st{.origin = {}, .ng = face_normal(mesh, p.triangle), .n = p.n(), .t = {}, .b = {}};
                // A degenerate triangle has no face: its particle's normal stands in.
                if (!std::isfinite(st.ng.x + st.ng.y + st.ng.z)) st.ng = st.n;
                if (glm::dot(st.ng, st.n) < 0.0f) st.ng = -st.ng;
                st.origin = p.p() + scene.ray_offset() * st.ng;
                basis(st.n, st.t, st.b);
                starts.push_back(st);
            }
            sources.clear();
            std::uint32_t cast = 0;
            for (std::uint32_t s = 0; s < rays; ++s) {
                // The row's particles take the rays in turn, shifted by one each grid row, so that
                // each gets strata at every radius and every angle.
                const Start& from = starts[(s % grid + s / grid) % count];
                const glm::vec3 &n = from.n, &ng = from.ng, &origin = from.origin, &t = from.t, &b = from.b;
                const std::uint64_t h = mix(options.seed ^ mix((static_cast<std::uint64_t>(i) << 24) ^ s));
                const float u1 = (static_cast<float>(s % grid) + unit(h)) / static_cast<float>(grid);
                const float u2 = (static_cast<float>(s / grid) + unit(mix(h))) / static_cast<float>(grid);
                // Cosine-weighted (Malley's method): a uniform point on the disc, lifted to the hemisphere.
                const float r = std::sqrt(u1), phi = glm::two_pi<float>() * u2;
                const glm::vec3 dir = r * std::cos(phi) * t + r * std::sin(phi) * b + std::sqrt(std::max(0.0f, 1.0f - u1)) * n;
                if (glm::dot(dir, ng) <= 0.0f) {
                    ++st.below_surface;
                    continue;
                }
                ++st.rays;
                ++cast;
                const std::optional<RayHit> hit = scene.intersect(origin, dir, 0.0f, std::numeric_limits<float>::infinity());
                if (!hit) continue;
                if (glm::dot(face_normal(mesh, hit->triangle), dir) >= 0.0f) {
                    ++st.back_faces;
                    continue;
                }
                const glm::vec2 q = atlas_point(atlas, hit->triangle, hit->u, hit->v);
                const auto x = static_cast<std::int64_t>(std::floor(q.x)), y = static_cast<std::int64_t>(std::floor(q.y));
                const std::uint32_t j = x >= 0 && y >= 0 && x < atlas.width && y < atlas.height
                                            ? holder[static_cast<std::size_t>(y) * atlas.width + static_cast<std::size_t>(x)]
                                            : Atlas::kEmpty;
                if (j == Atlas::kEmpty) {
                    ++st.unmapped;
                    continue;
                }
                ++st.hits;
                sources.emplace_back(j, -dir);
            }
            // Each ray cast stands for 1 / cast of the hemisphere: the directions under the face
            // (where the interpolated normal tilts away from it) are left to the others, rather
            // than counted as black.
            const float weight = cast > 0 ? 1.0f / static_cast<float>(cast) : 0.0f;
            std::sort(sources.begin(), sources.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
            std::vector<TransferEntry>& row = rows[i];
            std::vector<glm::vec4>& toward = directions[i];
            for (std::size_t k = 0; k < sources.size();) {
                std::size_t e = k;
                glm::vec3 sum(0.0f);
                for (; e < sources.size() && sources[e].first == sources[k].first; ++e) sum += sources[e].second;
                const std::uint32_t j = sources[k].first;
                // Rays that reach one source from a row leave within a few texels' angle of each other.
                const glm::vec3 d = glm::length(sum) > 0.0f ? glm::normalize(sum) : sources[k].second;
                row.push_back({j, weight * static_cast<float>(e - k)});
                toward.emplace_back(d, std::clamp(glm::dot(row_normal[j], d), -1.0f, 1.0f));
                k = e;
            }
        }
    });
    out.row_begin.assign(std::size_t{out.rows} + 1, 0);
    for (std::size_t i = 0; i < rows.size(); ++i) out.row_begin[i + 1] = out.row_begin[i] + static_cast<std::uint32_t>(rows[i].size());
    out.entries.reserve(out.row_begin.back());
    out.entry_direction.reserve(out.row_begin.back());
    for (std::size_t i = 0; i < rows.size(); ++i) {
        out.entries.insert(out.entries.end(), rows[i].begin(), rows[i].end());
        out.entry_direction.insert(out.entry_direction.end(), directions[i].begin(), directions[i].end());
        std::vector<TransferEntry>().swap(rows[i]);
        std::vector<glm::vec4>().swap(directions[i]);
    }
    if (stats != nullptr) {
        *stats = {};
        for (const TransferStats& c : counts) {
            stats->rays += c.rays;
            stats->hits += c.hits;
            stats->below_surface += c.below_surface;
            stats->back_faces += c.back_faces;
            stats->unmapped += c.unmapped;
        }
        stats->block = options.block;
        stats->seconds = clock.seconds();
    }
    return out;
}

ViewAtlasMap build_view_atlas_map(const Camera& camera, const Mesh& mesh, const RayScene& scene, const Atlas& atlas,
                                  std::span<const Particle> particles, unsigned threads, const PixelHits* hits) {
    ViewAtlasMap map;
    map.width = camera.intrinsics.w;
    map.height = camera.intrinsics.h;
    const std::size_t n = static_cast<std::size_t>(std::max(map.width, 0)) * static_cast<std::size_t>(std::max(map.height, 0));
    std::optional<PixelHits> cast;
    if (hits == nullptr) hits = &cast.emplace(cast_pixel_hits(scene, camera, threads));
    if (!hits->fits(camera))
        throw Error("build_view_atlas_map: the pixel hits are not the camera's (" + std::to_string(hits->width) + "x" +
                    std::to_string(hits->height) + " for a " + std::to_string(map.width) + "x" + std::to_string(map.height) +
                    " image)");
    map.texel.assign(n, glm::vec2(-1.0f));
    map.cos_view.assign(n, 0.0f);
    parallel_for(static_cast<std::size_t>(std::max(map.height, 0)), std::max(threads, 1u), [&](std::size_t y) {
        for (int x = 0; x < map.width; ++x) {
            const std::size_t k = y * static_cast<std::size_t>(map.width) + static_cast<std::size_t>(x);
            const std::uint32_t triangle = hits->triangle[k];
            if (triangle == PixelHits::kMiss) continue;
            const glm::vec2 uv = hits->uv[k];
            const glm::vec3 dir(camera.ray_direction(x + 0.5, static_cast<double>(y) + 0.5));
            map.texel[k] = atlas_point(atlas, triangle, uv.x, uv.y);
            const SurfacePoint sp = surface_point(mesh, triangle, glm::dvec2(uv.x, uv.y));
            map.cos_view[k] = std::max(0.0f, -glm::dot(sp.normal, glm::normalize(dir)));
        }
    });
    std::vector<std::uint8_t> read(static_cast<std::size_t>(atlas.width) * atlas.height, 0);
    const auto mark = [&](int x, int y) { read[static_cast<std::size_t>(y) * atlas.width + static_cast<std::size_t>(x)] = 1; };
    for (const glm::vec2 q : map.texel) {
        if (q.x < 0.0f) continue;
        const Taps t = taps_of(atlas, q);
        mark(t.x0, t.y0), mark(t.x1, t.y0), mark(t.x0, t.y1), mark(t.x1, t.y1);
    }
    for (std::size_t i = 0; i < particles.size(); ++i)
        if (read[static_cast<std::size_t>(particles[i].texel_y()) * atlas.width + particles[i].texel_x()] != 0)
            map.reads.push_back(static_cast<std::uint32_t>(i));
    return map;
}

namespace {

void check_frames(const IndirectScene& s, std::span<const std::size_t> frames) {
    for (const std::size_t f : frames)
        if (f >= s.lights.size() || f >= s.frame_view.size() || f >= s.visibility->frame_count ||
            s.frame_view[f] >= s.view_maps.size())
            throw Error("indirect light: frame " + std::to_string(f) + " has no light, view or visibility");
        else if (f < s.visibility->lit_complete.size() && !s.visibility->lit_complete[f])
            throw Error("indirect light: frame " + std::to_string(f) + "'s lit bits hold only the particles its view sees "
                        "(VisibilityOptions::lit_seen_only): complete_lit must cast the rest first");
}

void check_scene(const IndirectScene& s, std::span<const std::size_t> frames, std::span<const glm::vec3> albedo) {
    if (s.visibility == nullptr || s.atlas == nullptr || s.transfer == nullptr)
        throw Error("indirect light: the scene lacks its visibility, atlas or transfer");
    const IndirectTransfer& t = *s.transfer;
    const std::size_t n = s.particles.size();
    if ((t.row_of.empty() ? t.rows : t.row_of.size()) != n || albedo.size() != n || s.visibility->particle_count != n)
        throw Error("indirect light: the transfer, the albedo and the visibility must have one entry per particle");
    validate_transfer(t);
    check_frames(s, frames);
}

// What the bounces need of a checked scene, built once per IndirectImages: the material, its
// lobe's table, each row's particles and their mean albedo, and the buffers of one batch of frames.
struct Bouncer {
    const IndirectScene& s;
    std::span<const glm::vec3> albedo;
    shared::MaterialGpu m;
    LobeAlbedo lobe;
    IndirectOptions o;
    RowMembers rows;
    std::vector<glm::vec3> row_albedo, row_position, row_normal;
    /// The lobe's first bounce sent where it goes (the transfer's entry directions), not spread.
    bool directional = false;
    std::vector<glm::vec4> radiosity, e, total;
    std::vector<glm::vec4> by_source; ///< the gather's scratch (detail::gather_indirect_float_unchecked)
    /// With `directional`, per row and frame (row-major: r * frames + k, 16 bytes: the lobe's
    /// gather reads one or two cache lines per entry): the direction toward the light (xyz) and
    /// the mean of I max(0, N.u) / d^2 / I over the row's particles (w; the direct irradiance is
    /// the light's intensity times it).
    std::vector<glm::vec4> light_geometry;
    std::vector<glm::vec3> intensity; ///< with `directional`: per frame of the batch, its light's intensity
    /// With `ratio`: per particle, its indirect and direct irradiance (r + g + b) summed over the
    /// frames that light it and whose view sees it.
    bool ratio = false;
    std::vector<double> sum_indirect, sum_direct;

    Bouncer(const IndirectScene& scene, std::span<const glm::vec3> a, const std::optional<SpecularModel>& material,
            const IndirectOptions& options)
        : s(scene), albedo(a), m(material_gpu(material)), lobe(material), o(options),
          rows(row_members(scene.transfer->row_of, scene.transfer->rows, scene.particles.size())),
          row_albedo(scene.transfer->rows) {
        directional = o.lobe_directions && !lobe.zero() && !scene.transfer->entry_direction.empty();
        row_frames(scene.particles, rows, row_position, row_normal);
        for (std::size_t r = 0; r < row_albedo.size(); ++r) {
            glm::vec3 sum(0.0f);
            for (std::uint32_t k = rows.begin[r]; k < rows.begin[r + 1]; ++k) sum += albedo[rows.members[k]];
            row_albedo[r] = sum / static_cast<float>(rows.begin[r + 1] - rows.begin[r]);
        }
    }
    [[nodiscard]] std::uint32_t row(std::size_t particle) const {
        return s.transfer->row_of.empty() ? static_cast<std::uint32_t>(particle) : s.transfer->row_of[particle];
    }

    // The indirect irradiance of every row for `frames`: total[k * rows + r] for frames[k].
    void run(std::span<const std::size_t> frames) {
        const std::size_t n = s.transfer->rows, values = frames.size() * n;
        radiosity.resize(values);
        e.resize(values);
        total.assign(values, glm::vec4(0.0f));
        if (directional) light_geometry.resize(values);
        const float kd_bounce = shared::material_diffuse_factor(m, kMeanCosine, kMeanCosine);
        const glm::vec3 lobe_bounce = lobe(kMeanCosine);
        // Bounce 1's sources: the frame's direct light on each particle, reflected diffusely (and
        // by the lobe, spread diffusely unless `directional`), the mean over each row's particles.
        // A row's particles stay in cache over the batch's frames.
        parallel_for_chunks(n, std::max(o.threads, 1u), 256, [&](unsigned, std::size_t begin, std::size_t end) {
            for (std::size_t r = begin; r < end; ++r) {
                for (std::size_t k = 0; k < frames.size(); ++k) {
                    const PointLight& light = s.lights[frames[k]];
                    glm::vec3 sum(0.0f);
                    double geometry = 0.0;
                    for (std::uint32_t q = rows.begin[r]; q < rows.begin[r + 1]; ++q) {
                        const std::uint32_t j = rows.members[q];
                        if (!s.visibility->lights(j, frames[k])) continue;
                        const glm::dvec3 to_light = light.position - glm::dvec3(s.particles[j].p());
                        const double d2 = glm::dot(to_light, to_light);
                        if (!(d2 > 0.0)) continue; // a light on the surface lights nothing through it (never a division by 0)
                        const double cos_in = glm::dot(glm::dvec3(s.particles[j].n()), to_light) / std::sqrt(d2);
                        if (!(cos_in > 0.0)) continue;
                        const float kd = shared::material_diffuse_factor(m, static_cast<float>(cos_in), kMeanCosine);
                        const glm::vec3 e0(light.intensity * (cos_in / d2));
                        sum += (albedo[j] * kd + (directional ? glm::vec3(0.0f) : lobe(static_cast<float>(cos_in)))) * e0;
                        geometry += cos_in / d2;
                        if (ratio && s.visibility->sees(j, s.frame_view[frames[k]])) sum_direct[j] += e0.x + e0.y + e0.z;
                    }
                    const float count = static_cast<float>(rows.begin[r + 1] - rows.begin[r]);
                    radiosity[k * n + r] = glm::vec4(sum / count, 0.0f);
                    if (directional) {
                        // A light at the block's centre lights none of its particles: no direction, no lobe light.
                        const glm::vec3 to_light = glm::vec3(light.position) - row_position[r];
                        const float length = glm::length(to_light);
                        const glm::vec3 u = length > 0.0f ? to_light / length : glm::vec3(0.0f);
                        light_geometry[r * frames.size() + k] = glm::vec4(u, static_cast<float>(geometry / count));
                    }
                }
            }
        });
        for (std::uint32_t bounce = 1; bounce <= o.bounces; ++bounce) {
            if (o.kernel != nullptr) {
                o.kernel->run(*s.transfer, radiosity, static_cast<std::uint32_t>(frames.size()), e);
            } else {
                detail::gather_indirect_float_unchecked(*s.transfer, radiosity, static_cast<std::uint32_t>(frames.size()), e,
                                                        o.threads, &by_source);
            }
            if (bounce == 1 && directional) add_directional_lobe(frames);
            const bool more = bounce < o.bounces;
            parallel_for_chunks(values, std::max(o.threads, 1u), 16384, [&](unsigned, std::size_t begin, std::size_t end) {
                for (std::size_t k = begin; k < end; ++k) {
                    total[k] += e[k];
                    if (more) radiosity[k] = glm::vec4(row_albedo[k % n] * kd_bounce + lobe_bounce, 0.0f) * e[k];
                }
            });
        }
        if (!ratio) return;
        parallel_for_chunks(s.particles.size(), std::max(o.threads, 1u), 4096, [&](unsigned, std::size_t begin, std::size_t end) {
            for (std::size_t i = begin; i < end; ++i)
                for (std::size_t k = 0; k < frames.size(); ++k)
                    if (s.visibility->lights(i, frames[k]) && s.visibility->sees(i, s.frame_view[frames[k]])) {
                        const glm::vec4& t = total[k * n + row(i)];
                        sum_indirect[i] += t.x + t.y + t.z;
                    }
        });
    }

    // Bounce 1 of the lobe, where it goes (lobe.h): each entry's rays left source j toward row i
    // in direction v (the transfer's entry direction), so row i gets pi w f_s(u_j, v) E0_j from
    // it (E = pi x the cosine-weighted mean of the radiance its rays meet, transfer.h). The
    // inputs are right by construction and the transfer was checked once (check_scene), so the
    // C++ path skips the checks; the kernel makes its own, as the gather's does.
    void add_directional_lobe(std::span<const std::size_t> frame_list) {
        const auto frames = static_cast<std::uint32_t>(frame_list.size());
        intensity.resize(frames);
        for (std::size_t f = 0; f < frames; ++f) intensity[f] = glm::vec3(s.lights[frame_list[f]].intensity);
        if (o.lobe_kernel != nullptr) {
            o.lobe_kernel->run(*s.transfer, m, row_normal, light_geometry, intensity, frames, e);
        } else {
            detail::add_directed_lobe_float_unchecked(*s.transfer, m, row_normal, light_geometry, intensity, frames, e,
                                                      o.threads);
        }
    }
};

} // namespace

std::vector<glm::vec4> indirect_irradiance(const IndirectScene& s, std::span<const std::size_t> frames,
                                           std::span<const glm::vec3> albedo, const std::optional<SpecularModel>& material,
                                           const IndirectOptions& o) {
    check_scene(s, frames, albedo);
    Bouncer bouncer(s, albedo, material, o);
    bouncer.run(frames);
    const std::size_t n = s.particles.size(), rows = s.transfer->rows;
    std::vector<glm::vec4> out(frames.size() * n);
    for (std::size_t k = 0; k < frames.size(); ++k)
        for (std::size_t i = 0; i < n; ++i) out[k * n + i] = bouncer.total[k * rows + bouncer.row(i)];
    return out;
}

struct IndirectImages::Impl {
    IndirectScene s;
    std::span<const glm::vec3> albedo;
    Bouncer bouncer;
    /// Per texel: rho E / pi (the diffuse term) and, with a lobe, E / pi (what the lobe reflects).
    Image radiance, irradiance;
    Image out; ///< the frame's image handed to the sink
    Impl(const IndirectScene& scene, std::span<const glm::vec3> a, const std::optional<SpecularModel>& material,
         const IndirectOptions& o)
        : s(scene), albedo(a), bouncer(s, albedo, material, o),
          radiance(static_cast<int>(scene.atlas->width), static_cast<int>(scene.atlas->height), 3, 0.0f),
          irradiance(bouncer.lobe.zero() ? Image()
                                         : Image(static_cast<int>(scene.atlas->width), static_cast<int>(scene.atlas->height), 3, 0.0f)) {}
};

IndirectImages::IndirectImages(const IndirectScene& s, std::span<const glm::vec3> albedo,
                               const std::optional<SpecularModel>& material, const IndirectOptions& o) {
    check_scene(s, {}, albedo);
    m_impl = std::make_unique<Impl>(s, albedo, material, o);
}
IndirectImages::~IndirectImages() = default;

void IndirectImages::render(std::span<const std::size_t> frames, const std::function<void(std::size_t, const Image&)>& sink,
                            std::vector<float>* ratio) {
    Impl& im = *m_impl;
    const IndirectScene& s = im.s;
    check_frames(s, frames);
    const std::size_t n = s.particles.size(), rows = s.transfer->rows;
    const Atlas& atlas = *s.atlas;
    Bouncer& bouncer = im.bouncer;
    bouncer.ratio = ratio != nullptr;
    if (bouncer.ratio) {
        bouncer.sum_indirect.assign(n, 0.0);
        bouncer.sum_direct.assign(n, 0.0);
    }
    const std::span<const glm::vec3> albedo = im.albedo;
    const shared::MaterialGpu& m = bouncer.m;
    const LobeAlbedo& lobe = bouncer.lobe;
    const unsigned threads = std::max(bouncer.o.threads, 1u);
    Image& radiance = im.radiance;
    Image& irradiance = im.irradiance;
    const std::size_t batch = std::max<std::uint32_t>(bouncer.o.batch_frames, 1u);
    for (std::size_t first = 0; first < frames.size(); first += batch) {
        const std::span<const std::size_t> part = frames.subspan(first, std::min(batch, frames.size() - first));
        bouncer.run(part);
        for (std::size_t k = 0; k < part.size(); ++k) {
            // The particles' radiance in their texels, those the view reads (ViewAtlasMap::reads;
            // the others keep an earlier frame's values, which no pixel of this view reads; the
            // texels of no particle stay 0, as the albedo atlas's empty texels; the particles own
            // distinct texels).
            const ViewAtlasMap& map = s.view_maps[s.frame_view[part[k]]];
            const std::vector<std::uint32_t>& read = map.reads;
            parallel_for_chunks(read.size(), threads, 16384, [&](unsigned, std::size_t begin, std::size_t end) {
                for (std::size_t r = begin; r < end; ++r) {
                    const std::size_t i = read[r];
                    const glm::vec3 l = glm::one_over_pi<float>() * glm::vec3(bouncer.total[k * rows + bouncer.row(i)]);
                    const int x = static_cast<int>(s.particles[i].texel_x()), y = static_cast<int>(s.particles[i].texel_y());
                    for (int c = 0; c < 3; ++c) {
                        radiance.at(x, y, c) = albedo[i][c] * l[c];
                        if (!lobe.zero()) irradiance.at(x, y, c) = l[c];
                    }
                }
            });
            // One image for every frame of the call (no fresh pages a frame), each pixel written.
            Image& out = im.out;
            if (out.width != map.width || out.height != map.height) out = Image(map.width, map.height, 3, 0.0f);
            parallel_for(static_cast<std::size_t>(map.height), threads, [&](std::size_t y) {
                for (int x = 0; x < map.width; ++x) {
                    const std::size_t p = y * static_cast<std::size_t>(map.width) + static_cast<std::size_t>(x);
                    const glm::vec2 q = map.texel[p];
                    if (q.x < 0.0f) {
                        for (int c = 0; c < 3; ++c) out.at(x, static_cast<int>(y), c) = 0.0f;
                        continue;
                    }
                    const auto [x0, y0, x1, y1, ax, ay] = taps_of(atlas, q);
                    const float kd = shared::material_diffuse_factor(m, kMeanCosine, map.cos_view[p]);
                    const auto bilinear = [&](const Image& im, int c) {
                        const float top = (1.0f - ax) * im.at(x0, y0, c) + ax * im.at(x1, y0, c);
                        const float bottom = (1.0f - ax) * im.at(x0, y1, c) + ax * im.at(x1, y1, c);
                        return (1.0f - ay) * top + ay * bottom;
                    };
                    const glm::vec3 a = lobe(map.cos_view[p]);
                    for (int c = 0; c < 3; ++c)
                        out.at(x, static_cast<int>(y), c) = kd * bilinear(radiance, c) + (lobe.zero() ? 0.0f : a[c] * bilinear(irradiance, c));
                }
            });
            sink(part[k], out);
        }
    }
    if (ratio != nullptr) {
        ratio->assign(n, 0.0f);
        for (std::size_t i = 0; i < n; ++i)
            if (bouncer.sum_direct[i] > 0.0) (*ratio)[i] = static_cast<float>(bouncer.sum_indirect[i] / bouncer.sum_direct[i]);
    }
}

void indirect_images(const IndirectScene& s, std::span<const std::size_t> frames, std::span<const glm::vec3> albedo,
                     const std::optional<SpecularModel>& material, const IndirectOptions& o,
                     const std::function<void(std::size_t, const Image&)>& sink, std::vector<float>* ratio) {
    IndirectImages(s, albedo, material, o).render(frames, sink, ratio);
}

} // namespace specula
