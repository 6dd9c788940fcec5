#include "geometry/chart_atlas.h"

#include "core/error.h"

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdio>
#include <deque>
#include <limits>
#include <numbers>
#include <numeric>
#include <optional>
#include <queue>
#include <string>
#include <tuple>
#include <unordered_map>

namespace specula {

namespace {

constexpr std::uint32_t kNone = 0xFFFFFFFFu;
constexpr int kRelaxIterations = 4;
/// Charts of at least this many triangles that fill less than kChartMinRectFill of their
/// smallest bounding rectangle are split (curved bands, rings): they would waste the texture.
constexpr std::size_t kMinTrianglesToSplitForFill = 16; ///< Lloyd iterations of the charts after the greedy pass (relax_charts)

double cos_degrees(double d) { return std::cos(d * std::numbers::pi / 180.0); }

// ---- topology ---------------------------------------------------------------------------

struct Topology {
    std::vector<glm::dvec3> normal;                    ///< unit face normal
    std::vector<double> area;
    std::vector<glm::dvec3> centroid;
    std::vector<std::array<std::uint32_t, 3>> across;  ///< triangle across edge k (corners k, k + 1), or kNone
    std::vector<std::array<bool, 3>> crease;           ///< that edge is sharper than the crease angle
    std::size_t crease_edges = 0;
};

Topology build_topology(const Mesh& mesh) {
    const std::size_t count = mesh.triangles.size();
    Topology topo;
    topo.normal.resize(count);
    topo.area.resize(count);
    topo.centroid.resize(count);
    topo.across.assign(count, {kNone, kNone, kNone});
    topo.crease.assign(count, {false, false, false});
    for (std::size_t t = 0; t < count; ++t) {
        const glm::uvec3 tri = mesh.triangles[t];
        const glm::dvec3 p0(mesh.positions[tri.x]), p1(mesh.positions[tri.y]), p2(mesh.positions[tri.z]);
        const glm::dvec3 c = glm::cross(p1 - p0, p2 - p0);
        const double len = glm::length(c);
        topo.area[t] = 0.5 * len;
        topo.normal[t] = len > 0.0 ? c / len : glm::dvec3(0.0, 0.0, 1.0);
        topo.centroid[t] = (p0 + p1 + p2) / 3.0;
    }
    // Edges by their (smaller, larger) position index; an edge joins two triangles when
    // exactly two use it, in opposite directions (consistent winding).
    struct Use {
        std::uint32_t a, b, tri;
        std::uint8_t k;
        bool forward;
    };
    std::vector<Use> uses;
    uses.reserve(3 * count);
    for (std::uint32_t t = 0; t < count; ++t)
        for (std::uint8_t k = 0; k < 3; ++k) {
            const std::uint32_t a = mesh.triangles[t][k], b = mesh.triangles[t][(k + 1) % 3];
            uses.push_back({std::min(a, b), std::max(a, b), t, k, a < b});
        }
    std::sort(uses.begin(), uses.end(), [](const Use& x, const Use& y) { return std::tie(x.a, x.b, x.tri) < std::tie(y.a, y.b, y.tri); });
    const double crease_cos = cos_degrees(kChartCreaseDegrees);
    for (std::size_t i = 0; i < uses.size();) {
        std::size_t j = i + 1;
        while (j < uses.size() && uses[j].a == uses[i].a && uses[j].b == uses[i].b) ++j;
        if (j - i == 2 && uses[i].forward != uses[i + 1].forward && uses[i].tri != uses[i + 1].tri) {
            const Use &u = uses[i], &v = uses[i + 1];
            topo.across[u.tri][u.k] = v.tri;
            topo.across[v.tri][v.k] = u.tri;
            if (glm::dot(topo.normal[u.tri], topo.normal[v.tri]) < crease_cos) {
                topo.crease[u.tri][u.k] = topo.crease[v.tri][v.k] = true;
                ++topo.crease_edges;
            }
        }
        i = j;
    }
    return topo;
}

/// The triangle a chart may grow into across edge k, or kNone.
std::uint32_t growth_neighbour(const Topology& topo, std::uint32_t t, int k) {
    return topo.crease[t][k] ? kNone : topo.across[t][k];
}

// ---- 1. charts --------------------------------------------------------------------------

/// Greedy growth under the normal cone; returns the chart of each triangle.
std::vector<std::uint32_t> grow_charts(const Topology& topo, std::size_t& chart_count) {
    const std::size_t count = topo.normal.size();
    const double cone_cos = cos_degrees(kChartConeDegrees);
    std::vector<std::uint32_t> chart_of(count, kNone);
    using Entry = std::pair<double, std::uint32_t>; // (1 - n.mean, triangle)
    std::priority_queue<Entry, std::vector<Entry>, std::greater<>> heap;
    chart_count = 0;
    for (std::uint32_t seed = 0; seed < count; ++seed) {
        if (chart_of[seed] != kNone) continue;
        const std::uint32_t c = static_cast<std::uint32_t>(chart_count++);
        glm::dvec3 sum(0.0);
        const auto add = [&](std::uint32_t t) {
            chart_of[t] = c;
            sum += topo.area[t] * topo.normal[t];
        };
        add(seed);
        const auto mean = [&] {
            const double l = glm::length(sum);
            return l > 0.0 ? sum / l : topo.normal[seed];
        };
        const auto push_neighbours = [&](std::uint32_t t) {
            const glm::dvec3 m = mean();
            for (int k = 0; k < 3; ++k) {
                const std::uint32_t u = growth_neighbour(topo, t, k);
                if (u != kNone && chart_of[u] == kNone) heap.emplace(1.0 - glm::dot(topo.normal[u], m), u);
            }
        };
        push_neighbours(seed);
        while (!heap.empty()) {
            const auto [cost, t] = heap.top();
            heap.pop();
            if (chart_of[t] != kNone) continue;
            const glm::dvec3 m = mean();
            const double d = glm::dot(topo.normal[t], m);
            if (1.0 - d > cost + 1e-12) { // the mean moved away since it was queued: queue it again
                heap.emplace(1.0 - d, t);
                continue;
            }
            if (d < cone_cos) continue; // outside the cone (another neighbour may queue it again later)
            add(t);
            push_neighbours(t);
        }
    }
    return chart_of;
}

/// Numbers the charts densely, in order of their lowest triangle.
void renumber(std::vector<std::uint32_t>& chart_of, std::size_t& chart_count) {
    std::vector<std::uint32_t> id(chart_count, kNone);
    std::uint32_t next = 0;
    for (std::uint32_t& c : chart_of) {
        if (id[c] == kNone) id[c] = next++;
        c = id[c];
    }
    chart_count = next;
}

/// Mean normal (area-weighted, the L2,1 proxy of Cohen-Steiner et al. 2004) of each chart.
std::vector<glm::dvec3> proxy_normals(const Topology& topo, const std::vector<std::uint32_t>& chart_of, std::size_t chart_count) {
    std::vector<glm::dvec3> sum(chart_count, glm::dvec3(0.0));
    for (std::size_t t = 0; t < chart_of.size(); ++t) sum[chart_of[t]] += topo.area[t] * topo.normal[t];
    for (std::size_t c = 0; c < chart_count; ++c) {
        const double l = glm::length(sum[c]);
        sum[c] = l > 0.0 ? sum[c] / l : glm::dvec3(0.0, 0.0, 1.0);
    }
    return sum;
}

/// One Lloyd iteration of variational shape approximation (Cohen-Steiner, Alliez and Desbrun
/// 2004, "Variational shape approximation", section 3.2) on normals: every chart restarts
/// from its triangle closest to its proxy normal, and all charts grow at once, the triangle
/// closest to a neighbouring chart's proxy first (error area * |n - N|^2 = 2 area (1 - n.N)),
/// within the cone of that proxy. Triangles no chart reaches start new charts (greedy, as
/// grow_charts). Charts so move toward the regions their normals describe: a leftover cap at
/// a pole becomes one chart instead of slivers left by the first greedy pass.
std::vector<std::uint32_t> relax_charts(const Topology& topo, const std::vector<std::uint32_t>& chart_of, std::size_t& chart_count) {
    const std::size_t count = chart_of.size();
    const double cone_cos = cos_degrees(kChartConeDegrees);
    const std::vector<glm::dvec3> proxy = proxy_normals(topo, chart_of, chart_count);
    std::vector<std::uint32_t> seed(chart_count, kNone);
    std::vector<double> seed_error(chart_count, std::numeric_limits<double>::infinity());
    for (std::uint32_t t = 0; t < count; ++t) {
        const std::uint32_t c = chart_of[t];
        const double e = topo.area[t] * (1.0 - glm::dot(topo.normal[t], proxy[c]));
        if (e < seed_error[c]) {
            seed_error[c] = e;
            seed[c] = t;
        }
    }
    std::vector<std::uint32_t> next(count, kNone);
    using Entry = std::tuple<double, std::uint32_t, std::uint32_t>; // (error, triangle, chart)
    std::priority_queue<Entry, std::vector<Entry>, std::greater<>> heap;
    const auto push_neighbours = [&](std::uint32_t t, std::uint32_t c) {
        for (int k = 0; k < 3; ++k) {
            const std::uint32_t u = growth_neighbour(topo, t, k);
            if (u != kNone && next[u] == kNone) heap.emplace(topo.area[u] * (1.0 - glm::dot(topo.normal[u], proxy[c])), u, c);
        }
    };
    for (std::uint32_t c = 0; c < chart_count; ++c) next[seed[c]] = c;
    for (std::uint32_t c = 0; c < chart_count; ++c) push_neighbours(seed[c], c);
    while (!heap.empty()) {
        const auto [e, t, c] = heap.top();
        heap.pop();
        if (next[t] != kNone || glm::dot(topo.normal[t], proxy[c]) < cone_cos) continue;
        next[t] = c;
        push_neighbours(t, c);
    }
    // What no chart reached: new charts, grown greedily among the unassigned triangles.
    std::size_t added = 0;
    std::vector<std::uint32_t> rest = next;
    for (std::uint32_t& c : rest) c = c == kNone ? kNone : 0u; // 0: taken
    {
        Topology limited = topo;
        for (std::uint32_t t = 0; t < count; ++t)
            for (int k = 0; k < 3; ++k) {
                const std::uint32_t u = limited.across[t][k];
                if (u != kNone && (next[t] != kNone || next[u] != kNone)) limited.across[t][k] = kNone;
            }
        std::size_t grown = 0;
        std::vector<std::uint32_t> extra = grow_charts(limited, grown);
        std::vector<std::uint32_t> id(grown, kNone);
        for (std::uint32_t t = 0; t < count; ++t) {
            if (next[t] != kNone) continue;
            std::uint32_t& i = id[extra[t]];
            if (i == kNone) i = static_cast<std::uint32_t>(chart_count + added++);
            next[t] = i;
        }
    }
    chart_count += added;
    return next;
}

/// Straightens chart borders: a triangle with two or three neighbours in another chart
/// (a tooth of a zigzag border) moves to that chart when its normal is within that chart's
/// cone. It has at most one neighbour in its own chart, so its chart stays connected.
/// Shorter borders: fewer seam vertices, and charts that pack tighter.
void smooth_borders(const Topology& topo, std::vector<std::uint32_t>& chart_of, std::size_t chart_count) {
    const double cone_cos = cos_degrees(kChartConeDegrees);
    for (int pass = 0; pass < 8; ++pass) {
        const std::vector<glm::dvec3> proxy = proxy_normals(topo, chart_of, chart_count);
        std::size_t moved = 0;
        for (std::uint32_t t = 0; t < chart_of.size(); ++t) {
            std::uint32_t other[3];
            int n = 0;
            for (int k = 0; k < 3; ++k) {
                const std::uint32_t u = growth_neighbour(topo, t, k);
                if (u != kNone && chart_of[u] != chart_of[t]) other[n++] = chart_of[u];
            }
            std::uint32_t to = kNone;
            if (n >= 2 && other[0] == other[1]) to = other[0];
            else if (n == 3 && (other[0] == other[2] || other[1] == other[2])) to = other[2];
            if (to == kNone || glm::dot(topo.normal[t], proxy[to]) < cone_cos) continue;
            chart_of[t] = to;
            ++moved;
        }
        if (moved == 0) break;
    }
}

/// Merges neighbouring charts, smallest first, while the union's normals stay within the cone.
void merge_charts(const Topology& topo, std::vector<std::uint32_t>& chart_of, std::size_t& chart_count) {
    const double cone_cos = cos_degrees(kChartConeDegrees);
    std::vector<std::vector<std::uint32_t>> members(chart_count);
    for (std::uint32_t t = 0; t < chart_of.size(); ++t) members[chart_of[t]].push_back(t);
    std::vector<glm::dvec3> sum(chart_count, glm::dvec3(0.0));
    std::vector<double> area(chart_count, 0.0);
    for (std::uint32_t t = 0; t < chart_of.size(); ++t) {
        sum[chart_of[t]] += topo.area[t] * topo.normal[t];
        area[chart_of[t]] += topo.area[t];
    }
    std::vector<std::uint32_t> order(chart_count);
    std::iota(order.begin(), order.end(), 0u);
    std::stable_sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) { return area[a] < area[b]; });
    std::vector<std::uint32_t> merged_into(chart_count, kNone);
    const auto root = [&](std::uint32_t c) {
        while (merged_into[c] != kNone) c = merged_into[c];
        return c;
    };
    for (std::uint32_t c : order) {
        if (merged_into[c] != kNone) continue;
        // Neighbouring charts by shared (growable) edges, most shared edges first.
        std::vector<std::pair<std::uint32_t, std::uint32_t>> shared; // (chart, edges)
        for (std::uint32_t t : members[c])
            for (int k = 0; k < 3; ++k) {
                const std::uint32_t u = growth_neighbour(topo, t, k);
                if (u == kNone) continue;
                const std::uint32_t d = root(chart_of[u]);
                if (d == c) continue;
                auto it = std::find_if(shared.begin(), shared.end(), [&](const auto& p) { return p.first == d; });
                if (it == shared.end()) shared.emplace_back(d, 1u);
                else ++it->second;
            }
        std::stable_sort(shared.begin(), shared.end(), [](const auto& a, const auto& b) { return a.second > b.second; });
        for (const auto& [d, edges] : shared) {
            const glm::dvec3 s = sum[c] + sum[d];
            const double l = glm::length(s);
            if (l <= 0.0) continue;
            const glm::dvec3 m = s / l;
            const auto inside = [&](const std::vector<std::uint32_t>& tris) {
                return std::all_of(tris.begin(), tris.end(), [&](std::uint32_t t) { return glm::dot(topo.normal[t], m) >= cone_cos; });
            };
            if (!inside(members[c]) || !inside(members[d])) continue;
            // Merge c into d.
            for (std::uint32_t t : members[c]) chart_of[t] = d;
            members[d].insert(members[d].end(), members[c].begin(), members[c].end());
            members[c].clear();
            sum[d] = s;
            area[d] += area[c];
            merged_into[c] = d;
            break;
        }
    }
    renumber(chart_of, chart_count);
}

