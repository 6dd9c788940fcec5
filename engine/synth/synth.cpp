#include "synth/synth.h"

#include "core/error.h"
#include "core/file_util.h"
#include "core/log.h"
#include "core/output_dir.h"

#include <cstdio>
#include <future>

namespace specula::synth {

namespace fs = std::filesystem;

ImageFormat parse_image_format(std::string_view text) {
    if (text == "png8") return ImageFormat::Png8;
    if (text == "png16") return ImageFormat::Png16;
    if (text == "exr") return ImageFormat::Exr;
    throw UsageError("--format: unknown image format '" + std::string(text) + "' (png8, png16, exr)");
}

std::string_view to_string(ImageFormat format) {
    switch (format) {
    case ImageFormat::Png8: return "png8";
    case ImageFormat::Png16: return "png16";
    case ImageFormat::Exr: return "exr";
    }
    return "?";
}

RigOptions SynthOptions::rig_options() const {
    RigOptions r;
    r.size = size;
    r.views = views;
    r.lights = lights;
    r.test_views = test_views;
    r.test_lights = test_lights;
    r.held_out_lights = held_out_lights;
    r.directional = directional;
    r.kind = rig;
    r.light_angles_deg = light_angles_deg;
    r.exposure = exposure;
    return r;
}

SynthObject to_object(Preset preset) { return SynthObject{std::move(preset.name), std::move(preset.mesh), std::move(preset.material)}; }

nlohmann::json lobe_to_json(const LafortuneRgb& lobe) {
    const auto arr = [](const glm::vec3& v) { return nlohmann::json::array({v.x, v.y, v.z}); };
    return {{"cx", arr(lobe.cx)}, {"cz", arr(lobe.cz)}, {"n", arr(lobe.n)}};
}

LafortuneRgb lobe_from_json(const nlohmann::json& j) {
    const auto vec = [&](const char* key) {
        if (!j.contains(key) || !j[key].is_array() || j[key].size() != 3) throw Error(std::string("lobe: '") + key + "' must be 3 numbers");
        return glm::vec3(j[key][0].get<float>(), j[key][1].get<float>(), j[key][2].get<float>());
    };
    return LafortuneRgb{vec("cx"), vec("cz"), vec("n")};
}

nlohmann::json material_to_json(const SpecularModel& model) {
    const auto arr = [](const glm::vec3& v) { return nlohmann::json::array({v.x, v.y, v.z}); };
    nlohmann::json j;
    if (const auto* lobe = std::get_if<LafortuneRgb>(&model)) {
        j = lobe_to_json(*lobe);
    } else {
        const CoatedParams& c = std::get<CoatedParams>(model);
        j = {{"eta", c.eta}, {"alpha", c.alpha}, {"tint", arr(c.tint)}};
    }
    j["family"] = to_string(family_of(model));
    return j;
}

SpecularModel material_from_json(const nlohmann::json& j) {
    if (!j.is_object() || !j.contains("family") || !j["family"].is_string()) throw Error("material: 'family' must be a string");
    const std::optional<MaterialFamily> family = material_family_from_string(j["family"].get<std::string>());
    if (!family) throw Error("material: unknown family '" + j["family"].get<std::string>() + "' (lafortune, coated)");
    if (*family == MaterialFamily::Lafortune) return lobe_from_json(j);
    const auto number = [&](const char* key) {
        if (!j.contains(key) || !j[key].is_number()) throw Error(std::string("material: '") + key + "' must be a number");
        return j[key].get<float>();
    };
    if (!j.contains("tint") || !j["tint"].is_array() || j["tint"].size() != 3) throw Error("material: 'tint' must be 3 numbers");
    return CoatedParams{number("eta"), number("alpha"), glm::vec3(j["tint"][0].get<float>(), j["tint"][1].get<float>(), j["tint"][2].get<float>())};
}

namespace {

std::string frame_stem(int view_index, int light) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "v%02d_l%d", view_index, light);
    return buf;
}

std::string view_stem(int view_index) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "v%02d", view_index);
    return buf;
}

Image mask_image(const std::vector<std::uint8_t>& mask, int w, int h) {
    Image m(w, h, 1);
    for (std::size_t i = 0; i < mask.size(); ++i) m.pixels[i] = mask[i] ? 1.0f : 0.0f;
    return m;
}

// The albedo truth as a texture: the material's, or a small constant one.
Image albedo_truth(const Material& material) {
    if (!material.albedo_texture.empty()) return material.albedo_texture;
    Image t(4, 4, 3);
    for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 4; ++x)
            for (int c = 0; c < 3; ++c) t.at(x, y, c) = material.albedo_value[c];
    return t;
}

class StageClock {
public:
    void add(const std::string& name, double seconds) {
        for (StageTime& t : m_times)
            if (t.name == name) {
                t.seconds += seconds;
                return;
            }
        m_times.push_back({name, seconds});
    }
    [[nodiscard]] const std::vector<StageTime>& times() const { return m_times; }

private:
    std::vector<StageTime> m_times;
};

} // namespace

