// specula render BUNDLE (--capture DIR --frame I | --camera ... --light ...) -o IMAGE:
// maps options onto a camera, a light and render settings, and renders the bundle
// (engine/evaluate/bundle_render.h).
#include "commands.h"

#include "capture/capture.h"
#include "core/error.h"
#include "core/log.h"
#include "evaluate/bundle_render.h"
#include "export/bundle.h"
#include "gpu/context.h"

#include <cmath>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

namespace specula::cli {

namespace {

struct RenderArgs {
    std::string bundle;
    std::string capture;
    std::optional<long long> frame;
    std::string out;
    std::string mode = "both";
    std::string specular = "analytic";
    bool no_shadows = false;
    std::string camera; // eye,target,up
    std::string light;  // x,y,z,intensity or x,y,z,r,g,b
    std::string size = "512";
    std::optional<double> fov;
    std::optional<double> fl;
    std::string device;
};

render::Mode parse_mode(const std::string& m) {
    return m == "diffuse" ? render::Mode::Diffuse : m == "specular" ? render::Mode::Specular : render::Mode::Both;
}

void run_render(const RenderArgs& a) {
    const bool from_capture = !a.capture.empty() || a.frame.has_value();
    const bool free_pose = !a.camera.empty() || !a.light.empty();
    if (from_capture && free_pose) throw UsageError("give either --capture and --frame, or --camera and --light, not both");
    if (!from_capture && !free_pose) throw UsageError("give --capture DIR --frame INDEX, or --camera EYE,TARGET,UP --light X,Y,Z,I");
    const render::Settings settings{.mode = parse_mode(a.mode),
                                    .specular = a.specular == "factorized" ? render::SpecularModel::Factorized
                                                                           : render::SpecularModel::Analytic,
                                    .shadows = !a.no_shadows};
    Camera camera;
    PointLight light;
    std::string what;
    if (from_capture) {
        if (a.capture.empty()) throw UsageError("--frame needs --capture DIR");
        if (!a.frame) throw UsageError("--capture needs --frame INDEX");
        const Capture capture = load_capture(a.capture, {.load_mesh = false, .load_images = false});
        const std::size_t n = capture.desc.frames.size();
        if (*a.frame < 0 || static_cast<std::size_t>(*a.frame) >= n)
            throw UsageError("--frame: " + std::to_string(*a.frame) + " is out of range: " + capture_json_path(a.capture).string() +
                             " has " + std::to_string(n) + " frames (0 to " + std::to_string(n - 1) + ")");
        const FrameDesc& f = capture.desc.frames[static_cast<std::size_t>(*a.frame)];
        camera = f.camera();
        light = f.light;
        what = "frame " + std::to_string(*a.frame) + " (" + f.file_path.generic_string() + ")";
    } else {
        if (a.camera.empty() || a.light.empty()) throw UsageError("a free pose needs both --camera and --light");
        int w = 0, h = 0;
        const auto x = a.size.find('x');
        try {
            w = std::stoi(a.size.substr(0, x));
            h = x == std::string::npos ? w : std::stoi(a.size.substr(x + 1));
        } catch (const std::exception&) {
            throw UsageError("--size: '" + a.size + "' is not N or WxH");
        }
        std::optional<double> fov = a.fov;
        if (!fov && !a.fl) fov = 40.0;
        camera = evaluate::parse_free_camera(a.camera, w, h, fov, a.fl);
        light = evaluate::parse_light(a.light);
        what = "a free pose";
    }
    const Bundle bundle = read_bundle(a.bundle);
    evaluate::require_specular_model(bundle, settings.specular, a.bundle);
    gpu::Context ctx(gpu::ContextOptions{.device = a.device});
    evaluate::BundleRenderer renderer(ctx, bundle, a.bundle);
    const render::Frame frame = renderer.render(camera, light, settings);
    evaluate::write_rendered_image(a.out, frame.color);
    std::string note = frame.info.specular_note.empty() ? "" : " (" + frame.info.specular_note + ")";
    note += frame.info.shadow_pass ? ", shadows" : ", no shadows (" + frame.info.shadow_note + ")";
    if (settings.shadows && !frame.info.shadow_pass) log::warn("rendered without shadows: " + frame.info.shadow_note);
    log::info("wrote " + a.out + ": " + what + ", " + std::to_string(frame.color.width) + "x" +
              std::to_string(frame.color.height) + ", " + render::mode_name(settings.mode) + "/" +
              render::specular_model_name(settings.specular) + note + ", " + std::to_string(frame.info.wall_ms) + " ms");
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
    cmd->add_option("--capture", a->capture, "Capture folder (or its capture.json) whose frame to re-render");
    cmd->add_option("--frame", a->frame, "Frame index in capture.json's frames list");
    cmd->add_option("--camera", a->camera, "Free camera: eye,target,up (9 numbers, world units)");
    cmd->add_option("--light", a->light, "Free point light: x,y,z,intensity or x,y,z,r,g,b");
    cmd->add_option("--size", a->size, "Free camera image size: N or WxH")->capture_default_str();
    cmd->add_option("--fov", a->fov, "Free camera vertical field of view, degrees (default 40)");
    cmd->add_option("--fl", a->fl, "Free camera focal length in pixels (instead of --fov)")->excludes("--fov");
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