// ---- 2. flattening ----------------------------------------------------------------------

struct Flat {
    std::vector<std::uint32_t> tris;                 ///< mesh triangles of the chart
    std::vector<std::uint32_t> vertex;               ///< local vertex -> position index
    std::vector<std::array<std::uint32_t, 3>> local; ///< per chart triangle: local vertex indices
    std::vector<glm::dvec2> uv;                      ///< per local vertex, in surface units (after normalization)
};

/// Local vertex numbering of a chart; `slot` (one entry per position, kNone) is restored on return.
void index_vertices(const Mesh& mesh, Flat& f, std::vector<std::uint32_t>& slot) {
    f.vertex.clear();
    f.local.resize(f.tris.size());
    for (std::size_t i = 0; i < f.tris.size(); ++i)
        for (int k = 0; k < 3; ++k) {
            const std::uint32_t p = mesh.triangles[f.tris[i]][k];
            if (slot[p] == kNone) {
                slot[p] = static_cast<std::uint32_t>(f.vertex.size());
                f.vertex.push_back(p);
            }
            f.local[i][k] = slot[p];
        }
    for (std::uint32_t p : f.vertex) slot[p] = kNone;
}

/// A triangle's corners in its own orthonormal frame: x along p0 -> p1, y toward p2.
std::array<glm::dvec2, 3> triangle_frame(const glm::dvec3& p0, const glm::dvec3& p1, const glm::dvec3& p2) {
    const glm::dvec3 e1 = p1 - p0, e2 = p2 - p0;
    const double l1 = glm::length(e1);
    const glm::dvec3 x = e1 / l1;
    const glm::dvec3 n = glm::cross(e1, e2);
    const glm::dvec3 y = glm::normalize(glm::cross(n, x));
    return {glm::dvec2(0.0), glm::dvec2(l1, 0.0), glm::dvec2(glm::dot(e2, x), glm::dot(e2, y))};
}

/// LSCM (see the header). Returns false when the system cannot be solved.
bool lscm(const Mesh& mesh, const Topology& topo, Flat& f) {
    const std::size_t nv = f.vertex.size();
    const std::size_t nt = f.tris.size();
    f.uv.assign(nv, glm::dvec2(0.0));
    if (nt == 1) { // one triangle: its own frame is exact
        const glm::uvec3 t = mesh.triangles[f.tris[0]];
        const auto q = triangle_frame(glm::dvec3(mesh.positions[t.x]), glm::dvec3(mesh.positions[t.y]), glm::dvec3(mesh.positions[t.z]));
        for (int k = 0; k < 3; ++k) f.uv[f.local[0][k]] = q[k];
        return topo.area[f.tris[0]] > 0.0;
    }
    // Pins: an approximate diameter (the farthest vertex from vertex 0, then the farthest from it).
    const auto pos = [&](std::uint32_t v) { return glm::dvec3(mesh.positions[f.vertex[v]]); };
    const auto farthest = [&](std::uint32_t from) {
        std::uint32_t best = from;
        double best_d = -1.0;
        for (std::uint32_t v = 0; v < nv; ++v) {
            const double d = glm::dot(pos(v) - pos(from), pos(v) - pos(from));
            if (d > best_d) {
                best_d = d;
                best = v;
            }
        }
        return best;
    };
    const std::uint32_t pin_a = farthest(0);
    const std::uint32_t pin_b = farthest(pin_a);
    if (pin_a == pin_b) return false;
    const double span = glm::length(pos(pin_b) - pos(pin_a));
    // Unknowns (u_v, v_v) at 2v, 2v + 1; the pins' four move to the right-hand side.
    std::vector<std::int64_t> free_index(2 * nv, -1);
    std::int64_t n_free = 0;
    for (std::uint32_t v = 0; v < nv; ++v)
        if (v != pin_a && v != pin_b) {
            free_index[2 * v] = n_free++;
            free_index[2 * v + 1] = n_free++;
        }
    std::vector<double> pinned(2 * nv, 0.0);
    pinned[2 * pin_b] = span; // pin_a at (0, 0), pin_b at (span, 0)
    using Triplet = Eigen::Triplet<double>;
    std::vector<Triplet> entries;
    entries.reserve(12 * nt);
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(2 * nt));
    for (std::size_t i = 0; i < nt; ++i) {
        const glm::uvec3 t = mesh.triangles[f.tris[i]];
        const double area = topo.area[f.tris[i]];
        if (!(area > 0.0)) return false;
        const auto x = triangle_frame(glm::dvec3(mesh.positions[t.x]), glm::dvec3(mesh.positions[t.y]), glm::dvec3(mesh.positions[t.z]));
        const double w = 1.0 / std::sqrt(area);
        const auto row_re = static_cast<Eigen::Index>(2 * i), row_im = row_re + 1;
        for (int j = 0; j < 3; ++j) {
            // E_j = x_{j+2} - x_{j+1} = a + i b; E_j U_j = (a u - b v) + i (b u + a v).
            const glm::dvec2 e = x[(j + 2) % 3] - x[(j + 1) % 3];
            const double a = w * e.x, b = w * e.y;
            const std::uint32_t v = f.local[i][j];
            const double coeff[2][2] = {{a, -b}, {b, a}}; // [row re/im][u/v]
            for (int r = 0; r < 2; ++r)
                for (int comp = 0; comp < 2; ++comp) {
                    const std::int64_t col = free_index[2 * v + comp];
                    if (col >= 0) entries.emplace_back(r == 0 ? row_re : row_im, static_cast<Eigen::Index>(col), coeff[r][comp]);
                    else rhs[r == 0 ? row_re : row_im] -= coeff[r][comp] * pinned[2 * v + comp];
                }
        }
    }
    Eigen::SparseMatrix<double> a(static_cast<Eigen::Index>(2 * nt), static_cast<Eigen::Index>(n_free));
    a.setFromTriplets(entries.begin(), entries.end());
    const Eigen::SparseMatrix<double> at = a.transpose();
    const Eigen::SparseMatrix<double> normal = at * a;
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(normal);
    if (solver.info() != Eigen::Success) return false;
    const Eigen::VectorXd x = solver.solve(at * rhs);
    if (solver.info() != Eigen::Success || !x.allFinite()) return false;
    for (std::uint32_t v = 0; v < nv; ++v) {
        const std::int64_t iu = free_index[2 * v], iv = free_index[2 * v + 1];
        f.uv[v] = iu >= 0 ? glm::dvec2(x[static_cast<Eigen::Index>(iu)], x[static_cast<Eigen::Index>(iv)])
                          : glm::dvec2(pinned[2 * v], pinned[2 * v + 1]);
    }
    return true;
}