SynthResult write_synthetic_capture(const SynthObject& object, const fs::path& out, const SynthOptions& options) {
    const Stopwatch total;
    if (options.threads < 1 || options.threads > 256) throw UsageError("--threads must be between 1 and 256");
    if (!(options.noise_sigma >= 0.0) || !(options.shot_noise >= 0.0) || !std::isfinite(options.noise_sigma) || !std::isfinite(options.shot_noise))
        throw UsageError("--noise and --shot-noise must be finite and non-negative");
    if (options.bounces < 0 || options.bounces > Interreflection::kMaxBounces)
        throw UsageError("--bounces must be between 0 (direct light only) and " + std::to_string(Interreflection::kMaxBounces) +
                         ", not " + std::to_string(options.bounces));
    if (options.bounce_samples < 1 || options.bounce_samples > Interreflection::kMaxSamples)
        throw UsageError("--bounce-samples must be between 1 and " + std::to_string(Interreflection::kMaxSamples) + ", not " +
                         std::to_string(options.bounce_samples));
    // The output folder is checked and locked before any work (core/output_dir.h).
    OutputFolder folder(out, {.option = "--out", .force = options.force, .inputs = options.inputs});
    StageClock clock;
    Stopwatch sw;

    const RigOptions rig_options = options.rig_options();
    const Rig rig = make_rig(object.mesh, rig_options);
    Material material = object.material;
    if (options.lambertian && material.coated)
        throw UsageError("--lambertian applies to the lafortune family only: the coated family's diffuse term is not Lambertian");
    if (options.lambertian) material.lobe = LafortuneRgb{};
    clock.add("rig", sw.seconds());

    sw.restart();
    const Renderer renderer(object.mesh, material);
    clock.add("scene (Embree BVH)", sw.seconds());
    log::info("synth: " + object.name + ", " + std::to_string(object.mesh.triangle_count()) + " triangles, " +
              std::to_string(rig.frame_count(Split::Train)) + " train + " + std::to_string(rig.frame_count(Split::Test)) +
              " test frames at " + std::to_string(options.size) + "x" + std::to_string(options.size));

    const bool is_float = options.format == ImageFormat::Exr;
    const std::string ext = is_float ? ".exr" : ".png";
    const int bits = options.format == ImageFormat::Png16 ? 16 : 8;
    const float saturation = 1.0f;
    const NoiseOptions noise{options.noise_sigma, options.shot_noise};

    SynthResult result;
    result.triangles = object.mesh.triangle_count();
    result.views = rig.views.size();
    result.train_frames = rig.frame_count(Split::Train);
    result.test_frames = rig.frame_count(Split::Test);

    const auto write = [&](const fs::path& tmp) {
        fs::create_directories(tmp / "images");
        fs::create_directories(tmp / "masks");
        fs::create_directories(tmp / "truth");
        sw.restart();
        write_mesh_glb(tmp / "mesh.glb", renderer.mesh());
        write_image(tmp / "truth" / "albedo.exr", albedo_truth(material), ColorSpace::Linear);
        clock.add("mesh and truth", sw.seconds());

        CaptureDesc desc;
        desc.dir = tmp;
        desc.mesh_path = "mesh.glb";
        desc.color_space = is_float ? ColorSpace::Linear : ColorSpace::Srgb;
        if (!is_float) desc.saturation = saturation;

        const std::size_t total_frames = rig.frame_count();
        log::Progress progress("synth: frames", total_frames);
        // Encoding a PNG costs about as much as rendering the frame: one writer thread
        // encodes frame k while frame k + 1 renders. Its time is measured on its side;
        // reading it after get() is ordered by the future.
        std::future<void> pending;
        double write_seconds = 0.0;
        const auto wait_for_writer = [&] {
            if (!pending.valid()) return;
            const Stopwatch wait;
            pending.get();
            clock.add("wait for writer", wait.seconds());
        };
        std::size_t frame_index = 0;
        for (const RigView& view : rig.views) {
            const fs::path mask_rel = fs::path("masks") / (view_stem(view.view_index) + ".png");
            for (std::size_t l = 0; l < view.lights.size(); ++l) {
                sw.restart();
                const Interreflection indirect{.bounces = options.bounces,
                                               .samples = options.bounce_samples,
                                               .seed = options.seed,
                                               .frame = frame_index};
                RenderedFrame frame = renderer.render(view.camera, view.lights[l], options.threads, indirect);
                clock.add("render", sw.seconds());
                result.shadowed_pixels += frame.shadowed_pixels;
                for (std::uint8_t m : frame.mask) result.object_pixels += m != 0;

                sw.restart();
                apply_noise(frame.color, noise, options.seed, frame_index);
                if (!is_float) result.clipped_pixels += count_clipped(frame.color, frame.mask, saturation);
                clock.add("noise", sw.seconds());

                const fs::path image_rel = fs::path("images") / (frame_stem(view.view_index, static_cast<int>(l)) + ext);
                wait_for_writer();
                pending = std::async(std::launch::async, [&, image_rel, mask_rel, cs = desc.color_space, first = l == 0, frame = std::move(frame)] {
                    const Stopwatch write;
                    write_image(tmp / image_rel, frame.color, cs, bits);
                    if (first) write_image(tmp / mask_rel, mask_image(frame.mask, frame.color.width, frame.color.height), ColorSpace::Linear, 8);
                    write_seconds += write.seconds();
                });

                FrameDesc f;
                f.file_path = image_rel;
                f.view_index = view.view_index;
                f.transform = view.camera.camera_to_world;
                f.intrinsics = view.camera.intrinsics;
                f.light = view.lights[l];
                f.mask_path = mask_rel;
                f.split = view.split_of(l);
                desc.frames.push_back(std::move(f));

                ++frame_index;
                progress.update(frame_index);
                if (options.on_frame) options.on_frame(frame_index, total_frames);
            }
        }
        wait_for_writer();
        clock.add("write images (overlapped)", write_seconds);
        progress.finish();

        desc.ground_truth = {
            {"preset", object.name},
            {"material", material_to_json(material.specular())},
            // Lafortune and Lambertian only in the lafortune family: a coated capture has no lobe
            // to compare a fit with, and its diffuse term is not Lambertian.
            {"lambertian", !material.coated && material.lobe.is_zero()},
            {"albedo_texture", "truth/albedo.exr"},
            {"albedo_sampling", "bilinear at texel centres over mesh TEXCOORD_0; u repeats, v clamps; v = 0 is the top row (glTF)"},
            {"noise",
             {{"sigma", options.noise_sigma},
              {"shot", options.shot_noise},
              {"model", "additive Gaussian per channel, variance = sigma^2 + shot * value (linear, full scale 1.0), before clipping"}}},
            {"exposure", options.exposure},
            {"seed", options.seed},
            {"format", std::string(to_string(options.format))},
            {"clipped_pixels", result.clipped_pixels},
            {"rig",
             {{"name", std::string(to_string(rig_options.kind))},
              {"views", options.views},
              {"lights", options.lights},
              {"test_views", options.test_views},
              {"test_lights", options.test_lights},
              {"held_out_lights", options.held_out_lights},
              {"light_type", options.directional ? "directional" : "point"},
              {"fov_deg", rig_options.fov_deg},
              {"camera_distance", rig.camera_distance},
              {"object_center", {rig.center.x, rig.center.y, rig.center.z}},
              {"object_radius", rig.radius},
              {"light_angles_deg", rig_options.train_light_angles_deg()},
              {"light_ring_radius", rig_options.train_light_angles_deg().empty()
                                        ? nlohmann::json(rig_options.ring_radius * rig.camera_distance)
                                        : nlohmann::json(nullptr)},
              {"exposure_rule", "I = exposure * 0.6 * pi * d_min^2 / 0.8 (d_min: light to nearest vertex)"}}},
            {"generator", "specula synth"},
        };
        if (!material.coated) desc.ground_truth["lobe"] = lobe_to_json(material.lobe);
        // Only with interreflections: captures of direct light stay as they were.
        if (options.bounces > 0) {
            desc.ground_truth["bounces"] = options.bounces;
            desc.ground_truth["bounce_samples"] = options.bounce_samples;
        }
        sw.restart();
        write_capture_json(desc);
        clock.add("capture.json", sw.seconds());
    };
    write(folder.staging());
    folder.commit();
    result.dir = folder.path();
    result.times = clock.times();
    result.seconds = total.seconds();
    return result;
}

void export_preset(const Preset& preset, const fs::path& out, bool force) {
    (void)write_folder_atomically(out, {.option = "--out", .force = force}, [&](const fs::path& tmp) {
        write_mesh_glb(tmp / "mesh.glb", preset.mesh);
        const Image albedo = albedo_truth(preset.material);
        write_image(tmp / "albedo.exr", albedo, ColorSpace::Linear);
        write_image(tmp / "albedo.png", albedo, ColorSpace::Srgb, 8);
        const nlohmann::json j = {
            {"preset", preset.name},
            {"description", preset.description},
            {"triangles", preset.mesh.triangle_count()},
            {"vertices", preset.mesh.positions.size()},
            {"albedo_texture", "albedo.exr"},
            {"albedo_preview", "albedo.png"},
            {"albedo_size", {albedo.width, albedo.height}},
            {"lobe", lobe_to_json(preset.material.lobe)},
            {"coated", material_to_json(preset.coated)},
        };
        write_text_file(tmp / "preset.json", j.dump(2) + "\n");
    });
}

} // namespace specula::synth
