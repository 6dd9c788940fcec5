#include "diffuse/albedo_texture.h"

#include "core/error.h"
#include "core/timer.h"

#include <algorithm>
#include <cmath>

namespace specula {

namespace {

/// Step 5 (header): pull-push (Gortler et al. 1996, "The Lumigraph", section 3.4.1). Pull: each
/// coarser level averages the filled texels of its 2x2 children (filled when one of them is).
/// Push: from the coarsest level down, every empty texel takes the bilinear interpolation of
/// the (complete) level above at its center. Returns how many texels it filled.
std::size_t pull_push(Image& image, std::vector<std::uint8_t>& filled) {
    struct Level {
        int w, h;
        std::vector<glm::vec3> color;
        std::vector<std::uint8_t> filled;
    };
    std::vector<Level> levels;
    {
        Level l0{image.width, image.height, std::vector<glm::vec3>(filled.size()), filled};
        for (int y = 0; y < l0.h; ++y)
            for (int x = 0; x < l0.w; ++x)
                l0.color[std::size_t(y) * std::size_t(l0.w) + std::size_t(x)] =
                    glm::vec3(image.at(x, y, 0), image.at(x, y, 1), image.at(x, y, 2));
        levels.push_back(std::move(l0));
    }
    while (levels.back().w > 1 || levels.back().h > 1) {
        const Level& f = levels.back();
        Level c{(f.w + 1) / 2, (f.h + 1) / 2, {}, {}};
        c.color.assign(std::size_t(c.w) * std::size_t(c.h), glm::vec3(0.0f));
        c.filled.assign(c.color.size(), 0);
        for (int y = 0; y < c.h; ++y)
            for (int x = 0; x < c.w; ++x) {
                glm::vec3 sum(0.0f);
                int n = 0;
                for (int dy = 0; dy < 2; ++dy)
                    for (int dx = 0; dx < 2; ++dx) {
                        const int fx = 2 * x + dx, fy = 2 * y + dy;
                        if (fx >= f.w || fy >= f.h) continue;
                        const std::size_t i = std::size_t(fy) * std::size_t(f.w) + std::size_t(fx);
                        if (!f.filled[i]) continue;
                        sum += f.color[i];
                        ++n;
                    }
                if (n > 0) {
                    const std::size_t i = std::size_t(y) * std::size_t(c.w) + std::size_t(x);
                    c.color[i] = sum / float(n);
                    c.filled[i] = 1;
                }
            }
        levels.push_back(std::move(c));
    }
    if (!levels.back().filled[0]) return 0; // nothing filled anywhere
    std::size_t count = 0;
    for (std::size_t k = levels.size() - 1; k-- > 0;) {
        Level& f = levels[k];
        const Level& c = levels[k + 1];
        for (int y = 0; y < f.h; ++y)
            for (int x = 0; x < f.w; ++x) {
                const std::size_t i = std::size_t(y) * std::size_t(f.w) + std::size_t(x);
                if (f.filled[i]) continue;
                // The texel's center in the coarser level's texel coordinates (clamped to its edge).
                const float cx = std::clamp((x + 0.5f) / 2.0f - 0.5f, 0.0f, float(c.w - 1));
                const float cy = std::clamp((y + 0.5f) / 2.0f - 0.5f, 0.0f, float(c.h - 1));
                const int x0 = int(cx), y0 = int(cy), x1 = std::min(x0 + 1, c.w - 1), y1 = std::min(y0 + 1, c.h - 1);
                const float ax = cx - float(x0), ay = cy - float(y0);
                const auto at = [&](int xx, int yy) { return c.color[std::size_t(yy) * std::size_t(c.w) + std::size_t(xx)]; };
                f.color[i] = (1.0f - ay) * ((1.0f - ax) * at(x0, y0) + ax * at(x1, y0)) + ay * ((1.0f - ax) * at(x0, y1) + ax * at(x1, y1));
                f.filled[i] = 1;
                if (k == 0) ++count;
            }
    }
    const Level& l0 = levels[0];
    for (int y = 0; y < l0.h; ++y)
        for (int x = 0; x < l0.w; ++x) {
            const std::size_t i = std::size_t(y) * std::size_t(l0.w) + std::size_t(x);
            if (filled[i]) continue;
            for (int c = 0; c < 3; ++c) image.at(x, y, c) = l0.color[i][c];
            filled[i] = 1;
        }
    return count;
}

} // namespace

AlbedoTexture make_albedo_texture(const Atlas& atlas, std::span<const Particle> particles, std::span<const glm::vec3> albedo,
                                  std::span<const std::uint8_t> valid) {
    const Stopwatch sw;
    if (albedo.size() != particles.size() || valid.size() != particles.size())
        throw Error("albedo texture: albedo and valid must have one entry per particle");
    const int w = static_cast<int>(atlas.width), h = static_cast<int>(atlas.height);
    AlbedoTexture out;
    out.image = Image(w, h, 3, 0.0f);
    // 0 unowned, 1 empty, 2 filled
    std::vector<std::uint8_t> state(static_cast<std::size_t>(w) * static_cast<std::size_t>(h), 0);
    for (std::size_t p = 0; p < particles.size(); ++p) {
        const int x = static_cast<int>(particles[p].texel_x()), y = static_cast<int>(particles[p].texel_y());
        if (x >= w || y >= h) throw Error("albedo texture: particle " + std::to_string(p) + " lies outside the atlas");
        const std::size_t i = static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x);
        ++out.stats.texels;
        if (valid[p]) {
            state[i] = 2;
            for (int c = 0; c < 3; ++c) out.image.at(x, y, c) = albedo[p][c];
            ++out.stats.solved;
        } else {
            state[i] = 1;
        }
    }
    std::vector<std::size_t> empty;
    for (std::size_t i = 0; i < state.size(); ++i)
        if (state[i] == 1) empty.push_back(i);