double cross2(const glm::dvec2& a, const glm::dvec2& b) { return a.x * b.y - a.y * b.x; }

/// Do segments (a, b) and (c, d) meet (touching included)?
bool segments_meet(const glm::dvec2& a, const glm::dvec2& b, const glm::dvec2& c, const glm::dvec2& d) {
    const double o1 = cross2(b - a, c - a), o2 = cross2(b - a, d - a), o3 = cross2(d - c, a - c), o4 = cross2(d - c, b - c);
    if (((o1 > 0.0 && o2 < 0.0) || (o1 < 0.0 && o2 > 0.0)) && ((o3 > 0.0 && o4 < 0.0) || (o3 < 0.0 && o4 > 0.0))) return true;
    const auto on = [](const glm::dvec2& p, const glm::dvec2& q, const glm::dvec2& r, double o) { // r on segment pq, given orient
        return o == 0.0 && r.x >= std::min(p.x, q.x) && r.x <= std::max(p.x, q.x) && r.y >= std::min(p.y, q.y) &&
               r.y <= std::max(p.y, q.y);
    };
    return on(a, b, c, o1) || on(a, b, d, o2) || on(c, d, a, o3) || on(c, d, b, o4);
}

/// Does the chart's boundary (edges without a neighbour in the chart) cross itself?
bool boundary_crosses_itself(const Topology& topo, const std::vector<std::uint32_t>& chart_of, std::uint32_t chart, const Flat& f) {
    std::vector<std::array<std::uint32_t, 2>> edges;
    for (std::size_t i = 0; i < f.tris.size(); ++i)
        for (int k = 0; k < 3; ++k) {
            const std::uint32_t u = topo.across[f.tris[i]][k];
            if (u == kNone || chart_of[u] != chart) edges.push_back({f.local[i][k], f.local[i][(k + 1) % 3]});
        }
    if (edges.size() < 3) return false;
    glm::dvec2 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
    double length = 0.0;
    for (const auto& e : edges) {
        lo = glm::min(lo, glm::min(f.uv[e[0]], f.uv[e[1]]));
        hi = glm::max(hi, glm::max(f.uv[e[0]], f.uv[e[1]]));
        length += glm::length(f.uv[e[1]] - f.uv[e[0]]);
    }
    // A uniform grid of cells about two mean edge lengths wide (at most 1024 x 1024).
    const double cell = std::max({2.0 * length / double(edges.size()), (hi.x - lo.x) / 1024.0, (hi.y - lo.y) / 1024.0, 1e-300});
    const int nx = std::max(1, int(std::ceil((hi.x - lo.x) / cell))), ny = std::max(1, int(std::ceil((hi.y - lo.y) / cell)));
    std::vector<std::vector<std::uint32_t>> grid(std::size_t(nx) * std::size_t(ny));
    const auto cell_of = [&](double v, double origin, int n) { return std::clamp(int((v - origin) / cell), 0, n - 1); };
    for (std::uint32_t e = 0; e < edges.size(); ++e) {
        const glm::dvec2 a = f.uv[edges[e][0]], b = f.uv[edges[e][1]];
        const int x0 = cell_of(std::min(a.x, b.x), lo.x, nx), x1 = cell_of(std::max(a.x, b.x), lo.x, nx);
        const int y0 = cell_of(std::min(a.y, b.y), lo.y, ny), y1 = cell_of(std::max(a.y, b.y), lo.y, ny);
        for (int y = y0; y <= y1; ++y)
            for (int x = x0; x <= x1; ++x) grid[std::size_t(y) * std::size_t(nx) + std::size_t(x)].push_back(e);
    }
    for (const auto& bucket : grid)
        for (std::size_t i = 0; i < bucket.size(); ++i)
            for (std::size_t j = i + 1; j < bucket.size(); ++j) {
                const auto& e = edges[bucket[i]];
                const auto& g = edges[bucket[j]];
                if (e[0] == g[0] || e[0] == g[1] || e[1] == g[0] || e[1] == g[1]) continue; // adjacent along the boundary
                if (segments_meet(f.uv[e[0]], f.uv[e[1]], f.uv[g[0]], f.uv[g[1]])) return true;
            }
    return false;
}

/// A chart turned to its smallest bounding rectangle, landscape: texel coordinates of a
/// point q of the flattening are origin + scale * (rot * q - lo).
struct ChartFrame {
    glm::dmat2 rot{1.0};
    glm::dvec2 lo{0.0};
    glm::dvec2 extent{0.0}; ///< surface units
};

std::vector<glm::dvec2> convex_hull(std::vector<glm::dvec2> p) {
    // Andrew's monotone chain (Andrew 1979, "Another efficient algorithm for convex hulls in two dimensions").
    std::sort(p.begin(), p.end(), [](const glm::dvec2& a, const glm::dvec2& b) { return a.x < b.x || (a.x == b.x && a.y < b.y); });
    p.erase(std::unique(p.begin(), p.end()), p.end());
    if (p.size() < 3) return p;
    std::vector<glm::dvec2> h(2 * p.size());
    std::size_t k = 0;
    for (std::size_t i = 0; i < p.size(); ++i) {
        while (k >= 2 && cross2(h[k - 1] - h[k - 2], p[i] - h[k - 2]) <= 0.0) --k;
        h[k++] = p[i];
    }
    for (std::size_t i = p.size() - 1, t = k + 1; i > 0; --i) {
        while (k >= t && cross2(h[k - 1] - h[k - 2], p[i - 1] - h[k - 2]) <= 0.0) --k;
        h[k++] = p[i - 1];
    }
    h.resize(k - 1);
    return h;
}

ChartFrame chart_frame(const std::vector<glm::dvec2>& points) {
    const std::vector<glm::dvec2> hull = convex_hull(points);
    ChartFrame best;
    double best_area = std::numeric_limits<double>::infinity();
    const auto consider = [&](const glm::dvec2& dir) {
        // rot maps dir to +x (a rotation: columns (c, -s), (s, c) for dir = (c, s)).
        const glm::dmat2 rot(glm::dvec2(dir.x, -dir.y), glm::dvec2(dir.y, dir.x));
        glm::dvec2 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
        for (const glm::dvec2& q : hull) {
            const glm::dvec2 r = rot * q;
            lo = glm::min(lo, r);
            hi = glm::max(hi, r);
        }
        const double area = (hi.x - lo.x) * (hi.y - lo.y);
        if (area < best_area) {
            best_area = area;
            best = {rot, lo, hi - lo};
        }
    };
    consider({1.0, 0.0});
    for (std::size_t i = 0; i < hull.size(); ++i) {
        const glm::dvec2 e = hull[(i + 1) % hull.size()] - hull[i];
        const double l = glm::length(e);
        if (l > 0.0) consider(e / l);
    }
    if (best.extent.y > best.extent.x) { // landscape: turn by 90 degrees, (x, y) -> (y, -x)
        const glm::dmat2 quarter(glm::dvec2(0.0, -1.0), glm::dvec2(1.0, 0.0));
        best.rot = quarter * best.rot;
        best.lo = glm::dvec2(best.lo.y, -(best.lo.x + best.extent.x));
        best.extent = glm::dvec2(best.extent.y, best.extent.x);
    }
    return best;
}

/// The chart's area over the area of its smallest bounding rectangle.
double chart_rect_fill(const Flat& f) {
    double area = 0.0;
    for (const auto& l : f.local) area += 0.5 * cross2(f.uv[l[1]] - f.uv[l[0]], f.uv[l[2]] - f.uv[l[0]]);
    const ChartFrame fr = chart_frame(f.uv);
    const double rect = fr.extent.x * fr.extent.y;
    return rect > 0.0 ? area / rect : 1.0;
}

