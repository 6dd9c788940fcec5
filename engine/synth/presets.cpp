#include "synth/presets.h"

#include "core/error.h"
#include "synth/shapes.h"

#include <glm/gtc/constants.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>

namespace specula::synth {

namespace {

constexpr float kTwoPi = glm::two_pi<float>();
constexpr float kAlbedoMin = 0.05f;
constexpr float kAlbedoMax = 0.9f;

// ---- Texture helpers -----------------------------------------------------------------

std::uint32_t hash2(int x, int y, std::uint32_t seed) {
    std::uint32_t h = static_cast<std::uint32_t>(x) * 0x8da6b343u ^ static_cast<std::uint32_t>(y) * 0xd8163841u ^ seed * 0xcb1ab31fu;
    h ^= h >> 15;
    h *= 0x2c1b3c6du;
    h ^= h >> 12;
    h *= 0x297a2d39u;
    h ^= h >> 15;
    return h;
}

float hash01(int x, int y, std::uint32_t seed) { return static_cast<float>(hash2(x, y, seed) >> 8) * (1.0f / 16777216.0f); }

// Value noise on a lattice that repeats every `period` cells in x, so textures
// wrapped around a surface of revolution have no seam.
float periodic_noise(float x, float y, int period, std::uint32_t seed) {
    const float fx = std::floor(x), fy = std::floor(y);
    const float tx = x - fx, ty = y - fy;
    const float sx = tx * tx * (3.0f - 2.0f * tx), sy = ty * ty * (3.0f - 2.0f * ty);
    const auto wrap = [period](int i) { return ((i % period) + period) % period; };
    const int x0 = wrap(static_cast<int>(fx)), x1 = wrap(static_cast<int>(fx) + 1), y0 = static_cast<int>(fy);
    const float a = hash01(x0, y0, seed), b = hash01(x1, y0, seed), c = hash01(x0, y0 + 1, seed), d = hash01(x1, y0 + 1, seed);
    return glm::mix(glm::mix(a, b, sx), glm::mix(c, d, sx), sy);
}

// Fractal sum over `octaves`, periodic in u over [0, 1); result in about [0, 1].
float periodic_fbm(float u, float v, int base_period, int octaves, std::uint32_t seed) {
    float sum = 0.0f, amplitude = 0.5f, norm = 0.0f;
    int period = base_period;
    for (int o = 0; o < octaves; ++o) {
        sum += amplitude * periodic_noise(u * static_cast<float>(period), v * static_cast<float>(period), period, seed + static_cast<std::uint32_t>(o));
        norm += amplitude;
        amplitude *= 0.5f;
        period *= 2;
    }
    return sum / norm;
}

float smoothstep(float e0, float e1, float x) {
    const float t = std::clamp((x - e0) / (e1 - e0), 0.0f, 1.0f);
    return t * t * (3.0f - 2.0f * t);
}

// Fills a w x h linear RGB texture from f(u, v) at texel centres, clamped to [0.05, 0.9].
Image make_texture(int w, int h, const std::function<glm::vec3(float, float)>& f) {
    Image image(w, h, 3);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            const glm::vec3 c = f((static_cast<float>(x) + 0.5f) / static_cast<float>(w), (static_cast<float>(y) + 0.5f) / static_cast<float>(h));
            for (int k = 0; k < 3; ++k) image.at(x, y, k) = std::clamp(c[k], kAlbedoMin, kAlbedoMax);
        }
    }
    return image;
}

// "Text": rows of blocks of pseudo-random widths with gaps, inside [0, 1]^2 of (s, t).
bool text_blocks(float s, float t, int rows, int columns, std::uint32_t seed) {
    if (s < 0.0f || s >= 1.0f || t < 0.0f || t >= 1.0f) return false;
    const int row = static_cast<int>(t * static_cast<float>(rows));
    const float ty = t * static_cast<float>(rows) - static_cast<float>(row);
    if (ty < 0.2f || ty > 0.8f) return false; // line spacing
    const int col = static_cast<int>(s * static_cast<float>(columns));
    const float tx = s * static_cast<float>(columns) - static_cast<float>(col);
    const float width = 0.35f + 0.6f * hash01(col, row, seed);
    const bool space = hash01(col, row, seed + 7u) < 0.18f;
    return !space && tx < width;
}

