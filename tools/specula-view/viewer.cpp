#include "viewer.h"

#include "orbit.h"

#include "capture/capture.h"
#include "core/error.h"
#include "core/format.h"
#include "core/log.h"
#include "core/timer.h"
#include "evaluate/bundle_render.h"
#include "evaluate/pose.h"
#include "export/bundle.h"
#include "gpu/context.h"
#include "gpu/image.h"
#include "gpu/pass_clock.h"
#include "gpu/presenter.h"
#include "gpu/render_target.h"
#include "gpu/sequence.h"
#include "render/renderer.h"

#define GLFW_INCLUDE_VULKAN
#include <GLFW/glfw3.h>

#include <glm/gtc/constants.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <optional>
#include <thread>
#include <vector>

#include <csignal>

namespace specula::view {

namespace {

// ---------------------------------------------------------------------------------------------
// Options

/// Where the viewer starts, and the photograph of a capture frame (if any).
struct Start {
    evaluate::Pose pose;
    std::optional<Image> photo;
};

Start resolve_start(const ViewerConfig& c, const Bundle& bundle) {
    Start s{.pose = evaluate::resolve_pose(c.pose, mesh_bounds(bundle.mesh)), .photo = std::nullopt};
    if (s.pose.frame) s.photo = evaluate::read_frame_photo(*s.pose.frame);
    return s;
}

render::Settings settings_of(const ViewerConfig& c) {
    if (c.mode != "both" && c.mode != "diffuse" && c.mode != "specular")
        throw UsageError("--mode: '" + c.mode + "' is not both, diffuse or specular");
    if (c.specular != "analytic" && c.specular != "factorized")
        throw UsageError("--specular: '" + c.specular + "' is not analytic or factorized");
    if (c.passes != "fused" && c.passes != "separate" && c.passes != "deferred")
        throw UsageError("--passes: '" + c.passes + "' is not deferred, fused or separate");
    return {.mode = c.mode == "diffuse" ? render::Mode::Diffuse : c.mode == "specular" ? render::Mode::Specular : render::Mode::Both,
            .specular = c.specular == "factorized" ? render::SpecularPath::Factorized : render::SpecularPath::Analytic,
            .passes = c.passes == "separate" ? render::Passes::Separate
                      : c.passes == "fused"  ? render::Passes::Fused
                                             : render::Passes::Deferred,
            .shadows = c.shadows};
}

std::string settings_name(const render::Settings& s) {
    std::string name = std::string(render::mode_name(s.mode)) + "/" + render::specular_path_name(s.specular);
    if (s.passes == render::Passes::Deferred) name += ", deferred";
    else if (s.mode == render::Mode::Both) name += s.passes == render::Passes::Fused ? ", 1 pass" : ", 2 passes";
    if (s.shadows) name += ", shadows"; // off by default in the viewer (ViewerConfig::shadows)
    return name;
}

// ---------------------------------------------------------------------------------------------
// Shared by the window and the offscreen paths

std::string lavapipe_threads() {
    const char* t = std::getenv("LP_NUM_THREADS");
    return t != nullptr ? std::string(t) : "unset (lavapipe default: " + std::to_string(std::thread::hardware_concurrency()) + ")";
}

/// The p-quantile (0 < p <= 1) of sorted values.
double quantile(const std::vector<double>& sorted, double p) {
    const std::size_t i = static_cast<std::size_t>(std::ceil(p * static_cast<double>(sorted.size()))) - 1;
    return sorted[std::min(i, sorted.size() - 1)];
}

struct FrameStats {
    std::vector<double> ms;
    /// Per pass (gpu::PassClock labels, in first-seen order): its GPU milliseconds per frame.
    std::vector<std::pair<std::string, std::vector<double>>> passes;

    std::vector<double> triangles; ///< per frame, the triangles drawn (its level of detail's)
    std::vector<double> shaded;    ///< per deferred frame, the fraction of the target's pixels shaded
    std::vector<double> whole;     ///< per frame with patches chosen by the view, the patches drawn at level 0
    std::size_t patches = 0;       ///< the mesh's patches (with patches chosen by the view)