/// Scales the flattening to the chart's surface area and checks it (step 3).
bool check_flattening(const Mesh& mesh, const Topology& topo, const std::vector<std::uint32_t>& chart_of, std::uint32_t chart,
                      Flat& f) {
    double uv_area = 0.0, area = 0.0;
    for (std::size_t i = 0; i < f.tris.size(); ++i) {
        const glm::dvec2 q0 = f.uv[f.local[i][0]], q1 = f.uv[f.local[i][1]], q2 = f.uv[f.local[i][2]];
        const double a = 0.5 * cross2(q1 - q0, q2 - q0);
        if (!(a > 0.0)) return false; // flipped or degenerate
        uv_area += a;
        area += topo.area[f.tris[i]];
    }
    const double scale = std::sqrt(area / uv_area);
    for (glm::dvec2& q : f.uv) q *= scale;
    for (std::size_t i = 0; i < f.tris.size(); ++i) {
        const glm::uvec3 t = mesh.triangles[f.tris[i]];
        const glm::dvec2 s = triangle_stretch(glm::dvec3(mesh.positions[t.x]), glm::dvec3(mesh.positions[t.y]),
                                              glm::dvec3(mesh.positions[t.z]), f.uv[f.local[i][0]], f.uv[f.local[i][1]],
                                              f.uv[f.local[i][2]]);
        if (!(s.y > 0.0) || s.x > kChartMaxAngleDistortion * s.y) return false;
        const double a = s.x * s.y;
        if (a > kChartMaxAreaDistortion || a * kChartMaxAreaDistortion < 1.0) return false;
    }
    if (f.tris.size() >= kMinTrianglesToSplitForFill && chart_rect_fill(f) < kChartMinRectFill) return false;
    return !boundary_crosses_itself(topo, chart_of, chart, f);
}

/// Splits a chart's triangles in two connected halves: breadth-first regions grown from the
/// chart's two farthest triangles (by centroid: the farthest from its first triangle, then
/// the farthest from that one).
std::array<std::vector<std::uint32_t>, 2> split_chart(const Topology& topo, const std::vector<std::uint32_t>& chart_of, std::uint32_t chart,
                                                      const std::vector<std::uint32_t>& tris, std::vector<std::uint32_t>& label) {
    const auto farthest = [&](std::uint32_t from) {
        std::uint32_t best = from;
        double best_d = -1.0;
        for (std::uint32_t t : tris) {
            const glm::dvec3 d = topo.centroid[t] - topo.centroid[from];
            if (glm::dot(d, d) > best_d) {
                best_d = glm::dot(d, d);
                best = t;
            }
        }
        return best;
    };
    const std::uint32_t a = farthest(tris.front());
    std::uint32_t b = farthest(a);
    if (b == a) b = tris.front() == a ? tris.back() : tris.front();
    std::deque<std::uint32_t> queue{a, b};
    label[a] = 0;
    label[b] = 1;
    while (!queue.empty()) {
        const std::uint32_t t = queue.front();
        queue.pop_front();
        for (int k = 0; k < 3; ++k) {
            const std::uint32_t u = growth_neighbour(topo, t, k);
            if (u == kNone || chart_of[u] != chart || label[u] != kNone) continue;
            label[u] = label[t];
            queue.push_back(u);
        }
    }
    std::array<std::vector<std::uint32_t>, 2> halves;
    for (std::uint32_t t : tris) {
        // A chart is connected over growth edges, so every triangle is reached.
        halves[label[t] == 1 ? 1 : 0].push_back(t);
        label[t] = kNone;
    }
    return halves;
}

} // namespace

glm::dvec2 triangle_stretch(const glm::dvec3& p0, const glm::dvec3& p1, const glm::dvec3& p2, const glm::dvec2& q0, const glm::dvec2& q1,
                            const glm::dvec2& q2) {
    // J = Q X^-1 with X, Q the edge matrices of the triangle in its own frame and in 2D.
    const auto x = triangle_frame(p0, p1, p2);
    const glm::dmat2 xm(x[1] - x[0], x[2] - x[0]); // columns
    const glm::dmat2 qm(q1 - q0, q2 - q0);
    const glm::dmat2 j = qm * glm::inverse(xm);
    // Singular values of a 2x2 matrix: sigma1,2^2 = (|J|_F^2 +- sqrt(|J|_F^4 - 4 det^2)) / 2.
    const double fro = j[0][0] * j[0][0] + j[0][1] * j[0][1] + j[1][0] * j[1][0] + j[1][1] * j[1][1];
    const double det = glm::determinant(j);
    const double disc = std::sqrt(std::max(0.0, fro * fro - 4.0 * det * det));
    const double s1 = std::sqrt(0.5 * (fro + disc));
    const double s2 = s1 > 0.0 ? std::abs(det) / s1 : 0.0;
    return {s1, det < 0.0 ? -s2 : s2};
}

ChartSet make_charts(const Mesh& mesh) {
    if (mesh.triangles.empty()) throw Error("atlas: the mesh has no triangles");
    const Topology topo = build_topology(mesh);
    ChartSet set;
    set.crease_edges = topo.crease_edges;
    std::size_t grown = 0;
    std::vector<std::uint32_t> chart_of = grow_charts(topo, grown);
    for (int i = 0; i < kRelaxIterations; ++i) {
        chart_of = relax_charts(topo, chart_of, grown);
        renumber(chart_of, grown);
    }
    smooth_borders(topo, chart_of, grown);
    renumber(chart_of, grown);
    merge_charts(topo, chart_of, grown);

    // Flatten every chart; split the ones that fail (a single triangle never does).
    std::vector<std::vector<std::uint32_t>> work(grown);
    for (std::uint32_t t = 0; t < chart_of.size(); ++t) work[chart_of[t]].push_back(t);
    std::vector<std::uint32_t> slot(mesh.positions.size(), kNone), label(mesh.triangles.size(), kNone);
    set.chart_of.assign(mesh.triangles.size(), kNone);
    set.corner_uv.assign(3 * mesh.triangles.size(), glm::dvec2(0.0));
    std::vector<Flat> done;
    std::deque<std::vector<std::uint32_t>> pending(work.begin(), work.end());
    std::uint32_t scratch_id = static_cast<std::uint32_t>(grown); // ids for charts being split (chart_of is relabelled below)
    while (!pending.empty()) {
        Flat f;
        f.tris = std::move(pending.front());
        pending.pop_front();
        const std::uint32_t id = scratch_id++;
        for (std::uint32_t t : f.tris) chart_of[t] = id;
        index_vertices(mesh, f, slot);
        const bool single = f.tris.size() == 1; // flattened exactly: no check can fail
        const bool flat = lscm(mesh, topo, f);
        if (single && !(flat && cross2(f.uv[f.local[0][1]] - f.uv[f.local[0][0]], f.uv[f.local[0][2]] - f.uv[f.local[0][0]]) > 0.0)) {
            // A degenerate triangle (no area) still gets a small positive one.
            f.uv[f.local[0][0]] = {0.0, 0.0};
            f.uv[f.local[0][1]] = {1e-6, 0.0};
            f.uv[f.local[0][2]] = {0.0, 1e-6};
        }
        if (single || (flat && check_flattening(mesh, topo, chart_of, id, f))) {
            done.push_back(std::move(f));
            continue;
        }
        ++set.splits;
        auto halves = split_chart(topo, chart_of, id, f.tris, label);
        for (auto& h : halves)
            if (!h.empty()) pending.push_back(std::move(h));
    }
    // Charts numbered by their lowest triangle.
    std::sort(done.begin(), done.end(), [](const Flat& a, const Flat& b) {
        return *std::min_element(a.tris.begin(), a.tris.end()) < *std::min_element(b.tris.begin(), b.tris.end());
    });
    set.charts = done.size();
    for (std::uint32_t c = 0; c < done.size(); ++c)
        for (std::size_t i = 0; i < done[c].tris.size(); ++i) {
            const std::uint32_t t = done[c].tris[i];
            set.chart_of[t] = c;
            for (int k = 0; k < 3; ++k) set.corner_uv[3 * std::size_t(t) + std::size_t(k)] = done[c].uv[done[c].local[i][k]];
        }
    for (std::uint32_t t = 0; t < mesh.triangles.size(); ++t)
        for (int k = 0; k < 3; ++k) {
            const std::uint32_t u = topo.across[t][k];
            if (u != kNone && u > t && set.chart_of[u] != set.chart_of[t]) ++set.seam_edges;
        }
    return set;
}

// ---- 4 to 6: density, packing, texels ---------------------------------------------------

namespace {

/// A chart's reserved texels at cell resolution (cells of `cell` x `cell` texels) in one
/// orientation: the texels whose centers lie within Chebyshev distance kChartMargin + 0.5 of
/// its triangles. Charts whose reserved texels do not overlap keep their triangles at least
/// 2 kChartMargin apart: were two points of two charts closer than that, the texel center
/// nearest their midpoint would lie within kChartMargin + 0.5 of both.
struct CellMask {
    int w = 0, h = 0;                ///< cells
    int words = 0;                   ///< 64-bit words per row
    std::vector<std::uint64_t> bits; ///< h rows of `words` words; bit x of a row: cell x
    std::vector<int> lo, hi;         ///< per row: first and last set cell (hi < lo: none)
    std::vector<std::vector<std::pair<int, int>>> runs; ///< per row: (first cell, length) of each run of set cells
    std::uint64_t count = 0;

    void init(int width, int height) {
        w = width;
        h = height;
        words = (w + 63) / 64;
        bits.assign(std::size_t(words) * std::size_t(h), 0);
    }
    void set(int x, int y) { bits[std::size_t(y) * std::size_t(words) + std::size_t(x / 64)] |= std::uint64_t(1) << (x % 64); }
    [[nodiscard]] bool get(int x, int y) const {
        return (bits[std::size_t(y) * std::size_t(words) + std::size_t(x / 64)] >> (x % 64)) & 1u;
    }
    void finish() {
        lo.assign(std::size_t(h), w);
        hi.assign(std::size_t(h), -1);
        runs.assign(std::size_t(h), {});
        count = 0;
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x)
                if (get(x, y)) {
                    lo[std::size_t(y)] = std::min(lo[std::size_t(y)], x);
                    hi[std::size_t(y)] = x;
                    auto& r = runs[std::size_t(y)];
                    if (!r.empty() && r.back().first + r.back().second == x) ++r.back().second;
                    else r.emplace_back(x, 1);
                    ++count;
                }
    }
};