// Catmull-Rom spline through points (uniform parameter), `per_segment` samples per
// span, excluding the first point (the profile already ends there).
std::vector<glm::vec2> catmull_rom(const std::vector<glm::vec2>& p, int per_segment) {
    std::vector<glm::vec2> out;
    const int n = static_cast<int>(p.size());
    for (int i = 0; i + 1 < n; ++i) {
        const glm::vec2 p0 = p[std::max(i - 1, 0)], p1 = p[i], p2 = p[i + 1], p3 = p[std::min(i + 2, n - 1)];
        for (int k = 1; k <= per_segment; ++k) {
            const float t = static_cast<float>(k) / static_cast<float>(per_segment);
            const float t2 = t * t, t3 = t2 * t;
            out.push_back(0.5f * ((2.0f * p1) + (-p0 + p2) * t + (2.0f * p0 - 5.0f * p1 + 4.0f * p2 - p3) * t2 +
                                  (-p0 + 3.0f * p1 - 3.0f * p2 + p3) * t3));
        }
    }
    return out;
}

// The inner wall of a vessel: the outer curve's points above `y_min`, walked back
// down and moved `thickness` inward along the curve's normal.
std::vector<glm::vec2> inner_wall(const std::vector<glm::vec2>& outer, float thickness, float y_min) {
    std::vector<glm::vec2> out;
    const int n = static_cast<int>(outer.size());
    for (int i = n - 1; i >= 0; --i) {
        if (outer[i].y < y_min) break;
        const glm::vec2 t = outer[std::min(i + 1, n - 1)] - outer[std::max(i - 1, 0)];
        const glm::vec2 normal = glm::normalize(glm::vec2(t.y, -t.x));
        out.push_back(outer[i] - thickness * normal);
    }
    return out;
}

LafortuneRgb lobe_rgb(glm::vec3 cx, glm::vec3 cz, glm::vec3 n) { return LafortuneRgb{cx, cz, n}; }

// ---- can (the thesis's "coke"/pepsi) -----------------------------------------------------

Preset make_can() {
    // Profile: domed bottom, rounded bottom rim, straight labelled side, shoulder
    // tapering to the neck, a rolled lip, and the recessed lid. Units: about 10 cm.
    Profile prof({0.0f, 0.035f});
    prof.line_to({0.25f, 0.0f}, 16)
        .arc_to({0.25f, 0.08f}, 0.0f, 10)
        .set_mark(0)
        .line_to({0.33f, 1.0f}, 80)
        .set_mark(1)
        .arc_to({0.29f, 1.0f}, 0.5f * glm::pi<float>(), 8)
        .arc_to({0.29f, 1.09f}, -glm::pi<float>(), 8)
        .arc_to({0.235f, 1.09f}, glm::pi<float>(), 6)
        .line_to({0.23f, 1.07f}, 3)
        .arc_to({0.22f, 1.07f}, -0.5f * glm::pi<float>(), 4)
        .line_to({0.0f, 1.06f}, 16);
    Preset p;
    p.name = "can";
    p.mesh = make_revolution(prof, 96);
    const float v_label0 = prof.mark(0), v_label1 = prof.mark(1);
    p.material.albedo_texture = make_texture(1024, 512, [=](float u, float v) {
        const glm::vec3 aluminium(0.55f, 0.56f, 0.58f);
        if (v < v_label0 || v > v_label1) {
            // Brushed metal: fine radial streaks.
            return aluminium * (0.9f + 0.15f * periodic_noise(u * 256.0f, v * 8.0f, 256, 11u));
        }
        const float t = (v - v_label0) / (v_label1 - v_label0); // 0 at the bottom of the side, 1 at the top
        const glm::vec3 red(0.62f, 0.05f, 0.06f), white(0.86f, 0.85f, 0.82f), blue(0.05f, 0.12f, 0.50f), gold(0.85f, 0.70f, 0.12f);
        if (t < 0.06f || t > 0.94f) return white;
        if (std::abs(t - 0.08f) < 0.008f || std::abs(t - 0.92f) < 0.008f) return blue;
        // A white wave band that winds twice around the can.
        const float wave = 0.42f + 0.08f * std::sin(kTwoPi * 2.0f * u);
        if (std::abs(t - wave) < 0.035f) return white;
        if (std::abs(t - wave) < 0.05f) return blue;
        // Title blocks on both sides, small print near the bottom.
        const float s = std::fmod(u * 2.0f, 1.0f);
        if (t > 0.58f && t < 0.82f && text_blocks((s - 0.15f) / 0.7f, (t - 0.58f) / 0.24f, 2, 9, 3u)) return gold;
        if (t > 0.14f && t < 0.30f && text_blocks((s - 0.1f) / 0.8f, (t - 0.14f) / 0.16f, 5, 40, 5u)) return white;
        return red;
    });
    p.material.lobe = lobe_rgb({-0.8962f, -0.9050f, -0.9130f}, {0.7587f, 0.7650f, 0.7720f}, {10.11f, 10.50f, 10.90f});
    return p;
}

