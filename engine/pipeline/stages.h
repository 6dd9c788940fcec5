#pragma once
// The stages of `specula reconstruct`, one function each, in pipeline order (docs/pipeline.md).
// Each takes the run (pipeline/run.h: configuration, timing, plan, devices, what was left out)
// and the typed outputs of earlier stages, and returns its own output; reconstruct() calls them
// in order and pipeline/report.h turns their outputs into report.json. A stage asks the planner
// (pipeline/planner.h) what the scene needs and records the decision with its cost.
#include "capture/capture.h"
#include "diffuse/albedo_texture.h"
#include "diffuse/lambert_solve.h"
#include "evaluate/evaluate.h"
#include "evaluate/indirect_light.h"
#include "export/bundle.h"
#include "factorization/factorization.h"
#include "geometry/atlas.h"
#include "geometry/particles.h"
#include "geometry/ray_scene.h"
#include "indirect/indirect.h"
#include "pipeline/joint.h"
#include "pipeline/planner.h"
#include "pipeline/run.h"
#include "refine/albedo_refine.h"
#include "refine/pixel_fit.h"
#include "specular/core_fit.h"
#include "specular/lafortune_fit.h"
#include "specular/residuals.h"
#include "visibility/visibility.h"

#include <cstddef>
#include <functional>
#include <memory>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace specula {

/// 1. The capture (its mesh and images), or the preloaded one (the sweep loads once).
const Capture& load_stage(PipelineRun& run, const Capture* preloaded, std::optional<Capture>& storage);

/// 2. The plan from the capture alone: can the mesh occlude itself (occlusion rays), do the
///    lights allow the photometric solve. Returns the diffuse solve's options with the mode set.
[[nodiscard]] LambertOptions plan_stage(PipelineRun& run, const Capture& capture);

/// 3. The atlas (sized by the train views) and its texel centres, the surface particles.
struct GeometryStage {
    Atlas atlas;
    ParticleSet particles;
};
[[nodiscard]] GeometryStage geometry_stage(PipelineRun& run, const Capture& capture);

/// 4. Which views see and which frames light each particle (Embree; occlusion rays only where
///    the plan casts them), the per-view surface maps, and the probe of what skipped rays cost.
struct VisibilityStage {
    VisibilityInputs inputs;
    std::optional<RayScene> scene; ///< built inside the stage (its BVH is part of its cost)
    Visibility visibility;
};
[[nodiscard]] VisibilityStage visibility_stage(PipelineRun& run, const Capture& capture, const GeometryStage& geometry);

/// 5. The diffuse solve. `solve` and `options` are the last solve's: the specular stage's joint
///    rounds replace them (their options then carry the lobe that solve subtracted).
struct DiffuseStage {
    LambertInputs inputs;
    LambertOptions options;
    LambertOutputs solve;
    /// `solve` read the train frames less the validation frames (split_validation_frames), not
    /// all of them: the first solve, where the material's candidates start from that split.
    /// Cleared by every solve of all the train frames.
    bool on_fit_split = false;
};
[[nodiscard]] DiffuseStage diffuse_stage(PipelineRun& run, const Capture& capture, const GeometryStage& geometry,
                                         const VisibilityStage& visibility, const LambertOptions& options);

/// 5b. Light that bounced off the object (planner.h decide_indirect; indirect/indirect.h): where
///     it counts, the transfer and the views' atlas maps are built once, then each round removes
///     from the train frames the indirect light that the current albedo sends, and solves again
///     (Yu et al. 1999). `diffuse` then reads the corrected images, which this stage holds.
struct IndirectRound {
    double albedo_change = 0.0; ///< RMS of the albedo's change over the solved particles, relative to their RMS albedo
    double seconds = 0.0;       ///< the indirect images and the solve
    bool material = false;      ///< the round after the specular stages, with the fitted material's lobe (indirect_update_stage)
    /// Object pixels of the train frames its solve did not use: the light added there is over
    /// kIndirectMaxShare of what they show (planner.h).
    std::size_t pixels_left_out = 0;
};
struct IndirectStage {
    std::optional<IndirectTransfer> transfer;    ///< absent: left out
    TransferStats transfer_stats;
    std::vector<ViewAtlasMap> view_maps;         ///< per view
    std::vector<FrameImage> corrected;           ///< per frame: the train frames less their indirect light
    std::vector<IndirectRound> rounds;
    std::optional<IndirectMeasure> measure;      ///< what the planner decided from (planner.h)
    IndirectOptions options;                     ///< its kernel: `gather`'s, or null (the C++ reference)
    std::shared_ptr<IndirectGatherVk> gather;    ///< the Vulkan gather, on a GPU
    std::shared_ptr<IndirectLobeVk> lobe;        ///< the Vulkan kernel of the directed lobe's first bounce, on a GPU
    std::string backend_reason;                  ///< why the gather and the lobe's term run where they do
    double seconds = 0.0;                        ///< transfer, maps and rounds
    [[nodiscard]] bool on() const noexcept { return transfer.has_value() && !corrected.empty(); }
};
/// Casts the light rays the visibility stage left out (VisibilityOptions::lit_seen_only) for the
/// frames its measure and its rounds read: their emitters need not be seen by the frame's view.
[[nodiscard]] IndirectStage indirect_stage(PipelineRun& run, const Capture& capture, const GeometryStage& geometry,
                                           VisibilityStage& visibility, DiffuseStage& diffuse);


