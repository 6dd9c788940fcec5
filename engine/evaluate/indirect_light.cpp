#include "evaluate/indirect_light.h"

#include "core/error.h"
#include "core/timer.h"
#include "geometry/chart_atlas.h"

#include <algorithm>
#include <numeric>
#include <string>
#include <utility>

namespace specula::evaluate {

namespace {
const nlohmann::json* indirect_info(const Bundle& bundle) {
    if (!bundle.info.is_object()) return nullptr;
    const auto it = bundle.info.find("indirect_light");
    return it != bundle.info.end() && it->is_object() ? &*it : nullptr;
}
} // namespace

bool indirect_removed_from_albedo(const Bundle& bundle) {
    const nlohmann::json* info = indirect_info(bundle);
    if (info == nullptr) return false;
    const auto it = info->find("removed_from_albedo");
    return it != info->end() && it->is_boolean() && it->get<bool>();
}

namespace {
// `object`'s whole number `key` clamped to [lo, hi], else `fallback`.
std::uint32_t setting(const nlohmann::json* object, const char* key, std::uint32_t fallback, std::int64_t lo, std::int64_t hi) {
    if (object == nullptr || !object->is_object()) return fallback;
    const auto it = object->find(key);
    if (it == object->end() || !it->is_number_integer()) return fallback;
    const std::int64_t v = it->is_number_unsigned() ? static_cast<std::int64_t>(std::min<std::uint64_t>(it->get<std::uint64_t>(), 1u << 30))
                                                    : it->get<std::int64_t>();
    return static_cast<std::uint32_t>(std::clamp(v, lo, hi));
}
} // namespace

std::uint32_t indirect_bounces_of(const Bundle& bundle) { return setting(indirect_info(bundle), "bounces", 2, 1, 8); }

BundleTransfer indirect_transfer_of(const Bundle& bundle) {
    const nlohmann::json* info = indirect_info(bundle);
    const auto it = info != nullptr ? info->find("transfer") : nlohmann::json::const_iterator();
    const nlohmann::json* transfer = info != nullptr && it != info->end() ? &*it : nullptr;
    return {.rays = setting(transfer, "rays", kTransferRays, 1, 4096), .block = setting(transfer, "block", kTransferBlock, 1, 64)};
}

std::vector<glm::vec3> particle_albedo(std::span<const Particle> particles, const Image& texture) {
    std::vector<glm::vec3> out(particles.size());
    for (std::size_t p = 0; p < particles.size(); ++p) {
        const int x = static_cast<int>(particles[p].texel_x()), y = static_cast<int>(particles[p].texel_y());
        out[p] = glm::vec3(texture.at(x, y, 0), texture.at(x, y, std::min(1, texture.channels - 1)),
                           texture.at(x, y, std::min(2, texture.channels - 1)));
    }
    return out;
}

IndirectLightAdder::IndirectLightAdder(const IndirectScene& scene, std::vector<glm::vec3> albedo,
                                       const std::optional<SpecularModel>& material, const IndirectOptions& options)
    : m_frames(scene.lights.size()), m_batch(std::max<std::uint32_t>(options.batch_frames, 1u)), m_albedo(std::move(albedo)),
      m_images(scene, m_albedo, material, options) {}

void IndirectLightAdder::expect(std::vector<std::size_t> frames) {
    for (std::size_t f : frames)
        if (f >= m_frames)
            throw Error("indirect light: frame " + std::to_string(f) + " is not one of the scene's " + std::to_string(m_frames));
    m_order = std::move(frames);
    m_ready.clear();
}

void IndirectLightAdder::add(std::size_t frame, Image& rendered) {
    if (frame >= m_frames)
        throw Error("indirect light: frame " + std::to_string(frame) + " is not one of the scene's " + std::to_string(m_frames));
    if (!m_ready.contains(frame)) {
        const Stopwatch clock;
        m_ready.clear();
        std::vector<std::size_t> batch{frame};
        if (m_order.empty()) {
            for (std::size_t f = frame + 1; f < m_frames && batch.size() < m_batch; ++f) batch.push_back(f);
        } else {
            const auto it = std::find(m_order.begin(), m_order.end(), frame);
            if (it != m_order.end())
                for (auto next = it + 1; next != m_order.end() && batch.size() < m_batch; ++next) batch.push_back(*next);
        }
        m_images.render(batch, [&](std::size_t f, const Image& light) { m_ready.emplace(f, light); });
        m_seconds += clock.seconds();
    }
    const auto it = m_ready.find(frame);
    const Image& light = it->second;
    if (light.width != rendered.width || light.height != rendered.height || rendered.channels < 3)
        throw Error("indirect light: frame " + std::to_string(frame) + "'s render is " + std::to_string(rendered.width) + " x " +
                    std::to_string(rendered.height) + ", its view " + std::to_string(light.width) + " x " +
                    std::to_string(light.height));
    for (int y = 0; y < light.height; ++y)
        for (int x = 0; x < light.width; ++x)
            for (int c = 0; c < 3; ++c) rendered.at(x, y, c) += light.at(x, y, c);
    m_ready.erase(it);
}

BundleIndirectLight::BundleIndirectLight(const Bundle& bundle, std::span<const VisibilityView> views,
                                         std::span<const PointLight> lights, std::span<const std::uint32_t> frame_view,
                                         const BundleIndirectOptions& options)
    : m_mesh(bundle.mesh), m_lights(lights.begin(), lights.end()), m_frame_view(frame_view.begin(), frame_view.end()) {
    if (bundle.albedo.width <= 0 || bundle.albedo.height <= 0 || bundle.albedo.channels < 1)
        throw Error("indirect light of a bundle: the bundle has no albedo texture");
    if (lights.size() != frame_view.size())
        throw Error("indirect light of a bundle: " + std::to_string(lights.size()) + " lights for " +
                    std::to_string(frame_view.size()) + " frames");
    for (std::size_t f = 0; f < frame_view.size(); ++f)
        if (frame_view[f] >= views.size())
            throw Error("indirect light of a bundle: frame " + std::to_string(f) + "'s view " + std::to_string(frame_view[f]) +
                        " is not one of the " + std::to_string(views.size()) + " views");
    const unsigned threads = std::max(options.threads, 1u);
    Stopwatch clock;
    m_atlas = atlas_from_texture_coordinates(m_mesh, static_cast<std::uint32_t>(bundle.albedo.width),
                                             static_cast<std::uint32_t>(bundle.albedo.height));
    m_particles = build_particles(m_mesh, m_atlas);
    m_stats.particles = m_particles.particles.size();
    m_stats.charts = m_atlas.charts.size();
    m_stats.atlas_s = clock.seconds();

    clock.restart();
    m_scene.emplace(m_mesh);
    m_transfer = build_transfer(m_particles.particles, m_mesh, *m_scene, m_atlas,
                                TransferOptions{.rays = options.rays, .block = options.block, .threads = threads});
    m_stats.rows = m_transfer.rows;
    m_stats.entries = m_transfer.entry_count();
    m_stats.transfer_s = clock.seconds();

    clock.restart();
    // Only the lit bits count here: no surface maps, no footprint test against captured pixels.
    // As the reconstruction has them: exact where a frame's view sees the particle, else one ray
    // a row of the transfer (complete_lit's stand-ins).
    m_visibility = compute_visibility(m_particles.particles, m_mesh, *m_scene, views, m_lights,
                                      VisibilityOptions{.threads = threads, .frame_view = m_frame_view, .surface_maps = false,
                                                        .lit_seen_only = true});
    std::vector<std::size_t> all(m_lights.size());
    std::iota(all.begin(), all.end(), std::size_t{0});
    complete_lit(m_visibility, m_particles.particles, m_mesh, *m_scene, views, m_lights, m_frame_view, all, threads,
                 row_stand_ins(m_transfer));
    m_stats.visibility_s = clock.seconds();

    clock.restart();
    m_view_maps.reserve(views.size());
    for (const VisibilityView& view : views)
        m_view_maps.push_back(build_view_atlas_map(view.camera, m_mesh, *m_scene, m_atlas, m_particles.particles, threads));
    m_stats.view_maps_s = clock.seconds();

    const IndirectScene scene{.particles = m_particles.particles,
                              .visibility = &m_visibility,
                              .lights = m_lights,
                              .frame_view = m_frame_view,
                              .atlas = &m_atlas,
                              .transfer = &m_transfer,
                              .view_maps = m_view_maps};
    m_adder = std::make_unique<IndirectLightAdder>(
        scene, particle_albedo(m_particles.particles, bundle.albedo), bundle.material.specular,
        IndirectOptions{.bounces = options.bounces, .threads = threads, .lobe_directions = options.lobe_directions});
}

BundleIndirectLight::~BundleIndirectLight() = default;

void BundleIndirectLight::expect(std::vector<std::size_t> frames) { m_adder->expect(std::move(frames)); }

void BundleIndirectLight::add(std::size_t frame, Image& rendered) { m_adder->add(frame, rendered); }

double BundleIndirectLight::light_seconds() const noexcept { return m_adder->seconds(); }

} // namespace specula::evaluate