/// The mask turned by `quarter` quarter turns: cell (x, y) -> (h - 1 - y, x) per turn (the
/// texel map (x, y) -> (H - y, x), a rotation, so no chart is mirrored).
CellMask turn(const CellMask& m, int quarter) {
    CellMask r = m;
    for (int q = 0; q < quarter; ++q) {
        CellMask t;
        t.init(r.h, r.w);
        for (int y = 0; y < r.h; ++y)
            for (int x = 0; x < r.w; ++x)
                if (r.get(x, y)) t.set(r.h - 1 - y, x);
        r = std::move(t);
    }
    r.finish();
    return r;
}

/// Occupied cells of the atlas, rows added as charts are placed.
class Occupancy {
public:
    explicit Occupancy(int width) : m_width(width), m_words((width + 63) / 64) {}

    [[nodiscard]] int width() const noexcept { return m_width; }
    [[nodiscard]] int height() const noexcept { return int(m_count.size()); }
    /// The first row with a free cell: nothing can start above it.
    [[nodiscard]] int first_open_row() const noexcept { return m_first_open; }

    /// The leftmost x at which the mask fits with its corner in row y0, or -1. Bit-parallel
    /// over x: per run of set cells of length n starting at a, the positions p whose cells
    /// p .. p + n - 1 of the row are all free (shift-and doubling), shifted by a, and-ed.
    [[nodiscard]] int first_fit(const CellMask& m, int y0) const {
        const int positions = m_width - m.w + 1;
        if (positions <= 0) return -1;
        std::vector<std::uint64_t>& valid = m_valid;
        valid.assign(std::size_t(m_words), 0);
        for (int j = 0; j < positions / 64; ++j) valid[std::size_t(j)] = ~std::uint64_t(0);
        if (positions % 64 != 0) valid[std::size_t(positions / 64)] = (std::uint64_t(1) << (positions % 64)) - 1;
        for (int r = 0; r < m.h; ++r) {
            const int y = y0 + r;
            if (y >= height()) break; // rows below the packed ones are free
            const std::uint64_t* row = &m_bits[std::size_t(y) * std::size_t(m_words)];
            if (m_count[std::size_t(y)] == 0) continue;
            for (const auto& [a, n] : m.runs[std::size_t(r)]) {
                // Successive rows y0 share rows of the atlas: free runs cached per (row, length).
                const std::uint64_t key = (std::uint64_t(y) << 32) | std::uint64_t(n);
                auto it = m_cache.find(key);
                if (it == m_cache.end()) {
                    free_runs(row, n, m_run);
                    it = m_cache.emplace(key, m_run).first;
                }
                const std::vector<std::uint64_t>& run = it->second;
                // valid &= run >> a
                bool any = false;
                for (int j = 0; j < m_words; ++j) {
                    const int src = j + a / 64, sh = a % 64;
                    std::uint64_t v = src < m_words ? run[std::size_t(src)] >> sh : 0;
                    if (sh != 0 && src + 1 < m_words) v |= run[std::size_t(src + 1)] << (64 - sh);
                    valid[std::size_t(j)] &= v;
                    any = any || valid[std::size_t(j)] != 0;
                }
                if (!any) return -1;
            }
        }
        for (int j = 0; j < m_words; ++j)
            if (valid[std::size_t(j)]) return j * 64 + std::countr_zero(valid[std::size_t(j)]);
        return -1;
    }

    /// Forgets the cached free runs (after a placement changed rows).
    void clear_cache() { m_cache.clear(); }

    void place(const CellMask& m, int x0, int y0) {
        clear_cache();
        if (y0 + m.h > height()) {
            m_bits.resize(std::size_t(y0 + m.h) * std::size_t(m_words), 0);
            m_count.resize(std::size_t(y0 + m.h), 0);
        }
        const int shift = x0 % 64, base = x0 / 64;
        for (int r = 0; r < m.h; ++r) {
            if (m.hi[std::size_t(r)] < m.lo[std::size_t(r)]) continue;
            std::uint64_t* row = &m_bits[std::size_t(y0 + r) * std::size_t(m_words)];
            const std::uint64_t* mrow = &m.bits[std::size_t(r) * std::size_t(m.words)];
            for (int j = 0; j < m.words; ++j) {
                const std::uint64_t v = mrow[j];
                if (v == 0) continue;
                row[base + j] |= v << shift;
                if (shift != 0 && base + j + 1 < m_words) row[base + j + 1] |= v >> (64 - shift);
            }
            int n = 0;
            for (int j = 0; j < m_words; ++j) n += std::popcount(row[j]);
            m_count[std::size_t(y0 + r)] = n;
        }
        while (m_first_open < height() && m_count[std::size_t(m_first_open)] == m_width) ++m_first_open;
    }

private:
    /// out bit p: cells p .. p + n - 1 of the row are all free (and inside the width).
    void free_runs(const std::uint64_t* row, int n, std::vector<std::uint64_t>& out) const {
        out.resize(std::size_t(m_words));
        for (int j = 0; j < m_words; ++j) out[std::size_t(j)] = ~row[j];
        const int tail = m_width % 64;
        if (tail != 0) out[std::size_t(m_words - 1)] &= (std::uint64_t(1) << tail) - 1;
        // f_{2k} = f_k & (f_k >> k); f_{k + 1} = f_k & (f_1 >> k): binary method over n.
        m_base.assign(out.begin(), out.end());
        int have = 1;
        const int top = std::bit_width(unsigned(n)) - 1;
        for (int bit = top - 1; bit >= 0; --bit) {
            and_shifted(out, out, have);
            have *= 2;
            if ((n >> bit) & 1) {
                and_shifted(out, m_base, have);
                have += 1;
            }
        }
    }
    /// a &= b >> k (multiword, bit 0 of word 0 the first cell).
    void and_shifted(std::vector<std::uint64_t>& a, const std::vector<std::uint64_t>& b, int k) const {
        m_tmp.assign(b.begin(), b.end());
        const int wk = k / 64, sh = k % 64;
        for (int j = 0; j < m_words; ++j) {
            const int src = j + wk;
            std::uint64_t v = src < m_words ? m_tmp[std::size_t(src)] >> sh : 0;
            if (sh != 0 && src + 1 < m_words) v |= m_tmp[std::size_t(src + 1)] << (64 - sh);
            a[std::size_t(j)] &= v;
        }
    }

    int m_width, m_words;
    mutable std::vector<std::uint64_t> m_valid, m_run, m_base, m_tmp;
    mutable std::unordered_map<std::uint64_t, std::vector<std::uint64_t>> m_cache;
    std::vector<std::uint64_t> m_bits;
    std::vector<int> m_count; ///< occupied cells per row
    int m_first_open = 0;
};

struct Placement {
    int x = 0, y = 0; ///< cell of the mask's corner
    int quarter = 0;  ///< quarter turns
};

/// First-fit packing of the charts' reserved-texel masks: charts, largest first, each at the
/// position and orientation whose bottom is highest up (then leftmost), scanning rows top
/// down. (Levy et al. 2002 pack with a "Tetris" horizon; keeping every cell also fills the
/// holes of rings and the hollows under curved bands.)
std::vector<Placement> pack_masks(const std::vector<std::array<CellMask, 4>>& masks, int width) {
    std::vector<std::uint32_t> order(masks.size());
    std::iota(order.begin(), order.end(), 0u);
    std::stable_sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) { return masks[a][0].count > masks[b][0].count; });
    Occupancy occ(width);
    std::vector<Placement> out(masks.size());
    for (std::uint32_t c : order) {
        int best_bottom = std::numeric_limits<int>::max();
        Placement best;
        for (int q = 0; q < 4; ++q) {
            const CellMask& m = masks[c][std::size_t(q)];
            if (m.w > width) continue;
            for (int y = occ.first_open_row(); y + m.h < best_bottom; ++y) {
                const int x = occ.first_fit(m, y);
                if (x >= 0) {
                    best_bottom = y + m.h;
                    best = {x, y, q};
                    break;
                }
            }
        }
        if (best_bottom == std::numeric_limits<int>::max()) throw Error("atlas: a chart is wider than the texture");
        occ.place(masks[c][std::size_t(best.quarter)], best.x, best.y);
        out[c] = best;
    }
    return out;
}

/// Does the square center +- half (per axis) meet the triangle? (Separating axes: x, y and the edge normals.)
bool square_meets_triangle(const glm::dvec2& center, const glm::dvec2 tri[3], double half) {
    const glm::dvec2 lo = glm::min(tri[0], glm::min(tri[1], tri[2])), hi = glm::max(tri[0], glm::max(tri[1], tri[2]));
    if (hi.x < center.x - half || lo.x > center.x + half || hi.y < center.y - half || lo.y > center.y + half) return false;
    for (int k = 0; k < 3; ++k) {
        const glm::dvec2 e = tri[(k + 1) % 3] - tri[k];
        const glm::dvec2 n(-e.y, e.x);
        const double t0 = glm::dot(n, tri[0]), t1 = glm::dot(n, tri[1]), t2 = glm::dot(n, tri[2]);
        const double tmin = std::min({t0, t1, t2}), tmax = std::max({t0, t1, t2});
        const double c = glm::dot(n, center), r = half * (std::abs(n.x) + std::abs(n.y)); // the square's half-extent along n
        if (c + r < tmin || c - r > tmax) return false;
    }
    return true;
}

// ---- build_chart_atlas's steps ----------------------------------------------------------

/// Step 4's results, with the per-triangle and per-chart inputs the later steps share.
struct ChartSizes {
    std::vector<std::vector<std::uint32_t>> members; ///< per chart: its triangles
    std::vector<double> surface;                     ///< per triangle: its surface area
    std::vector<double> scale;                       ///< per chart: texels per surface unit wanted
    std::vector<ChartFrame> frames;                  ///< per chart: its smallest bounding rectangle
    double unseen_texels = 0.0;                      ///< texels a triangle facing no camera asks for
    bool fill_budget = false;                        ///< no cameras: texels follow surface area and fill the budget
};

