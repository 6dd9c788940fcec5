#include "diffuse/albedo_texture.h"

#include "core/error.h"
#include "core/timer.h"

namespace specula {

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

void write_albedo_texture(const AlbedoTexture& texture, const std::filesystem::path& stem) {
    std::filesystem::path exr = stem, png = stem;
    exr += ".exr";
    png += ".png";
    write_image(exr, texture.image, ColorSpace::Linear);
    write_image(png, texture.image, ColorSpace::Srgb, 8);
}

} // namespace specula
