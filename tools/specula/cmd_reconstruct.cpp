// specula reconstruct CAPTURE -o OUT: maps options onto a ReconstructConfig and runs the pipeline.
#include "commands.h"

#include "core/error.h"
#include "core/log.h"
#include "pipeline/reconstruct.h"
#include "shared/coated.h"

#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace specula::cli {

namespace {

struct ReconstructArgs {
    ReconstructConfig config;
    std::string backend = "auto";
    std::string mode = "auto";
    std::string occlusion_rays = "auto";
    std::string tap_irradiance = "on";
    std::string normal_map = "auto";
    std::string indirect = "auto";
    std::string indirect_lobe = "directed";
    bool force_occlusion_rays = false;
    std::vector<std::uint32_t> grid;
    std::string views = "best";
    std::uint32_t texture_size = 4096;
    std::string atlas = "charts";
    std::string specular = "auto";
    std::string material = "auto";
    bool coated_tint = false;
    std::optional<double> coated_eta;
    std::string factor_param = "auto";
    std::string factor_warp = "auto";
    std::string indirect_block = "auto";
    std::string refine_method = "pixels";
};

void run_reconstruct(ReconstructArgs& args) {
    ReconstructConfig& c = args.config;
    c.backend = args.backend == "cpu" ? Backend::Cpu : Backend::Vulkan;
    c.backend_auto = args.backend == "auto";
    c.diffuse_mode = args.mode == "photometric" ? DiffuseModeChoice::Photometric
                     : args.mode == "albedo"    ? DiffuseModeChoice::Albedo
                                                : DiffuseModeChoice::Auto;
    c.occlusion_rays = args.occlusion_rays == "on" || args.force_occlusion_rays ? Toggle::On
                       : args.occlusion_rays == "off"                          ? Toggle::Off
                                                                               : Toggle::Auto;
    c.lambert.tap_irradiance = args.tap_irradiance == "on";
    c.normal_map = args.normal_map == "on" ? Toggle::On : args.normal_map == "off" ? Toggle::Off : Toggle::Auto;
    c.indirect = args.indirect == "on" ? Toggle::On : args.indirect == "off" ? Toggle::Off : Toggle::Auto;
    c.indirect_lobe_directions = args.indirect_lobe == "directed";
    c.refine_method = args.refine_method == "back-projection" ? RefineMethod::BackProjection : RefineMethod::Pixels;
    if (args.force_occlusion_rays && args.occlusion_rays == "off")
        throw UsageError("--force-occlusion-rays contradicts --occlusion-rays off");
    if (!args.grid.empty()) {
        for (std::uint32_t g : args.grid)
            if (g < 4 || g > 256) throw UsageError("--factorization-grid: each resolution must be in [4, 256], got " + std::to_string(g));
        if (args.grid[0] * (args.grid.size() > 1 ? args.grid[1] : args.grid[0]) > factorization::kMaxGridProduct)
            throw UsageError("--factorization-grid: H x D must be at most " + std::to_string(factorization::kMaxGridProduct) +
                             " (the matrix F, 3 H^2 D^2 floats, must fit one 128 MiB storage binding)");
        c.factorization_grid_h = args.grid[0];
        c.factorization_grid_d = args.grid.size() > 1 ? args.grid[1] : args.grid[0];
    }
    c.factor_param = factor_param_from_string(args.factor_param); // "auto": nullopt
    if (args.factor_warp != "auto") c.shared_warp = args.factor_warp == "shared";
    c.indirect_block = args.indirect_block == "auto" ? 0u : static_cast<std::uint32_t>(std::stoul(args.indirect_block));
    c.lambert.choice = args.views == "robust" ? ViewChoice::Robust : ViewChoice::BestView;
    c.specular = args.specular == "on" ? SpecularMode::On : args.specular == "off" ? SpecularMode::Off : SpecularMode::Auto;
    c.material = material_family_from_string(args.material); // "auto": nullopt (CLI11 checked the name)
    c.coated.fit_tint = args.coated_tint;
    c.coated.fixed_eta = args.coated_eta;
    c.atlas.max_width = args.texture_size;
    c.atlas.max_height = args.texture_size;
    c.atlas.mode = atlas_mode_from_string(args.atlas).value_or(AtlasMode::Charts); // CLI11 checked the name
    const ReconstructResult result = reconstruct(c);
    log::info("wrote " + c.out_dir.string() + ": object.glb, albedo.exr, albedo.png, report.json" +
              (c.write_html ? ", report.html" : "") +
              (c.evaluate ? ", evaluation.json, sheets/" : "") + " in " + std::to_string(result.total_seconds) + " s");
    for (const LeftOut& l : result.left_out) log::info("left out: " + l.what + " (" + l.why + ")");
    for (const PlanDecision& d : result.plan.decisions) {
        std::string cost;
        if (d.avoided_seconds) cost = ", avoided ~" + std::to_string(*d.avoided_seconds) + " s";
        else if (d.measured_seconds) cost = ", cost " + std::to_string(*d.measured_seconds) + " s";
        log::info("planner: " + d.name + " = " + d.value + " (" + (d.forced ? "forced" : "auto") + cost + ")");
    }
}

} // namespace

