// Time of the full metric set (RMS, DDE, L1, L2, CO, PSNR, SSIM, Hausdorff) on one
// captured/rendered pair, CPU reference vs Vulkan, masked and full frame. Not a test.
//   metrics_bench [size=512] [reps=5]
#include "metrics/image_metrics.h"
#include "vulkan_env.h"

#include "core/timer.h"
#include "metrics_scene.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <vector>

using namespace specula;
using namespace specula::metrics;

namespace {

double best_of(int reps, const std::function<void()>& fn) {
    double best = 1e30;
    for (int i = 0; i < reps; ++i) {
        Stopwatch sw;
        fn();
        best = std::min(best, sw.seconds());
    }
    return best;
}

void bench(const char* name, const MetricsInputs& in, int reps, ImageMetricsVk* vk, const MetricsOptions& o = {}) {
    FrameMetrics c, v;
    const double tc = best_of(reps, [&] { c = image_metrics_cpu(in, o); });
    std::printf("%-28s cpu    %8.1f ms   rms %.5f ssim %.5f hd %.5f (exact %d)\n", name, tc * 1e3, c.rms, c.ssim,
                c.hausdorff, c.hausdorff_exact);
    if (vk == nullptr) return;
    (void)vk->run(in, o); // warm-up (buffer allocation)
    const double tv = best_of(reps, [&] { v = vk->run(in, o); });
    std::printf("%-28s vulkan %8.1f ms   (gpu %.1f ms)  rms %.5f ssim %.5f hd %.5f\n", name, tv * 1e3,
                vk->last_gpu_ns().value_or(0.0) * 1e-6, v.rms, v.ssim, v.hausdorff);
}

} // namespace

int main(int argc, char** argv) {
    const int size = argc > 1 ? std::atoi(argv[1]) : 512;
    const int reps = argc > 2 ? std::atoi(argv[2]) : 5;
    const auto pair = test::metrics_pair(size, size, 3, 1);
    gpu::Context* ctx = test::vulkan_context();
    std::unique_ptr<ImageMetricsVk> vk;
    if (ctx) {
        vk = std::make_unique<ImageMetricsVk>(*ctx);
        std::printf("device: %s\n", ctx->info().name.c_str());
    } else {
        std::printf("no Vulkan: %s\n", test::vulkan_unavailable_reason().c_str());
    }
    std::printf("%dx%d RGB, best of %d\n", size, size, reps);
    const MetricsInputs masked{pair.captured, pair.rendered, pair.mask};
    const MetricsInputs full{pair.captured, pair.rendered};
    bench("render pair, masked", masked, reps, vk.get());
    bench("render pair, full frame", full, reps, vk.get());
    MetricsOptions no_hd;
    no_hd.hausdorff = false;
    bench("render pair, full, no HD", full, reps, vk.get(), no_hd);
    // Worst case for the Hausdorff search: unrelated images (black vs white).
    const Image black(size, size, 3, 0.0f), white(size, size, 3, 1.0f);
    bench("black vs white, full", MetricsInputs{black, white}, 1, vk.get());
    return 0;
}