/// 4. Desired texels per triangle, then per chart: the scale (texels per surface unit).
/// Fills the summary's size_source, triangles_seen_by_no_camera and desired_texels.
ChartSizes size_charts(const Mesh& mesh, const ChartSet& set, std::span<const Camera> cameras, const AtlasOptions& options,
                       AtlasSummary& s) {
    const std::size_t tri_count = mesh.triangles.size();
    ChartSizes out;
    out.members.resize(set.charts);
    for (std::uint32_t t = 0; t < tri_count; ++t) out.members[set.chart_of[t]].push_back(t);
    std::vector<double>& surface = out.surface;
    surface.resize(tri_count);
    for (std::size_t t = 0; t < tri_count; ++t) {
        const glm::uvec3 tri = mesh.triangles[t];
        surface[t] = 0.5 * glm::length(glm::cross(glm::dvec3(mesh.positions[tri.y]) - glm::dvec3(mesh.positions[tri.x]),
                                                  glm::dvec3(mesh.positions[tri.z]) - glm::dvec3(mesh.positions[tri.x])));
    }

    std::vector<double> desired(tri_count, 0.0);
    const double budget_area = double(options.max_width) * double(options.max_height);
    out.unseen_texels = 0.5 * double(options.min_patch) * double(options.min_patch);
    out.fill_budget = cameras.empty();
    if (!out.fill_budget) {
        s.size_source = "cameras";
        const std::vector<double> pixels = best_pixel_footprint(mesh, cameras);
        for (std::size_t t = 0; t < tri_count; ++t) {
            if (pixels[t] > 0.0) {
                desired[t] = kChartTexelsPerPatchTexel * options.texels_per_pixel * pixels[t];
            } else {
                desired[t] = out.unseen_texels;
                ++s.triangles_seen_by_no_camera;
            }
        }
    } else {
        // Texels follow surface area, at the density whose texels fill the budget (the
        // margins and the packing then shrink it below, like the patchwork's fill).
        s.size_source = "surface area";
        const double total = std::accumulate(surface.begin(), surface.end(), 0.0);
        for (std::size_t t = 0; t < tri_count; ++t) desired[t] = budget_area * surface[t] / total;
    }
    for (double d : desired) s.desired_texels += d;
    out.scale.assign(set.charts, 0.0);
    out.frames.resize(set.charts);
    for (std::uint32_t c = 0; c < set.charts; ++c) {
        double want = 0.0, area = 0.0;
        std::vector<glm::dvec2> points;
        points.reserve(3 * out.members[c].size());
        for (std::uint32_t t : out.members[c]) {
            want += desired[t];
            area += surface[t];
            for (int k = 0; k < 3; ++k) points.push_back(set.corner_uv[3 * std::size_t(t) + std::size_t(k)]);
        }
        out.scale[c] = area > 0.0 ? std::sqrt(want / area) : 1.0;
        out.frames[c] = chart_frame(points);
    }
    return out;
}

// 5. Packing; every chart scaled by one factor until the budget holds. A chart's own
// texel frame (orientation 0): p = k (rot q - lo) + kPad, q its flattening; its mask is
// padded to whole cells, Wt x Ht texels.
constexpr double kPad = kChartMargin + 1.0; // reserved texels (within kChartMargin + 0.5) start at index >= 0

struct ChartLayout {
    double k = 0.0;     ///< texels per surface unit
    int wt = 0, ht = 0; ///< texel size of the orientation-0 mask (whole cells)
};

/// Every chart's reserved cells, in the four orientations.
struct ChartMasks {
    std::vector<std::array<CellMask, 4>> masks;
    int narrowest_fit = 1; ///< cells: every chart must fit the width in some orientation
};

/// Lays every chart out at `scale` times its own scale on cells of `cell` texels (filling
/// `layout`) and builds its masks.
ChartMasks chart_masks(const ChartSet& set, const ChartSizes& sizes, double scale, int cell, std::vector<ChartLayout>& layout) {
    ChartMasks out;
    out.masks.resize(set.charts);
    for (std::uint32_t c = 0; c < set.charts; ++c) {
        ChartLayout& l = layout[c];
        const ChartFrame& frame = sizes.frames[c];
        l.k = sizes.scale[c] * scale;
        const glm::dvec2 e = frame.extent * l.k + 2.0 * kPad;
        const int wc = std::max(1, int(std::ceil(e.x / cell))), hc = std::max(1, int(std::ceil(e.y / cell)));
        l.wt = wc * cell;
        l.ht = hc * cell;
        // A cell is reserved when one of its texel centers lies within kChartMargin + 0.5
        // of a triangle: the square of its centers grown by that distance meets it.
        const double half = 0.5 * (cell - 1) + kChartMargin + 0.5;
        CellMask m;
        m.init(wc, hc);
        for (std::uint32_t t : sizes.members[c]) {
            glm::dvec2 tri[3];
            for (int k = 0; k < 3; ++k) tri[k] = l.k * (frame.rot * set.corner_uv[3 * std::size_t(t) + std::size_t(k)] - frame.lo) + kPad;
            const glm::dvec2 lo = glm::min(tri[0], glm::min(tri[1], tri[2])) - half;
            const glm::dvec2 hi = glm::max(tri[0], glm::max(tri[1], tri[2])) + half;
            const int x0 = std::max(0, int(std::floor(lo.x / cell))), x1 = std::min(wc - 1, int(std::floor(hi.x / cell)));
            const int y0 = std::max(0, int(std::floor(lo.y / cell))), y1 = std::min(hc - 1, int(std::floor(hi.y / cell)));
            for (int y = y0; y <= y1; ++y)
                for (int x = x0; x <= x1; ++x)
                    if (!m.get(x, y) && square_meets_triangle({(x + 0.5) * cell, (y + 0.5) * cell}, tri, half)) m.set(x, y);
        }
        for (int q = 0; q < 4; ++q) out.masks[c][std::size_t(q)] = turn(m, q);
        out.narrowest_fit = std::max(out.narrowest_fit, std::min(wc, hc));
    }
    return out;
}

/// One packing of the masks and the texture it needs.
struct PackTrial {
    std::optional<std::vector<Placement>> placed;
    std::uint64_t area = std::numeric_limits<std::uint64_t>::max(); ///< width x height, texels
    std::uint32_t width = 0, height = 0;                              ///< texels
};

/// The width: a square atlas at the expected fill (`estimate` texels at 0.8), at least the
/// narrowest orientation of every chart, at most the budget; two widths tried, the smaller
/// texture kept.
PackTrial pack_smallest(const ChartMasks& m, const std::vector<ChartLayout>& layout, double estimate, int cell,
                        const AtlasOptions& options) {
    const int budget_cells = int(options.max_width) / cell;
    PackTrial best;
    const double base = std::sqrt(estimate / 0.8) / cell;
    for (const double f : {1.0, 1.25}) {
        const int width = std::clamp(int(std::ceil(base * f)), m.narrowest_fit, std::max(m.narrowest_fit, budget_cells));
        std::vector<Placement> p = pack_masks(m.masks, width);
        std::uint32_t w = 0, h = 0;
        for (std::size_t c = 0; c < p.size(); ++c) {
            const bool turned = p[c].quarter % 2 == 1;
            w = std::max<std::uint32_t>(w, std::uint32_t(p[c].x * cell + (turned ? layout[c].ht : layout[c].wt)));
            h = std::max<std::uint32_t>(h, std::uint32_t(p[c].y * cell + (turned ? layout[c].wt : layout[c].ht)));
        }
        const std::uint64_t a = std::uint64_t(w) * h;
        if (a < best.area) {
            best.placed = std::move(p);
            best.area = a;
            best.width = w;
            best.height = h;
        }
    }
    return best;
}

/// Step 5's result: where every chart went, at what scale, in how large a texture.
struct ChartPacking {
    std::vector<ChartLayout> layout;
    std::vector<Placement> placed;
    int cell = 1;                        ///< texels per cell side
    double scale = 1.0;                  ///< the factor every chart's scale was multiplied by
    std::uint32_t width = 0, height = 0; ///< the atlas, texels
};

/// 5. Packs the charts, shrinking them all by one factor until the texture fits the budget.
ChartPacking pack_charts(const ChartSet& set, const ChartSizes& sizes, const AtlasOptions& options) {
    const double budget_area = double(options.max_width) * double(options.max_height);
    ChartPacking out;
    out.layout.resize(set.charts);
    for (int attempt = 0;; ++attempt) {
        // Cells: at most about 768 across the atlas, so the search stays cheap on big budgets.
        double estimate = 0.0;
        for (std::uint32_t c = 0; c < set.charts; ++c) {
            const glm::dvec2 e = sizes.frames[c].extent * (sizes.scale[c] * out.scale) + 2.0 * kPad;
            estimate += e.x * e.y;
        }
        out.cell = std::max(1, int(std::ceil(std::sqrt(estimate / 0.7) / 768.0)));
        const ChartMasks masks = chart_masks(set, sizes, out.scale, out.cell, out.layout);
        PackTrial best = pack_smallest(masks, out.layout, estimate, out.cell, options);
        if (best.width <= options.max_width && best.height <= options.max_height) {
            out.placed = std::move(*best.placed);
            // Sides rounded up to multiples of 4 (within the budget): mip levels 1 and 2 then
            // halve exactly, so their texels cover the same texels of level 0 as their uv square.
            const auto round4 = [](std::uint32_t v, std::uint32_t limit) { return (v + 3u) / 4u * 4u <= limit ? (v + 3u) / 4u * 4u : v; };
            out.width = round4(best.width, options.max_width);
            out.height = round4(best.height, options.max_height);
            return out;
        }
        if (attempt > 200 || out.scale < 1e-6)
            throw Error("atlas: " + std::to_string(set.charts) + " charts do not fit a " + std::to_string(options.max_width) + "x" +
                        std::to_string(options.max_height) + " texture even at the smallest scale; raise the budget");
        const double needed = double(best.area) * std::max(1.0, double(best.width) / options.max_width);
        out.scale *= std::clamp(std::sqrt(budget_area / needed), 0.5, 0.98);
    }
}

