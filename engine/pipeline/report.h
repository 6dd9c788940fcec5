#pragma once
// report.json from the stages' outputs (pipeline/stages.h): what ran, how long it took, what it
// measured and what it left out, and report.html from it (engine/report). The keys are
// documented in docs/pipeline.md section 8.
#include "pipeline/stages.h"

#include <nlohmann/json.hpp>

#include <optional>

namespace specula {

/// Everything report.json describes, by reference to the stages' outputs.
struct ReportInputs {
    const Capture& capture;
    bool preloaded = false;
    const GeometryStage& geometry;
    const VisibilityStage& visibility;
    const DiffuseStage& diffuse;
    const IndirectStage& indirect;
    const SpecularStage& specular;
    const RefineStage& refine;
    const AlbedoTexture& texture;
    const NormalMapStage& normals;
    const FactorizationStage& factorization;
    const Bundle& bundle;
    const std::optional<evaluate::EvaluationResult>& evaluation;
    /// The core material as ordinary viewers draw it (viewer_stage), when evaluated.
    const std::optional<evaluate::EvaluationResult>& viewer;
};

/// The content of report.json (run.result.total_seconds must be set).
[[nodiscard]] nlohmann::json report_json(PipelineRun& run, const ReportInputs& in);

/// Writes report.html (unless config.write_html is off), then report.json last: its presence
/// means the outputs of the run are complete.
void write_reports(const PipelineRun& run, const nlohmann::json& report);

} // namespace specula
