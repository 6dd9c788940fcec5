// specula reconstruct CAPTURE -o OUT: maps options onto a ReconstructConfig and runs the pipeline.
#include "commands.h"

#include "core/error.h"
#include "core/log.h"
#include "pipeline/reconstruct.h"

#include <map>
#include <memory>
#include <string>

namespace specula::cli {

namespace {

struct ReconstructArgs {
    ReconstructConfig config;
    std::string backend = "vulkan";
    std::string mode = "albedo";
    std::string views = "best";
    std::uint32_t texture_size = 4096;
    std::string specular = "auto";
};

void run_reconstruct(ReconstructArgs& args) {
    ReconstructConfig& c = args.config;
    c.backend = args.backend == "cpu" ? LambertBackend::Cpu : LambertBackend::Vulkan;
    c.lambert.mode = args.mode == "photometric" ? LambertMode::Photometric : LambertMode::Albedo;
    c.lambert.choice = args.views == "robust" ? ViewChoice::Robust : ViewChoice::BestView;
    c.specular = args.specular == "on" ? SpecularMode::On : args.specular == "off" ? SpecularMode::Off : SpecularMode::Auto;
    c.atlas.max_width = args.texture_size;
    c.atlas.max_height = args.texture_size;
    const ReconstructResult result = reconstruct(c);
    log::info("wrote " + c.out_dir.string() + ": object.glb, albedo.exr, albedo.png, report.json" +
              (c.evaluate ? ", evaluation.json, sheets/" : "") + " in " + std::to_string(result.total_seconds) + " s");
    for (const LeftOut& l : result.left_out) log::info("left out: " + l.what + " (" + l.why + ")");
}

} // namespace

void add_reconstruct_command(CLI::App& app) {
    auto args = std::make_shared<ReconstructArgs>();
    CLI::App* cmd = app.add_subcommand(
        "reconstruct",
        "Reconstruct a capture: the albedo texture and the specular lobe. Writes OUT/object.glb (the bundle),\n"
        "OUT/albedo.exr (linear), OUT/albedo.png (sRGB), OUT/evaluation.json and OUT/sheets/ (every frame\n"
        "re-rendered and compared), and OUT/report.json (stage times, counts, choices, quality figures, and\n"
        "what was left out for this scene and why).");
    cmd->add_option("capture", args->config.capture, "Capture folder, or its capture.json")->required();
    cmd->add_option("-o,--out", args->config.out_dir, "Output folder (created if missing)")->required();
    cmd->add_option("--backend", args->backend, "Where the diffuse solve runs: vulkan (compute shaders) or cpu (the reference)")
        ->check(CLI::IsMember({"vulkan", "cpu"}))
        ->capture_default_str();
    cmd->add_option("-d,--device", args->config.device, "Vulkan device: index or name substring (see `specula devices`)");
    cmd->add_option("--mode", args->mode,
                    "albedo: known mesh normals, one unknown per channel; photometric: the thesis's eq. 3.1, also refines\n"
                    "normals, falls back to albedo per particle when its light directions are nearly coplanar")
        ->check(CLI::IsMember({"albedo", "photometric"}))
        ->capture_default_str();
    cmd->add_option("--views", args->views,
                    "best: the thesis's choice, the seeing view closest to the normal; robust: combine all views")
        ->check(CLI::IsMember({"best", "robust"}))
        ->capture_default_str();
    cmd->add_option("--texture-size", args->texture_size, "Largest albedo texture side (texels)")
        ->check(CLI::Range(16u, 32767u))
        ->capture_default_str();
    cmd->add_option("--texels-per-pixel", args->config.atlas.texels_per_pixel,
                    "Atlas texels per image pixel of a triangle's best view (more adds cost, no information)")
        ->check(CLI::Range(0.05, 8.0))
        ->capture_default_str();
    cmd->add_option("--noise", args->config.lambert.noise_sigma,
                    "Image noise sigma (full scale 1) used in the highlight-rejection margin")
        ->check(CLI::Range(0.0, 1.0))
        ->capture_default_str();
    cmd->add_option("--specular", args->specular,
                    "auto: fit the Lafortune lobe only when the residuals hold more energy than the noise (--noise);\n"
                    "on: always fit (the report gives its cost); off: no residual samples, no fit")
        ->check(CLI::IsMember({"auto", "on", "off"}))
        ->capture_default_str();
    cmd->add_option("--joint-rounds", args->config.joint_rounds,
                    "After a fit: rounds of (diffuse solve minus the lobe's light, residuals, refit) until the "
                    "lobe settles; 0 = the thesis's single pass")
        ->check(CLI::Range(0u, 10u))
        ->capture_default_str();
    cmd->add_flag("--force-occlusion-rays", args->config.force_occlusion_rays,
                  "Cast occlusion rays even when the mesh is convex (the default skips them there)");
    cmd->add_option("--threads", args->config.threads, "CPU threads")->check(CLI::Range(1u, 256u))->capture_default_str();
    cmd->add_flag("--no-evaluate{false}", args->config.evaluate,
                  "Skip the self-evaluation (re-rendering every frame from object.glb and comparing)");
    cmd->add_option("--eval-frames", args->config.evaluate_max_frames,
                    "Evaluate at most this many frames per split, evenly spaced (0: all)")
        ->capture_default_str();
    cmd->callback([args] { run_reconstruct(*args); });
}

} // namespace specula::cli
