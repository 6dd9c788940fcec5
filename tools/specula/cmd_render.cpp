// specula render BUNDLE (--capture DIR --frame I | --camera ... --light ...) -o IMAGE:
// maps options onto a camera and a light (engine/evaluate/pose.h, shared with specula-view)
// and render settings, and renders the bundle (engine/evaluate/bundle_render.h).
#include "commands.h"

#include "core/log.h"
#include "evaluate/bundle_render.h"
#include "evaluate/pose.h"
#include "export/bundle.h"
#include "gpu/context.h"

#include <memory>
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
    const render::Frame frame = renderer.render(pose.camera, pose.light, settings);
    evaluate::write_rendered_image(a.out, frame.color);
    std::string note = frame.info.specular_note.empty() ? "" : " (" + frame.info.specular_note + ")";
    note += frame.info.shadow_pass ? ", shadows" : ", no shadows (" + frame.info.shadow_note + ")";
    if (settings.shadows && !frame.info.shadow_pass) log::warn("rendered without shadows: " + frame.info.shadow_note);
    log::info("wrote " + a.out + ": " + pose.what + ", " + std::to_string(frame.color.width) + "x" +
              std::to_string(frame.color.height) + ", " + render::mode_name(settings.mode) + "/" +
              render::specular_path_name(settings.specular) + note + ", " + std::to_string(frame.info.wall_ms) + " ms");
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
    cmd->add_option("--specular", a->specular, "Specular model: analytic (the lobe) or factorized (the bundle's G/H cube-maps)")
        ->check(CLI::IsMember({"analytic", "factorized"}))
        ->capture_default_str();
    cmd->add_flag("--no-shadows", a->no_shadows,
                  "Render without cast shadows: the thesis's unshadowed render (default: shadow-mapped)");
    cmd->add_option("-d,--device", a->device, "Vulkan device: index or name substring (see `specula devices`)");
    cmd->callback([a] { run_render(*a); });
}

} // namespace specula::cli