/// 6. Residual samples and their energy, then (when the residuals hold specular energy, or
///    forced) the material: every applicable family (or the forced one) is estimated jointly
///    with the albedo on the train frames less the validation frames (one light of each view,
///    split_validation_frames), scored on those, and the winner of least validation error is
///    estimated again on all the train frames; that last estimate updates `diffuse`.
struct MaterialCandidate {
    MaterialFit fit;                      ///< the last accepted fit on the train frames less the validation frames
    JointResult joint;                    ///< its rounds, each with its validation error
    std::optional<double> validation_mse; ///< of the kept round (image units^2); absent without validation frames
    double seconds = 0.0;                 ///< its solves, residuals, fits and validation passes
    /// Not 0: `fit` is its screen on this many samples, too far behind for a full fit (kScreenFactor).
    std::size_t screen_samples = 0;
};
struct SpecularStage {
    bool residuals_ran = false;           ///< false: --specular off
    ResidualSamples residuals;            ///< the last residual samples' counts and timings (samples dropped)
    ResidualEnergy energy;
    std::optional<MaterialFit> fit;       ///< the winner's fit on all the train frames, when the fit ran
    std::string decision;                 ///< report.json specular.decision
    std::vector<MaterialCandidate> candidates; ///< every family estimated, in MaterialFamily order
    std::string choice;                   ///< why the winner won (or was forced)
    std::size_t validation_frames = 0;    ///< frames held out for the choice and the joint rounds
    /// "Diffuse only" as a candidate (decide_specular "validate": little residual energy, but
    /// validation frames): the validation error of the first solve's albedo with no specular.
    std::optional<double> diffuse_only_mse;
    double fit_seconds = 0.0;             ///< the fits alone (all candidates and the final fit)
    std::size_t fit_samples = 0;          ///< samples of the last fit (stride subsample)
    JointResult joint;                    ///< the final estimate's rounds
    bool final_solve = false;             ///< the albedo was solved once more with the final material (it still moved)
    double seconds = 0.0;                 ///< the candidates, the final fit and its joint rounds
    Backend backend = Backend::Cpu;       ///< where the per-particle passes ran
    /// glTF's core material for ordinary viewers, fitted to the final estimate's samples
    /// (specular/core_fit.h); absent when no material was fitted (the bundle's core is then diffuse only).
    std::optional<CoreFit> core;
};
/// `srgb_display`: the capture's display values are sRGB-encoded (every frame: metrics/display_values.h),
/// so the core material is fitted on them (CoreFitOptions::srgb_display).
[[nodiscard]] SpecularStage specular_stage(PipelineRun& run, DiffuseStage& diffuse, bool srgb_display);

/// Whether every frame's display values are sRGB-encoded (metrics::display_encoding_of).
[[nodiscard]] bool display_is_srgb(const Capture& capture);

/// 6b. After the specular stages, when the indirect light is on and a material was fitted: one
///     more round with the material known (its lobe reflects light between the surfaces too,
///     indirect/indirect.h), which updates `diffuse`'s solve before the refinement.
void indirect_update_stage(PipelineRun& run, const Capture& capture, const GeometryStage& geometry,
                           const VisibilityStage& visibility, const SpecularStage& specular, IndirectStage& indirect,
                           DiffuseStage& diffuse);

/// The atlas decision, once the stages whose cost grows with the particle count have run.
void atlas_decision(PipelineRun& run, const GeometryStage& geometry);

/// 7. Albedo refinement (refine/): the pixel fit, or back-projection through renders of the
///    train frames.
struct RefineStage {
    std::optional<AlbedoRefineResult> refined; ///< absent: left out (0 rounds, no ray scene, or no device)
    RefineMethod method = RefineMethod::Pixels;
    std::uint32_t rounds = 0;
    std::optional<PixelFitStats> pixel_fit;   ///< the pixel fit's counts and residuals
};
[[nodiscard]] RefineStage refine_stage(PipelineRun& run, const Capture& capture, const GeometryStage& geometry,
                                       const VisibilityStage& visibility, const DiffuseStage& diffuse);

