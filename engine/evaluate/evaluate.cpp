#include "evaluate/evaluate.h"

#include "core/error.h"
#include "core/file_util.h"
#include "core/log.h"
#include "core/parallel.h"
#include "core/timer.h"
#include "evaluate/bundle_render.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <initializer_list>
#include <iterator>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <span>
#include <sstream>
#include <string>

namespace specula::evaluate {

namespace {

const char* split_name(Split s) { return s == Split::Train ? "train" : "test"; }

/// Display value of a linear one, for the sheet's difference panel.
float display(float linear) { return linear_to_srgb(std::clamp(linear, 0.0f, 1.0f)); }

/// The levels of detail kept: triangles, and each coarser level's display PSNR against the whole mesh.
nlohmann::json lod_levels_json(const EvaluationResult& r) {
    nlohmann::json levels = nlohmann::json::array();
    for (std::size_t k = 0; k < r.lod_levels.size(); ++k) {
        nlohmann::json l{{"triangles", r.lod_levels[k].first}};
        if (k > 0) l["display_psnr_vs_whole_mesh"] = r.lod_levels[k].second;
        levels.push_back(l);
    }
    return levels;
}

nlohmann::json settings_json(const EvaluationResult& r) {
    return {{"mode", render::mode_name(r.render.mode)},
            {"specular", render::specular_path_name(r.render.specular)},
            {"passes", render::passes_name(r.render.passes)},
            {"shadows", r.render.shadows}, // cast shadows drawn (false: the thesis's unshadowed render)
            {"lod_max_error_px", r.lod_max_error_px}, // levels of detail (0: every triangle drawn)
            {"lod_levels", lod_levels_json(r)},
            {"metrics_backend", to_string(r.metrics_backend)},
            {"masked_pixels", "the capture's mask (render coverage where a frame has no mask); missing pixels left out"},
            {"rendered_clipped_at_saturation", true},
            {"display_values", "the capture's own encoding applied to both images: transfer function (sRGB or none), "
                               "clipped to [0, 1], quantized to the file's codes (float files: sRGB, not quantized); G = 1"},
            {"sheet_difference", "0.5 + " + std::to_string(static_cast<int>(kSheetAmplification)) +
                                     " x (rendered - captured), per channel, in sRGB display values"}};
}

double finite_or_zero(double v) { return std::isfinite(v) ? v : 0.0; }

// The display figures beside the linear ones: `keys` of the linear JSON copied with the suffix
// _linear, and the same keys of the display JSON with _display (evaluate.h, to_json).
void add_display_keys(nlohmann::json& linear, const nlohmann::json& display, std::initializer_list<const char*> keys) {
    for (const char* key : keys) {
        linear[std::string(key) + "_linear"] = linear[key];
        linear[std::string(key) + "_display"] = display[key];
    }
}

nlohmann::json summary_json(const metrics::MetricsSummary& linear, const metrics::MetricsSummary& display,
                            const std::string& encoding) {
    nlohmann::json j = metrics::to_json(linear);
    add_display_keys(j, metrics::to_json(display), {"q1", "rms", "rms_percent", "psnr"});
    j["display_encoding"] = encoding;
    return j;
}

nlohmann::json frame_metrics_json(const metrics::FrameMetrics& linear, const metrics::FrameMetrics& display) {
    nlohmann::json j = metrics::to_json(linear);
    add_display_keys(j, metrics::to_json(display), {"rms", "rms_percent", "psnr"});
    return j;
}

} // namespace


std::vector<std::size_t> select_frames(const CaptureDesc& desc, std::size_t max_frames_per_split) {
    std::vector<std::size_t> out;
    for (const Split split : {Split::Train, Split::Test}) {
        std::vector<std::size_t> idx;
        for (std::size_t i = 0; i < desc.frames.size(); ++i)
            if (desc.frames[i].split == split) idx.push_back(i);
        if (max_frames_per_split == 0 || idx.size() <= max_frames_per_split) {
            out.insert(out.end(), idx.begin(), idx.end());
        } else {
            // Evenly spaced: k * n / m for k < m (distinct since m < n), so every view is sampled.
            for (std::size_t k = 0; k < max_frames_per_split; ++k) out.push_back(idx[k * idx.size() / max_frames_per_split]);
        }
    }
    std::sort(out.begin(), out.end());
    return out;
}

std::vector<std::size_t> evaluated_frames(const CaptureDesc& desc, const EvaluateOptions& options) {
    std::vector<std::size_t> frames = select_frames(desc, options.max_frames_per_split);
    const auto is_train = [&](std::size_t f) { return desc.frames[f].split == Split::Train; };
    if (!options.include_train) {
        std::erase_if(frames, is_train);
    } else if (options.max_train_frames > 0) {
        std::vector<std::size_t> train;
        std::copy_if(frames.begin(), frames.end(), std::back_inserter(train), is_train);
        const std::size_t n = train.size(), m = options.max_train_frames;
        if (n > m) {
            std::set<std::size_t> keep;
            for (std::size_t k = 0; k < m; ++k) keep.insert(train[k * n / m]); // distinct since m < n
            std::erase_if(frames, [&](std::size_t f) { return is_train(f) && !keep.contains(f); });
        }
    }
    return frames;
}

Image make_sheet(const Image& captured, const Image& rendered, double amplification) {
    if (captured.width != rendered.width || captured.height != rendered.height)
        throw Error("make_sheet: captured " + std::to_string(captured.width) + "x" + std::to_string(captured.height) +
                    " and rendered " + std::to_string(rendered.width) + "x" + std::to_string(rendered.height) + " differ in size");
    const int w = captured.width, h = captured.height, gap = 4;
    Image sheet(3 * w + 2 * gap, h, 3, 1.0f); // white gaps
    auto channel = [](const Image& im, int x, int y, int c) { return im.at(x, y, im.channels >= 3 ? c : 0); };
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            for (int c = 0; c < 3; ++c) {
                const float a = channel(captured, x, y, c), b = channel(rendered, x, y, c);
                sheet.at(x, y, c) = a;
                sheet.at(w + gap + x, y, c) = b;
                const double d = 0.5 + amplification * (static_cast<double>(display(b)) - display(a));
                // Written through the sRGB encoding: store the linear value whose display value is d.
                sheet.at(2 * (w + gap) + x, y, c) = srgb_to_linear(static_cast<float>(std::clamp(d, 0.0, 1.0)));
            }
    return sheet;
}

Backend metrics_backend_for(const gpu::Context& ctx) noexcept {
    return ctx.info().kind == gpu::DeviceKind::Cpu ? Backend::Cpu : Backend::Vulkan;
}

EvaluationResult evaluate(gpu::Context& ctx, const Bundle& bundle, const Capture& capture, const EvaluateOptions& options) {
    const Stopwatch total;
    const CaptureDesc& desc = capture.desc;
    if (capture.images.size() != desc.frames.size())
        throw Error(desc.dir.string() + ": evaluate needs the capture's images (loaded " + std::to_string(capture.images.size()) +
                    " of " + std::to_string(desc.frames.size()) + ")");
    require_specular_model(bundle, options.render.specular, options.bundle_name);
    if (options.core_renders != nullptr && (options.core_material || options.external_render))
        throw UsageError("evaluate: core_renders goes with the bundle's own renders, not with core_material or external_render");
    for (const std::size_t f : options.sheet_frames)
        if (f >= desc.frames.size())
            throw UsageError("--sheet-frames: frame " + std::to_string(f) + " is out of range (the capture has " +
                             std::to_string(desc.frames.size()) + " frames, 0 to " + std::to_string(desc.frames.size() - 1) + ")");

    EvaluationResult result;
    result.bundle_name = options.bundle_name;
    result.capture_dir = desc.dir.string();
    result.render = options.render;
    result.lod_max_error_px = options.external_render ? 0.0 : options.renderer.lod_max_error_px;
    result.metrics_backend = options.metrics_backend;

    const Stopwatch setup;
    std::optional<BundleRenderer> renderer;
    if (!options.external_render) renderer.emplace(ctx, bundle, options.bundle_name, options.renderer);
    render::Settings render_settings = options.render;
    if (renderer && options.core_material) {
        renderer->draw_core_material(bundle.core);
        render_settings.specular = render::SpecularPath::Analytic;
    }
    result.render = render_settings;
    render::Settings core_settings = options.render; // EvaluateOptions::core_renders: as a core_material evaluation draws them
    core_settings.specular = render::SpecularPath::Analytic;
    std::unique_ptr<metrics::ImageMetricsVk> metrics_vk;
    if (options.metrics_backend == Backend::Vulkan) metrics_vk = std::make_unique<metrics::ImageMetricsVk>(ctx);
    result.timings.setup_s = setup.seconds();
    if (renderer && options.render.mode != render::Mode::Diffuse && !renderer->has_specular())
        result.warnings.push_back(options.bundle_name + ": no specular lobe: frames are rendered diffuse only");

    std::vector<std::size_t> frames = evaluated_frames(desc, options);
    if (renderer && renderer->renderer().levels_of_detail().size() > 1 && !frames.empty()) {
        // The levels kept as specula-view keeps them, scored on 4 of the evaluated frames.
        std::vector<Camera> cameras;
        std::vector<PointLight> lights;
        for (std::size_t i = 0; i < 4; ++i) {
            const FrameDesc& fd = desc.frames[frames[i * frames.size() / 4]];
            cameras.push_back(fd.camera());
            lights.push_back(fd.light);
        }
        render::Renderer& r = renderer->renderer();
        const std::vector<double> psnr = r.accept_levels_of_detail(cameras, lights, render_settings, options.lod_min_psnr_db);
        for (std::size_t k = 0; k < r.accepted_levels_of_detail(); ++k)
            result.lod_levels.emplace_back(r.levels_of_detail()[k].index_count / 3, psnr[k]);
    }
    // Another tool's images: the frames it rendered (read once here, in capture order).
    std::map<std::size_t, Image> external;
    if (options.external_render) {
        for (const std::size_t f : frames)
            if (std::optional<Image> im = options.external_render(f)) external.emplace(f, std::move(*im));
        std::erase_if(frames, [&](std::size_t f) { return !external.contains(f); });
    }
    std::set<std::size_t> sheet_set(options.sheet_frames.begin(), options.sheet_frames.end());
    if (options.sheet_dir && sheet_set.empty()) {
        for (const Split split : {Split::Train, Split::Test}) {
            const auto it = std::find_if(frames.begin(), frames.end(), [&](std::size_t f) { return desc.frames[f].split == split; });
            if (it != frames.end()) sheet_set.insert(*it);
        }
    }
    if (options.sheet_dir) std::filesystem::create_directories(*options.sheet_dir);

    std::vector<metrics::FrameMetrics> train_masked, train_full, test_masked, test_full;
    std::vector<metrics::FrameMetrics> train_masked_d, train_full_d, test_masked_d, test_full_d; // display values
    std::vector<metrics::FrameMetrics> direct_train, direct_test, direct_train_d, direct_test_d; // add_light: without it
    const metrics::MetricsOptions display_options = metrics::display_metrics_options(options.metrics);
    std::optional<metrics::DisplayEncoder> encoder; // rebuilt when a frame's encoding differs
    std::set<std::string> encodings;
    bool all_srgb_integer = true;
    std::optional<log::Progress> progress;
    if (options.progress) progress.emplace("evaluate", frames.size());
    std::size_t done = 0;
    std::size_t no_mask_frames = 0;
    for (const std::size_t fi : frames) {
        const FrameDesc& fd = desc.frames[fi];
        const FrameImage& captured = capture.images[fi];
        FrameEvaluation fe;
        fe.frame = fi;
        fe.file = fd.file_path.generic_string();
        fe.split = fd.split;
        fe.view_index = fd.view_index;

        const Stopwatch render_time;
        render::Frame frame;
        bool prerendered = false; // EvaluateOptions::rendered: drawn already
        if (options.rendered != nullptr)
            if (const auto it = options.rendered->find(fi); it != options.rendered->end()) {
                frame = std::move(it->second);
                options.rendered->erase(it);
                prerendered = true;
            }
        if (prerendered) {
            // scored as it was drawn
        } else if (renderer) {
            frame = renderer->render(fd.camera(), fd.light, render_settings);
        } else { // another tool's image: its nonzero pixels are its coverage
            frame.color = std::move(external.at(fi));
            const std::size_t n = static_cast<std::size_t>(frame.color.width) * frame.color.height;
            frame.mask.assign(n, 0);
            for (std::size_t p = 0; p < n; ++p)
                for (int c = 0; c < frame.color.channels; ++c)
                    if (frame.color.pixels[p * frame.color.channels + c] != 0.0f) frame.mask[p] = 255;
            frame.info.covered_pixels = static_cast<std::size_t>(std::count(frame.mask.begin(), frame.mask.end(), 255));
            frame.info.shadow_note = "another tool's render";
        }
        // A frame drawn already: the time of its render() (FrameInfo::wall_ms).
        fe.render_ms = prerendered ? frame.info.wall_ms : 1000.0 * render_time.seconds();
        if (options.core_renders != nullptr && renderer)
            if (const auto core = options.core_renders->find(fi); core != options.core_renders->end()) {
                renderer->draw_core_material(bundle.core);
                core->second = renderer->render(fd.camera(), fd.light, core_settings);
                renderer->draw_own_material();
            }
        fe.covered_pixels = frame.info.covered_pixels;
        fe.shadowed = frame.info.shadow_pass;
        if (renderer && options.render.shadows && !frame.info.shadow_pass) {
            fe.shadow_note = frame.info.shadow_note;
            log::warn(desc.dir.string() + ": frames[" + std::to_string(fi) + "] rendered without shadows: " + fe.shadow_note);
        }
        const Image& cap = captured.color;
        Image& ren = frame.color;
        if (cap.width != ren.width || cap.height != ren.height)
            throw Error(desc.dir.string() + ": frames[" + std::to_string(fi) + "]: image " + std::to_string(cap.width) + "x" +
                        std::to_string(cap.height) + " does not match its intrinsics " + std::to_string(ren.width) + "x" +
                        std::to_string(ren.height));
        if (std::isfinite(captured.saturation))
            for (float& v : ren.pixels) v = std::min(v, captured.saturation);

        const std::size_t n = static_cast<std::size_t>(cap.width) * cap.height;
        const bool has_mask = fd.mask_path.has_value() && captured.flags.size() == n;
        const bool has_flags = captured.flags.size() == n;
        fe.mask_source = has_mask ? "capture" : "render";
        if (!has_mask) ++no_mask_frames;
        std::vector<std::uint8_t> masked(n), full;
        for (std::size_t p = 0; p < n; ++p) {
            const std::uint8_t flags = has_flags ? captured.flags[p] : 0;
            const bool inside = has_mask ? (flags & kOutsideMask) == 0 : frame.mask[p] != 0;
            masked[p] = inside && (flags & kMissing) == 0 ? 1 : 0;
        }
        if (captured.missing_pixels > 0) {
            full.resize(n);
            for (std::size_t p = 0; p < n; ++p) full[p] = (captured.flags[p] & kMissing) == 0 ? 1 : 0;
        }

        const Stopwatch metrics_time;
        const auto run_metrics = [&](const Image& a, const Image& b, std::span<const std::uint8_t> pixels,
                                     const metrics::MetricsOptions& o) {
            const metrics::MetricsInputs in{a, b, pixels};
            return metrics_vk ? metrics_vk->run(in, o) : metrics::image_metrics_cpu(in, o);
        };
        // Display values: both images as the capture stores its own (metrics/display_values.h).
        const metrics::DisplayEncoding encoding = metrics::display_encoding_of(captured.file_info, desc.color_space);
        if (!encoder || encoder->encoding() != encoding) encoder.emplace(encoding);
        const Image cap_display = (*encoder)(cap);
        if (options.add_light) {
            // The render as the bundle's renderer draws it, scored before the added light.
            fe.masked_direct = run_metrics(cap, ren, masked, options.metrics);
            fe.masked_display_direct = run_metrics(cap_display, (*encoder)(ren), masked, display_options);
            options.add_light(fi, ren);
            if (std::isfinite(captured.saturation))
                for (float& v : ren.pixels) v = std::min(v, captured.saturation);
        }
        const Image ren_display = (*encoder)(ren);
        struct Score {
            const Image& a;
            const Image& b;
            std::span<const std::uint8_t> pixels;
            const metrics::MetricsOptions& o;
            metrics::FrameMetrics& out;
        };
        const Score scores[] = {{cap, ren, masked, options.metrics, fe.masked},
                                {cap, ren, full, options.metrics, fe.full},
                                {cap_display, ren_display, masked, display_options, fe.masked_display},
                                {cap_display, ren_display, full, display_options, fe.full_display}};
        // The kernels share one queue: side by side only on the CPU.
        parallel_for(std::size(scores), metrics_vk ? 1u : std::max(options.threads, 1u),
                     [&](std::size_t k) { scores[k].out = run_metrics(scores[k].a, scores[k].b, scores[k].pixels, scores[k].o); });
        fe.display_encoding = encoding.name();
        encodings.insert(fe.display_encoding);
        all_srgb_integer = all_srgb_integer && encoding.transfer == ColorSpace::Srgb && encoding.bits > 0;
        fe.metrics_ms = 1000.0 * metrics_time.seconds();
        result.timings.render_s += fe.render_ms / 1000.0;
        result.timings.metrics_s += fe.metrics_ms / 1000.0;

        if (fd.split == Split::Train) {
            train_masked.push_back(fe.masked);
            train_full.push_back(fe.full);
            train_masked_d.push_back(fe.masked_display);
            train_full_d.push_back(fe.full_display);
            if (fe.masked_direct) {
                direct_train.push_back(*fe.masked_direct);
                direct_train_d.push_back(*fe.masked_display_direct);
            }
            ++result.train_frames;
        } else {
            test_masked.push_back(fe.masked);
            test_full.push_back(fe.full);
            test_masked_d.push_back(fe.masked_display);
            test_full_d.push_back(fe.full_display);
            if (fe.masked_direct) {
                direct_test.push_back(*fe.masked_direct);
                direct_test_d.push_back(*fe.masked_display_direct);
            }
            ++result.test_frames;
        }

        if (options.sheet_dir && sheet_set.count(fi) != 0) {
            const Stopwatch sheet_time;
            char name[64];
            std::snprintf(name, sizeof name, "sheet_%04zu_%s_view%d.png", fi, split_name(fd.split), fd.view_index);
            const std::filesystem::path path = *options.sheet_dir / name;
            write_image(path, make_sheet(cap, ren), ColorSpace::Srgb, 8);
            result.sheets.push_back(path);
            result.timings.sheets_s += sheet_time.seconds();
        }
        result.frames.push_back(std::move(fe));
        if (progress) progress->update(++done);
    }
    if (progress) progress->finish();
    if (options.core_renders != nullptr) // the frames not evaluated here have no render
        std::erase_if(*options.core_renders, [&](const auto& kv) { return !std::binary_search(frames.begin(), frames.end(), kv.first); });
    for (const std::size_t f : options.sheet_frames)
        if (std::find(frames.begin(), frames.end(), f) == frames.end())
            result.warnings.push_back("sheet frame " + std::to_string(f) + " was not evaluated (see --frames): no sheet");
    if (no_mask_frames > 0)
        result.warnings.push_back(std::to_string(no_mask_frames) +
                                  " frame(s) have no mask: their masked measures use the render's coverage");

    result.metrics.train_masked = metrics::summarize(train_masked, options.metrics);
    result.metrics.train_full = metrics::summarize(train_full, options.metrics);
    result.metrics.test_masked = metrics::summarize(test_masked, options.metrics);
    result.metrics.test_full = metrics::summarize(test_full, options.metrics);
    result.display_metrics.train_masked = metrics::summarize(train_masked_d, display_options);
    result.display_metrics.train_full = metrics::summarize(train_full_d, display_options);
    result.display_metrics.test_masked = metrics::summarize(test_masked_d, display_options);
    result.display_metrics.test_full = metrics::summarize(test_full_d, display_options);
    if (options.add_light) {
        result.direct_metrics.emplace();
        result.direct_metrics->train_masked = metrics::summarize(direct_train, options.metrics);
        result.direct_metrics->test_masked = metrics::summarize(direct_test, options.metrics);
        result.direct_display_metrics.emplace();
        result.direct_display_metrics->train_masked = metrics::summarize(direct_train_d, display_options);
        result.direct_display_metrics->test_masked = metrics::summarize(direct_test_d, display_options);
    }
    result.display_encoding = encodings.size() == 1 ? *encodings.begin() : encodings.empty() ? "" : "mixed";
    result.display_first = !encodings.empty() && all_srgb_integer;
    result.timings.total_s = total.seconds();
    return result;
}

nlohmann::json to_json(const EvaluationResult& r, const std::filesystem::path& folder) {
    nlohmann::json j;
    j["bundle"] = r.bundle_name;
    j["capture"] = path_relative_to(r.capture_dir, folder);
    j["settings"] = settings_json(r);
    j["display_encoding"] = r.display_encoding;
    if (r.train_frames > 0)
        j["train"] = {{"masked", summary_json(r.metrics.train_masked, r.display_metrics.train_masked, r.display_encoding)},
                      {"full", summary_json(r.metrics.train_full, r.display_metrics.train_full, r.display_encoding)}};
    if (r.test_frames > 0)
        j["test"] = {{"masked", summary_json(r.metrics.test_masked, r.display_metrics.test_masked, r.display_encoding)},
                     {"full", summary_json(r.metrics.test_full, r.display_metrics.test_full, r.display_encoding)}};
    // The renders without the added light (EvaluateOptions::add_light): masked, beside the above.
    if (r.direct_metrics) {
        nlohmann::json direct = nlohmann::json::object();
        if (r.train_frames > 0)
            direct["train"] = {{"masked", summary_json(r.direct_metrics->train_masked, r.direct_display_metrics->train_masked,
                                                       r.display_encoding)}};
        if (r.test_frames > 0)
            direct["test"] = {{"masked", summary_json(r.direct_metrics->test_masked, r.direct_display_metrics->test_masked,
                                                      r.display_encoding)}};
        j["without_added_light"] = std::move(direct);
    }
    nlohmann::json frames = nlohmann::json::array();
    for (const FrameEvaluation& f : r.frames)
        frames.push_back({{"frame", f.frame},
                          {"file", f.file},
                          {"split", split_name(f.split)},
                          {"view_index", f.view_index},
                          {"mask_source", f.mask_source},
                          {"covered_pixels", f.covered_pixels},
                          {"shadowed", f.shadowed},
                          {"display_encoding", f.display_encoding},
                          {"masked", frame_metrics_json(f.masked, f.masked_display)},
                          {"full", frame_metrics_json(f.full, f.full_display)},
                          {"render_ms", finite_or_zero(f.render_ms)},
                          {"metrics_ms", finite_or_zero(f.metrics_ms)}});
    j["frames"] = std::move(frames);
    const std::size_t n = r.frames.size();
    j["timings"] = {{"setup_s", r.timings.setup_s},       {"render_s", r.timings.render_s},
                    {"metrics_s", r.timings.metrics_s},   {"sheets_s", r.timings.sheets_s},
                    {"total_s", r.timings.total_s},       {"per_frame_ms", r.timings.per_frame_ms(n)}};
    nlohmann::json sheets = nlohmann::json::array();
    for (const auto& s : r.sheets) sheets.push_back(s.string());
    j["sheets"] = std::move(sheets);
    j["warnings"] = r.warnings;
    return j;
}

std::string format_summary(const EvaluationResult& r) {
    std::ostringstream out;
    char line[256];
    // Q1 and PSNR on display and on linear values, display first for sRGB captures (the
    // field's figures); the other measures on linear values.
    const bool d1 = r.display_first;
    std::snprintf(line, sizeof line, "%-13s %6s %8s %9s %8s %9s %7s %7s %7s %7s %7s\n", "split", "frames",
                  d1 ? "Q1 disp" : "Q1 lin", d1 ? "PSNR disp" : "PSNR lin", d1 ? "Q1 lin" : "Q1 disp",
                  d1 ? "PSNR lin" : "PSNR disp", "Q2", "RMS%", "DDE%", "SSIM", "NCC");
    out << line;
    auto row = [&](const char* name, std::size_t split_frames, const metrics::MetricsSummary& s,
                   const metrics::MetricsSummary& d) {
        if (split_frames == 0) return;
        if (s.frames == 0) {
            std::snprintf(line, sizeof line, "%-13s %6llu   (no pixels)\n", name, static_cast<unsigned long long>(s.frames));
        } else {
            const metrics::MetricsSummary& first = d1 ? d : s;
            const metrics::MetricsSummary& second = d1 ? s : d;
            std::snprintf(line, sizeof line, "%-13s %6llu %8.2f %9.2f %8.2f %9.2f %7.2f %7.3f %7.3f %7.4f %7.4f\n", name,
                          static_cast<unsigned long long>(s.frames), first.q1, first.psnr, second.q1, second.psnr, s.q2,
                          s.rms_percent, s.dde_percent, s.ssim, s.ncc);
        }
        out << line;
    };
    row("train masked", r.train_frames, r.metrics.train_masked, r.display_metrics.train_masked);
    row("train full", r.train_frames, r.metrics.train_full, r.display_metrics.train_full);
    row("test masked", r.test_frames, r.metrics.test_masked, r.display_metrics.test_masked);
    row("test full", r.test_frames, r.metrics.test_full, r.display_metrics.test_full);
    if (r.direct_metrics) {
        out << "without the added light (indirect):\n";
        row("train masked", r.train_frames, r.direct_metrics->train_masked, r.direct_display_metrics->train_masked);
        row("test masked", r.test_frames, r.direct_metrics->test_masked, r.direct_display_metrics->test_masked);
    }
    if (!r.frames.empty()) {
        const bool quantized = !r.display_encoding.empty() && std::isdigit(static_cast<unsigned char>(r.display_encoding.back()));
        std::snprintf(line, sizeof line, "display values: %s (%s, G = 1); Q2, RMS%%, DDE%%, SSIM, NCC on linear values\n",
                      r.display_encoding.c_str(),
                      quantized || r.display_encoding == "mixed" ? "the capture's own encoding"
                                                                 : "float capture: sRGB of the values clipped to [0, 1], not quantized");
        out << line;
    }
    const std::size_t n = r.frames.size();
    std::snprintf(line, sizeof line,
                  "render %s/%s (%s), %s, metrics on %s: %zu frames, %.1f ms per frame (render %.1f + metrics %.1f), setup %.2f s, total %.2f s\n",
                  render::mode_name(r.render.mode), render::specular_path_name(r.render.specular), render::passes_name(r.render.passes),
                  r.render.shadows ? "shadows" : "no shadows", to_string(r.metrics_backend),
                  n, r.timings.per_frame_ms(n), n ? 1000.0 * r.timings.render_s / n : 0.0,
                  n ? 1000.0 * r.timings.metrics_s / n : 0.0, r.timings.setup_s, r.timings.total_s);
    out << line;
    if (!r.lod_levels.empty()) {
        out << "levels of detail kept (error under " << r.lod_max_error_px << " px):";
        for (std::size_t k = 0; k < r.lod_levels.size(); ++k) {
            std::snprintf(line, sizeof line, k == 0 ? " %zu triangles (the whole mesh)" : ", %zu (%.1f dB against it)",
                          r.lod_levels[k].first, r.lod_levels[k].second);
            out << line;
        }
        out << "\n";
    }
    return out.str();
}

} // namespace specula::evaluate
