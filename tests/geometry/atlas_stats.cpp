// Atlas figures (run by hand, not a ctest): builds the atlas of a capture's mesh from its
// train cameras, or of a preset's mesh by surface area, and prints the summary and the
// time taken, for the README's and pipeline.md's tables.
//   atlas_stats charts|patchwork CAPTURE [TEXELS_PER_PIXEL] [--png FILE]
//   atlas_stats charts|patchwork --preset NAME [--png FILE]
// --png writes the owner map: each chart (or patch) in its own colour, gutters darker.
#include "capture/capture.h"
#include "core/error.h"
#include "core/image.h"
#include "core/timer.h"
#include "geometry/atlas.h"
#include "synth/presets.h"

#include <cstdio>
#include <string>

using namespace specula;

int main(int argc, char** argv) try {
    if (argc < 3) {
        std::fprintf(stderr, "usage: atlas_stats charts|patchwork CAPTURE [TEXELS_PER_PIXEL] | --preset NAME\n");
        return 2;
    }
    AtlasOptions options;
    const auto mode = atlas_mode_from_string(argv[1]);
    if (!mode) throw UsageError("mode must be charts or patchwork");
    options.mode = *mode;
    std::string png;
    for (int i = 3; i + 1 < argc; ++i)
        if (std::string(argv[i]) == "--png") {
            png = argv[i + 1];
            argc = i;
        }
    Mesh mesh;
    std::vector<Camera> cams;
    if (std::string(argv[2]) == "--preset") {
        if (argc < 4) throw UsageError("--preset needs a name");
        mesh = synth::make_preset(argv[3]).mesh;
    } else {
        const Capture capture = load_capture(argv[2]);
        mesh = capture.mesh;
        for (const View& view : capture.views)
            for (std::size_t f : view.frames)
                if (capture.desc.frames[f].split == Split::Train) {
                    cams.push_back(view.camera);
                    break;
                }
        if (argc > 3) options.texels_per_pixel = std::stod(argv[3]);
    }
    const Stopwatch sw;
    const Atlas atlas = build_atlas(mesh, cams, options);
    std::printf("%s  built in %.2f s\n", describe(atlas.summary).c_str(), sw.seconds());
    if (!png.empty()) {
        Image img(static_cast<int>(atlas.width), static_cast<int>(atlas.height), 3, 0.0f);
        for (std::uint32_t y = 0; y < atlas.height; ++y)
            for (std::uint32_t x = 0; x < atlas.width; ++x) {
                const std::uint32_t o = atlas.owner_at(x, y);
                if (o == Atlas::kEmpty) continue;
                const std::uint32_t id = atlas.mode == AtlasMode::Charts ? atlas.chart_of[o] : o;
                const std::uint32_t h = (id + 1) * 2654435761u;
                const bool inside = in_patch(atlas.patch_bary(o, {x + 0.5, y + 0.5}));
                for (int c = 0; c < 3; ++c)
                    img.at(int(x), int(y), c) = (0.25f + 0.75f * float((h >> (8 * c)) & 255u) / 255.0f) * (inside ? 1.0f : 0.4f);
            }
        write_image(png, img, ColorSpace::Srgb, 8);
    }
    return 0;
} catch (const std::exception& e) {
    std::fprintf(stderr, "atlas_stats: %s\n", e.what());
    return 1;
}
