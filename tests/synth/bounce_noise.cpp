// bounce_noise: the time and the Monte Carlo noise of one interreflection frame (render.h,
// Interreflection), the figures docs/pipeline.md section 12 quotes.
//   bounce_noise [PRESET [SIZE [BOUNCES [SAMPLES [VIEW [LIGHT [THREADS]]]]]]]
//   (defaults: knot 512 2 <the default samples> 0 0 2; LAMBERTIAN=1: the preset without its
//   lobe; COSINE_ONLY=1: Interreflection::lobe_sampling off)
// Renders frame (VIEW, LIGHT) of the default spread rig once with direct light only and twice
// with BOUNCES bounces and SAMPLES paths per pixel, seeds 1 and 2, and prints seconds per frame
// and, in 8-bit display codes (sRGB of the value clipped at 1, times 255), over the mask: the
// RMS of the difference of the two seeds (sqrt(2) x one image's noise), its 99th percentile,
// and the mean light the bounces add; the same over the pixels where the bounces add at least
// 10 % (the concave parts, where interreflections matter).
#include "core/image.h"
#include "core/timer.h"
#include "synth/presets.h"
#include "synth/render.h"
#include "synth/rig.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <string>
#include <vector>

using namespace specula;
using namespace specula::synth;

namespace {

struct Stats {
    std::size_t pixels = 0;
    double sum_sq = 0.0, added = 0.0;
    std::vector<double> diffs;
    void add(double diff, double add) {
        ++pixels;
        sum_sq += diff * diff;
        added += add;
        diffs.push_back(std::abs(diff));
    }
    void print(const char* what) {
        if (pixels == 0) {
            std::printf("  %-28s no pixels\n", what);
            return;
        }
        std::sort(diffs.begin(), diffs.end());
        const double rms = std::sqrt(sum_sq / static_cast<double>(pixels));
        std::printf(
            "  %-28s %7zu values: seed difference RMS %.3f codes (one image's noise %.3f), p99 %.3f; bounces add %.2f codes\n",
            what, pixels, rms, rms / std::sqrt(2.0), diffs[diffs.size() * 99 / 100], added / static_cast<double>(pixels));
    }
};

double code(float linear) { return 255.0 * linear_to_srgb(std::clamp(linear, 0.0f, 1.0f)); }

} // namespace

int main(int argc, char** argv) {
    const std::string preset = argc > 1 ? argv[1] : "knot";
    const int size = argc > 2 ? std::atoi(argv[2]) : 512;
    const int bounces = argc > 3 ? std::atoi(argv[3]) : 2;
    const int samples = argc > 4 ? std::atoi(argv[4]) : Interreflection{}.samples;
    const int view = argc > 5 ? std::atoi(argv[5]) : 0;
    const int light = argc > 6 ? std::atoi(argv[6]) : 0;
    const int threads = argc > 7 ? std::atoi(argv[7]) : 2;

    const bool lambertian = std::getenv("LAMBERTIAN") != nullptr;
    const Preset p = make_preset(preset, lambertian);
    RigOptions ro;
    ro.size = size;
    const Rig rig = make_rig(p.mesh, ro);
    const RigView& v = rig.views.at(static_cast<std::size_t>(view));
    const PointLight& l = v.lights.at(static_cast<std::size_t>(light));
    const Renderer renderer(p.mesh, p.material);

    Stopwatch sw;
    const RenderedFrame direct = renderer.render(v.camera, l, threads);
    const double direct_seconds = sw.seconds();
    Interreflection ir{.bounces = bounces, .samples = samples, .seed = 1, .frame = 0};
    ir.lobe_sampling = std::getenv("COSINE_ONLY") == nullptr;
    sw.restart();
    const std::clock_t cpu_start = std::clock();
    const RenderedFrame a = renderer.render(v.camera, l, threads, ir);
    const double seconds = sw.seconds();
    // Processor time of all threads: on a busy machine, seconds / threads is what an idle one would take.
    const double cpu_seconds = static_cast<double>(std::clock() - cpu_start) / CLOCKS_PER_SEC;
    ir.seed = 2;
    const RenderedFrame b = renderer.render(v.camera, l, threads, ir);

    Stats all, concave;
    for (int y = 0; y < size; ++y)
        for (int x = 0; x < size; ++x) {
            if (!a.mask[static_cast<std::size_t>(y) * size + x]) continue;
            for (int c = 0; c < 3; ++c) {
                const double diff = code(a.color.at(x, y, c)) - code(b.color.at(x, y, c));
                const double add = code(a.color.at(x, y, c)) - code(direct.color.at(x, y, c));
                all.add(diff, add);
                if (a.color.at(x, y, c) >= 1.1f * direct.color.at(x, y, c) && a.color.at(x, y, c) > 0.0f) concave.add(diff, add);
            }
        }
    std::printf("%s%s %d px, view %d light %d, %d bounces x %d samples%s, %d threads: %.2f s per frame, %.2f s of processor time "
                "(direct light only %.3f s)\n",
                preset.c_str(), lambertian ? " (lambertian)" : "", size, view, light, bounces, samples,
                ir.lobe_sampling ? "" : " (cosine only)", threads, seconds, cpu_seconds, direct_seconds);
    all.print("masked");
    concave.print("where bounces add >= 10%");
    return 0;
}
