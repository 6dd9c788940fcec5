#pragma once
// specula-view: shows a bundle in a window with the raster passes of engine/render
// (Renderer::record into the window-sized target of a gpu::Presenter, which blits it to
// the swapchain), or renders it offscreen when there is no display.
#include "evaluate/pose.h"
#include "render/renderer.h"

#include <optional>
#include <string>

namespace specula::view {

struct ViewerConfig {
    std::string bundle;                 ///< .glb written by `specula reconstruct`
    /// Where the view starts: a capture frame's camera and light (--capture, --frame), or a
    /// free pose (--camera, --light, --size, --fov; a missing camera or light frames the object).
    evaluate::PoseOptions pose;
    std::string mode = "both";          ///< both, diffuse, specular
    std::string specular = "analytic";  ///< analytic, factorized
    std::string passes = "deferred";    ///< deferred (G-buffer, then per-pixel shading), fused (one pass for both terms) or separate (the thesis's two)
    /// Start with cast shadows (key S toggles). Off by default in the viewer: the shadow map
    /// redraws every triangle once more whenever the light moves, which halves the frame rate
    /// of large meshes on lavapipe; `specula render` and `evaluate` draw shadows by default.
    bool shadows = false;
    /// Levels of detail (render::Options::lod_max_error_px): the coarsest simplified mesh whose
    /// geometric error is at most this many pixels on screen; 0 draws every triangle.
    double lod_max_error_px = 0.5;
    /// Levels of detail whose renders score under this display PSNR against the whole mesh's
    /// (render::Renderer::accept_levels_of_detail, 4 poses) are left out.
    double lod_min_psnr_db = render::kDefaultLodMinPsnrDb;
    std::string device;                 ///< Vulkan device selector
    std::optional<int> frames;          ///< headless: render this many frames, then exit
    std::string screenshot;             ///< save the last frame (.png sRGB 8-bit, .exr linear)
    bool bench = false;                 ///< timed frames over a fixed camera and light path
    int bench_frames = 240;
    bool continuous = false;            ///< render every frame, not only on input
    bool offscreen = false;             ///< never open a window
    bool photo = false;                 ///< start showing the captured photograph (key C)
    std::string resize_to;              ///< headless tests: resize the window to WxH after the first frame
};

/// Runs the viewer. Throws UsageError for bad options, InputError for bad files,
/// Error for everything else (including validation messages when SPECULA_VALIDATION is on).
void run_viewer(const ViewerConfig& config);

} // namespace specula::view
