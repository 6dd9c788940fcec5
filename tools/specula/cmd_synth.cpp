// specula synth: render a synthetic capture with known truth (engine/synth).
// Maps options to SynthOptions and an object (preset or the user's mesh), calls
// the engine, and prints where it wrote, the counts and the time.
#include "capture/mesh.h"
#include "commands.h"
#include "core/error.h"
#include "core/image.h"
#include "core/log.h"
#include "material/material.h"
#include "synth/synth.h"

#include <cmath>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace specula::cli {

namespace {

struct SynthArgs {
    std::string preset;
    std::string out;
    std::string export_preset;
    std::string mesh;
    std::string albedo;
    std::vector<double> albedo_value;
    std::vector<double> lobe;
    std::vector<double> lobe_rgb;
    std::string format = "png8";
    std::string material = "lafortune";
    std::string rig = "spread";
    bool light_angles_given = false;
    bool bounce_samples_given = false;
    bool list_presets = false;
    synth::SynthOptions options;
};

void require_finite(const std::vector<double>& values, const char* option) {
    for (double v : values)
        if (!std::isfinite(v)) throw UsageError(std::string(option) + ": values must be finite numbers");
}

synth::LafortuneRgb parse_lobe(const SynthArgs& a) {
    synth::LafortuneRgb lobe;
    if (!a.lobe.empty()) {
        require_finite(a.lobe, "--lobe");
        lobe = {glm::vec3(static_cast<float>(a.lobe[0])), glm::vec3(static_cast<float>(a.lobe[1])), glm::vec3(static_cast<float>(a.lobe[2]))};
    } else {
        require_finite(a.lobe_rgb, "--lobe-rgb");
        const auto v = [&](int i) { return glm::vec3(static_cast<float>(a.lobe_rgb[i]), static_cast<float>(a.lobe_rgb[i + 1]), static_cast<float>(a.lobe_rgb[i + 2])); };
        lobe = {v(0), v(3), v(6)};
    }
    for (int c = 0; c < 3; ++c)
        if (!(lobe.n[c] > 0.0f)) throw UsageError(std::string(a.lobe.empty() ? "--lobe-rgb" : "--lobe") + ": the exponent N must be positive");
    return lobe;
}

MaterialFamily parse_family(const std::string& text) {
    const std::optional<MaterialFamily> f = material_family_from_string(text);
    if (!f) throw UsageError("--material: unknown material family '" + text + "' (lafortune, coated)");
    return *f;
}

synth::SynthObject make_object(const SynthArgs& a) {
    const MaterialFamily family = parse_family(a.material);
    if (family == MaterialFamily::Coated && (!a.lobe.empty() || !a.lobe_rgb.empty()))
        throw UsageError("--lobe and --lobe-rgb give a Lafortune lobe: they apply to --material lafortune only");
    synth::SynthObject object;
    if (!a.mesh.empty()) {
        MeshLoadResult loaded = load_mesh(a.mesh, "--mesh");
        for (const std::string& w : loaded.warnings) log::warn(a.mesh + ": " + w);
        object.name = std::filesystem::path(a.mesh).stem().string();
        object.mesh = std::move(loaded.mesh);
        object.material.albedo_value = glm::vec3(0.5f);
        if (family == MaterialFamily::Coated) {
            if (a.options.lambertian)
                throw UsageError("--lambertian applies to the lafortune family only: the coated family's diffuse term is not Lambertian");
            object.material.coated = CoatedParams{};
        }
    } else {
        object = synth::to_object(synth::make_preset(a.preset, a.options.lambertian, family));
    }
    if (!a.albedo.empty()) {
        if (!object.mesh.has_texcoords())
            throw UsageError("--albedo: the mesh has no texture coordinates (TEXCOORD_0); use --albedo-value r,g,b instead");
        object.material.albedo_texture = read_image(a.albedo, ColorSpace::Srgb, "--albedo");
        if (object.material.albedo_texture.channels < 3 && object.material.albedo_texture.channels != 1)
            throw InputError(a.albedo, "--albedo", "needs an RGB or grey image");
    } else if (!a.albedo_value.empty()) {
        require_finite(a.albedo_value, "--albedo-value");
        for (double v : a.albedo_value)
            if (v < 0.0 || v > 1.0) throw UsageError("--albedo-value: each channel must be in [0, 1]");
        object.material.albedo_texture = Image();
        object.material.albedo_value = glm::vec3(static_cast<float>(a.albedo_value[0]), static_cast<float>(a.albedo_value[1]),
                                                 static_cast<float>(a.albedo_value[2]));
    }
    if (!a.lobe.empty() || !a.lobe_rgb.empty()) object.material.lobe = parse_lobe(a);
    return object;
}

void run(SynthArgs& a) {
    if (a.list_presets) {
        for (const synth::PresetInfo& p : synth::list_presets()) std::printf("%-10s %s\n", p.name.c_str(), p.description.c_str());
        return;
    }
    if (a.out.empty()) throw UsageError("--out DIR is required");
    if (!a.export_preset.empty()) {
        const Stopwatch sw;
        const synth::Preset p = synth::make_preset(a.export_preset, a.options.lambertian);
        synth::export_preset(p, a.out, a.options.force);
        std::printf("wrote preset %s to %s: mesh.glb (%zu triangles), albedo.exr, albedo.png, preset.json in %.2f s\n",
                    p.name.c_str(), a.out.c_str(), p.mesh.triangle_count(), sw.seconds());
        return;
    }
    if (a.preset.empty() == a.mesh.empty()) throw UsageError("give exactly one of --preset NAME or --mesh FILE.glb (see --list-presets)");
    a.options.format = synth::parse_image_format(a.format);
    a.options.rig = synth::parse_rig_kind(a.rig);
    if (a.options.rig == synth::RigKind::Thesis && a.light_angles_given)
        throw UsageError("--light-angles places the spread rig's lights; the thesis rig's are all 15 degrees off the camera");
    if (a.bounce_samples_given && a.options.bounces == 0)
        log::warn("--bounce-samples has no effect without --bounces N (N >= 1)");
    if (!a.mesh.empty()) a.options.inputs.emplace_back(a.mesh);
    if (!a.albedo.empty()) a.options.inputs.emplace_back(a.albedo);
    const synth::SynthObject object = make_object(a);
    const synth::SynthResult r = synth::write_synthetic_capture(object, a.out, a.options);
    std::printf("wrote %s\n", r.dir.c_str());
    std::printf("  object %s (%s material): %zu triangles; %zu views, %zu train + %zu test frames at %dx%d (%s, %s rig)\n",
                object.name.c_str(), to_string(object.material.family()), r.triangles, r.views, r.train_frames, r.test_frames,
                a.options.size, a.options.size, a.format.c_str(), a.rig.c_str());
    if (a.options.format != synth::ImageFormat::Exr)
        std::printf("  clipped object pixels (a channel at saturation 1.0): %zu of %zu (%.2f %%)\n", r.clipped_pixels, r.object_pixels,
                    r.object_pixels ? 100.0 * static_cast<double>(r.clipped_pixels) / static_cast<double>(r.object_pixels) : 0.0);
    std::printf("  shadowed object pixels (facing the light, occluded): %zu\n", r.shadowed_pixels);
    if (a.options.bounces > 0)
        std::printf("  interreflections: %d bounce%s, %d paths per pixel (seed %llu)\n", a.options.bounces,
                    a.options.bounces == 1 ? "" : "s", a.options.bounce_samples, static_cast<unsigned long long>(a.options.seed));
    std::printf("  time %.2f s:", r.seconds);
    for (const StageTime& t : r.times) std::printf(" %s %.2f s;", t.name.c_str(), t.seconds);
    std::printf("\n");
}

} // namespace