/// The summary's budget_scale and budget_clipped, and its notes on the budget and on
/// triangles no camera sees.
void note_budget(AtlasSummary& s, const ChartPacking& packing, const ChartSizes& sizes, const AtlasOptions& options) {
    const double scale = packing.scale;
    s.budget_scale = scale;
    s.budget_clipped = scale < 1.0 && !sizes.fill_budget;
    if (s.budget_clipped) {
        char line[256];
        std::snprintf(line, sizeof line,
                      "texture budget %ux%u reached: every chart scaled by %.3f (%.3g texels per pixel instead of %.3g)",
                      options.max_width, options.max_height, scale, options.texels_per_pixel * scale * scale, options.texels_per_pixel);
        s.notes.emplace_back(line);
    }
    if (s.triangles_seen_by_no_camera > 0) {
        char line[256];
        std::snprintf(line, sizeof line, "%zu triangles face no camera: they ask for %.3g texels each", s.triangles_seen_by_no_camera,
                      sizes.unseen_texels);
        s.notes.emplace_back(line);
    }
}

/// Sizes the atlas and fills its chart_of, charts (renumbered in placement order: rows, then
/// columns, which particles follow), corner_uv and corners.
void place_charts(Atlas& atlas, const Mesh& mesh, const ChartSet& set, const ChartSizes& sizes, const ChartPacking& packing) {
    const std::size_t tri_count = mesh.triangles.size();
    const std::vector<Placement>& placed = packing.placed;
    const int cell = packing.cell;
    std::vector<std::uint32_t> placement(set.charts);
    std::iota(placement.begin(), placement.end(), 0u);
    std::stable_sort(placement.begin(), placement.end(), [&](std::uint32_t a, std::uint32_t b) {
        return placed[a].y != placed[b].y ? placed[a].y < placed[b].y : placed[a].x < placed[b].x;
    });
    std::vector<std::uint32_t> new_id(set.charts);
    for (std::uint32_t i = 0; i < set.charts; ++i) new_id[placement[i]] = i;

    atlas.width = packing.width;
    atlas.height = packing.height;
    atlas.chart_of.resize(tri_count);
    atlas.charts.resize(set.charts);
    atlas.corners.resize(3 * tri_count);
    atlas.corner_uv.resize(3 * tri_count);
    for (std::uint32_t t = 0; t < tri_count; ++t) atlas.chart_of[t] = new_id[set.chart_of[t]];
    for (std::uint32_t c = 0; c < set.charts; ++c) {
        ChartPlacement& cp = atlas.charts[new_id[c]];
        const ChartLayout& l = packing.layout[c];
        const bool turned = placed[c].quarter % 2 == 1;
        cp.x = std::uint32_t(placed[c].x * cell);
        cp.y = std::uint32_t(placed[c].y * cell);
        cp.width = std::min<std::uint32_t>(std::uint32_t(turned ? l.ht : l.wt), atlas.width - cp.x);
        cp.height = std::min<std::uint32_t>(std::uint32_t(turned ? l.wt : l.ht), atlas.height - cp.y);
        cp.triangles = static_cast<std::uint32_t>(sizes.members[c].size());
    }
    // Corner coordinates: the same double for every corner of a chart vertex (its texel
    // point), rounded once to the float uv; the texel coordinates are that float times the
    // size (exact in double), so the particles see what the renderer interpolates.
    for (std::uint32_t c = 0; c < set.charts; ++c) {
        const ChartFrame& fr = sizes.frames[c];
        const ChartLayout& l = packing.layout[c];
        const glm::dvec2 origin(double(placed[c].x * cell), double(placed[c].y * cell));
        for (std::uint32_t t : sizes.members[c])
            for (int corner = 0; corner < 3; ++corner) {
                const std::size_t i = 3 * std::size_t(t) + std::size_t(corner);
                glm::dvec2 p = l.k * (fr.rot * set.corner_uv[i] - fr.lo) + kPad;
                double w = l.wt, h = l.ht;
                for (int q = 0; q < placed[c].quarter; ++q) { // (x, y) -> (H - y, x), as turn()
                    p = glm::dvec2(h - p.y, p.x);
                    std::swap(w, h);
                }
                p += origin;
                const glm::vec2 uv(float(p.x / atlas.width), float(p.y / atlas.height));
                atlas.corner_uv[i] = uv;
                atlas.corners[i] = glm::dvec2(double(uv.x) * atlas.width, double(uv.y) * atlas.height);
            }
    }
    // Vertices per chart (distinct positions).
    std::vector<std::uint32_t> seen(mesh.positions.size(), kNone);
    for (std::uint32_t c = 0; c < set.charts; ++c) {
        std::uint32_t n = 0;
        for (std::uint32_t t : sizes.members[c])
            for (int k = 0; k < 3; ++k) {
                const std::uint32_t p = mesh.triangles[t][k];
                if (seen[p] != c) {
                    seen[p] = c;
                    ++n;
                }
            }
        atlas.charts[new_id[c]].vertices = n;
    }
}

/// The texels whose centers may lie in [lo, hi] along one axis of `limit` texels (first, last).
std::pair<long, long> texel_range(double lo, double hi, std::uint32_t limit) {
    const long a = std::max(0L, long(std::floor(lo - 0.5))), b = std::min(long(limit) - 1, long(std::ceil(hi - 0.5)));
    return {a, b};
}

// 6. Texels: interior (center in a triangle), then the gutter ring (within Chebyshev
// distance kChartGutterReach of the chart: what bilinear lookups inside it read, with a
// quarter texel to spare), owned by the closest triangle.

/// A triangle without area in the texture owns no texel (only atlases read from texture
/// coordinates have them: build_chart_atlas's flattening keeps every triangle's orientation).
bool flat_in_texture(const Atlas& atlas, std::uint32_t t) {
    const glm::dvec2 c0 = atlas.corner_texel(t, 0);
    return !(std::abs(cross2(atlas.corner_texel(t, 1) - c0, atlas.corner_texel(t, 2) - c0)) > 1e-12);
}

/// Sizes atlas.owner and gives each interior texel its triangle; returns which texels are interior.
std::vector<std::uint8_t> assign_interior(Atlas& atlas) {
    const std::size_t tri_count = atlas.chart_of.size();
    const std::size_t width = atlas.width;
    atlas.owner.assign(std::size_t(atlas.width) * atlas.height, Atlas::kEmpty);
    std::vector<std::uint8_t> interior(atlas.owner.size(), 0);
    for (std::uint32_t t = 0; t < tri_count; ++t) {
        if (flat_in_texture(atlas, t)) continue;
        const glm::dvec2 c0 = atlas.corner_texel(t, 0), c1 = atlas.corner_texel(t, 1), c2 = atlas.corner_texel(t, 2);
        const glm::dvec2 lo = glm::min(c0, glm::min(c1, c2)), hi = glm::max(c0, glm::max(c1, c2));
        const auto [x0, x1] = texel_range(lo.x, hi.x, atlas.width);
        const auto [y0, y1] = texel_range(lo.y, hi.y, atlas.height);
        for (long y = y0; y <= y1; ++y)
            for (long x = x0; x <= x1; ++x) {
                const std::size_t i = std::size_t(y) * width + std::size_t(x);
                if (interior[i]) continue;
                if (!in_patch(atlas.patch_bary(t, {x + 0.5, y + 0.5}))) continue;
                interior[i] = 1;
                atlas.owner[i] = t;
            }
    }
    return interior;
}

/// Gives each gutter texel its owner and empties the other non-interior texels. The owner of
/// a gutter texel is its chart's triangle closest to it (Euclidean), which may lie farther
/// than the reach in Chebyshev distance (at most sqrt(2) times it).
void assign_gutter(Atlas& atlas, const std::vector<std::uint8_t>& interior) {
    const std::size_t tri_count = atlas.chart_of.size();
    const std::size_t width = atlas.width;
    std::vector<double> gutter_distance(atlas.owner.size(), std::numeric_limits<double>::infinity());
    std::vector<std::uint8_t> in_reach(atlas.owner.size(), 0);
    const double search = kChartGutterReach * std::sqrt(2.0);
    for (std::uint32_t t = 0; t < tri_count; ++t) {
        if (flat_in_texture(atlas, t)) continue;
        const glm::dvec2 tri[3] = {atlas.corner_texel(t, 0), atlas.corner_texel(t, 1), atlas.corner_texel(t, 2)};
        const glm::dvec2 lo = glm::min(tri[0], glm::min(tri[1], tri[2])) - search, hi = glm::max(tri[0], glm::max(tri[1], tri[2])) + search;
        const auto [x0, x1] = texel_range(lo.x, hi.x, atlas.width);
        const auto [y0, y1] = texel_range(lo.y, hi.y, atlas.height);
        for (long y = y0; y <= y1; ++y)
            for (long x = x0; x <= x1; ++x) {
                const std::size_t i = std::size_t(y) * width + std::size_t(x);
                if (interior[i]) continue;
                const glm::dvec2 center(x + 0.5, y + 0.5);
                const glm::dvec2 st = closest_point_bary(tri[0], tri[1], tri[2], center);
                const glm::dvec2 q = tri[0] + st.x * (tri[1] - tri[0]) + st.y * (tri[2] - tri[0]);
                const double d = glm::length(center - q);
                if (d > search) continue;
                if (!in_reach[i] && square_meets_triangle(center, tri, kChartGutterReach)) in_reach[i] = 1;
                if (d < gutter_distance[i]) {
                    gutter_distance[i] = d;
                    atlas.owner[i] = t;
                }
            }
    }
    for (std::size_t i = 0; i < atlas.owner.size(); ++i)
        if (!interior[i] && !in_reach[i]) atlas.owner[i] = Atlas::kEmpty;
}

