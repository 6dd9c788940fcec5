// specula-view: a window onto a bundle, rendered by engine/render's raster passes.
// Parses arguments into a ViewerConfig and runs it; exit code 0 success, 1 failure
// (bad input, no device, validation messages), 2 usage error (as `specula`).
#include "viewer.h"

#include "core/error.h"
#include "core/log.h"
#include "specula/version.h"

#include <CLI/CLI.hpp>

#include <malloc.h>

#include <cstdio>
#include <exception>
#include <string>

int main(int argc, char** argv) {
    // lavapipe bins every frame's triangles into freshly allocated scene memory (tens of MB
    // for 200k triangles); with glibc's default trimming that memory goes back to the
    // kernel after each frame and is page-faulted in again on the next: 10k faults and
    // ~20 ms of CPU per knot_hd frame. Keep freed memory in the process instead.
    mallopt(M_TRIM_THRESHOLD, 1 << 30);
    mallopt(M_MMAP_THRESHOLD, 32 << 20);
    specula::view::ViewerConfig c;
    CLI::App app{"specula-view: show a Specula bundle (.glb) under a point light in a window, with the same raster passes\n"
                 "as `specula render`. Mouse: left drag orbits, right/middle drag pans, wheel zooms, shift + left drag\n"
                 "(or the arrow keys) moves the light. Keys: 1 diffuse, 2 specular, 3 both, F factorized/analytic,\n"
                 "P deferred/fused/separate passes, S shadows on/off, C captured photograph (with --capture), R reset, H help, Q/Esc quit.\n"
                 "The title shows mode and frame time. It draws direct light only: the light that bounced off the\n"
                 "object itself, which `specula reconstruct` removes from the albedo (--indirect), is not drawn, so\n"
                 "hollows look darker than in the photographs; `specula render --indirect` draws a pose with it (offline,\n"
                 "seconds a pose).\n"
                 "Draws only when something changes (unless --continuous). Without a display, --frames and --bench\n"
                 "render offscreen; interactive use needs a display (or Xvfb: xvfb-run -a specula-view ...)."};
    app.set_version_flag("--version", std::string("specula-view ") + specula::kVersion);
    app.footer("Exit status: 0 success; 1 failure (bad input file, no usable device or display, validation messages\n"
               "when SPECULA_VALIDATION=1); 2 usage error.");
    bool quiet = false;
    bool verbose = false;
    app.add_flag("-q,--quiet", quiet, "Print only warnings and errors");
    app.add_flag("-v,--verbose", verbose, "Print debugging detail (device, culling)");
    app.add_option("bundle", c.bundle, "Bundle written by `specula reconstruct` (.glb)")->required();
    app.add_option("--capture", c.pose.capture, "Capture folder (or its capture.json): start from a frame's camera and light");
    app.add_option("--frame", c.pose.frame, "Frame index in capture.json's frames list (with --capture); C shows its photograph");
    app.add_option("--camera", c.pose.camera, "Free start camera: eye,target,up (9 numbers, world units); default: the object, from the front");
    app.add_option("--light", c.pose.light, "Free start light: x,y,z,intensity or x,y,z,r,g,b; default: above right of the camera");
    app.add_option("--size", c.pose.size, "Window (free camera image) size: N or WxH")->capture_default_str();
    app.add_option("--fov", c.pose.fov, "Free camera vertical field of view, degrees (default 40)");
    app.add_option("--mode", c.mode, "Terms drawn at the start: both, diffuse or specular")
        ->check(CLI::IsMember({"both", "diffuse", "specular"}))
        ->capture_default_str();
    app.add_option("--specular", c.specular, "Specular model at the start: analytic (the lobe) or factorized (G/H cube-maps)")
        ->check(CLI::IsMember({"analytic", "factorized"}))
        ->capture_default_str();
    app.add_option("--passes", c.passes, "How the terms are drawn: deferred (the mesh's interpolated inputs to a G-buffer, then every\n"
                                         "pixel shaded once: fastest on lavapipe with small triangles), fused (one pass summing the\n"
                                         "diffuse and specular terms) or separate (the thesis's two passes, as `specula render` draws\n"
                                         "them); the same image")
        ->check(CLI::IsMember({"deferred", "fused", "separate"}))
        ->capture_default_str();
    app.add_option("--lod", c.lod_max_error_px,
                   "Levels of detail: each patch of the mesh (512 triangles) draws the coarsest simplified version of itself\n"
                   "(meshoptimizer, its border kept, down to 1/8 of the triangles) whose geometric error is at most this many\n"
                   "pixels on screen, unless it holds a silhouette (or, with shadows, a shadow's edge); 0 draws every triangle")
        ->default_val(c.lod_max_error_px)
        ->check(CLI::Range(0.0, 100.0));
    app.add_option("--lod-psnr", c.lod_min_psnr_db,
                   "Levels of detail are kept only where they look like the whole mesh: rendered at the start size on 4 poses,\n"
                   "a level scoring under this display PSNR (dB) against the whole mesh's render is left out with every coarser one\n"
                   "(coarser triangles interpolate the atlas coordinates and normals over larger spans: texture edges and\n"
                   "highlights move at any distance)")
        ->default_val(c.lod_min_psnr_db)
        ->check(CLI::Range(0.0, 200.0));
    app.add_flag("--shadows,!--no-shadows", c.shadows,
                 "Start with cast shadows (a shadow map; off by default here: it costs a second pass over every triangle "
                 "whenever the light moves; key S toggles). --no-shadows: the thesis's unshadowed render (the default)");
    app.add_option("-d,--device", c.device, "Vulkan device: index or name substring (see `specula devices`)");
    app.add_option("--frames", c.frames, "Headless: draw N frames of the start view, then exit (offscreen when there is no display)");
    app.add_option("--screenshot", c.screenshot, "With --frames: save the last frame (.png: what the window shows, sRGB 8-bit; .exr: linear float)");
    app.add_flag("--bench", c.bench, "Time frames over a fixed path (one turn of the camera, one of the light) and print the median\n"
                                     "and percentiles; the window presents unpaced (mailbox/immediate) when the surface allows");
    app.add_option("--bench-frames", c.bench_frames, "Timed frames of --bench (after 8 warm-up frames)")->capture_default_str();
    app.add_flag("--continuous", c.continuous, "Draw frames continuously, not only when input changes something");
    app.add_flag("--offscreen", c.offscreen, "Never open a window (with --frames or --bench)");
    app.add_flag("--photo", c.photo, "Start showing the captured photograph of --frame (as after pressing C)");
    app.add_option("--resize-to", c.resize_to, "Headless tests: resize the window to WxH after the first of --frames")
        ->group("Testing");
    try {
        app.parse(argc, argv);
        if (quiet) specula::log::set_level(specula::log::Level::Quiet);
        if (verbose) specula::log::set_level(specula::log::Level::Verbose);
        specula::view::run_viewer(c);
        return 0;
    } catch (const CLI::ParseError& e) {
        return app.exit(e) == 0 ? 0 : 2; // --help and --version exit 0
    } catch (const specula::UsageError& e) {
        std::fprintf(stderr, "usage error: %s\n", e.what());
        return 2;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "error: %s\n", e.what());
        return 1;
    }
}