void add_reconstruct_command(CLI::App& app) {
    auto args = std::make_shared<ReconstructArgs>();
    CLI::App* cmd = app.add_subcommand(
        "reconstruct",
        "Reconstruct a capture: the albedo texture and the specular lobe. Writes OUT/object.glb (the bundle),\n"
        "OUT/albedo.exr (linear; the bundle's float albedo, which Specula's tools read beside object.glb),\n"
        "OUT/albedo.png (sRGB), OUT/evaluation.json and OUT/sheets/ (every frame\n"
        "re-rendered and compared), OUT/report.html (one self-contained page) and OUT/report.json (the planner's\n"
        "decisions, stage times, GPU dispatch times, counts, quality figures, the lobe, and what was left out\n"
        "for this scene and why). Every planner decision can be forced: --occlusion-rays, --mode, --specular,\n"
        "--atlas, --texels-per-pixel/--texture-size, --factorization-grid, --factor-param, --normal-map; the report then gives\n"
        "the cost of the forced work.");
    cmd->add_option("capture", args->config.capture, "Capture folder, or its capture.json")->required();
    cmd->add_option("-o,--out", args->config.out_dir,
                    "Output folder, written as a whole: the run writes into .OUT.tmp-* beside it and renames that into\n"
                    "place once complete, so OUT holds the previous result or the new one, never a part. Refused: OUT\n"
                    "holding the capture, or being written by another run")
        ->required();
    cmd->add_flag("--force", args->config.force,
                  "Replace a non-empty OUT that holds no earlier result of reconstruct (only once the new one is complete)");
    cmd->add_option("--backend", args->backend,
                    "Where the per-particle passes (diffuse solves, residual samples) run: vulkan (compute shaders), cpu\n"
                    "(the C++ reference) or auto: vulkan on a GPU, cpu on a CPU Vulkan driver such as lavapipe, where the\n"
                    "kernels run slower (the same answer). The evaluation renders with Vulkan either way")
        ->check(CLI::IsMember({"auto", "vulkan", "cpu"}))
        ->capture_default_str();
    cmd->add_option("-d,--device", args->config.device, "Vulkan device: index or name substring (see `specula devices`)");
    cmd->add_option("--mode", args->mode,
                    "Diffuse solve. auto: albedo while a lobe may be fitted (the photometric solve would absorb part of\n"
                    "each highlight into a tilted normal); with --specular off, photometric when at least half the train\n"
                    "views have >= 3 non-coplanar light directions; albedo: known mesh normals, one unknown per channel;\n"
                    "photometric: the thesis's eq. 3.1, also refines normals, falls back to albedo per particle when its\n"
                    "light directions are nearly coplanar")
        ->check(CLI::IsMember({"auto", "albedo", "photometric"}))
        ->capture_default_str();
    cmd->add_option("--views", args->views,
                    "best: the thesis's choice, the seeing view closest to the normal; robust: combine all views")
        ->check(CLI::IsMember({"best", "robust"}))
        ->capture_default_str();
    cmd->add_option("--atlas", args->atlas,
                    "Texture atlas. charts: connected charts flattened by least-squares conformal maps, seams only\n"
                    "where needed, vertices shared within a chart (what other tools can edit and filter); patchwork:\n"
                    "the thesis's reference, every triangle its own patch")
        ->check(CLI::IsMember({"charts", "patchwork"}))
        ->capture_default_str();
    cmd->add_option("--texture-size", args->texture_size, "Largest albedo texture side (texels)")
        ->check(CLI::Range(16u, 32767u))
        ->capture_default_str();
    cmd->add_option("--texels-per-pixel", args->config.atlas.texels_per_pixel,
                    "Atlas texels per image pixel of a triangle's best view; the planner uses 1 (more sharpens albedo\n"
                    "edges a little for other views at several times the particle stages' cost; less trades detail for time)")
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
    cmd->add_option("--material", args->material,
                    "the specular model family: lafortune (the thesis: Lambert + one Lafortune lobe per channel),\n"
                    "coated (a Lambertian base under a dielectric coating of index eta: its diffuse falls with the\n"
                    "Fresnel transmission at the light and the viewer, plus a GGX reflection of roughness alpha), or\n"
                    "auto: estimate both on the train frames less one light of each view and keep the one with the\n"
                    "least error on those held-out frames (the report gives both, with their times)")
        ->check(CLI::IsMember({"auto", "lafortune", "coated"}))
        ->capture_default_str();
    cmd->add_flag("--coated-tint", args->coated_tint,
                  "coated: fit a specular tint per channel (default: 1, a clear dielectric coating)");
    cmd->add_option("--coated-eta", args->coated_eta,
                    "coated: hold the coating's index of refraction at this value and fit alpha alone (when it is\n"
                    "known: about 1.5 for most plastics, varnishes and glazes); default: fitted, and held at 1.5 only\n"
                    "where the fit runs to the top of its range (the report says so)")
        ->check(CLI::Range(double(shared::kCoatedMinEta), double(shared::kCoatedMaxEta)));
    cmd->add_option("--joint-rounds", args->config.joint_rounds,
                    "After a fit: rounds of (diffuse solve minus the lobe's light, residuals, refit) until the "
                    "lobe settles; 0 = the thesis's single pass")
        ->check(CLI::Range(0u, 10u))
        ->capture_default_str();
    cmd->add_option("--refine-method", args->refine_method,
                    "Albedo refinement, which sharpens albedo edges for held-out views. pixels: the albedo whose\n"
                    "bilinear atlas read best reproduces every train pixel (least squares through the atlas point each\n"
                    "pixel's centre ray hits; no renders, no Vulkan device); back-projection: rounds of (render the train\n"
                    "frames from the albedo, solve them, add the difference to the captured frames' solve)")
        ->check(CLI::IsMember({"pixels", "back-projection"}))
        ->capture_default_str();
    cmd->add_option("--refine-rounds", args->config.refine_rounds,
                    "Albedo refinement: iterations of the pixel fit (default: the planner's 8; each a pass over the\n"
                    "train pixels) or rounds of back-projection (default 2; each one render of every train frame and one\n"
                    "diffuse solve); 0 = the solve's bilinear reading of the best view")
        ->check(CLI::Range(0u, 32u));
    cmd->add_option("--normal-map", args->normal_map,
                    "Refined normals as a tangent-space normal map in the bundle (glTF normalTexture, with TANGENT):\n"
                    "a photometric solve with the final material subtracted. auto: on when a train view has >= 12 lights\n"
                    "in well-spread directions (a photometric dome or light stage); off: the mesh normals only")
        ->check(CLI::IsMember({"auto", "on", "off"}))
        ->capture_default_str();
    cmd->add_option("--indirect", args->indirect,
                    "Light that bounced off the object itself (inverse global illumination, Yu et al. 1999): removed\n"
                    "from the train frames before the solves (the albedo of concave parts is otherwise too bright) and\n"
                    "added to the evaluation's renders. auto: on when the mesh can see itself (not convex), that light\n"
                    "changes the captures by >= 0.5 8-bit codes at the 99th percentile, and the pixels no light reaches\n"
                    "directly show at least a quarter of it (a capture rendered with direct light only shows none). The bundle\n"
                    "says so: `render` and `evaluate` add it back from the bundle (their --indirect); the viewer shows direct\n"
                    "light only")
        ->check(CLI::IsMember({"auto", "on", "off"}))
        ->capture_default_str();
    cmd->add_option("--indirect-bounces", args->config.indirect_bounces, "Bounces of the indirect light")
        ->check(CLI::Range(1u, 4u))
        ->capture_default_str();
    cmd->add_option("--indirect-rays", args->config.indirect_rays,
                    "Rays per row of the transfer (stratified cosine-weighted hemisphere; rounded up to a square):\n"
                    "more rays, less noise in the indirect light (most in a glossy lobe's directed light) and more time")
        ->check(CLI::Range(1u, 1024u))
        ->capture_default_str();
    cmd->add_option("--indirect-lobe", args->indirect_lobe,
                    "The fitted lobe's first bounce: directed (each transfer ray's source sends f_s toward it: a glossy\n"
                    "wall lights the wall its highlight faces) or spread (the lobe's directional albedo, spread diffusely:\n"
                    "less noise from few rays, the wrong place for a glossy lobe's light)")
        ->check(CLI::IsMember({"directed", "spread"}))
        ->capture_default_str();
    cmd->add_option("--indirect-block", args->indirect_block,
                    "The transfer's rows: blocks of N x N texels of one chart that receive and send the indirect light\n"
                    "as one (it varies slowly over the surface); 1: every particle its own row (N^2 times the rows, the\n"
                    "rays and the gathers' time); auto: about 100k rows, at least 2 (2 at 256 px, 3 at 512 px)")
        ->check(CLI::IsMember({"auto", "1", "2", "3", "4", "5", "6", "7", "8"}))
        ->capture_default_str();
    cmd->add_option("--indirect-rounds", args->config.indirect_rounds,
                    "At most this many rounds of (indirect light from the albedo, solve on the captures less it);\n"
                    "they stop sooner when the albedo changes by less than 0.5%")
        ->check(CLI::Range(1u, 10u))
        ->capture_default_str();
    cmd->add_option("--occlusion-rays", args->occlusion_rays,
                    "auto: Embree occlusion rays only where the mesh can occlude itself (not convex); on: always (the\n"
                    "report gives their measured cost); off: never (biased where the mesh shadows or hides itself)")
        ->check(CLI::IsMember({"auto", "on", "off"}))
        ->capture_default_str();
    cmd->add_option("--tap-irradiance", args->tap_irradiance,
                    "on: scale each of a sample's 4 bilinear pixels to the particle's irradiance, from what the ray\n"
                    "through each pixel hits (one depth ray per pixel of every view); off: mix them as they are (the\n"
                    "thesis's sampling: biased where the normal turns within a pixel, e.g. rims, lips, creases)")
        ->check(CLI::IsMember({"on", "off"}))
        ->capture_default_str();
    cmd->add_flag("--force-occlusion-rays", args->force_occlusion_rays, "The same as --occlusion-rays on");
    cmd->add_flag("--light-rays-from-shadow-maps", args->config.light_rays_from_shadow_maps,
                  "Let each frame's pixel shadow map answer for the particles' light rays (a frame lights a particle\n"
                  "its view sees when none of the sample's 4 pixels is dark): about 40% off the visibility stage, the\n"
                  "same bits bar a few pairs in a million; off by default, since those few move some lobes by a few\n"
                  "tenths of a percent (docs/pipeline.md section 2)");
    cmd->add_option("--factorization-grid", args->grid,
                    "H[,D]: the factorization's h and d grid resolutions (default: the planner's, from the lobe's width:\n"
                    "2 cells per lobe half-width, h in [16, 128], d in [16, 64]); H x D at most 3072")
        ->delimiter(',')
        ->expected(1, 2);
    cmd->add_option("--factor-param", args->factor_param,
                    "Parametrization of the factorization's cube-maps: gshd (the thesis's half/difference vectors of the\n"
                    "light and view), mirrored (those of the light's mirror direction and the view: near separable for a\n"
                    "lobe about the mirror direction, Cx < 0), warped (those of a direction scaled by the lobe's Cx and Cz,\n"
                    "the cube-maps holding the lobe over its closed-form radial factor |C u|^N: separable for any Lafortune\n"
                    "lobe), or auto (each that fits the lobe, the one of least error against the lobe)")
        ->check(CLI::IsMember({"auto", "gshd", "mirrored", "warped"}))
        ->capture_default_str();
    cmd->add_option("--factor-warp", args->factor_warp,
                    "The warped parametrization's warp: per-channel (each channel's own: exact, 6 cube-map lookups a pixel\n"
                    "and term), shared (one for the three channels: 2 lookups, at some error where the channels' lobes\n"
                    "differ), or auto (shared where its error against the lobe stays within 3%, the terms' own target)")
        ->check(CLI::IsMember({"auto", "per-channel", "shared"}))
        ->capture_default_str();
    cmd->add_flag("--no-html{false}", args->config.write_html, "Do not write report.html");
    cmd->add_flag("--embed-float-albedo", args->config.embed_float_albedo,
                  "Put the linear float albedo inside object.glb (12 bytes a texel) instead of naming OUT/albedo.exr\n"
                  "beside it; without albedo.exr beside it, Specula's tools fall back to the 8-bit base colour");
    cmd->add_option("--threads", args->config.threads, "CPU threads")->check(CLI::Range(1u, 256u))->capture_default_str();
    cmd->add_flag("--no-evaluate{false}", args->config.evaluate,
                  "Skip the self-evaluation (re-rendering every frame from object.glb and comparing)");
    cmd->add_option("--eval-frames", args->config.evaluate_max_frames,
                    "Evaluate at most this many frames per split, evenly spaced (0: all)")
        ->capture_default_str();
    cmd->add_option("--eval-train-frames", args->config.evaluate_train_frames,
                    "Evaluate at most this many train frames, evenly spaced (0: all); every test frame is evaluated. The\n"
                    "report says how many; `specula evaluate` scores every frame")
        ->capture_default_str();
    cmd->callback([args] { run_reconstruct(*args); });
}

} // namespace specula::cli
