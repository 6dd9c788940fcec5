// specula render BUNDLE (--capture DIR --frame I | --camera ... --light ...) -o IMAGE:
// maps options onto a camera and a light (engine/evaluate/pose.h, shared with specula-view)
// and render settings, and renders the bundle (engine/evaluate/bundle_render.h).
#include "commands.h"

#include "core/format.h"
#include "core/log.h"
#include "core/timer.h"
#include "evaluate/bundle_render.h"
#include "evaluate/indirect_light.h"
#include "evaluate/pose.h"
#include "export/bundle.h"
#include "gpu/context.h"

#include <cstdint>
#include <memory>
#include <span>
#include <string>

namespace specula::cli {

namespace {

struct RenderArgs {
    std::string bundle;
    evaluate::PoseOptions pose; // --capture/--frame, or --camera/--light/--size/--fov/--fl
    std::string out;
    std::string mode = "both";
    std::string specular = "analytic";
    bool no_shadows = false;
    std::string device;
    IndirectArgs indirect;
    int threads = 2;
};

render::Mode parse_mode(const std::string& m) {
    return m == "diffuse" ? render::Mode::Diffuse : m == "specular" ? render::Mode::Specular : render::Mode::Both;
}

void run_render(const RenderArgs& a) {
    const render::Settings settings{.mode = parse_mode(a.mode),
                                    .specular = a.specular == "factorized" ? render::SpecularPath::Factorized
                                                                           : render::SpecularPath::Analytic,
                                    .shadows = !a.no_shadows};
    const evaluate::Pose pose = evaluate::resolve_pose(a.pose); // before the bundle: usage errors first
    const Bundle bundle = read_bundle(a.bundle);
    evaluate::require_specular_model(bundle, settings.specular, a.bundle);
    gpu::Context ctx(gpu::ContextOptions{.device = a.device});
    evaluate::BundleRenderer renderer(ctx, bundle, a.bundle);
    if (a.specular == "core") renderer.draw_core_material(bundle.core); // what ordinary viewers show
    render::Frame frame = renderer.render(pose.camera, pose.light, settings);
    // The light that bounced off the object (evaluate/indirect_light.h), for this one view and light.
    std::string indirect_note = ", direct light only";
    if (a.specular != "core" && a.indirect.wanted(bundle)) {
        const Stopwatch clock;
        const evaluate::BundleIndirectOptions io = a.indirect.options(bundle, static_cast<unsigned>(a.threads));
        const VisibilityView view{.camera = pose.camera, .flags = {}};
        const std::uint32_t frame_view = 0;
        evaluate::BundleIndirectLight light(bundle, std::span(&view, 1), std::span(&pose.light, 1), std::span(&frame_view, 1), io);
        light.add(0, frame.color);
        indirect_note = format_text(", indirect light added (%.0f bounces, %.1f s)", double(io.bounces), clock.seconds());
    }
    evaluate::write_rendered_image(a.out, frame.color);
    std::string note = frame.info.specular_note.empty() ? "" : " (" + frame.info.specular_note + ")";
    note += frame.info.shadow_pass ? ", shadows" : ", no shadows (" + frame.info.shadow_note + ")";
    if (settings.shadows && !frame.info.shadow_pass) log::warn("rendered without shadows: " + frame.info.shadow_note);
    log::info("wrote " + a.out + ": " + pose.what + ", " + std::to_string(frame.color.width) + "x" +
              std::to_string(frame.color.height) + ", " + render::mode_name(settings.mode) + "/" +
              (a.specular == "core" ? std::string("core") : std::string(render::specular_path_name(settings.specular))) + note + indirect_note + ", " + std::to_string(frame.info.wall_ms) + " ms");
}

} // namespace

void add_render_command(CLI::App& app) {
    auto a = std::make_shared<RenderArgs>();
    CLI::App* cmd = app.add_subcommand(
        "render",
        "Render a bundle (.glb) with the raster renderer: a capture frame's camera and light exactly (--capture, --frame),\n"
        "or a free pose (--camera, --light). Writes IMAGE by extension: .exr linear float, .png sRGB 8-bit.");
    cmd->add_option("bundle", a->bundle, "Bundle written by reconstruct (.glb)")->required();
    cmd->add_option("-o,--out", a->out, "Output image (.exr or .png)")->required();
    cmd->add_option("--capture", a->pose.capture, "Capture folder (or its capture.json) whose frame to re-render");
    cmd->add_option("--frame", a->pose.frame, "Frame index in capture.json's frames list");
    cmd->add_option("--camera", a->pose.camera, "Free camera: eye,target,up (9 numbers, world units)");
    cmd->add_option("--light", a->pose.light, "Free point light: x,y,z,intensity or x,y,z,r,g,b");
    cmd->add_option("--size", a->pose.size, "Free camera image size: N or WxH")->capture_default_str();
    cmd->add_option("--fov", a->pose.fov, "Free camera vertical field of view, degrees (default 40)");
    cmd->add_option("--fl", a->pose.fl, "Free camera focal length in pixels (instead of --fov)")->excludes("--fov");
    cmd->add_option("--mode", a->mode, "Terms drawn: both, diffuse or specular")
        ->check(CLI::IsMember({"both", "diffuse", "specular"}))
        ->capture_default_str();
    cmd->add_option("--specular", a->specular,
                    "Specular model: analytic (the lobe), factorized (the bundle's G/H cube-maps), or core (the bundle's glTF\n"
                    "core material with glTF's BRDF as three.js draws it, direct light only: what ordinary viewers show)")
        ->check(CLI::IsMember({"analytic", "factorized", "core"}))
        ->capture_default_str();
    cmd->add_flag("--no-shadows", a->no_shadows,
                  "Render without cast shadows: the thesis's unshadowed render (default: shadow-mapped)");
    add_indirect_options(cmd, a->indirect, "Seconds on 2 cores; the real-time viewer draws\n"
                                 "direct light only");
    cmd->add_option("--threads", a->threads, "Threads for the indirect light")->check(CLI::Range(1, 256))->capture_default_str();
    cmd->add_option("-d,--device", a->device, "Vulkan device: index or name substring (see `specula devices`)");
    cmd->callback([a] { run_render(*a); });
}

} // namespace specula::cli