    // One dilation pass: texels filled in this pass are not used until the next one.
    const auto pass = [&](bool same_patch) {
        std::vector<std::pair<std::size_t, glm::vec3>> fills;
        for (std::size_t i : empty) {
            if (state[i] != 1) continue;
            const int x = static_cast<int>(i % static_cast<std::size_t>(w)), y = static_cast<int>(i / static_cast<std::size_t>(w));
            const std::uint32_t own = atlas.owner[i];
            glm::vec3 sum(0.0f);
            int n = 0;
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx) {
                    const int nx = x + dx, ny = y + dy;
                    if ((dx == 0 && dy == 0) || nx < 0 || ny < 0 || nx >= w || ny >= h) continue;
                    const std::size_t j = static_cast<std::size_t>(ny) * static_cast<std::size_t>(w) + static_cast<std::size_t>(nx);
                    if (state[j] != 2 || (same_patch && atlas.owner[j] != own)) continue;
                    sum += glm::vec3(out.image.at(nx, ny, 0), out.image.at(nx, ny, 1), out.image.at(nx, ny, 2));
                    ++n;
                }
            if (n > 0) fills.emplace_back(i, sum / static_cast<float>(n));
        }
        for (const auto& [i, v] : fills) {
            state[i] = 2;
            const int x = static_cast<int>(i % static_cast<std::size_t>(w)), y = static_cast<int>(i / static_cast<std::size_t>(w));
            for (int c = 0; c < 3; ++c) out.image.at(x, y, c) = v[c];
        }
        return fills.size();
    };
    for (;;) {
        std::size_t n;
        while ((n = pass(true)) > 0) out.stats.filled_same_patch += n;
        n = pass(false);
        if (n == 0) break;
        out.stats.filled_across += n;
    }
    glm::dvec3 mean(0.0);
    std::size_t filled = 0;
    for (std::size_t i = 0; i < state.size(); ++i)
        if (state[i] == 2) {
            const int x = static_cast<int>(i % static_cast<std::size_t>(w)), y = static_cast<int>(i / static_cast<std::size_t>(w));
            mean += glm::dvec3(out.image.at(x, y, 0), out.image.at(x, y, 1), out.image.at(x, y, 2));
            ++filled;
        }
    if (filled > 0) mean /= static_cast<double>(filled);
    for (std::size_t i : empty)
        if (state[i] == 1) {
            const int x = static_cast<int>(i % static_cast<std::size_t>(w)), y = static_cast<int>(i / static_cast<std::size_t>(w));
            for (int c = 0; c < 3; ++c) out.image.at(x, y, c) = static_cast<float>(mean[c]);
            state[i] = 2;
            ++out.stats.filled_global;
        }

    // 4. Gutters: kGutterDilationPasses rings of unowned texels around the owned ones, each
    // texel the mean of its filled 8-neighbours (the previous rings'), so that a chart's
    // border texels continue outward (what mip levels and wide filters read next to a chart).
    std::vector<std::size_t> frontier;
    const auto add_unowned_neighbours = [&](std::size_t i, std::vector<std::size_t>& to) {
        const int x = static_cast<int>(i % static_cast<std::size_t>(w)), y = static_cast<int>(i / static_cast<std::size_t>(w));
        for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
                const int nx = x + dx, ny = y + dy;
                if (nx < 0 || ny < 0 || nx >= w || ny >= h) continue;
                const std::size_t j = static_cast<std::size_t>(ny) * static_cast<std::size_t>(w) + static_cast<std::size_t>(nx);
                if (state[j] == 0) {
                    state[j] = 3; // queued
                    to.push_back(j);
                }
            }
    };
    for (std::size_t i = 0; i < state.size(); ++i)
        if (state[i] == 2) add_unowned_neighbours(i, frontier);
    for (int pass = 0; pass < kGutterDilationPasses && !frontier.empty(); ++pass) {
        std::vector<std::pair<std::size_t, glm::vec3>> fills;
        fills.reserve(frontier.size());
        for (std::size_t i : frontier) {
            const int x = static_cast<int>(i % static_cast<std::size_t>(w)), y = static_cast<int>(i / static_cast<std::size_t>(w));
            glm::vec3 sum(0.0f);
            int n = 0;
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx) {
                    const int nx = x + dx, ny = y + dy;
                    if ((dx == 0 && dy == 0) || nx < 0 || ny < 0 || nx >= w || ny >= h) continue;
                    if (state[static_cast<std::size_t>(ny) * static_cast<std::size_t>(w) + static_cast<std::size_t>(nx)] != 2) continue;
                    sum += glm::vec3(out.image.at(nx, ny, 0), out.image.at(nx, ny, 1), out.image.at(nx, ny, 2));
                    ++n;
                }
            fills.emplace_back(i, sum / static_cast<float>(std::max(n, 1)));
        }
        std::vector<std::size_t> next;
        for (const auto& [i, v] : fills) {
            const int x = static_cast<int>(i % static_cast<std::size_t>(w)), y = static_cast<int>(i / static_cast<std::size_t>(w));
            for (int c = 0; c < 3; ++c) out.image.at(x, y, c) = v[c];
            state[i] = 2;
        }
        for (const auto& [i, v] : fills) add_unowned_neighbours(i, next);
        out.stats.filled_dilation += fills.size();
        frontier = std::move(next);
    }
    for (std::size_t i : frontier) state[i] = 0; // queued for a pass that did not run

    // 5. Everything else: pull-push.
    std::vector<std::uint8_t> done(state.size());
    for (std::size_t i = 0; i < state.size(); ++i) done[i] = state[i] == 2;
    out.stats.filled_pull_push = pull_push(out.image, done);
    out.stats.seconds = sw.seconds();
    return out;
}

AlbedoTexture make_albedo_texture(const Atlas& atlas, std::span<const Particle> particles, const LambertOutputs& solve) {
    std::vector<glm::vec3> albedo(particles.size());
    std::vector<std::uint8_t> valid(particles.size());
    for (std::size_t p = 0; p < particles.size(); ++p) {
        albedo[p] = solve.albedo(p);
        valid[p] = (solve.particles[p].status & shared::kLambertOk) ? 1 : 0;
    }
    return make_albedo_texture(atlas, particles, albedo, valid);
}

void write_albedo_texture(const AlbedoTexture& texture, const std::filesystem::path& stem, bool exr) {
    std::filesystem::path exr_path = stem, png = stem;
    exr_path += ".exr";
    png += ".png";
    if (exr) write_image(exr_path, texture.image, ColorSpace::Linear);
    write_image(png, texture.image, ColorSpace::Srgb, 8);
}

} // namespace specula
