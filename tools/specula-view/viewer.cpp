#include "viewer.h"

#include "orbit.h"

#include "capture/capture.h"
#include "core/error.h"
#include "core/log.h"
#include "core/timer.h"
#include "evaluate/bundle_render.h"
#include "export/bundle.h"
#include "gpu/context.h"
#include "gpu/image.h"
#include "gpu/render_target.h"
#include "gpu/sequence.h"
#include "gpu/swapchain.h"
#include "render/renderer.h"

#define GLFW_INCLUDE_VULKAN
#include <GLFW/glfw3.h>

#include <glm/gtc/constants.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <sstream>
#include <thread>
#include <vector>

#include <csignal>

namespace specula::view {

namespace {

// ---------------------------------------------------------------------------------------------
// Options

std::pair<int, int> parse_size(const std::string& text) {
    const auto x = text.find('x');
    try {
        std::size_t used = 0;
        const std::string a = text.substr(0, x);
        const int w = std::stoi(a, &used);
        if (used != a.size()) throw std::invalid_argument(text);
        int h = w;
        if (x != std::string::npos) {
            const std::string b = text.substr(x + 1);
            h = std::stoi(b, &used);
            if (used != b.size()) throw std::invalid_argument(text);
        }
        if (w < 1 || h < 1 || w > 16384 || h > 16384) throw std::invalid_argument(text);
        return {w, h};
    } catch (const std::exception&) {
        throw UsageError("--size: '" + text + "' is not N or WxH (1 to 16384)");
    }
}

/// Where the viewer starts, and the photograph of a capture frame (if any).
struct Start {
    Camera camera;
    PointLight light;
    glm::dvec3 up{0.0, 1.0, 0.0};
    std::string what;
    std::optional<Image> photo;
};

// The world axis closest to the camera's up: the orbit turns about it.
glm::dvec3 snapped_up(const Camera& camera) {
    const glm::dvec3 u = glm::normalize(glm::dvec3(camera.camera_to_world[1]));
    int best = 0;
    for (int a = 1; a < 3; ++a)
        if (std::abs(u[a]) > std::abs(u[best])) best = a;
    glm::dvec3 axis(0.0);
    axis[best] = u[best] < 0.0 ? -1.0 : 1.0;
    return axis;
}

Start resolve_start(const ViewerConfig& c, const Bundle& bundle) {
    const bool from_capture = !c.capture.empty() || c.frame.has_value();
    const bool free_pose = !c.camera.empty() || !c.light.empty();
    if (from_capture && free_pose) throw UsageError("give either --capture and --frame, or --camera and --light, not both");
    Start s;
    if (from_capture) {
        if (c.capture.empty()) throw UsageError("--frame needs --capture DIR");
        if (!c.frame) throw UsageError("--capture needs --frame INDEX");
        const Capture capture = load_capture(c.capture, {.load_mesh = false, .load_images = false});
        const std::size_t n = capture.desc.frames.size();
        if (*c.frame < 0 || static_cast<std::size_t>(*c.frame) >= n)
            throw UsageError("--frame: " + std::to_string(*c.frame) + " is out of range: " + capture_json_path(c.capture).string() +
                             " has " + std::to_string(n) + " frames (0 to " + std::to_string(n - 1) + ")");
        const std::size_t i = static_cast<std::size_t>(*c.frame);
        const FrameDesc& f = capture.desc.frames[i];
        s.camera = f.camera();
        s.light = f.light;
        s.up = snapped_up(s.camera);
        s.what = "frame " + std::to_string(i) + " (" + f.file_path.generic_string() + ")";
        s.photo = read_image(capture.desc.resolve(f.file_path), capture.desc.color_space,
                             "frames[" + std::to_string(i) + "].file_path");
        if (s.photo->width != f.intrinsics.w || s.photo->height != f.intrinsics.h)
            throw InputError(capture.desc.resolve(f.file_path), "frames[" + std::to_string(i) + "].file_path",
                             "the image is " + std::to_string(s.photo->width) + "x" + std::to_string(s.photo->height) +
                                 " but the frame's intrinsics say " + std::to_string(f.intrinsics.w) + "x" +
                                 std::to_string(f.intrinsics.h));
        return s;
    }
    const auto [w, h] = parse_size(c.size);
    const double fov = c.fov.value_or(40.0);
    if (!(fov > 0.0 && fov < 180.0)) throw UsageError("--fov: must be in (0, 180) degrees");
    const Bounds b = mesh_bounds(bundle.mesh);
    const glm::dvec3 center(b.center());
    const double r = std::max(static_cast<double>(b.radius()), 1e-6);
    const double distance = 1.15 * r / std::sin(0.5 * glm::radians(fov));
    if (!c.camera.empty()) {
        const auto v = evaluate::parse_numbers(c.camera, "--camera", {9}, "eye_x,eye_y,eye_z,target_x,target_y,target_z,up_x,up_y,up_z");
        s.camera = evaluate::parse_free_camera(c.camera, w, h, fov, std::nullopt);
        s.up = glm::normalize(glm::dvec3(v[6], v[7], v[8]));
    } else {
        s.camera = evaluate::free_camera(center + distance * glm::normalize(glm::dvec3(0.0, 0.35, 1.0)), center,
                                         {0.0, 1.0, 0.0}, w, h, fov, std::nullopt);
    }
    if (!c.light.empty()) {
        s.light = evaluate::parse_light(c.light);
    } else {
        // Above, right of and behind the camera; rho/pi * I/d^2 = 0.8 rho on a surface facing it.
        const glm::dvec3 eye = s.camera.center();
        const glm::dvec3 right(s.camera.camera_to_world[0]), up(s.camera.camera_to_world[1]);
        s.light.position = eye + 0.5 * distance * (right + up);
        const double d = glm::length(s.light.position - center);
        s.light.intensity = glm::dvec3(0.8 * glm::pi<double>() * d * d);
    }
    s.what = "a free pose";
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
            .specular = c.specular == "factorized" ? render::SpecularModel::Factorized : render::SpecularModel::Analytic,
            .passes = c.passes == "separate" ? render::Passes::Separate
                      : c.passes == "fused"  ? render::Passes::Fused
                                             : render::Passes::Deferred,
            .shadows = c.shadows};
}

std::string settings_name(const render::Settings& s) {
    std::string name = std::string(render::mode_name(s.mode)) + "/" + render::specular_model_name(s.specular);
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

struct FrameStats {
    std::vector<double> ms;
    void report(const std::string& what) const {
        if (ms.empty()) return;
        std::vector<double> v = ms;
        std::sort(v.begin(), v.end());
        const auto pct = [&](double p) {
            const std::size_t i = static_cast<std::size_t>(std::ceil(p * static_cast<double>(v.size()))) - 1;
            return v[std::min(i, v.size() - 1)];
        };
        const double median = pct(0.5);
        char line[512];
        std::snprintf(line, sizeof line,
                      "bench: %s: %zu frames, median %.2f ms (%.1f fps), p95 %.2f ms, p99 %.2f ms, min %.2f ms, max %.2f ms",
                      what.c_str(), v.size(), median, 1e3 / median, pct(0.95), pct(0.99), v.front(), v.back());
        std::printf("%s\n", line);
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

Image to_linear_rgb(const std::vector<glm::vec4>& rgba, int w, int h) {
    Image img(w, h, 3);
    for (std::size_t i = 0; i < rgba.size(); ++i)
        for (int c = 0; c < 3; ++c) img.pixels[3 * i + static_cast<std::size_t>(c)] = rgba[i][c];
    return img;
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
    evaluate::BundleRenderer renderer(*ctx, bundle, c.bundle);
    log::debug(std::string("back-face culling ") + (renderer.renderer().culls_back_faces() ? "on" : "off (open mesh)"));
    OrbitView view(start.camera, start.light, mesh_bounds(bundle.mesh), start.up);
    const Camera camera = view.camera(start.camera.intrinsics.w, start.camera.intrinsics.h);
    const int w = camera.intrinsics.w, h = camera.intrinsics.h;
    if (c.bench) {
        gpu::RenderTarget target(*ctx, static_cast<uint32_t>(w), static_cast<uint32_t>(h), "viewer target");
        gpu::Sequence seq(*ctx, 1);
        FrameStats stats;
        for (int i = 0; i < kBenchWarmup + c.bench_frames; ++i) {
            const Stopwatch sw;
            const Camera cam = view.camera(w, h);
            seq.reset();
            seq.record([&](VkCommandBuffer cmd) { (void)renderer.renderer().record(cmd, target, cam, view.light(), settings); });
            seq.submit_and_wait();
            if (i >= kBenchWarmup) stats.ms.push_back(sw.seconds() * 1e3);
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
        in.settings->specular = in.settings->specular == render::SpecularModel::Analytic ? render::SpecularModel::Factorized
                                                                                        : render::SpecularModel::Analytic;
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

void swap_image_barrier(VkCommandBuffer cmd, VkImage image, VkImageLayout from, VkImageLayout to, VkPipelineStageFlags src_stage,
                        VkAccessFlags src_access, VkPipelineStageFlags dst_stage, VkAccessFlags dst_access) {
    gpu::image_barrier(cmd, image, VK_IMAGE_ASPECT_COLOR_BIT, 1, from, to, src_stage, src_access, dst_stage, dst_access);
}

VkImageBlit blit_region(uint32_t sw, uint32_t sh, const ImageRect& dst) {
    VkImageBlit r{};
    r.srcSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    r.srcOffsets[1] = {static_cast<int32_t>(sw), static_cast<int32_t>(sh), 1};
    r.dstSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    r.dstOffsets[0] = {static_cast<int32_t>(std::lround(dst.x)), static_cast<int32_t>(std::lround(dst.y)), 0};
    r.dstOffsets[1] = {static_cast<int32_t>(std::lround(dst.x + dst.width)), static_cast<int32_t>(std::lround(dst.y + dst.height)), 1};
    return r;
}

/// The GPU side of the window: the target the passes draw into, the swapchain, one
/// command buffer and its synchronization (one frame in flight: the renderer's
/// parameters and the target are reused every frame).
class WindowFrames {
public:
    WindowFrames(gpu::Context& ctx, VkSurfaceKHR surface, gpu::PresentPacing pacing)
        : m_ctx(&ctx), m_chain(ctx, surface, pacing, "the viewer window"),
          m_acquired(gpu::make_semaphore(ctx, "image acquired")), m_done(gpu::make_fence(ctx, true, "frame done")) {
        const VkCommandPoolCreateInfo pool{.sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO,
                                           .flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT,
                                           .queueFamilyIndex = ctx.queue_family()};
        VkCommandPool p = VK_NULL_HANDLE;
        SPECULA_VK_CHECK(vkCreateCommandPool(ctx.device(), &pool, nullptr, &p), "creating the viewer's command pool");
        m_pool = gpu::UniqueCommandPool(ctx.device(), p);
        const VkCommandBufferAllocateInfo alloc{.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO,
                                                .commandPool = p,
                                                .level = VK_COMMAND_BUFFER_LEVEL_PRIMARY,
                                                .commandBufferCount = 1};
        SPECULA_VK_CHECK(vkAllocateCommandBuffers(ctx.device(), &alloc, &m_cmd), "allocating the viewer's command buffer");
        VkFormatProperties props{};
        vkGetPhysicalDeviceFormatProperties(ctx.physical_device(), gpu::choose_color_target_format(ctx), &props);
        if (!(props.optimalTilingFeatures & VK_FORMAT_FEATURE_BLIT_SRC_BIT))
            throw gpu::DeviceError(ctx.info().name + ": the render target's format cannot be blitted to the window");
        if (!m_chain.srgb()) log::warn("the window offers no sRGB format: colours are shown without sRGB encoding");
    }
    ~WindowFrames() {
        if (m_ctx) vkDeviceWaitIdle(m_ctx->device()); // nothing may be in flight when the members go
    }
    WindowFrames(const WindowFrames&) = delete;
    WindowFrames& operator=(const WindowFrames&) = delete;

    /// Recreates the swapchain and target for the framebuffer size; false when minimized.
    bool resize(int width, int height) {
        if (!m_chain.recreate(static_cast<uint32_t>(std::max(width, 0)), static_cast<uint32_t>(std::max(height, 0)))) {
            m_target.reset();
            return false;
        }
        if (!m_target || m_target->width() != m_chain.width() || m_target->height() != m_chain.height())
            m_target = std::make_unique<gpu::RenderTarget>(*m_ctx, m_chain.width(), m_chain.height(), "viewer target");
        return true;
    }
    [[nodiscard]] bool ready() const noexcept { return m_chain.valid() && m_target != nullptr; }
    [[nodiscard]] int width() const noexcept { return static_cast<int>(m_chain.width()); }
    [[nodiscard]] int height() const noexcept { return static_cast<int>(m_chain.height()); }
    [[nodiscard]] const gpu::Swapchain& chain() const noexcept { return m_chain; }

    enum class Shot { None, Shown, Linear };
    /// Draws and presents one frame: the passes (or the photograph) blitted to the
    /// window. `shot`: also copy what is shown (sRGB bytes) or the linear target out.
    /// Returns false when the swapchain must be recreated (nothing was drawn).
    bool draw(render::Renderer& renderer, const Camera& camera, const PointLight& light, const render::Settings& settings,
              const gpu::Image* photo, const ImageRect& photo_rect, Shot shot) {
        const VkDevice dev = m_ctx->device();
        const VkFence fence = m_done.get();
        SPECULA_VK_CHECK(vkWaitForFences(dev, 1, &fence, VK_TRUE, UINT64_MAX), "waiting for the previous frame");
        const std::optional<uint32_t> index = m_chain.acquire(m_acquired.get());
        if (!index) return false;
        const VkImage swap = m_chain.image(*index);
        SPECULA_VK_CHECK(vkResetFences(dev, 1, &fence), "resetting the frame fence");
        SPECULA_VK_CHECK(vkResetCommandBuffer(m_cmd, 0), "resetting the viewer's command buffer");
        const VkCommandBufferBeginInfo begin{.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO,
                                             .flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT};
        SPECULA_VK_CHECK(vkBeginCommandBuffer(m_cmd, &begin), "beginning the viewer's command buffer");

        // The swapchain image: whatever it held -> transfer destination. The acquire
        // semaphore is waited on at the transfer stage, which this barrier chains to.
        swap_image_barrier(m_cmd, swap, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                           VK_PIPELINE_STAGE_TRANSFER_BIT, 0, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT);
        const uint32_t w = m_chain.width(), h = m_chain.height();
        if (photo != nullptr) {
            // Letterbox: clear, then the photograph scaled into the start image's rectangle.
            const VkClearColorValue black{{0.0f, 0.0f, 0.0f, 1.0f}};
            const VkImageSubresourceRange all{VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
            vkCmdClearColorImage(m_cmd, swap, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, &black, 1, &all);
            swap_image_barrier(m_cmd, swap, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                               VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
                               VK_ACCESS_TRANSFER_WRITE_BIT);
            gpu::image_barrier(m_cmd, *photo, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                               VK_PIPELINE_STAGE_TRANSFER_BIT, 0, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_READ_BIT);
            const VkImageBlit region = blit_region(photo->width(), photo->height(), photo_rect);
            vkCmdBlitImage(m_cmd, photo->handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, swap, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                           1, &region, VK_FILTER_LINEAR);
            gpu::image_barrier(m_cmd, *photo, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL,
                               VK_PIPELINE_STAGE_TRANSFER_BIT, 0, VK_PIPELINE_STAGE_TRANSFER_BIT, 0);
        } else {
            (void)renderer.record(m_cmd, *m_target, camera, light, settings);
            if (shot == Shot::Linear) {
                m_target->record_readback(m_cmd); // leaves the colour in TRANSFER_SRC
            } else {
                gpu::image_barrier(m_cmd, m_target->color(), VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL,
                                   VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT,
                                   VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
                                   VK_ACCESS_TRANSFER_READ_BIT);
            }
            // Same size: a texel-exact copy with the format conversion (linear float -> sRGB bytes).
            const VkImageBlit region = blit_region(w, h, {0.0, 0.0, static_cast<double>(w), static_cast<double>(h)});
            vkCmdBlitImage(m_cmd, m_target->color().handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, swap,
                           VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &region, VK_FILTER_NEAREST);
        }
        if (shot == Shot::Shown) {
            if (!m_chain.readable()) throw gpu::DeviceError("the window's images cannot be read back for a screenshot");
            const VkDeviceSize bytes = VkDeviceSize{w} * h * 4;
            if (!m_shot || m_shot->size() < bytes) m_shot = std::make_unique<gpu::HostBuffer>(*m_ctx, bytes, "screenshot");
            swap_image_barrier(m_cmd, swap, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                               VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
                               VK_ACCESS_TRANSFER_READ_BIT);
            const VkBufferImageCopy copy{.bufferOffset = 0,
                                         .bufferRowLength = 0,
                                         .bufferImageHeight = 0,
                                         .imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1},
                                         .imageOffset = {0, 0, 0},
                                         .imageExtent = {w, h, 1}};
            vkCmdCopyImageToBuffer(m_cmd, swap, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, m_shot->handle(), 1, &copy);
            const VkMemoryBarrier to_host{.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
                                          .srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT,
                                          .dstAccessMask = VK_ACCESS_HOST_READ_BIT};
            vkCmdPipelineBarrier(m_cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &to_host, 0, nullptr, 0,
                                 nullptr);
            swap_image_barrier(m_cmd, swap, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_IMAGE_LAYOUT_PRESENT_SRC_KHR,
                               VK_PIPELINE_STAGE_TRANSFER_BIT, 0, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, 0);
        } else {
            // Presentation is ordered by the semaphore; the layout change must follow the writes.
            swap_image_barrier(m_cmd, swap, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_IMAGE_LAYOUT_PRESENT_SRC_KHR,
                               VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, 0);
        }
        SPECULA_VK_CHECK(vkEndCommandBuffer(m_cmd), "ending the viewer's command buffer");

        const VkSemaphore wait = m_acquired.get();
        const VkPipelineStageFlags wait_stage = VK_PIPELINE_STAGE_TRANSFER_BIT;
        const VkSemaphore signal = m_chain.ready(*index);
        const VkSubmitInfo submit{.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO,
                                  .waitSemaphoreCount = 1,
                                  .pWaitSemaphores = &wait,
                                  .pWaitDstStageMask = &wait_stage,
                                  .commandBufferCount = 1,
                                  .pCommandBuffers = &m_cmd,
                                  .signalSemaphoreCount = 1,
                                  .pSignalSemaphores = &signal};
        SPECULA_VK_CHECK(vkQueueSubmit(m_ctx->queue(), 1, &submit, fence), "submitting a viewer frame");
        const bool presented = m_chain.present(*index);
        // Wait here rather than at the next frame: the frame time then is this frame's
        // whole cost, and the next frame's input is applied with no frame of lag.
        SPECULA_VK_CHECK(vkWaitForFences(dev, 1, &fence, VK_TRUE, UINT64_MAX), "waiting for a viewer frame");
        if (!presented) m_stale = true;
        return true;
    }

    /// The screenshot of the last draw() (call after it returned).
    [[nodiscard]] Image shown_image() const {
        const int w = width(), h = height();
        Image img(w, h, 3);
        const auto* px = reinterpret_cast<const unsigned char*>(m_shot->data());
        const bool bgr = m_chain.format() == VK_FORMAT_B8G8R8A8_SRGB || m_chain.format() == VK_FORMAT_B8G8R8A8_UNORM;
        for (std::size_t i = 0; i < static_cast<std::size_t>(w) * h; ++i)
            for (int c = 0; c < 3; ++c) {
                const float v = px[4 * i + static_cast<std::size_t>(bgr ? 2 - c : c)] / 255.0f;
                img.pixels[3 * i + static_cast<std::size_t>(c)] = m_chain.srgb() ? srgb_to_linear(v) : v;
            }
        return img;
    }
    [[nodiscard]] Image linear_image() const { return to_linear_rgb(m_target->read_color(), width(), height()); }

    /// A present reported the swapchain out of date or suboptimal.
    [[nodiscard]] bool stale() const noexcept { return m_stale; }
    void clear_stale() noexcept { m_stale = false; }

private:
    gpu::Context* m_ctx;
    gpu::Swapchain m_chain;
    std::unique_ptr<gpu::RenderTarget> m_target;
    std::unique_ptr<gpu::HostBuffer> m_shot;
    gpu::UniqueSemaphore m_acquired;
    gpu::UniqueFence m_done;
    gpu::UniqueCommandPool m_pool;
    VkCommandBuffer m_cmd = VK_NULL_HANDLE; // freed with the pool
    bool m_stale = false;
};

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

    const int w0 = start.camera.intrinsics.w, h0 = start.camera.intrinsics.h;
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
        evaluate::BundleRenderer renderer(ctx, bundle, c.bundle);
        log::debug(std::string("back-face culling ") + (renderer.renderer().culls_back_faces() ? "on" : "off (open mesh)"));
        std::optional<gpu::Image> photo;
        if (start.photo) {
            const VkFormat f = gpu::choose_float_texture_format(ctx);
            photo.emplace(ctx, gpu::ImageDesc{.name = "captured photograph", .kind = gpu::ImageKind::Texture2D,
                                              .width = static_cast<uint32_t>(start.photo->width),
                                              .height = static_cast<uint32_t>(start.photo->height), .format = f});
            photo->upload(gpu::pack_rgba(start.photo->pixels, start.photo->channels,
                                         static_cast<std::size_t>(start.photo->width) * start.photo->height, f));
        }
        OrbitView view(start.camera, start.light, mesh_bounds(bundle.mesh), start.up);
        WindowFrames frames(ctx, surface.get(), c.bench ? gpu::PresentPacing::Unpaced : gpu::PresentPacing::Vsync);

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
        while (!glfwWindowShouldClose(window.get())) {
            const bool want_frame = headless || c.continuous || input.dirty;
            // Nothing to draw (or minimized): sleep until an event arrives.
            if (want_frame && !(frames.ready() == false && !input.resized))
                glfwPollEvents();
            else
                glfwWaitEventsTimeout(kIdleWakeSeconds);
            if (g_stop) break;
            if (input.resized || frames.stale()) {
                int fw = 0, fh = 0;
                glfwGetFramebufferSize(window.get(), &fw, &fh);
                input.resized = false;
                frames.clear_stale();
                frames.resize(fw, fh);
            }
            // Iconified (X11 keeps the size of a minimized window): draw nothing until restored.
            if (glfwGetWindowAttrib(window.get(), GLFW_ICONIFIED) == GLFW_TRUE) {
                input.dirty = true;
                glfwWaitEventsTimeout(kIdleWakeSeconds);
                continue;
            }
            if (!frames.ready() || !(headless || c.continuous || input.dirty)) continue;

            const bool last = headless && drawn + 1 == wanted;
            const bool shot = last && !c.screenshot.empty();
            const bool linear_shot = shot && std::filesystem::path(c.screenshot).extension() == ".exr";
            const Stopwatch sw;
            const Camera camera = view.camera(frames.width(), frames.height());
            const bool show_photo = input.show_photo && photo.has_value();
            const bool ok = frames.draw(renderer.renderer(), camera, view.light(), settings, show_photo ? &*photo : nullptr,
                                        view.image_rect(frames.width(), frames.height()),
                                        shot ? (linear_shot && !show_photo ? WindowFrames::Shot::Linear : WindowFrames::Shot::Shown)
                                             : WindowFrames::Shot::None);
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
                const auto [rw, rh] = parse_size(c.resize_to);
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
                                                      start.what, ms, frames.width(), frames.height())
                                                 .c_str());
            if (c.bench) {
                if (drawn > kBenchWarmup) stats.ms.push_back(ms);
                bench_step(view, c.bench_frames);
            }
            if (shot) {
                const Image img = linear_shot && !show_photo ? frames.linear_image() : frames.shown_image();
                evaluate::write_rendered_image(c.screenshot, img);
                log::info("wrote " + c.screenshot + " (" + std::to_string(img.width) + "x" + std::to_string(img.height) +
                          ", frame " + std::to_string(drawn) + ", window)");
            }
            if (headless && drawn >= wanted) break;
        }
        if (c.bench)
            stats.report(std::to_string(frames.width()) + "x" + std::to_string(frames.height()) + " " +
                         settings_name(settings) + ", window (present " +
                         (frames.chain().present_mode() == VK_PRESENT_MODE_FIFO_KHR ? "fifo"
                          : frames.chain().present_mode() == VK_PRESENT_MODE_MAILBOX_KHR ? "mailbox"
                                                                                         : "immediate") +
                         "), " + ctx.info().name + ", LP_NUM_THREADS " + lavapipe_threads());
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
              start.what);
    if (c.photo && !start.photo) throw UsageError("--photo needs --capture DIR --frame INDEX");
    if (!c.resize_to.empty()) {
        (void)parse_size(c.resize_to);
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