// ---- cologne --------------------------------------------------------------------------

Preset make_cologne() {
    // A flat glass body (rounded box) with a ridged cylindrical cap pushed 2 cm into its top.
    const UvRect body_rect{0.0f, 0.0f, 1.0f, 0.7f};
    constexpr float kInset = 4.0f / 512.0f; // texels of gutter around each face tile
    Mesh mesh = make_rounded_box({0.42f, 0.55f, 0.2f}, 0.06f, 16, 6, body_rect, kInset);
    Profile cap({0.0f, 0.53f});
    cap.line_to({0.15f, 0.53f}, 6)
        .arc_to({0.15f, 0.54f}, 0.0f, 3)
        .line_to({0.16f, 0.82f}, 30)
        .arc_to({0.13f, 0.82f}, 0.5f * glm::pi<float>(), 8)
        .line_to({0.0f, 0.85f}, 10);
    append_mesh(mesh, make_revolution(cap, 64, 0.72f, 1.0f));
    Preset p;
    p.name = "cologne";
    p.mesh = std::move(mesh);
    const UvRect front = rounded_box_face_rect(body_rect, kInset, 4); // +Z
    const UvRect back = rounded_box_face_rect(body_rect, kInset, 5);  // -Z
    p.material.albedo_texture = make_texture(512, 512, [=](float u, float v) {
        const glm::vec3 amber(0.50f, 0.28f, 0.07f), cream(0.85f, 0.80f, 0.65f), ink(0.08f, 0.07f, 0.06f);
        if (v >= 0.71f) { // cap: dark with fine gold ridges around it
            const float ridge = 0.5f + 0.5f * std::cos(kTwoPi * 48.0f * u);
            return glm::mix(glm::vec3(0.10f, 0.08f, 0.05f), glm::vec3(0.45f, 0.36f, 0.12f), ridge * ridge);
        }
        const glm::vec3 glass = amber * (0.9f + 0.2f * periodic_fbm(u, v, 8, 3, 21u));
        const auto label = [&](const UvRect& r, float x0, float y0, float x1, float y1, int rows, std::uint32_t seed) -> glm::vec3 {
            const float s = (u - r.u0) / (r.u1 - r.u0), t = (v - r.v0) / (r.v1 - r.v0);
            if (s < x0 || s > x1 || t < y0 || t > y1) return glm::vec3(-1.0f);
            const float ls = (s - x0) / (x1 - x0), lt = (t - y0) / (y1 - y0);
            if (ls < 0.04f || ls > 0.96f || lt < 0.04f || lt > 0.96f) return ink; // frame
            return text_blocks((ls - 0.1f) / 0.8f, (lt - 0.1f) / 0.8f, rows, 14, seed) ? ink : cream;
        };
        if (const glm::vec3 c = label(front, 0.2f, 0.3f, 0.8f, 0.75f, 4, 31u); c.x >= 0.0f) return c;
        if (const glm::vec3 c = label(back, 0.3f, 0.55f, 0.7f, 0.8f, 6, 37u); c.x >= 0.0f) return c;
        return glass;
    });
    p.material.lobe = lobe_rgb({-0.8874f, -0.8950f, -0.9020f}, {1.1162f, 1.1100f, 1.1050f}, {18.09f, 18.50f, 18.90f});
    return p;
}

// ---- vase -----------------------------------------------------------------------------

