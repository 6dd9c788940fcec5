// presenter_probe OUT_DIR: opens a kWindowW x kWindowH window (GLFW; run it under Xvfb),
// presents through gpu::Presenter what presenter_probe.h describes and writes what it
// reads back, as linear float EXR files, for view_test.cpp to check:
//   target.exr        Readback::Target of a frame that clears the target to kClear
//   target_shown.exr  Readback::Shown of the same frame (the swapchain image as presented)
//   partial_shown.exr the same frame saying it drew only kRect: kClear there, 0 elsewhere
//   corner_shown.exr  the same frame saying it drew a rectangle past the window's far corner
//   image_shown.exr   Readback::Shown of known_image() blitted 1:1 into kRect, the rest black
//   scaled_shown.exr  Readback::Shown of known_image() scaled 2x into kScaledRect
// Exit status: 0 done; 1 failure (including validation messages with SPECULA_VALIDATION=1,
// or a misuse the presenter failed to refuse); 3 no display.
#include "presenter_probe.h"

#include "core/error.h"
#include "core/image.h"
#include "gpu/context.h"
#include "gpu/image.h"
#include "gpu/presenter.h"
#include "gpu/render_target.h"
#include "gpu/swapchain.h"

#define GLFW_INCLUDE_VULKAN
#include <GLFW/glfw3.h>

#include <cstdio>
#include <exception>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>

namespace {

using namespace specula;
using namespace specula::view::probe;

/// Presents until a frame is not refused as out of date (at most 5 tries).
void present(gpu::Presenter& p, const std::function<bool()>& frame) {
    for (int i = 0; i < 5; ++i) {
        if (frame()) return;
        if (!p.resize(kWindowW, kWindowH)) throw Error("the window is minimized");
    }
    throw Error("the swapchain stays out of date");
}

void run(const std::filesystem::path& out, GLFWwindow* window) {
    uint32_t ext_count = 0;
    const char** exts = glfwGetRequiredInstanceExtensions(&ext_count);
    gpu::ContextOptions options{.application_name = "presenter_probe"};
    for (uint32_t i = 0; i < ext_count; ++i) options.instance_extensions.emplace_back(exts[i]);
    options.device_extensions.emplace_back(VK_KHR_SWAPCHAIN_EXTENSION_NAME);
    gpu::Context ctx(options);
    VkSurfaceKHR raw = VK_NULL_HANDLE;
    SPECULA_VK_CHECK(glfwCreateWindowSurface(ctx.instance(), window, nullptr, &raw), "creating the probe's surface");
    gpu::Surface surface(ctx.instance(), raw);
    {
        gpu::Presenter p(ctx, surface.get(), gpu::PresentPacing::Vsync, "the probe window");
        int fw = 0, fh = 0;
        glfwGetFramebufferSize(window, &fw, &fh);
        if (fw != kWindowW || fh != kWindowH)
            throw Error("the framebuffer is " + std::to_string(fw) + "x" + std::to_string(fh) + ", not the window's size");
        if (!p.resize(kWindowW, kWindowH) || !p.ready()) throw Error("no swapchain for a visible window");
        if (p.width() != kWindowW || p.height() != kWindowH) throw Error("the swapchain is not the window's size");

        const auto clear = [&](gpu::Readback readback, std::optional<gpu::PixelRect> drawn = std::nullopt) {
            return p.present_target(
                [&](VkCommandBuffer cmd, const gpu::RenderTarget& target) {
                    target.begin(cmd, gpu::RenderTarget::Load::Clear, {kClear[0], kClear[1], kClear[2], 1.0f});
                    target.end(cmd);
                    return drawn;
                },
                readback);
        };
        present(p, [&] { return clear(gpu::Readback::Target); });
        write_image(out / "target.exr", p.target_image(), ColorSpace::Linear);
        present(p, [&] { return clear(gpu::Readback::Shown); });
        write_image(out / "target_shown.exr", p.shown_image(), ColorSpace::Linear);
        // The same frame saying it drew only kRect (and a rectangle reaching past the window's
        // corner, which the presenter clips): only that part is shown, the rest is 0.
        present(p, [&] { return clear(gpu::Readback::Shown, gpu::PixelRect{kRect.x0, kRect.y0, kRect.x1, kRect.y1}); });
        write_image(out / "partial_shown.exr", p.shown_image(), ColorSpace::Linear);
        present(p, [&] { return clear(gpu::Readback::Shown, gpu::PixelRect{kWindowW - 5, kWindowH - 4, kWindowW + 9, kWindowH + 9}); });
        write_image(out / "corner_shown.exr", p.shown_image(), ColorSpace::Linear);

        const Image known = known_image();
        const VkFormat f = gpu::choose_float_texture_format(ctx);
        gpu::Image texture(ctx, {.name = "known image", .kind = gpu::ImageKind::Texture2D, .width = kImageW, .height = kImageH,
                                 .format = f});
        texture.upload(gpu::pack_rgba(known.pixels, 3, static_cast<std::size_t>(kImageW) * kImageH, f));
        const auto blit = [&](const Rect& r) {
            return p.present_image(texture, {.x0 = r.x0, .y0 = r.y0, .x1 = r.x1, .y1 = r.y1}, gpu::Readback::Shown);
        };
        present(p, [&] { return blit(kRect); });
        write_image(out / "image_shown.exr", p.shown_image(), ColorSpace::Linear);
        present(p, [&] { return blit(kScaledRect); });
        write_image(out / "scaled_shown.exr", p.shown_image(), ColorSpace::Linear);

        bool refused = false;
        try {
            (void)p.present_image(texture, {.x0 = 0, .y0 = 0, .x1 = 1, .y1 = 1}, gpu::Readback::Target);
        } catch (const Error&) {
            refused = true;
        }
        if (!refused) throw Error("present_image with Readback::Target was not refused");
    } // the presenter waits for the device before the surface goes
    surface.reset();
    if (ctx.validation_enabled() && ctx.validation_message_count() > 0) {
        for (const gpu::ValidationMessage& m : ctx.validation_messages())
            std::fprintf(stderr, "validation: %s: %s\n", m.id_name.c_str(), m.text.c_str());
        throw Error(std::to_string(ctx.validation_message_count()) + " validation message(s)");
    }
}

} // namespace

int main(int argc, char** argv) {
    if (argc != 2) {
        std::fprintf(stderr, "usage: presenter_probe OUT_DIR\n");
        return 1;
    }
    if (glfwInit() != GLFW_TRUE) {
        std::fprintf(stderr, "presenter_probe: no display\n");
        return 3;
    }
    int rc = 0;
    glfwWindowHint(GLFW_CLIENT_API, GLFW_NO_API);
    glfwWindowHint(GLFW_RESIZABLE, GLFW_FALSE);
    GLFWwindow* window = glfwCreateWindow(kWindowW, kWindowH, "presenter_probe", nullptr, nullptr);
    if (window == nullptr) {
        std::fprintf(stderr, "presenter_probe: cannot create a window\n");
        rc = 3;
    } else {
        glfwPollEvents(); // let the window be mapped before the first present
        try {
            run(argv[1], window);
        } catch (const std::exception& e) {
            std::fprintf(stderr, "presenter_probe: %s\n", e.what());
            rc = 1;
        }
        glfwDestroyWindow(window);
    }
    glfwTerminate();
    return rc;
}
