#include "pipeline/reconstruct.h"

#include "core/error.h"
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

ReconstructResult reconstruct(const ReconstructConfig& config, const Capture* preloaded) {
    if (config.out_dir.empty()) throw UsageError("no output folder given");
    const Stopwatch total;
    ReconstructResult result;
    PipelineRun run(config, result);

    std::optional<Capture> loaded;
    const Capture& capture = load_stage(run, preloaded, loaded);
    const LambertOptions lambert = plan_stage(run, capture);
    const GeometryStage geometry = geometry_stage(run, capture);
    const VisibilityStage visibility = visibility_stage(run, capture, geometry);
    DiffuseStage diffuse = diffuse_stage(run, capture, geometry, visibility, lambert);
    const SpecularStage specular = specular_stage(run, diffuse); // joint rounds update `diffuse`
    atlas_decision(run, geometry);
    const RefineStage refine = refine_stage(run, capture, geometry, diffuse);
    const AlbedoTexture texture = texture_stage(run, geometry, diffuse, refine);
    const FactorizationStage factorization = factorization_stage(run, specular);
    record_specular_cost(run, specular, factorization);
    const Bundle bundle = bundle_stage(run, capture, geometry, texture, factorization);
    const std::optional<evaluate::EvaluationResult> evaluation = evaluation_stage(run, capture, bundle);

    result.total_seconds = total.seconds();
    result.report = report_json(run, ReportInputs{.capture = capture,
                                                  .preloaded = preloaded != nullptr,
                                                  .geometry = geometry,
                                                  .visibility = visibility,
                                                  .diffuse = diffuse,
                                                  .specular = specular,
                                                  .refine = refine,
                                                  .texture = texture,
                                                  .factorization = factorization,
                                                  .bundle = bundle,
                                                  .evaluation = evaluation});
    write_reports(run, result.report);
    return result;
}

} // namespace specula