    void add_drawn(const render::FrameInfo& info, double target_pixels) {
        triangles.push_back(static_cast<double>(info.triangles));
        if (info.patches > 0) {
            whole.push_back(static_cast<double>(info.patches_whole));
            patches = info.patches;
        }
        if (info.deferred) shaded.push_back(static_cast<double>(info.drawn.area()) / target_pixels);
    }

    void add_passes(const std::vector<std::pair<std::string, double>>& marks) {
        for (const auto& [label, t] : marks) {
            auto it = std::find_if(passes.begin(), passes.end(), [&](const auto& p) { return p.first == label; });
            if (it == passes.end()) it = passes.insert(passes.end(), {label, {}});
            it->second.push_back(t);
        }
    }

    void report(const std::string& what) const {
        if (ms.empty()) return;
        std::vector<double> v = ms;
        std::sort(v.begin(), v.end());
        const double median = quantile(v, 0.5);
        char line[512];
        std::snprintf(line, sizeof line,
                      "bench: %s: %zu frames, median %.2f ms (%.1f fps), p95 %.2f ms, p99 %.2f ms, min %.2f ms, max %.2f ms",
                      what.c_str(), v.size(), median, 1e3 / median, quantile(v, 0.95), quantile(v, 0.99), v.front(), v.back());
        std::printf("%s\n", line);
        if (!triangles.empty()) {
            std::vector<double> t = triangles;
            std::sort(t.begin(), t.end());
            std::printf("bench: triangles drawn per frame: median %.0f, min %.0f, max %.0f\n", quantile(t, 0.5), t.front(),
                        t.back());
        }
        if (!whole.empty()) {
            std::vector<double> w = whole;
            std::sort(w.begin(), w.end());
            std::printf("bench: patches drawn whole per frame (a silhouette or a shadow's edge in them, or no coarser level "
                        "under --lod): median %.0f of %zu, min %.0f, max %.0f\n",
                        quantile(w, 0.5), patches, w.front(), w.back());
        }
        if (!shaded.empty()) {
            std::vector<double> f = shaded;
            std::sort(f.begin(), f.end());
            std::printf("bench: pixels shaded per frame (the box the mesh can cover): median %.1f%%, max %.1f%%\n",
                        100.0 * quantile(f, 0.5), 100.0 * f.back());
        }
        // Where a frame's time goes: each pass's median GPU time (timestamps), and the rest of the
        // median frame (blit and present, recording, submission, waiting).
        if (!passes.empty()) {
            std::string out = "bench: passes, median GPU ms:";
            double sum = 0.0;
            for (const auto& [label, t] : passes) {
                std::vector<double> sorted = t;
                std::sort(sorted.begin(), sorted.end());
                const double m = quantile(sorted, 0.5);
                sum += m;
                char part[96];
                std::snprintf(part, sizeof part, " %s %.2f,", label.c_str(), m);
                out += part;
            }
            char rest[128];
            std::snprintf(rest, sizeof rest, " the rest of the median frame %.2f (blit, present, CPU)", std::max(0.0, median - sum));
            std::printf("%s%s\n", out.c_str(), rest);
        } else {
            std::printf("bench: passes: no timestamps on this device\n");
        }
        std::fflush(stdout);
    }
};

/// The fixed path of --bench: one turn of the camera about the target and one turn of
/// the light the other way, over `frames` frames.
void bench_step(OrbitView& view, int frames) {
    const double step = glm::two_pi<double>() / frames;
    view.orbit(step, 0.0);
    view.move_light(-step, 0.0);
}

constexpr int kBenchWarmup = 8; // frames before timing starts (first-use costs)

/// Counts validation messages, printing the first few as they arrive.
void watch_validation(gpu::Context& ctx) {
    if (!ctx.validation_enabled()) return;
    ctx.set_validation_handler([&ctx](const gpu::ValidationMessage& m) {
        if (ctx.validation_message_count() <= 10)
            std::fprintf(stderr, "validation: %s: %s\n", m.id_name.c_str(), m.text.c_str());
    });
}

void require_no_validation_messages(gpu::Context& ctx) {
    if (!ctx.validation_enabled()) return;
    const std::size_t n = ctx.validation_message_count();
    if (n > 0) throw Error(std::to_string(n) + " validation message(s) (the first are printed above)");
}

/// The bundle's renderer with the viewer's levels of detail (--lod): built, then kept only where
/// their renders of four poses of the bench's path look like the whole mesh's (--lod-psnr).
evaluate::BundleRenderer view_renderer(gpu::Context& ctx, const Bundle& bundle, const ViewerConfig& c, const Start& start,
                                       const render::Settings& settings) {
    const Stopwatch sw;
    evaluate::BundleRenderer renderer(ctx, bundle, c.bundle, {.lod_max_error_px = c.lod_max_error_px, .cluster_culling = true});
    render::Renderer& r = renderer.renderer();
    log::debug(std::string("back-face culling ") + (r.culls_back_faces() ? "on" : "off (open mesh)"));
    if (r.levels_of_detail().size() < 2) return renderer;
    OrbitView view(start.pose.camera, start.pose.light, mesh_bounds(bundle.mesh), start.pose.up);
    std::vector<Camera> cameras;
    std::vector<PointLight> lights;
    constexpr int kPoses = 4;
    for (int i = 0; i < kPoses; ++i) {
        cameras.push_back(view.camera(start.pose.camera.intrinsics.w, start.pose.camera.intrinsics.h));
        lights.push_back(view.light());
        bench_step(view, kPoses);
    }
    const std::vector<double> psnr = r.accept_levels_of_detail(cameras, lights, settings, c.lod_min_psnr_db);
    std::string text = "levels of detail (" + format_text("%.2f", sw.seconds()) + " s):";
    for (std::size_t k = 0; k < psnr.size(); ++k) {
        const render::LevelOfDetail& l = r.levels_of_detail()[k];
        text += format_text(" %.0f triangles", double(l.index_count / 3));
        if (k > 0)
            text += format_text(" (%.1f dB", psnr[k]) + (k < r.accepted_levels_of_detail() ? ")" : ", left out)");
        text += k + 1 < psnr.size() ? "," : "";
    }
    log::info(text + format_text("; the levels kept are drawn where their error is under %g px, those under %g dB display PSNR "
                                 "against the whole mesh on 4 poses are left out",
                                 c.lod_max_error_px, c.lod_min_psnr_db));
    return renderer;
}

// ---------------------------------------------------------------------------------------------
// Offscreen: the same passes into an offscreen target; no window.

void run_offscreen(const ViewerConfig& c, const Bundle& bundle, const Start& start, const render::Settings& settings,
                   const std::string& why) {
    log::info("no window (" + why + "): rendering offscreen");
    std::unique_ptr<gpu::Context> ctx;
    try {
        ctx = std::make_unique<gpu::Context>(gpu::ContextOptions{.device = c.device, .application_name = "specula-view"});
    } catch (const std::exception& e) {
        throw Error("neither a window (" + why + ") nor offscreen rendering works: " + e.what());
    }
    watch_validation(*ctx);
    evaluate::BundleRenderer renderer = view_renderer(*ctx, bundle, c, start, settings);
    OrbitView view(start.pose.camera, start.pose.light, mesh_bounds(bundle.mesh), start.pose.up);
    const Camera camera = view.camera(start.pose.camera.intrinsics.w, start.pose.camera.intrinsics.h);
    const int w = camera.intrinsics.w, h = camera.intrinsics.h;
    if (c.bench) {
        gpu::RenderTarget target(*ctx, static_cast<uint32_t>(w), static_cast<uint32_t>(h), "viewer target");
        gpu::Sequence seq(*ctx, 1);
        gpu::PassClock clock(*ctx);
        FrameStats stats;
        for (int i = 0; i < kBenchWarmup + c.bench_frames; ++i) {
            const Stopwatch sw;
            const Camera cam = view.camera(w, h);
            seq.reset();
            render::FrameInfo info;
            seq.record([&](VkCommandBuffer cmd) {
                clock.start(cmd);
                info = renderer.renderer().record(cmd, target, cam, view.light(), settings, &clock);
            });
            seq.submit_and_wait();
            if (i >= kBenchWarmup) {
                stats.ms.push_back(sw.seconds() * 1e3);
                stats.add_drawn(info, static_cast<double>(w) * h);
                stats.add_passes(clock.read());
            }
            bench_step(view, c.bench_frames);
        }
        stats.report(std::to_string(w) + "x" + std::to_string(h) + " " + settings_name(settings) + ", offscreen (no present), " + ctx->info().name +
                     ", LP_NUM_THREADS " + lavapipe_threads());
    }
    if (c.frames && c.photo) { // the captured photograph is what the window would show
        if (!c.screenshot.empty()) evaluate::write_rendered_image(c.screenshot, *start.photo);
    } else if (c.frames) {
        render::Frame frame;
        for (int i = 0; i < *c.frames; ++i) frame = renderer.render(camera, view.light(), settings);
        if (!c.screenshot.empty()) {
            evaluate::write_rendered_image(c.screenshot, frame.color);
            log::info("wrote " + c.screenshot + " (" + std::to_string(w) + "x" + std::to_string(h) + ", offscreen)");
        }
    }
    require_no_validation_messages(*ctx);
}

// ---------------------------------------------------------------------------------------------
// The window

std::string g_glfw_error; // the last GLFW error (GLFW reports through a callback)

// SIGINT / SIGTERM ask the frame loop to end, so that Ctrl-C in a terminal (or a test's
// kill) still tears down in order and checks validation. The idle wait wakes 4 times a
// second to look at it; nothing is drawn then.
volatile std::sig_atomic_t g_stop = 0;
constexpr double kIdleWakeSeconds = 0.25;

class Glfw {
public:
    Glfw() {
        glfwSetErrorCallback([](int code, const char* text) { g_glfw_error = std::string(text) + " (GLFW error " + std::to_string(code) + ")"; });
        m_ok = glfwInit() == GLFW_TRUE;
    }
    ~Glfw() {
        if (m_ok) glfwTerminate();
    }
    Glfw(const Glfw&) = delete;
    Glfw& operator=(const Glfw&) = delete;
    [[nodiscard]] bool ok() const noexcept { return m_ok; }

private:
    bool m_ok = false;
};

struct WindowDeleter {
    void operator()(GLFWwindow* w) const noexcept { glfwDestroyWindow(w); }
};
using UniqueWindow = std::unique_ptr<GLFWwindow, WindowDeleter>;

/// What input changed; the frame loop reads it.
struct Input {
    OrbitView* view = nullptr;
    render::Settings* settings = nullptr;
    bool has_factorization = false;
    bool has_photo = false;
    bool show_photo = false;
    bool dirty = true;   // something changed: draw a frame
    bool resized = true; // the framebuffer may have changed size
    enum class Drag { None, Orbit, Pan, Light } drag = Drag::None;
    double x = 0.0, y = 0.0;
};

Input& input_of(GLFWwindow* w) { return *static_cast<Input*>(glfwGetWindowUserPointer(w)); }

constexpr const char* kHelp =
    "specula-view keys and mouse:\n"
    "  left drag           orbit the camera about the target\n"
    "  right/middle drag   pan\n"
    "  wheel, +/-          zoom\n"
    "  shift + left drag   move the light about the object (also the arrow keys)\n"
    "  1 / 2 / 3           diffuse only / specular only / both\n"
    "  F                   factorized <-> analytic specular (bundles with cube-maps)\n"
    "  P                   passes: deferred -> one fused pass -> the two separate passes -> deferred\n"
    "  S                   cast shadows (shadow map) on <-> off (the thesis's unshadowed render)\n"
    "  C                   captured photograph of the frame <-> render (with --capture)\n"
    "  R                   reset camera and light\n"
    "  H                   this help\n"
    "  Q, Esc              quit\n";

void on_key(GLFWwindow* w, int key, int, int action, int) {
    if (action != GLFW_PRESS && action != GLFW_REPEAT) return;
    Input& in = input_of(w);
    const double step = glm::radians(10.0);
    switch (key) {
    case GLFW_KEY_ESCAPE:
    case GLFW_KEY_Q: glfwSetWindowShouldClose(w, GLFW_TRUE); break;
    case GLFW_KEY_1: in.settings->mode = render::Mode::Diffuse; break;
    case GLFW_KEY_2: in.settings->mode = render::Mode::Specular; break;
    case GLFW_KEY_3: in.settings->mode = render::Mode::Both; break;
    case GLFW_KEY_F:
        if (!in.has_factorization) {
            std::fprintf(stderr, "the bundle has no factorization cube-maps: the specular model stays analytic\n");
            return;
        }
        in.settings->specular = in.settings->specular == render::SpecularPath::Analytic ? render::SpecularPath::Factorized
                                                                                        : render::SpecularPath::Analytic;
        break;
    case GLFW_KEY_P:
        in.settings->passes = in.settings->passes == render::Passes::Deferred ? render::Passes::Fused
                              : in.settings->passes == render::Passes::Fused  ? render::Passes::Separate
                                                                              : render::Passes::Deferred;
        break;
    case GLFW_KEY_S: in.settings->shadows = !in.settings->shadows; break;
    case GLFW_KEY_C:
        if (!in.has_photo) {
            std::fprintf(stderr, "no captured photograph: start with --capture DIR --frame INDEX\n");
            return;
        }
        in.show_photo = !in.show_photo;
        break;
    case GLFW_KEY_R: in.view->reset(); break;
    case GLFW_KEY_H: std::printf("%s", kHelp); return;
    case GLFW_KEY_LEFT: in.view->move_light(-step, 0.0); break;
    case GLFW_KEY_RIGHT: in.view->move_light(step, 0.0); break;
    case GLFW_KEY_UP: in.view->move_light(0.0, -step); break;
    case GLFW_KEY_DOWN: in.view->move_light(0.0, step); break;
    case GLFW_KEY_EQUAL:
    case GLFW_KEY_KP_ADD: in.view->zoom(1.0); break;
    case GLFW_KEY_MINUS:
    case GLFW_KEY_KP_SUBTRACT: in.view->zoom(-1.0); break;
    default: return;
    }
    in.dirty = true;
}

void on_mouse_button(GLFWwindow* w, int button, int action, int mods) {
    Input& in = input_of(w);
    if (action == GLFW_RELEASE) {
        in.drag = Input::Drag::None;
        return;
    }
    glfwGetCursorPos(w, &in.x, &in.y);
    if (button == GLFW_MOUSE_BUTTON_LEFT)
        in.drag = (mods & GLFW_MOD_SHIFT) ? Input::Drag::Light : Input::Drag::Orbit;
    else if (button == GLFW_MOUSE_BUTTON_RIGHT || button == GLFW_MOUSE_BUTTON_MIDDLE)
        in.drag = Input::Drag::Pan;
}

void on_cursor(GLFWwindow* w, double x, double y) {
    Input& in = input_of(w);
    const double dx = x - in.x, dy = y - in.y;
    in.x = x;
    in.y = y;
    constexpr double kRadiansPerPixel = 0.01;
    switch (in.drag) {
    case Input::Drag::None: return;
    case Input::Drag::Orbit: in.view->orbit(-dx * kRadiansPerPixel, -dy * kRadiansPerPixel); break;
    case Input::Drag::Light: in.view->move_light(dx * kRadiansPerPixel, dy * kRadiansPerPixel); break;
    case Input::Drag::Pan: {
        int ww = 0, wh = 0, fw = 0, fh = 0;
        glfwGetWindowSize(w, &ww, &wh);
        glfwGetFramebufferSize(w, &fw, &fh);
        if (ww <= 0 || fw <= 0 || fh <= 0) return;
        // Cursor (screen units) -> framebuffer pixels -> pixels of the start image.
        const double px = (static_cast<double>(fw) / ww) / in.view->window_scale(fw, fh);
        in.view->pan(dx * px, dy * px);
        break;
    }
    }
    in.dirty = true;
}

void on_scroll(GLFWwindow* w, double, double dy) {
    Input& in = input_of(w);
    in.view->zoom(dy);
    in.dirty = true;
}

void on_framebuffer_size(GLFWwindow* w, int, int) {
    Input& in = input_of(w);
    in.resized = true;
    in.dirty = true;
}

void on_refresh(GLFWwindow* w) { input_of(w).dirty = true; }

/// The start image's rectangle in the window, corners rounded to whole pixels.
gpu::PixelRect pixel_rect(const ImageRect& r) {
    return {.x0 = static_cast<int32_t>(std::lround(r.x)),
            .y0 = static_cast<int32_t>(std::lround(r.y)),
            .x1 = static_cast<int32_t>(std::lround(r.x + r.width)),
            .y1 = static_cast<int32_t>(std::lround(r.y + r.height))};
}

std::string title_of(const std::string& bundle, const render::Settings& s, bool photo, const std::string& what, double ms,
                     int w, int h) {
    char t[512];
    if (photo)
        std::snprintf(t, sizeof t, "specula-view | %s | captured photograph of %s | %dx%d", bundle.c_str(), what.c_str(), w, h);
    else
        std::snprintf(t, sizeof t, "specula-view | %s | %s | %.1f ms (%.0f fps) | %dx%d", bundle.c_str(),
                      settings_name(s).c_str(), ms, ms > 0.0 ? 1e3 / ms : 0.0, w, h);
    return t;
}

void run_window(const ViewerConfig& c, const Bundle& bundle, const Start& start, render::Settings settings) {
    const bool headless = c.frames.has_value() || c.bench;
    Glfw glfw;
    std::string failure;
    if (!glfw.ok())
        failure = "no display: " + (g_glfw_error.empty() ? std::string("glfwInit failed") : g_glfw_error);
    else if (glfwVulkanSupported() != GLFW_TRUE)
        failure = "GLFW finds no Vulkan loader with window-system support";
    if (!failure.empty()) {
        if (!headless)
            throw Error(failure + ".\nspecula-view needs a display for interactive use: run it on a desktop session, or under "
                                  "Xvfb (xvfb-run -a specula-view ...). --frames N --screenshot FILE and --bench also run "
                                  "offscreen without one.");
        run_offscreen(c, bundle, start, settings, failure);
        return;
    }

    const int w0 = start.pose.camera.intrinsics.w, h0 = start.pose.camera.intrinsics.h;
    glfwWindowHint(GLFW_CLIENT_API, GLFW_NO_API);
    glfwWindowHint(GLFW_RESIZABLE, GLFW_TRUE);
    UniqueWindow window(glfwCreateWindow(w0, h0, "specula-view", nullptr, nullptr));
    if (!window) {
        const std::string why = "cannot create a window: " + g_glfw_error;
        if (!headless) throw Error(why);
        run_offscreen(c, bundle, start, settings, why);
        return;
    }

    uint32_t ext_count = 0;
    const char** exts = glfwGetRequiredInstanceExtensions(&ext_count);
    gpu::ContextOptions options{.device = c.device, .application_name = "specula-view"};
    for (uint32_t i = 0; i < ext_count; ++i) options.instance_extensions.emplace_back(exts[i]);
    options.device_extensions.emplace_back(VK_KHR_SWAPCHAIN_EXTENSION_NAME);
    gpu::Context ctx(options);
    watch_validation(ctx);
    VkSurfaceKHR raw_surface = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(glfwCreateWindowSurface(ctx.instance(), window.get(), nullptr, &raw_surface),
                     "creating the window's Vulkan surface");
    gpu::Surface surface(ctx.instance(), raw_surface);
    {
        evaluate::BundleRenderer renderer = view_renderer(ctx, bundle, c, start, settings);
        std::optional<gpu::Image> photo;
        if (start.photo) {
            const VkFormat f = gpu::choose_float_texture_format(ctx);
            photo.emplace(ctx, gpu::ImageDesc{.name = "captured photograph", .kind = gpu::ImageKind::Texture2D,
                                              .width = static_cast<uint32_t>(start.photo->width),
                                              .height = static_cast<uint32_t>(start.photo->height), .format = f});
            photo->upload(gpu::pack_rgba(start.photo->pixels, start.photo->channels,
                                         static_cast<std::size_t>(start.photo->width) * start.photo->height, f));
        }
        OrbitView view(start.pose.camera, start.pose.light, mesh_bounds(bundle.mesh), start.pose.up);
        gpu::Presenter presenter(ctx, surface.get(), c.bench ? gpu::PresentPacing::Unpaced : gpu::PresentPacing::Vsync,
                                 "the viewer window");

        Input input;
        input.view = &view;
        input.settings = &settings;
        input.has_factorization = renderer.has_factorization();
        input.has_photo = photo.has_value();
        input.show_photo = c.photo;
        glfwSetWindowUserPointer(window.get(), &input);
        glfwSetKeyCallback(window.get(), on_key);
        glfwSetMouseButtonCallback(window.get(), on_mouse_button);
        glfwSetCursorPosCallback(window.get(), on_cursor);
        glfwSetScrollCallback(window.get(), on_scroll);
        glfwSetFramebufferSizeCallback(window.get(), on_framebuffer_size);
        glfwSetWindowRefreshCallback(window.get(), on_refresh);
        glfwSetWindowIconifyCallback(window.get(), [](GLFWwindow* w, int) { on_refresh(w); });
        if (!headless) std::printf("%s (H prints this again)\n", kHelp);

        const int wanted = c.bench ? kBenchWarmup + c.bench_frames : c.frames.value_or(0);
        g_stop = 0;
        const auto on_signal = [](int) { g_stop = 1; };
        std::signal(SIGINT, on_signal);
        std::signal(SIGTERM, on_signal);
        const Stopwatch running;
        int drawn = 0;
        FrameStats stats;
        gpu::PassClock clock(ctx);
        while (!glfwWindowShouldClose(window.get())) {
            const bool want_frame = headless || c.continuous || input.dirty;
            // Nothing to draw (or minimized): sleep until an event arrives.
            if (want_frame && !(presenter.ready() == false && !input.resized))
                glfwPollEvents();
            else
                glfwWaitEventsTimeout(kIdleWakeSeconds);
            if (g_stop) break;
            if (input.resized || presenter.stale()) {
                int fw = 0, fh = 0;
                glfwGetFramebufferSize(window.get(), &fw, &fh);
                input.resized = false;
                presenter.clear_stale();
                presenter.resize(static_cast<uint32_t>(std::max(fw, 0)), static_cast<uint32_t>(std::max(fh, 0)));
            }
            // Iconified (X11 keeps the size of a minimized window): draw nothing until restored.
            if (glfwGetWindowAttrib(window.get(), GLFW_ICONIFIED) == GLFW_TRUE) {
                input.dirty = true;
                glfwWaitEventsTimeout(kIdleWakeSeconds);
                continue;
            }
            if (!presenter.ready() || !(headless || c.continuous || input.dirty)) continue;

            const bool last = headless && drawn + 1 == wanted;
            const bool shot = last && !c.screenshot.empty();
            const bool linear_shot = shot && std::filesystem::path(c.screenshot).extension() == ".exr";
            const Stopwatch sw;
            const int fb_w = static_cast<int>(presenter.width()), fb_h = static_cast<int>(presenter.height());
            const Camera camera = view.camera(fb_w, fb_h);
            const bool show_photo = input.show_photo && photo.has_value();
            const gpu::Readback readback = !shot                           ? gpu::Readback::None
                                           : linear_shot && !show_photo ? gpu::Readback::Target
                                                                        : gpu::Readback::Shown;
            render::FrameInfo info;
            const bool ok = show_photo ? presenter.present_image(*photo, pixel_rect(view.image_rect(fb_w, fb_h)), readback)
                                       : presenter.present_target(
                                             [&](VkCommandBuffer cmd, const gpu::RenderTarget& target) {
                                                 if (c.bench) clock.start(cmd);
                                                 info = renderer.renderer().record(cmd, target, camera, view.light(), settings,
                                                                                   c.bench ? &clock : nullptr);
                                                 return std::optional<gpu::PixelRect>(gpu::PixelRect{
                                                     .x0 = info.drawn.x0, .y0 = info.drawn.y0, .x1 = info.drawn.x1,
                                                     .y1 = info.drawn.y1});
                                             },
                                             readback);
            if (!ok) {
                input.resized = true; // out of date: recreate and draw again
                continue;
            }
            const double ms = sw.seconds() * 1e3;
            input.dirty = false;
            ++drawn;
            if (drawn == 1) log::info("specula-view: first frame drawn");
            if (drawn == 1 && !c.resize_to.empty()) {
                // Exercise a resize (swapchain and target recreation) in headless runs: ask
                // for the new size and wait (at most 5 s) until the framebuffer has it.
                const auto [rw, rh] = evaluate::parse_image_size(c.resize_to, "--resize-to");
                glfwSetWindowSize(window.get(), rw, rh);
                const Stopwatch wait;
                int fw = 0, fh = 0;
                do {
                    glfwWaitEventsTimeout(0.05);
                    glfwGetFramebufferSize(window.get(), &fw, &fh);
                } while ((fw != rw || fh != rh) && wait.seconds() < 5.0);
                if (fw != rw || fh != rh)
                    throw Error("--resize-to: the window is " + std::to_string(fw) + "x" + std::to_string(fh) +
                                " after 5 s, not " + c.resize_to + " (a window manager may have refused)");
            }
            glfwSetWindowTitle(window.get(), title_of(std::filesystem::path(c.bundle).filename().string(), settings, show_photo,
                                                      start.pose.what, ms, fb_w, fb_h)
                                                 .c_str());
            if (c.bench) {
                if (drawn > kBenchWarmup) {
                    stats.ms.push_back(ms);
                    if (!show_photo) stats.add_drawn(info, static_cast<double>(fb_w) * fb_h);
                    stats.add_passes(clock.read()); // present_target waited for the frame
                }
                bench_step(view, c.bench_frames);
            }
            if (shot) {
                const Image img = linear_shot && !show_photo ? presenter.target_image() : presenter.shown_image();
                evaluate::write_rendered_image(c.screenshot, img);
                log::info("wrote " + c.screenshot + " (" + std::to_string(img.width) + "x" + std::to_string(img.height) +
                          ", frame " + std::to_string(drawn) + ", window)");
            }
            if (headless && drawn >= wanted) break;
        }
        if (c.bench)
            stats.report(std::to_string(presenter.width()) + "x" + std::to_string(presenter.height()) + " " +
                         settings_name(settings) + ", window (present " + presenter.present_mode_name() + "), " +
                         ctx.info().name + ", LP_NUM_THREADS " + lavapipe_threads());
        glfwSetWindowUserPointer(window.get(), nullptr);
        std::signal(SIGINT, SIG_DFL);
        std::signal(SIGTERM, SIG_DFL);
        char line[128];
        std::snprintf(line, sizeof line, "specula-view: %d frame(s) drawn in %.1f s", drawn, running.seconds());
        log::info(line);
    } // GPU objects go (after a device wait) before the surface and the window
    surface.reset();
    window.reset();
    require_no_validation_messages(ctx);
}

} // namespace

void run_viewer(const ViewerConfig& c) {
    if (c.frames && *c.frames < 1) throw UsageError("--frames: must be at least 1");
    if (c.bench && c.bench_frames < 1) throw UsageError("--bench-frames: must be at least 1");
    if (!c.screenshot.empty() && !c.frames) throw UsageError("--screenshot needs --frames N");
    if (!c.screenshot.empty()) {
        const std::string ext = std::filesystem::path(c.screenshot).extension().string();
        if (ext != ".png" && ext != ".exr") throw UsageError("--screenshot: " + c.screenshot + " must end in .png or .exr");
    }
    const render::Settings settings = settings_of(c);
    const Bundle bundle = read_bundle(c.bundle);
    evaluate::require_specular_model(bundle, settings.specular, c.bundle);
    const Start start = resolve_start(c, bundle);
    log::info("specula-view: " + c.bundle + " (" + std::to_string(bundle.mesh.triangles.size()) + " triangles), starting at " +
              start.pose.what);
    if (c.photo && !start.photo) throw UsageError("--photo needs --capture DIR --frame INDEX");
    if (!c.resize_to.empty()) {
        (void)evaluate::parse_image_size(c.resize_to, "--resize-to");
        if (!c.frames || *c.frames < 2) throw UsageError("--resize-to needs --frames N with N >= 2");
    }
    if (c.offscreen) {
        if (!c.frames && !c.bench) throw UsageError("--offscreen needs --frames N or --bench");
        run_offscreen(c, bundle, start, settings, "--offscreen");
        return;
    }
    run_window(c, bundle, start, settings);
}

} // namespace specula::view