void add_synth_command(CLI::App& app) {
    auto args = std::make_shared<SynthArgs>();
    CLI::App* sub = app.add_subcommand("synth", "Render a synthetic capture of a known object (ground truth for tests and evaluation)");
    sub->add_option("--preset", args->preset, "Built-in object (see --list-presets)");
    sub->add_option("--out", args->out, "Output folder (written atomically; must not exist or be empty unless --force)");
    sub->add_flag("--list-presets", args->list_presets, "List the built-in objects and exit");
    sub->add_option("--export-preset", args->export_preset, "Write only NAME's mesh.glb and albedo texture into --out");
    sub->add_option("--size", args->options.size, "Image width and height in pixels")->capture_default_str();
    sub->add_option("--views", args->options.views, "Train views around the object")->capture_default_str();
    sub->add_option("--rig", args->rig,
                    "Lights of each view: spread (train lights at --light-angles off the camera, test lights off the "
                    "image-plane rings) or thesis (the thesis's six lights around the camera: every light, train and "
                    "test, on one ring 15 degrees around the camera direction seen from the object, at the camera's "
                    "distance)")
        ->capture_default_str();
    sub->add_option("--lights", args->options.lights,
                    "Lights per train view, equally spaced in azimuth around the camera direction; with --rig thesis, "
                    "the lights on each view's 15-degree ring (6: the thesis's)")
        ->capture_default_str();
    sub->add_option("--light-angles", args->options.light_angles_deg,
                    "--rig spread: train lights' angles off the camera direction seen from the object, degrees (cycled "
                    "over the lights; wide angles see grazing highlights)")
        ->delimiter(',')
        ->capture_default_str()
        ->each([args](const std::string&) { args->light_angles_given = true; });
    sub->add_option("--test-views", args->options.test_views, "Test views between train views")->capture_default_str();
    sub->add_option("--test-lights", args->options.test_lights,
                    "Lights per test view, off the rig's rings (--rig thesis: on the 15-degree ring, between the train lights)")->capture_default_str();
    sub->add_option("--held-out-lights", args->options.held_out_lights,
                    "Per train view, this many more lights (between the train lights in azimuth and in angle off the "
                    "camera) whose frames are test frames of that view: the held-out test a single-view or few-view "
                    "photometric rig has")
        ->capture_default_str();
    sub->add_flag("--directional", args->options.directional,
                  "Directional (distant) lights, capture format 1.1: each toward where the rig's point light would be, "
                  "seen from the object's centre, with the irradiance it would give there (a photometric-stereo dome)");
    sub->add_option("--noise", args->options.noise_sigma, "Gaussian noise sigma, relative to full scale 1.0")->capture_default_str();
    sub->add_option("--shot-noise", args->options.shot_noise, "Shot noise: variance = K * value")->capture_default_str();
    sub->add_option("--exposure", args->options.exposure, "Light intensity factor (1: facing diffuse albedo 0.8 at 0.6)")->capture_default_str();
    sub->add_option("--format", args->format, "Image files: png8, png16 (sRGB) or exr (linear float)")->capture_default_str();
    sub->add_option("--bounces", args->options.bounces,
                    "Interreflections: 0 renders direct light only; N (1 to 4) adds the light the object reflects onto "
                    "itself up to N times (path tracing from each pixel's surface point: cosine-weighted directions, "
                    "the direct light at every point they reach, black where they leave the object). Concave shapes "
                    "(knot, cologne) brighten in their hollows; the mask and the shadow counts stay direct-light ones")
        ->capture_default_str();
    sub->add_option("--bounce-samples", args->options.bounce_samples,
                    "Paths per pixel for --bounces (1 to 65536); time grows with S x N (knot, 512 px, 2 bounces, "
                    "the default: 12 s of processor time a frame). Monte Carlo noise falls as about S^-0.6: with "
                    "the default it is below one 8-bit step over the knot (0.6) but not in its hollows (1.4), and 3 to 5 "
                    "steps in the glossy vase's and woodenpot's hollows (docs/pipeline.md section 12)")
        ->capture_default_str()
        ->each([args](const std::string&) { args->bounce_samples_given = true; });
    sub->add_option("--seed", args->options.seed, "Noise seed (also seeds the --bounces samples)")->capture_default_str();
    sub->add_option("--threads", args->options.threads, "Render threads")->capture_default_str();
    sub->add_option("--material", args->material,
                    "Material family: lafortune (Lambert + the preset's Lafortune lobe) or coated (a Lambertian base "
                    "under a clear dielectric coating with GGX reflection: the preset's eta and alpha, tint 1; "
                    "eta 1.5, alpha 0.1 for --mesh); the albedo is the same")
        ->capture_default_str();
    sub->add_flag("--lambertian", args->options.lambertian, "No specular lobe (diffuse only; lafortune family only)");
    sub->add_flag("--force", args->options.force, "Replace a non-empty --out (only once the new capture is complete)");
    sub->add_option("--mesh", args->mesh, "Your own object: a glTF mesh (.glb/.gltf)");
    sub->add_option("--albedo", args->albedo, "Albedo texture for --mesh (needs TEXCOORD_0); sRGB-encoded if 8/16-bit");
    sub->add_option("--albedo-value", args->albedo_value, "Constant albedo r,g,b in [0, 1]")->expected(3)->delimiter(',')->excludes("--albedo");
    auto* lobe = sub->add_option("--lobe", args->lobe, "Lafortune lobe cx,cz,n for all channels")->expected(3)->delimiter(',');
    auto* lobe_rgb = sub->add_option("--lobe-rgb", args->lobe_rgb, "Per-channel lobe: cx_r,cx_g,cx_b,cz_r,cz_g,cz_b,n_r,n_g,n_b")
                         ->expected(9)
                         ->delimiter(',');
    lobe->excludes(lobe_rgb);
    sub->callback([args] { run(*args); });
}

} // namespace specula::cli
