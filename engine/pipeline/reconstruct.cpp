#include "pipeline/reconstruct.h"

#include "core/error.h"
#include "core/file_util.h"
#include "core/log.h"
#include "core/output_dir.h"
#include "pipeline/report.h"
#include "pipeline/run.h"
#include "pipeline/stages.h"

namespace specula {

const char* to_string(SpecularMode mode) noexcept {
    switch (mode) {
    case SpecularMode::Auto: return "auto";
    case SpecularMode::On: return "on";
    case SpecularMode::Off: return "off";
    }
    return "?";
}

namespace {

// An earlier result of reconstruct: its report.json, which names specula's version.
bool holds_reconstruct_result(const std::filesystem::path& out) {
    std::error_code ec;
    const std::filesystem::path report = out / "report.json";
    if (!std::filesystem::is_regular_file(report, ec)) return false;
    try {
        return read_text_file(report).find("\"specula_version\"") != std::string::npos;
    } catch (const Error&) {
        return false;
    }
}

} // namespace

ReconstructResult reconstruct(const ReconstructConfig& config, const Capture* preloaded) {
    if (config.out_dir.empty()) throw UsageError("no output folder given");
    const Stopwatch total;
    // The output folder is checked, locked and staged before any stage runs; every stage
    // writes into the staging folder (run.config.out_dir), moved into place at the end.
    const std::vector<std::filesystem::path> inputs =
        capture_input_paths(preloaded != nullptr ? preloaded->desc : read_capture_desc(config.capture));
    OutputFolder out(config.out_dir, {.option = "--out", .force = config.force, .is_previous = holds_reconstruct_result,
                                      .inputs = inputs});
    for (const std::string& line : out.recovered()) log::info(line);
    ReconstructConfig staged = config;
    staged.out_dir = out.staging();
    ReconstructResult result;
    PipelineRun run(staged, result);

    std::optional<Capture> loaded;
    const Capture& capture = load_stage(run, preloaded, loaded);
    const LambertOptions lambert = plan_stage(run, capture);
    const GeometryStage geometry = geometry_stage(run, capture);
    VisibilityStage visibility = visibility_stage(run, capture, geometry); // the indirect stage completes its lit bits
    DiffuseStage diffuse = diffuse_stage(run, capture, geometry, visibility, lambert);
    IndirectStage indirect = indirect_stage(run, capture, geometry, visibility, diffuse); // may correct `diffuse`'s images
    // The views' pixel hits (12 bytes a pixel, 42 MB on the knot at 384 px): the indirect
    // measure's atlas maps took them; the pixel fit takes them, released after it.
    const auto release_pixel_hits = [&] { decltype(visibility.visibility.pixel_hits)().swap(visibility.visibility.pixel_hits); };
    if (config.refine_method != RefineMethod::Pixels) release_pixel_hits();
    const SpecularStage specular = specular_stage(run, diffuse, display_is_srgb(capture)); // joint rounds update `diffuse`
    indirect_update_stage(run, capture, geometry, visibility, specular, indirect, diffuse);
    atlas_decision(run, geometry);
    const RefineStage refine = refine_stage(run, capture, geometry, visibility, diffuse);
    release_pixel_hits();
    const AlbedoTexture texture = texture_stage(run, geometry, diffuse, refine);
    const NormalMapStage normals = normal_map_stage(run, geometry, diffuse);
    const FactorizationStage factorization = factorization_stage(run, specular);
    record_specular_cost(run, specular, factorization);
    const Bundle bundle = bundle_stage(run, capture, geometry, texture, factorization, normals, indirect, specular);
    const std::unique_ptr<evaluate::IndirectLightAdder> indirect_light =
        indirect_light_of(indirect, geometry, visibility, texture, factorization);
    // The viewer evaluation's frames drawn by the evaluation beside its own (one G-buffer and shadow map each).
    std::map<std::size_t, render::Frame> core_renders;
    const std::optional<evaluate::EvaluationResult> evaluation =
        evaluation_stage(run, capture, bundle, indirect_light.get(), &core_renders);
    const std::optional<evaluate::EvaluationResult> viewer = viewer_stage(run, capture, bundle, evaluation, &core_renders);

    result.total_seconds = total.seconds();
    result.report = report_json(run, ReportInputs{.capture = capture,
                                                  .preloaded = preloaded != nullptr,
                                                  .geometry = geometry,
                                                  .visibility = visibility,
                                                  .diffuse = diffuse,
                                                  .indirect = indirect,
                                                  .specular = specular,
                                                  .refine = refine,
                                                  .texture = texture,
                                                  .normals = normals,
                                                  .factorization = factorization,
                                                  .bundle = bundle,
                                                  .evaluation = evaluation,
                                                  .viewer = viewer});
    write_reports(run, result.report);
    out.commit();
    return result;
}

} // namespace specula