/// The summary's chart sizes, texture size, texel counts and ratios, and atlas vertices.
void summarize_atlas(Atlas& atlas, const Mesh& mesh, const std::vector<std::uint8_t>& interior) {
    AtlasSummary& s = atlas.summary;
    std::vector<std::uint32_t> sizes;
    for (const ChartPlacement& cp : atlas.charts) sizes.push_back(cp.triangles);
    std::sort(sizes.begin(), sizes.end());
    s.chart_triangles_max = sizes.back();
    s.chart_triangles_median = sizes[sizes.size() / 2];
    s.width = atlas.width;
    s.height = atlas.height;
    for (std::size_t i = 0; i < atlas.owner.size(); ++i)
        if (atlas.owner[i] != Atlas::kEmpty) ++(interior[i] ? s.interior_texels : s.gutter_texels);
    const double total = double(atlas.width) * atlas.height;
    s.fill_ratio = double(s.interior_texels + s.gutter_texels) / total;
    s.interior_ratio = double(s.interior_texels) / total;
    s.atlas_vertices = atlas_vertex_count(mesh, atlas);
}

/// The summary's distortion, per triangle relative to its chart's texels per surface area.
void measure_distortion(Atlas& atlas, const Mesh& mesh, const std::vector<double>& surface) {
    AtlasSummary& s = atlas.summary;
    const std::size_t tri_count = mesh.triangles.size();
    std::vector<double> chart_density(atlas.charts.size(), 0.0), chart_area(atlas.charts.size(), 0.0);
    std::vector<double> texel_area(tri_count);
    for (std::uint32_t t = 0; t < tri_count; ++t) {
        const glm::dvec2 c0 = atlas.corner_texel(t, 0);
        texel_area[t] = 0.5 * cross2(atlas.corner_texel(t, 1) - c0, atlas.corner_texel(t, 2) - c0);
        chart_density[atlas.chart_of[t]] += texel_area[t];
        chart_area[atlas.chart_of[t]] += surface[t];
    }
    std::vector<std::pair<double, double>> area_ratio; // (ratio, weight)
    double angle_sum = 0.0, weight_sum = 0.0;
    s.area_distortion_min = std::numeric_limits<double>::infinity();
    for (std::uint32_t t = 0; t < tri_count; ++t) {
        const std::uint32_t c = atlas.chart_of[t];
        const glm::uvec3 tri = mesh.triangles[t];
        const glm::dvec2 st = triangle_stretch(glm::dvec3(mesh.positions[tri.x]), glm::dvec3(mesh.positions[tri.y]),
                                               glm::dvec3(mesh.positions[tri.z]), atlas.corner_texel(t, 0), atlas.corner_texel(t, 1),
                                               atlas.corner_texel(t, 2));
        const double angle = st.y > 0.0 ? st.x / st.y : std::numeric_limits<double>::infinity();
        const double ratio = surface[t] > 0.0 && chart_density[c] > 0.0
                                 ? (texel_area[t] / surface[t]) / (chart_density[c] / chart_area[c])
                                 : 1.0;
        angle_sum += surface[t] * angle;
        weight_sum += surface[t];
        s.angle_distortion_max = std::max(s.angle_distortion_max, angle);
        s.area_distortion_min = std::min(s.area_distortion_min, ratio);
        s.area_distortion_max = std::max(s.area_distortion_max, ratio);
        area_ratio.emplace_back(ratio, surface[t]);
    }
    s.angle_distortion_mean = weight_sum > 0.0 ? angle_sum / weight_sum : 1.0;
    std::sort(area_ratio.begin(), area_ratio.end());
    double acc = 0.0;
    s.area_distortion_p05 = area_ratio.front().first;
    s.area_distortion_p95 = area_ratio.back().first;
    bool have05 = false;
    for (const auto& [r, w] : area_ratio) {
        acc += w;
        if (!have05 && acc >= 0.05 * weight_sum) {
            s.area_distortion_p05 = r;
            have05 = true;
        }
        if (acc >= 0.95 * weight_sum) {
            s.area_distortion_p95 = r;
            break;
        }
    }
}

} // namespace

Atlas build_chart_atlas(const Mesh& mesh, std::span<const Camera> cameras, const AtlasOptions& options) {
    const ChartSet set = make_charts(mesh); // 1 to 3
    Atlas atlas;
    atlas.mode = AtlasMode::Charts;
    AtlasSummary& s = atlas.summary;
    s.mode = to_string(AtlasMode::Charts);
    s.triangles = mesh.triangles.size();
    s.charts = set.charts;
    s.seam_edges = set.seam_edges;
    s.crease_edges = set.crease_edges;
    s.mesh_vertices = mesh.positions.size();

    const ChartSizes sizes = size_charts(mesh, set, cameras, options, s);  // 4
    const ChartPacking packing = pack_charts(set, sizes, options);         // 5
    note_budget(s, packing, sizes, options);
    place_charts(atlas, mesh, set, sizes, packing);
    const std::vector<std::uint8_t> interior = assign_interior(atlas);      // 6
    assign_gutter(atlas, interior);
    summarize_atlas(atlas, mesh, interior);
    measure_distortion(atlas, mesh, sizes.surface);
    return atlas;
}

Atlas atlas_from_texture_coordinates(const Mesh& mesh, std::uint32_t width, std::uint32_t height) {
    const std::size_t tri_count = mesh.triangles.size(), vertex_count = mesh.positions.size();
    if (!mesh.has_texcoords()) throw Error("atlas from texture coordinates: the mesh has no texture coordinates (one per vertex)");
    if (width == 0 || height == 0 || width > Atlas::kMaxDimension || height > Atlas::kMaxDimension)
        throw Error("atlas from texture coordinates: a texture of " + std::to_string(width) + " x " + std::to_string(height) +
                    " texels (1 to " + std::to_string(Atlas::kMaxDimension) + " a side)");
    if (tri_count == 0) throw Error("atlas from texture coordinates: the mesh has no triangles");
    for (std::size_t v = 0; v < vertex_count; ++v)
        if (!std::isfinite(mesh.texcoords[v].x) || !std::isfinite(mesh.texcoords[v].y))
            throw Error("atlas from texture coordinates: vertex " + std::to_string(v) + "'s texture coordinate is not finite");

    Atlas atlas;
    atlas.mode = AtlasMode::Charts;
    atlas.width = width;
    atlas.height = height;
    atlas.corners.resize(3 * tri_count);
    atlas.corner_uv.resize(3 * tri_count);
    // Charts: triangles joined through shared vertices (a vertex holds one coordinate, so its
    // triangles meet in the texture there too), by union-find over the vertices.
    std::vector<std::uint32_t> parent(vertex_count);
    std::iota(parent.begin(), parent.end(), 0u);
    const auto root = [&](std::uint32_t v) {
        while (parent[v] != v) v = parent[v] = parent[parent[v]];
        return v;
    };
    for (std::size_t t = 0; t < tri_count; ++t) {
        const glm::uvec3 tri = mesh.triangles[t];
        for (int k = 0; k < 3; ++k) {
            if (tri[k] >= vertex_count) throw Error("atlas from texture coordinates: triangle " + std::to_string(t) + "'s vertex out of range");
            atlas.corner_uv[3 * t + std::size_t(k)] = mesh.texcoords[tri[k]];
            atlas.corners[3 * t + std::size_t(k)] = glm::dvec2(mesh.texcoords[tri[k]]) * glm::dvec2(width, height);
        }
        parent[root(tri.y)] = root(tri.x);
        parent[root(tri.z)] = root(tri.x);
    }
    std::vector<std::uint32_t> chart_of_root(vertex_count, Atlas::kEmpty);
    atlas.chart_of.resize(tri_count);
    std::vector<glm::dvec2> lo, hi;
    for (std::size_t t = 0; t < tri_count; ++t) {
        std::uint32_t& chart = chart_of_root[root(mesh.triangles[t].x)];
        if (chart == Atlas::kEmpty) {
            chart = static_cast<std::uint32_t>(atlas.charts.size());
            atlas.charts.emplace_back();
            lo.emplace_back(std::numeric_limits<double>::infinity());
            hi.emplace_back(-std::numeric_limits<double>::infinity());
        }
        atlas.chart_of[t] = chart;
        ++atlas.charts[chart].triangles;
        for (int k = 0; k < 3; ++k) {
            lo[chart] = glm::min(lo[chart], atlas.corner_texel(std::uint32_t(t), k));
            hi[chart] = glm::max(hi[chart], atlas.corner_texel(std::uint32_t(t), k));
        }
    }
    // Each chart's rectangle: its triangles' bounds and the gutter's reach, within the texture.
    for (std::size_t c = 0; c < atlas.charts.size(); ++c) {
        const double reach = kChartGutterReach * std::sqrt(2.0);
        const auto [x0, x1] = texel_range(lo[c].x - reach, hi[c].x + reach, width);
        const auto [y0, y1] = texel_range(lo[c].y - reach, hi[c].y + reach, height);
        ChartPlacement& cp = atlas.charts[c];
        if (x1 < x0 || y1 < y0) continue; // outside the texture: no texel
        cp.x = std::uint32_t(x0);
        cp.y = std::uint32_t(y0);
        cp.width = std::uint32_t(x1 - x0 + 1);
        cp.height = std::uint32_t(y1 - y0 + 1);
    }
    AtlasSummary& s = atlas.summary;
    s.mode = to_string(AtlasMode::Charts);
    s.size_source = "texture coordinates";
    s.triangles = tri_count;
    s.charts = atlas.charts.size();
    s.mesh_vertices = vertex_count;
    const std::vector<std::uint8_t> interior = assign_interior(atlas);
    assign_gutter(atlas, interior);
    summarize_atlas(atlas, mesh, interior);
    return atlas;
}

} // namespace specula
