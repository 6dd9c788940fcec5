// Evaluate time per frame (render + metrics) of a truth bundle against a synthetic
// capture (run by hand, not a ctest): build/bench/evaluate_bench [preset] [size]
#include "capture/capture.h"
#include "evaluate/evaluate.h"
#include "gpu/context.h"
#include "synth/presets.h"
#include "synth/synth.h"

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

int main(int argc, char** argv) {
    using namespace specula;
    const std::string name = argc > 1 ? argv[1] : "can";
    const int size = argc > 2 ? std::atoi(argv[2]) : 512;
    const synth::Preset preset = synth::make_preset(name);
    const std::filesystem::path dir = std::filesystem::temp_directory_path() / ("specula_evaluate_bench_" + name);
    synth::SynthOptions o;
    o.size = size;
    o.views = 4;
    o.lights = 2;
    o.test_views = 1;
    o.test_lights = 2;
    o.format = synth::ImageFormat::Exr;
    o.force = true;
    (void)synth::write_synthetic_capture(synth::to_object(preset), dir, o);
    const Capture capture = load_capture(dir);
    Bundle b;
    b.mesh = preset.mesh;
    b.albedo = preset.material.albedo_texture;
    b.material.specular = preset.material.lobe;
    gpu::Context ctx;
    std::printf("%s, %dx%d, %zu triangles, device %s\n", name.c_str(), size, size, preset.mesh.triangle_count(),
                ctx.info().name.c_str());
    for (const auto backend : {Backend::Vulkan, Backend::Cpu})
        for (const bool hausdorff : {true, false}) {
            evaluate::EvaluateOptions eo{.metrics_backend = backend, .progress = false};
            eo.metrics.hausdorff = hausdorff;
            const evaluate::EvaluationResult r = evaluate::evaluate(ctx, b, capture, eo);
            std::printf("metrics %s%s:\n%s", to_string(backend), hausdorff ? "" : " (no hausdorff)",
                        evaluate::format_summary(r).c_str());
        }
    std::filesystem::remove_all(dir);
    return 0;
}