Preset make_vase() {
    // Foot, bulging body, narrow neck, flared lip rolled over into a short inner wall.
    const std::vector<glm::vec2> outer_ctrl = {{0.24f, 0.02f}, {0.32f, 0.15f}, {0.42f, 0.45f}, {0.30f, 0.75f},
                                               {0.13f, 0.95f}, {0.12f, 1.08f}, {0.17f, 1.2f}};
    std::vector<glm::vec2> outer = catmull_rom(outer_ctrl, 24);
    Profile prof({0.0f, 0.0f});
    prof.line_to({0.22f, 0.0f}, 12).arc_to({0.22f, 0.02f}, 0.0f, 6).append(outer);
    const std::vector<glm::vec2> inner = inner_wall(outer, 0.025f, 0.93f);
    prof.arc_to({0.17f - 0.0125f, 1.2f}, glm::pi<float>(), 8).append(std::vector<glm::vec2>(inner.begin() + 1, inner.end()));
    prof.line_to({0.0f, prof.points().back().y - 0.02f}, 8);
    Preset p;
    p.name = "vase";
    p.mesh = make_revolution(prof, 128);
    p.material.albedo_texture = make_texture(512, 512, [](float u, float v) {
        const glm::vec3 glaze(0.72f, 0.76f, 0.82f), cobalt(0.08f, 0.18f, 0.55f);
        if (v > 0.93f) return glaze * 0.6f; // inside the neck
        if (std::abs(v - 0.18f) < 0.012f || std::abs(v - 0.62f) < 0.012f || std::abs(v - 0.78f) < 0.008f) return cobalt;
        if (v > 0.25f && v < 0.55f) {
            // Petal motif: eight flowers around, each five-fold.
            const float cu = u * 8.0f, cell_u = cu - std::floor(cu) - 0.5f;
            const float cell_v = (v - 0.4f) / 0.15f * 0.5f;
            const float r = std::sqrt(cell_u * cell_u + cell_v * cell_v);
            const float a = std::atan2(cell_v, cell_u);
            const float petal = 0.3f + 0.12f * std::cos(5.0f * a);
            if (r < 0.06f) return glm::vec3(0.80f, 0.62f, 0.15f);
            if (r < petal) return glm::mix(cobalt, glaze, smoothstep(0.6f * petal, petal, r) * 0.6f);
        }
        return glaze * (0.93f + 0.1f * periodic_fbm(u, v, 4, 3, 41u));
    });
    p.material.lobe = lobe_rgb({-1.2127f, -1.2050f, -1.1980f}, {0.5653f, 0.5700f, 0.5750f}, {20.36f, 20.00f, 19.70f});
    return p;
}

// ---- woodenpot ----------------------------------------------------------------------------

Preset make_woodenpot() {
    // Squat turned-wood bowl with a thick rim and an open interior (self-shadowing inside).
    const std::vector<glm::vec2> outer_ctrl = {{0.46f, 0.04f}, {0.55f, 0.18f}, {0.58f, 0.30f}, {0.53f, 0.44f}, {0.48f, 0.52f}, {0.49f, 0.57f}};
    std::vector<glm::vec2> outer = catmull_rom(outer_ctrl, 20);
    Profile prof({0.0f, 0.0f});
    prof.line_to({0.42f, 0.0f}, 20).arc_to({0.42f, 0.04f}, 0.0f, 8).append(outer);
    const std::vector<glm::vec2> inner = inner_wall(outer, 0.05f, 0.12f);
    prof.arc_to({0.49f - 0.025f, 0.57f}, glm::pi<float>(), 10).append(std::vector<glm::vec2>(inner.begin() + 1, inner.end()));
    prof.line_to({0.0f, 0.1f}, 20);
    Preset p;
    p.name = "woodenpot";
    p.mesh = make_revolution(prof, 128);
    p.material.albedo_texture = make_texture(512, 512, [](float u, float v) {
        // Grain: lines running along the profile (constant u), bent by periodic noise;
        // darker late-wood where the lines bunch.
        const float warp = periodic_fbm(u, v * 0.5f, 4, 4, 51u);
        const float grain = 0.5f + 0.5f * std::sin(kTwoPi * (36.0f * u + 3.0f * warp + 0.5f * v));
        const float fine = periodic_noise(u * 256.0f, v * 16.0f, 256, 53u);
        const glm::vec3 early(0.55f, 0.34f, 0.15f), late(0.28f, 0.15f, 0.06f);
        return glm::mix(early, late, std::pow(grain, 3.0f)) * (0.92f + 0.12f * fine);
    });
    p.material.lobe = lobe_rgb({-1.4299f, -1.4200f, -1.4100f}, {-0.7763f, -0.7700f, -0.7650f}, {9.74f, 9.90f, 10.10f});
    return p;
}

// ---- knot -----------------------------------------------------------------------------------

