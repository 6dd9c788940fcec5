// specula evaluate BUNDLE CAPTURE: maps options onto EvaluateOptions, runs
// evaluate::evaluate (engine/evaluate/evaluate.h), prints the summary table and
// writes the JSON.
#include "commands.h"

#include "capture/capture.h"
#include "core/error.h"
#include "core/file_util.h"
#include "core/format.h"
#include "core/image.h"
#include "core/log.h"
#include "core/output_dir.h"
#include "evaluate/bundle_render.h"
#include "evaluate/evaluate.h"
#include "evaluate/indirect_light.h"
#include "export/bundle.h"
#include "gpu/context.h"

#include <cstdint>
#include <cstdio>
#include <fstream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace specula::cli {

namespace {

struct EvaluateArgs {
    std::string bundle;
    std::string capture;
    std::string json;
    std::string sheets;
    std::vector<std::size_t> sheet_frames;
    std::size_t frames = 0;
    std::string mode = "both";
    std::string specular = "analytic";
    bool no_shadows = false;
    double lod = 0.0;
    double lod_psnr = render::kDefaultLodMinPsnrDb;
    unsigned factor_terms = 0;
    std::string metrics = "auto";
    bool no_hausdorff = false;
    int threads = 2;
    std::string device;
    std::string renders;
    IndirectArgs indirect;
};

// An earlier --sheets folder: nothing but sheet_*.png files.
bool holds_only_sheets(const std::filesystem::path& dir) {
    std::error_code ec;
    for (std::filesystem::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
        const std::string name = it->path().filename().string();
        if (!it->is_regular_file(ec) || name.rfind("sheet_", 0) != 0 || it->path().extension() != ".png") return false;
    }
    return !ec;
}

void run_evaluate(const EvaluateArgs& a) {
    evaluate::EvaluateOptions o;
    o.render.mode = a.mode == "diffuse" ? render::Mode::Diffuse : a.mode == "specular" ? render::Mode::Specular : render::Mode::Both;
    o.render.specular = a.specular == "factorized" ? render::SpecularPath::Factorized : render::SpecularPath::Analytic;
    o.render.shadows = !a.no_shadows;
    o.renderer.lod_max_error_px = a.lod;
    o.renderer.cluster_culling = a.lod > 0.0; // as specula-view draws them: patches by the view (the same pixels otherwise)
    o.lod_min_psnr_db = a.lod_psnr;
    o.metrics.hausdorff = !a.no_hausdorff;
    o.max_frames_per_split = a.frames;
    o.threads = static_cast<unsigned>(a.threads);
    o.sheet_frames = a.sheet_frames;
    o.bundle_name = a.bundle;
    o.core_material = a.specular == "core";
    // The sheets folder is written as a whole (core/output_dir.h), checked and locked before
    // any work: it may not hold the bundle or the capture, and replaces only an earlier one.
    std::optional<OutputFolder> sheets;
    if (!a.sheets.empty()) {
        std::vector<std::filesystem::path> inputs = capture_input_paths(read_capture_desc(a.capture));
        inputs.emplace_back(a.bundle);
        sheets.emplace(a.sheets, OutputFolderOptions{.option = "--sheets", .is_previous = holds_only_sheets, .inputs = inputs});
        for (const std::string& line : sheets->recovered()) log::info(line);
        o.sheet_dir = sheets->staging();
    }

    Bundle bundle = read_bundle(a.bundle);
    evaluate::require_specular_model(bundle, o.render.specular, a.bundle);
    if (a.factor_terms != 0) { // the first K terms of the bundle's factorization
        const std::size_t held = bundle.material.factorized ? bundle.material.factorized->terms.size() : 0;
        if (a.factor_terms > held)
            throw UsageError("--factor-terms " + std::to_string(a.factor_terms) + ": " + a.bundle + " holds " +
                             std::to_string(held) + " factorization term(s)");
        bundle.material.factorized->terms.resize(a.factor_terms);
    }
    const Capture capture = load_capture(a.capture, {.load_mesh = false, .load_images = true, .threads = a.threads});
    for (const std::string& w : capture.warnings) log::warn(w);
    if (!a.renders.empty()) {
        // Another tool's renders (tools/threejs-render.mjs): RENDERS/<the frame's image stem>.pfm
        // or .exr, linear; the frames without one are left out.
        const std::filesystem::path dir = a.renders;
        if (!std::filesystem::is_directory(dir)) throw UsageError("--renders " + a.renders + ": not a folder");
        o.external_render = [dir, &capture](std::size_t frame) -> std::optional<Image> {
            const std::string stem = capture.desc.frames[frame].file_path.stem().string();
            for (const char* ext : {".pfm", ".exr"}) {
                const std::filesystem::path file = dir / (stem + ext);
                if (std::filesystem::is_regular_file(file)) return read_image(file, ColorSpace::Linear, "--renders");
            }
            return std::nullopt;
        };
    }
    gpu::Context ctx(gpu::ContextOptions{.device = a.device});
    o.metrics_backend = a.metrics == "cpu"      ? Backend::Cpu
                        : a.metrics == "vulkan" ? Backend::Vulkan
                                                : evaluate::metrics_backend_for(ctx);
    // The light that bounced off the object (evaluate/indirect_light.h), from the bundle alone.
    std::optional<evaluate::BundleIndirectLight> indirect;
    evaluate::BundleIndirectOptions io;
    if (a.renders.empty() && a.specular != "core" && a.indirect.wanted(bundle)) {
        io = a.indirect.options(bundle, static_cast<unsigned>(a.threads));
        const VisibilityInputs in = visibility_inputs(capture);
        log::info(format_text("indirect light: %.0f bounces, %.0f rays a row, blocks of %.0f x %.0f texels, from the bundle's "
                              "texture coordinates",
                              double(io.bounces), double(io.rays), double(io.block), double(io.block)) +
                  (a.indirect.mode == "auto" ? std::string(" (the bundle's albedo had it removed; --indirect off leaves it out)")
                                        : std::string()));
        indirect.emplace(bundle, in.views, in.lights, in.frame_view, io);
        indirect->expect(evaluate::evaluated_frames(capture.desc, o)); // its batches: the frames scored
        const evaluate::BundleIndirectStats& st = indirect->stats();
        log::info(format_text("indirect light: %.0f particles in %.0f charts, %.0f rows, %.0f entries; set up in %.1f s (atlas %.1f, "
                              "visibility %.1f, transfer %.1f, view maps %.1f)",
                              double(st.particles), double(st.charts), double(st.rows), double(st.entries), st.setup_s(), st.atlas_s,
                              st.visibility_s, st.transfer_s, st.view_maps_s));
        o.add_light = [&indirect](std::size_t frame, Image& rendered) { indirect->add(frame, rendered); };
    } else {
        log::info(!a.renders.empty()  ? "indirect light: left out: the renders are another tool's (--renders)"
                  : a.specular == "core" ? "indirect light: left out: an ordinary viewer draws direct light only (--specular core)"
                  : a.indirect.mode == "off" ? "indirect light: left out (--indirect off): the renders are direct light only"
                                      : "indirect light: left out (the bundle's albedo keeps the light that bounced off the object, "
                                        "so a direct-only render shows it; --indirect on adds it anyway)");
    }
    evaluate::EvaluationResult r = evaluate::evaluate(ctx, bundle, capture, o);
    if (indirect) log::info(format_text("indirect light: %.1f s for the frames' light", indirect->light_seconds()));
    for (const std::string& w : r.warnings) log::warn(w);
    std::fputs(evaluate::format_summary(r).c_str(), stdout);
    if (sheets) {
        sheets->commit();
        for (auto& s : r.sheets) s = sheets->path() / s.filename(); // where they are now
    }
    if (!a.json.empty()) {
        nlohmann::json j = evaluate::to_json(r, std::filesystem::path(a.json).parent_path());
        j["timings"]["capture_load_s"] = capture.load_seconds;
        if (indirect) {
            const evaluate::BundleIndirectStats& st = indirect->stats();
            j["indirect"] = {{"added", true},
                             {"method", "transfer between the particles of the bundle's own atlas (indirect/indirect.h)"},
                             {"bounces", io.bounces},
                             {"rays_per_row", io.rays},
                             {"block_texels", io.block},
                             {"particles", st.particles},
                             {"rows", st.rows},
                             {"entries", st.entries},
                             {"setup_s", st.setup_s()},
                             {"visibility_s", st.visibility_s},
                             {"transfer_s", st.transfer_s},
                             {"light_s", indirect->light_seconds()}};
        } else {
            j["indirect"] = {{"added", false}};
        }
        write_text_file(a.json, j.dump(2) + "\n");
        log::info("wrote " + a.json);
    }
    for (const auto& s : r.sheets) log::info("wrote " + s.string());
}

} // namespace