/// 8. The albedo texture (inpainting what no view saw), written as albedo.exr and albedo.png.
[[nodiscard]] AlbedoTexture texture_stage(PipelineRun& run, const GeometryStage& geometry, const DiffuseStage& diffuse,
                                          const RefineStage& refine);

/// 8b. Refined normals (planner.h decide_normal_map): the photometric solve with the final
///     material known. The bundle stage encodes them in its mesh's tangent frames
///     (export/normal_map.h) and fills the atlas like the albedo texture. Absent when left out.
struct NormalMapStats {
    std::size_t particles = 0;   ///< particles
    std::size_t refined = 0;     ///< with a photometric normal (the rest keep the mesh's)
    double mean_angle_deg = 0.0; ///< refined vs mesh normal, over the refined interior particles
    double median_angle_deg = 0.0;
    double p95_angle_deg = 0.0;
    double max_angle_deg = 0.0;
};
struct NormalMapStage {
    std::optional<std::vector<glm::vec3>> normals; ///< per particle: its refined normal, else the mesh's
    NormalMapStats stats;
};
[[nodiscard]] NormalMapStage normal_map_stage(PipelineRun& run, const GeometryStage& geometry, const DiffuseStage& diffuse);

/// 9. The chosen material, and its Kautz-McCool factorization on the grid the planner chose
///    from its width, in the parametrization of least error.
struct FactorizationStage {
    std::optional<SpecularModel> material;     ///< absent: no specular (left out, or no usable fit)
    std::vector<std::string> status;           ///< the fit's status words, when fitted
    std::optional<factorization::Factorization> cubes;
    std::vector<factorization::DirectError> per_term; ///< error of the first k terms, k = 1..K
};
[[nodiscard]] FactorizationStage factorization_stage(PipelineRun& run, const SpecularStage& specular);

/// The cost of specular stages that a flag forced on: the fits, the joint rounds and the factorization.
void record_specular_cost(PipelineRun& run, const SpecularStage& specular, const FactorizationStage& factorization);

/// 10. The bundle object.glb: mesh with atlas coordinates, albedo, lobe, cube-maps, and the core
///     material for ordinary viewers (the specular stage's fit; without one, diffuse only).
[[nodiscard]] Bundle bundle_stage(PipelineRun& run, const Capture& capture, const GeometryStage& geometry,
                                  const AlbedoTexture& texture, const FactorizationStage& factorization,
                                  const NormalMapStage& normals, const IndirectStage& indirect, const SpecularStage& specular);

/// 11. Self-evaluation: every test frame and a sample of the train frames (config.evaluate_train_frames)
///     re-rendered from the bundle and scored, with `add_light`'s light added when given (writes
///     evaluation.json and sheets/). Absent when left out (--no-evaluate, or no device). With
///     `core_renders`, the viewer stage's frames among them are drawn with the core material too,
///     right after their own (their G-buffer and shadow map drawn once), into it.
[[nodiscard]] std::optional<evaluate::EvaluationResult> evaluation_stage(PipelineRun& run, const Capture& capture,
                                                                         const Bundle& bundle,
                                                                         evaluate::IndirectLightAdder* add_light = nullptr,
                                                                         std::map<std::size_t, render::Frame>* core_renders = nullptr);

/// 11b. What ordinary viewers show: the bundle's core material rendered (glTF's BRDF as three.js
///      draws it, direct light) on the test frames and at most kViewerTrainFrames train frames,
///      scored like the evaluation; the frames in `core_renders` (the evaluation's) are not drawn
///      again. Absent when the evaluation was left out.
inline constexpr std::size_t kViewerTrainFrames = 8;
[[nodiscard]] std::optional<evaluate::EvaluationResult> viewer_stage(PipelineRun& run, const Capture& capture, const Bundle& bundle,
                                                                     const std::optional<evaluate::EvaluationResult>& evaluation,
                                                                     std::map<std::size_t, render::Frame>* core_renders = nullptr);

/// The indirect light of each frame for the evaluation (evaluate::EvaluateOptions::add_light):
/// from the final albedo texture and material; null when the stage was left out.
[[nodiscard]] std::unique_ptr<evaluate::IndirectLightAdder> indirect_light_of(const IndirectStage& indirect,
                                                                             const GeometryStage& geometry,
                                                                             const VisibilityStage& visibility,
                                                                             const AlbedoTexture& texture,
                                                                             const FactorizationStage& factorization);

} // namespace specula