Preset make_knot(bool hd) {
    Preset p;
    p.name = hd ? "knot_hd" : "knot";
    p.mesh = hd ? make_torus_knot(2, 3, 1.0f, 0.3f, 1600, 64, 8.0f) : make_torus_knot(2, 3, 1.0f, 0.3f, 480, 40, 8.0f);
    p.material.albedo_texture = make_texture(512, 256, [](float u, float v) {
        // Bands along the tube (u repeats 8 times along it), a thin dark line, and a stripe
        // spiralling around the tube (periodic in v, which wraps around the tube).
        const glm::vec3 teal(0.10f, 0.45f, 0.50f), ivory(0.80f, 0.75f, 0.60f), dark(0.06f, 0.06f, 0.08f);
        const float band = std::fmod(u * 2.0f, 1.0f);
        if (std::abs(band - 0.5f) < 0.02f) return dark;
        glm::vec3 c = band < 0.5f ? teal : ivory;
        const float spiral = std::fmod(v + 2.0f * u + 1.0f, 1.0f);
        if (std::abs(spiral - 0.5f) < 0.06f) c = glm::mix(c, glm::vec3(0.75f, 0.2f, 0.12f), 0.8f);
        return c;
    });
    p.material.lobe = lobe_rgb({-1.02f, -1.00f, -0.98f}, {0.95f, 0.96f, 0.97f}, {14.0f, 14.5f, 15.0f});
    return p;
}

// ---- sphere ---------------------------------------------------------------------------------

Preset make_sphere() {
    Preset p;
    p.name = "sphere";
    p.mesh = make_uv_sphere(glm::vec3(0.0f), 0.5f, 64, 32);
    p.material.albedo_texture = make_texture(512, 256, [](float u, float v) {
        const int cu = static_cast<int>(u * 16.0f), cv = static_cast<int>(v * 8.0f);
        return ((cu + cv) % 2 == 0) ? glm::vec3(0.75f, 0.70f, 0.62f) : glm::vec3(0.25f, 0.35f, 0.55f);
    });
    p.material.lobe = thesis_lobe("pepsi");
    return p;
}

struct PresetEntry {
    const char* name;
    const char* description;
    Preset (*make)();
};

const PresetEntry kPresets[] = {
    {"can", "soda can (thesis 'coke'): bevelled rims, rolled lip, recessed lid; striped label with text blocks; pepsi lobe", &make_can},
    {"cologne", "flat glass bottle (rounded box) with a ridged cylindrical cap; front and back labels; cologne lobe", &make_cologne},
    {"vase", "surface of revolution with a bulging body, narrow neck and flared lip; glaze with bands and petals; vase lobe", &make_vase},
    {"woodenpot", "squat turned bowl, open interior; wood grain; lobe with Cz < 0 as the thesis's woodenpot", &make_woodenpot},
    {"knot", "(2,3) torus knot tube: strong self-shadowing and self-occlusion; banded texture", [] { return make_knot(false); }},
    {"knot_hd", "the knot at high resolution (over 200k triangles), for timing on real loads", [] { return make_knot(true); }},
    {"sphere", "UV sphere with a checker texture and the pepsi lobe: closed-form checks", &make_sphere},
};

} // namespace

LafortuneRgb thesis_lobe(std::string_view object) {
    // Erdem 2003, table 5.2 (Cx, Cz, N).
    const auto same = [](float cx, float cz, float n) { return LafortuneRgb{glm::vec3(cx), glm::vec3(cz), glm::vec3(n)}; };
    if (object == "pepsi" || object == "coke" || object == "can") return same(-0.8962f, 0.7587f, 10.11f);
    if (object == "cologne") return same(-0.8874f, 1.1162f, 18.09f);
    if (object == "vase") return same(-1.2127f, 0.5653f, 20.36f);
    if (object == "woodenpot") return same(-1.4299f, -0.7763f, 9.74f);
    throw UsageError("unknown thesis object '" + std::string(object) + "' (pepsi, cologne, vase, woodenpot)");
}

std::vector<PresetInfo> list_presets() {
    std::vector<PresetInfo> out;
    for (const PresetEntry& e : kPresets) out.push_back({e.name, e.description});
    return out;
}

Preset make_preset(std::string_view name, bool lambertian) {
    for (const PresetEntry& e : kPresets) {
        if (name != e.name) continue;
        Preset p = e.make();
        p.description = e.description;
        if (lambertian) p.material.lobe = LafortuneRgb{};
        return p;
    }
    std::string names;
    for (const PresetEntry& e : kPresets) names += (names.empty() ? "" : ", ") + std::string(e.name);
    throw UsageError("unknown preset '" + std::string(name) + "' (presets: " + names + ")");
}

} // namespace specula::synth