void add_evaluate_command(CLI::App& app) {
    auto a = std::make_shared<EvaluateArgs>();
    CLI::App* cmd = app.add_subcommand(
        "evaluate",
        "Re-render every frame of a capture from a bundle and compare (thesis chapter 5: Q1, Q2, RMS%, DDE%, NCC,\n"
        "L1, L2, Hausdorff, PSNR, SSIM) over the object's pixels (the mask) and the full frame, per split (train/test).\n"
        "Q1, RMS and PSNR are given on linear values and on display values (both images in the capture's own\n"
        "encoding, e.g. sRGB 8-bit: the figures the field reports), display first for sRGB captures.");
    cmd->add_option("bundle", a->bundle, "Bundle written by reconstruct (.glb)")->required();
    cmd->add_option("capture", a->capture, "Capture folder, or its capture.json")->required();
    cmd->add_option("--json", a->json,
                    "Write the aggregates (train/test x masked/full) and per-frame measures here (psnr_display, psnr_linear, ...)");
    cmd->add_option("--sheets", a->sheets,
                    "Write captured | rendered | difference sheets (PNG) into this folder; difference = 0.5 + 4 x (rendered -\n"
                    "captured) in sRGB display values. The folder is written as a whole (it replaces an earlier sheets\n"
                    "folder only once complete) and may not hold the bundle or the capture");
    cmd->add_option("--sheet-frames", a->sheet_frames, "Frames to make sheets of (default: the first train and first test frame)")
        ->delimiter(',');
    cmd->add_option("--frames", a->frames, "At most N frames per split, evenly spaced (default: all)");
    cmd->add_option("--mode", a->mode, "Terms rendered: both, diffuse or specular")
        ->check(CLI::IsMember({"both", "diffuse", "specular"}))
        ->capture_default_str();
    cmd->add_option("--specular", a->specular,
                    "Specular model: analytic (the lobe), factorized (the bundle's G/H cube-maps), or core (the bundle's glTF\n"
                    "core material with glTF's BRDF as three.js draws it, direct light only: what ordinary viewers show)")
        ->check(CLI::IsMember({"analytic", "factorized", "core"}))
        ->capture_default_str();
    cmd->add_flag("--no-shadows", a->no_shadows,
                  "Render without cast shadows: the thesis's unshadowed render (default: shadow-mapped, like the captures)");
    cmd->add_option("--lod", a->lod,
                    "Draw levels of detail as specula-view does (its --lod): each patch of the mesh at the coarsest simplified\n"
                    "level whose geometric error is at most this many pixels, unless it holds a silhouette or a shadow's edge,\n"
                    "among the levels that score at least --lod-psnr against the whole mesh on 4 of the evaluated frames;\n"
                    "0, the default, draws every triangle")
        ->check(CLI::Range(0.0, 100.0));
    cmd->add_option("--lod-psnr", a->lod_psnr, "With --lod: the display PSNR (dB) under which a level is left out")
        ->capture_default_str()
        ->check(CLI::Range(0.0, 200.0));
    cmd->add_option("--factor-terms", a->factor_terms,
                    "With --specular factorized: render the first K terms of the bundle's factorization (default: all)")
        ->check(CLI::Range(1, 4));
    cmd->add_option("--metrics", a->metrics,
                    "Where the measures are computed: vulkan (the kernels), cpu (the C++ reference), or auto: cpu on a CPU\n"
                    "Vulkan driver such as lavapipe (4 to 9 times faster there), vulkan on a GPU")
        ->check(CLI::IsMember({"auto", "vulkan", "cpu"}))
        ->capture_default_str();
    cmd->add_flag("--no-hausdorff", a->no_hausdorff, "Skip the Hausdorff distance (the costliest measure on unrelated images)");
    add_indirect_options(cmd, a->indirect, "Seconds to a minute on 2 cores; the JSON gives\n"
                                 "the figures without it too (without_added_light)");
    cmd->add_option("--threads", a->threads, "Threads for image decoding, the indirect light and the C++ metrics (--metrics cpu)")->check(CLI::Range(1, 256))->capture_default_str();
    cmd->add_option("--renders", a->renders,
                    "Score another tool's renders instead of the bundle's own: this folder's <image stem>.pfm or .exr\n"
                    "(linear, the frame's size), e.g. three.js's from tools/threejs-render.mjs; frames without a file are\n"
                    "left out, and so is the indirect light (an ordinary viewer draws direct light only)");
    cmd->add_option("-d,--device", a->device, "Vulkan device: index or name substring (see `specula devices`)");
    cmd->callback([a] { run_evaluate(*a); });
}

} // namespace specula::cli
