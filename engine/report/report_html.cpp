#include "report/report_html.h"

#include "core/error.h"
#include "core/file_util.h"
#include "core/format.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>

namespace specula::report {

namespace fs = std::filesystem;
using nlohmann::json;

std::string html_escape(std::string_view text) {
    std::string out;
    out.reserve(text.size());
    for (const char c : text) {
        switch (c) {
        case '&': out += "&amp;"; break;
        case '<': out += "&lt;"; break;
        case '>': out += "&gt;"; break;
        case '"': out += "&quot;"; break;
        case '\'': out += "&#39;"; break;
        default: out += c;
        }
    }
    return out;
}

std::string base64(std::span<const std::uint8_t> bytes) {
    static constexpr char kAlphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    std::string out;
    out.reserve((bytes.size() + 2) / 3 * 4);
    std::size_t i = 0;
    for (; i + 3 <= bytes.size(); i += 3) {
        const std::uint32_t v = (std::uint32_t(bytes[i]) << 16) | (std::uint32_t(bytes[i + 1]) << 8) | bytes[i + 2];
        out += kAlphabet[(v >> 18) & 63];
        out += kAlphabet[(v >> 12) & 63];
        out += kAlphabet[(v >> 6) & 63];
        out += kAlphabet[v & 63];
    }
    if (const std::size_t rest = bytes.size() - i; rest > 0) {
        std::uint32_t v = std::uint32_t(bytes[i]) << 16;
        if (rest == 2) v |= std::uint32_t(bytes[i + 1]) << 8;
        out += kAlphabet[(v >> 18) & 63];
        out += kAlphabet[(v >> 12) & 63];
        out += rest == 2 ? kAlphabet[(v >> 6) & 63] : '=';
        out += '=';
    }
    return out;
}

std::string data_uri(const fs::path& png) {
    const std::string bytes = read_text_file(png, "image");
    return "data:image/png;base64," +
           base64(std::span(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size()));
}

namespace {

// An integer with thousands separators: 1,145,730 (counts printed with %g came out as 1.14573e+06).
std::string grouped(std::int64_t v) {
    const std::string digits = std::to_string(v < 0 ? -static_cast<std::uint64_t>(v) : static_cast<std::uint64_t>(v));
    std::string out = v < 0 ? "-" : "";
    for (std::size_t i = 0; i < digits.size(); ++i) { // a comma before each group of three from the right
        if (i > 0 && (digits.size() - i) % 3 == 0) out += ',';
        out += digits[i];
    }
    return out;
}

// A JSON number (or null / missing) as text; JSON integers (counts) whole, grouped by thousands.
std::string num(const json& j, const char* format = "%.4g") {
    if (j.is_number_unsigned()) return grouped(static_cast<std::int64_t>(std::min<std::uint64_t>(j.get<std::uint64_t>(), INT64_MAX)));
    if (j.is_number_integer()) return grouped(j.get<std::int64_t>());
    if (j.is_number()) return format_text(format, j.get<double>());
    if (j.is_boolean()) return j.get<bool>() ? "yes" : "no";
    if (j.is_string()) return html_escape(j.get<std::string>());
    return "&mdash;";
}

const json& at(const json& j, std::initializer_list<const char*> path) {
    static const json kNull;
    const json* p = &j;
    for (const char* key : path) {
        if (!p->is_object() || !p->contains(key)) return kNull;
        p = &(*p)[key];
    }
    return *p;
}

std::string str(const json& j) { return j.is_string() ? html_escape(j.get<std::string>()) : j.is_null() ? "&mdash;" : html_escape(j.dump()); }

std::string row(std::initializer_list<std::string> cells, bool header = false) {
    std::string out = "<tr>";
    for (const std::string& c : cells) out += (header ? "<th>" : "<td>") + c + (header ? "</th>" : "</td>");
    return out + "</tr>\n";
}

std::string quality_section(const json& report) {
    const json& ev = report.value("evaluation", json());
    std::string out = "<h2 id=\"quality\">Quality</h2>\n";
    if (!ev.is_object()) return out + "<p>No evaluation in this run (see <a href=\"#left-out\">left out</a>).</p>\n";
    // Q1 and PSNR on display values (the capture's own encoding, evaluate.h) beside the linear
    // ones, display first for an sRGB integer capture (the figures the field reports).
    const json& enc = at(ev, {"display_encoding"});
    const std::string encoding = enc.is_string() ? enc.get<std::string>() : std::string();
    const bool display_first = encoding.rfind("srgb", 0) == 0 && encoding.size() > 4 &&
                               std::isdigit(static_cast<unsigned char>(encoding.back())) != 0;
    out += "<p>Every frame re-rendered from <code>object.glb</code> with its camera and light and compared with the "
           "captured image (thesis chapter 5). <b>masked</b>: the object's pixels (primary); <b>full</b>: the whole "
           "frame, background included (comparable with the thesis's figures, Q1 89.3 to 93.0). "
           "Q1 = 100 &minus; mean RMS%, Q2 = 100 &minus; mean DDE%. <b>display</b>: both images in the capture's own "
           "encoding (" + (encoding.empty() ? std::string("&mdash;") : "<code>" + html_escape(encoding) + "</code>") +
           ": transfer function, clipped to [0, 1], quantized like the stored images), G = 1; <b>linear</b>: linear "
           "values. The other measures are on linear values.</p>\n<table>\n";
    const std::string d_q1 = "Q1 display", d_psnr = "PSNR display dB", l_q1 = "Q1 linear", l_psnr = "PSNR linear dB";
    out += row({"split", "pixels", "frames", display_first ? d_q1 : l_q1, display_first ? d_psnr : l_psnr,
                display_first ? l_q1 : d_q1, display_first ? l_psnr : d_psnr, "Q2", "RMS %", "DDE %", "SSIM", "NCC", "L1",
                "L2", "Hausdorff"},
               true);
    for (const char* split : {"train", "test"})
        for (const char* set : {"masked", "full"}) {
            const json& m = at(ev, {split, set});
            if (!m.is_object()) {
                out += row({split, set, "0", "&mdash;", "", "", "", "", "", "", "", "", "", "", ""});
                continue;
            }
            const std::string dq = num(m.value("q1_display", json()), "%.2f"), dp = num(m.value("psnr_display", json()), "%.2f");
            const std::string lq = num(m.value("q1", json()), "%.2f"), lp = num(m.value("psnr", json()), "%.2f");
            out += row({split, set, num(m.value("frames", json())), display_first ? dq : lq, display_first ? dp : lp,
                        display_first ? lq : dq, display_first ? lp : dp, num(m.value("q2", json()), "%.2f"),
                        num(m.value("rms_percent", json()), "%.3f"), num(m.value("dde_percent", json()), "%.3f"),
                        num(m.value("ssim", json()), "%.4f"), num(m.value("ncc", json()), "%.4f"), num(m.value("l1", json())),
                        num(m.value("l2", json())), num(m.value("hausdorff", json()))});
        }
    out += "</table>\n";
    return out;
}

// What ordinary glTF viewers show (report.json `viewer`): the core material and its masked display
// PSNR beside Specula's own renderer's on the same frames.
std::string viewer_section(const json& report) {
    const json& v = report.value("viewer", json());
    if (!v.is_object()) return {};
    std::string out = "<h2 id=\"viewer\">What ordinary viewers show</h2>\n<p>Viewers that do not read Specula's extension "
                      "(three.js, Blender, model-viewer) draw the glTF core material: ";
    const json& g = at(v, {"material", "gltf"});
    const json& cc = g.value("clearcoatFactor", json());
    const bool coat = cc.is_number() && cc.get<double>() > 0.0;
    out += (coat ? "a clearcoat of weight " + num(cc, "%.3f") + " and roughness " +
                       num(g.value("clearcoatRoughnessFactor", json()), "%.3f") + " (KHR_materials_clearcoat)"
                 : "roughness " + num(g.value("roughnessFactor", json()), "%.3f") + ", IOR " + num(g.value("ior", json()), "%.3f") +
                       ", specular " + num(g.value("specularFactor", json()), "%.4f") + " &times; colour " +
                       num(g.value("specularColorFactor", json()), "%.3f")) +
           ", fitted to the train frames in glTF's BRDF. Rendered as three.js draws it, direct light only, masked PSNR "
           "on display values:</p>\n<table>\n";
    out += row({"split", "frames", "viewers dB", "Specula dB"}, true);
    for (const char* split : {"train", "test"}) {
        const json& s = v.value(split, json());
        if (!s.is_object()) continue;
        out += row({split, num(s.value("frames", json())), num(s.value("psnr_display", json()), "%.2f"),
                    num(s.value("specula_psnr_display", json()), "%.2f")});
    }
    // tools/threejs-render.mjs --report replaces this placeholder with three.js's picture of the
    // test sheet's frame (it needs Node.js, three and Chromium, which reconstruct does not).
    out += "</table>\n<div id=\"threejs-picture\"><p>To see a frame as three.js draws this bundle, beside the photograph "
           "and Specula's render: <code>node tools/threejs-render.mjs --report OUT --capture CAPTURE</code> (Node.js, three, "
           "puppeteer-core and Chromium: <code>tools/install-deps.sh</code>).</p></div>\n";
    return out;
}

std::string planner_section(const json& report) {
    std::string out = "<h2 id=\"planner\">Planner decisions</h2>\n"
                      "<p>What this scene needed (pipeline.md section 9). <b>auto</b>: the planner chose; <b>forced</b>: a "
                      "command-line flag did. Cost: the estimated time the planner's choice avoided, or the measured time "
                      "of work a flag forced on.</p>\n<table>\n";
    out += row({"decision", "chosen", "mode", "why", "cost"}, true);
    const json& plan = report.value("planner", json());
    if (!plan.is_array() || plan.empty()) return out + "</table>\n<p>No planner decisions recorded.</p>\n";
    for (const json& d : plan) {
        std::string cost;
        if (d.value("avoided_seconds", json()).is_number())
            cost = "avoided &asymp; " + num(d["avoided_seconds"], "%.3g") + " s";
        else if (d.value("measured_seconds", json()).is_number())
            cost = "cost " + num(d["measured_seconds"], "%.3g") + " s (measured)";
        else
            cost = "&mdash;";
        if (!d.value("cost_basis", std::string()).empty())
            cost += "<br><small>" + html_escape(d["cost_basis"].get<std::string>()) + "</small>";
        const bool forced = d.value("mode", std::string()) == "forced";
        out += row({"<code>" + str(d.value("name", json())) + "</code>",
                    std::string(d.value("skipped", false) ? "<span class=\"skip\">" : "<span>") + str(d.value("value", json())) +
                        "</span>",
                    forced ? "<b>forced</b>" : "auto", str(d.value("reason", json())), cost});
    }
    return out + "</table>\n";
}

std::string left_out_section(const json& report) {
    std::string out = "<h2 id=\"left-out\">Left out</h2>\n";
    const json& lo = report.value("left_out", json());
    if (!lo.is_array() || lo.empty()) return out + "<p>Nothing: every stage ran for this scene.</p>\n";
    out += "<ul>\n";
    for (const json& l : lo) out += "<li><b>" + str(l.value("what", json())) + "</b>: " + str(l.value("why", json())) + "</li>\n";
    return out + "</ul>\n";
}

std::string time_section(const json& report) {
    std::string out = "<h2 id=\"time\">Time</h2>\n<p>Wall time per stage; total " + num(report.value("total_seconds", json()), "%.2f") +
                      " s";
    const json& dev = report.value("device", json());
    if (dev.is_object()) out += " on " + str(dev.value("name", json())) + " (" + str(dev.value("kind", json())) + ")";
    out += ".</p>\n";
    std::vector<Bar> bars;
    for (const json& s : report.value("stages", json::array()))
        if (s.is_object() && s.value("seconds", json()).is_number())
            bars.push_back({s.value("name", std::string("?")), s["seconds"].get<double>()});
    out += svg_bar_chart(bars, "s");
    const json& gpu = report.value("gpu_dispatches", json());
    if (gpu.is_array() && !gpu.empty()) {
        out += "<h3>GPU time per dispatch</h3>\n<p>From Vulkan timestamp queries (device time, not wall time).</p>\n<table>\n";
        out += row({"stage", "dispatch", "ms"}, true);
        for (const json& g : gpu)
            out += row({str(g.value("stage", json())), str(g.value("dispatch", json())), num(g.value("ms", json()), "%.3f")});
        out += "</table>\n";
    } else {
        out += "<p>No GPU dispatch times (CPU backend, or no timestamps on this device).</p>\n";
    }
    return out;
}

std::string counts_section(const json& r) {
    std::string out = "<h2 id=\"counts\">Counts</h2>\n<table>\n";
    out += row({"what", "count"}, true);
    const auto add = [&](const std::string& label, const json& v) { out += row({html_escape(label), num(v, "%.6g")}); };
    add("views", at(r, {"capture", "views"}));
    add("train frames", at(r, {"capture", "train_frames"}));
    add("test frames", at(r, {"capture", "test_frames"}));
    add("mesh triangles", at(r, {"capture", "mesh_triangles"}));
    out += row({"atlas", num(at(r, {"atlas", "width"}), "%.0f") + " x " + num(at(r, {"atlas", "height"}), "%.0f")});
    add("particles", at(r, {"particles", "count"}));
    add("particles seen by no view (inpainted)", at(r, {"visibility", "seen_by_no_view"}));
    add("occlusion rays cast", at(r, {"visibility", "rays_cast"}));
    add("occlusion rays avoided (convex)", at(r, {"visibility", "rays_avoided"}));
    add("diffuse: particles solved", at(r, {"diffuse", "ok"}));
    add("diffuse: photometric fell back to albedo mode", at(r, {"diffuse", "fallback_to_albedo_mode"}));
    const json& s = at(r, {"diffuse", "samples"});
    if (s.is_object())
        for (const auto& [k, v] : s.items()) add("diffuse samples: " + k, v);
    const json& rs = at(r, {"specular", "samples"});
    if (rs.is_object()) {
        add("residual samples: candidates", rs.value("candidates", json()));
        add("residual samples: used", rs.value("used", json()));
        add("residual samples: fitted (subsample)", rs.value("fitted", json()));
        const json& dropped = rs.value("dropped", json());
        if (dropped.is_object())
            for (const auto& [k, v] : dropped.items()) add("residual samples dropped: " + k, v);
    }
    add("albedo texels filled from neighbours", at(r, {"albedo_texture", "filled_same_patch"}));
    return out + "</table>\n";
}

// The model choice (report.json specular.material): every candidate family with its parameters,
// validation error and time, and why the winner won.
std::string material_section(const json& r) {
    const json& m = at(r, {"specular", "material"});
    if (!m.is_object()) return {};
    std::string out = "<h2 id=\"material\">Material model</h2>\n<p>Chosen: <b>" + str(m.value("family", json())) + "</b>. " +
                      str(m.value("choice", json())) + ".</p>\n<table>\n";
    out += row({"family", "fit", "validation mean square", "validation PSNR (linear, dB)", "joint rounds kept", "seconds"}, true);
    const json& candidates = m.value("candidates", json());
    if (candidates.is_array())
        for (const json& c : candidates)
            out += row({str(c.value("family", json())), str(c.value("summary", json())), num(c.value("validation_mse", json()), "%.3g"),
                        num(c.value("validation_psnr_linear_db", json()), "%.2f"), num(at(c, {"joint", "accepted"}), "%g"),
                        num(c.value("seconds", json()), "%.2f")});
    out += "</table>\n";
    // A candidate estimated twice (report.json joint.restart): where its first start ended, and which was kept.
    if (candidates.is_array())
        for (const json& c : candidates) {
            const json& restart = at(c, {"joint", "restart"});
            if (!restart.is_object()) continue;
            const bool common = restart.value("kept", std::string()) == "common";
            out += "<p>The " + str(c.value("family", json())) + " candidate's rounds ended at eta " +
                   num(restart.value("first_eta", json()), "%.4g") + " (validation mean square " +
                   num(restart.value("first_validation_mse", json()), "%.3g") + "), near no coating at all: it was estimated again from eta " +
                   num(restart.value("common_eta", json()), "%.3g") + ", a common dielectric (" +
                   num(restart.value("common_validation_mse", json()), "%.3g") + "), and the " +
                   (common ? "second" : "first") + " start kept.</p>\n";
        }
    const json& coated = at(r, {"specular", "coated"});
    if (coated.is_object())
        out += "<p>Coated: eta " + num(coated.value("eta", json()), "%.4g") + " &plusmn; " +
               num(at(coated, {"standard_errors", "eta"}), "%.2g") + ", alpha " + num(coated.value("alpha", json()), "%.4g") +
               " &plusmn; " + num(at(coated, {"standard_errors", "alpha"}), "%.2g") + ", status " +
               str(coated.value("status", json())) + ": " + str(coated.value("reason", json())) + ".</p>\n";
    return out;
}

std::string lobe_section(const json& r) {
    std::string out = "<h2 id=\"lobe\">Specular lobe</h2>\n";
    const json& sp = r.value("specular", json());
    const json& lobe = at(r, {"specular", "lobe"});
    if (at(r, {"specular", "coated"}).is_object()) return {}; // the coated family: the material section
    if (!sp.is_object() || !lobe.is_object()) {
        out += "<p>No lobe fitted";
        if (sp.is_object()) out += ": " + str(sp.value("decision", json()));
        return out + ".</p>\n";
    }
    out += "<p>One Lafortune lobe per channel, f<sub>s</sub>(u, v) = max(0, C<sub>x</sub>(u<sub>x</sub>v<sub>x</sub> + "
           "u<sub>y</sub>v<sub>y</sub>) + C<sub>z</sub>u<sub>z</sub>v<sub>z</sub>)<sup>N</sup>, &plusmn; standard errors "
           "from J<sup>T</sup>J. " + str(sp.value("decision", json())) + ".</p>\n<table>\n";
    out += row({"channel", "Cx", "Cz", "N", "status", "condition", "iterations", "rms"}, true);
    const json& se = at(r, {"specular", "standard_errors"});
    for (int k = 0; k < 3; ++k) {
        const auto pm = [&](const char* key) {
            const json& v = at(lobe, {key});
            const json& e = at(se, {key});
            std::string t = v.is_array() && v.size() > std::size_t(k) ? num(v[k], "%.4g") : "&mdash;";
            if (e.is_array() && e.size() > std::size_t(k)) t += " &plusmn; " + num(e[k], "%.2g");
            return t;
        };
        const auto item = [&](const json& arr, const char* f) {
            return arr.is_array() && arr.size() > std::size_t(k) ? num(arr[k], f) : std::string("&mdash;");
        };
        out += row({std::string(1, "RGB"[k]), pm("cx"), pm("cz"), pm("n"), item(lobe.value("status", json()), "%g"),
                    item(sp.value("condition", json()), "%.3g"), item(sp.value("iterations", json()), "%g"),
                    item(sp.value("rms", json()), "%.3g")});
    }
    out += "</table>\n";
    const json& f = r.value("factorization", json());
    if (f.is_object())
        out += "<p>Factorization (Kautz-McCool): h grid " + num(f.value("grid_h", json()), "%g") + ", d grid " +
               num(f.value("grid_d", json()), "%g") + ", cube faces " + num(f.value("cube_g", json()), "%g") + " / " +
               num(f.value("cube_h", json()), "%g") + "; relative RMS against the lobe " +
               num(f.value("relative_rms_vs_lobe_grid", json()), "%.3g") + " (grids), " +
               num(f.value("relative_rms_vs_lobe_cubemaps", json()), "%.3g") + " (cube-maps)" +
               (f.contains("terms") ? "; " + num(f.value("terms", json()), "%g") + " separable term(s): " +
                                          str(f.value("terms_reason", json()))
                                    : std::string()) +
               (f.contains("parametrization") ? "; parametrization " + str(f.value("parametrization", json())) + ": " +
                                                    str(f.value("parametrization_reason", json()))
                                              : std::string()) +
               ".</p>\n";
    return out;
}

std::string sheets_section(const json& r, const ReportHtmlOptions& o) {
    std::string out = "<h2 id=\"sheets\">Sheets</h2>\n";
    const json& sheets = at(r, {"evaluation", "sheets"});
    if (!sheets.is_array() || sheets.empty()) return out + "<p>No sheets in this run.</p>\n";
    out += "<p>captured | rendered | difference (0.5 + 4 &times; (rendered &minus; captured), display values), as in the "
           "thesis's figures 5.1-5.4.</p>\n";
    std::uint64_t embedded = 0;
    for (const json& s : sheets) {
        if (!s.is_string()) continue;
        fs::path p = s.get<std::string>();
        const fs::path rel = p.is_absolute() && !o.out_dir.empty() ? fs::relative(p, o.out_dir) : p;
        if (!p.is_absolute() && !o.out_dir.empty()) p = o.out_dir / p;
        std::error_code ec;
        const auto size = fs::file_size(p, ec);
        std::string src;
        if (!ec && embedded + size <= o.max_embed_bytes) {
            src = data_uri(p);
            embedded += size;
        } else {
            src = html_escape(rel.generic_string()); // beside the report
        }
        out += "<figure><img alt=\"sheet\" src=\"" + src + "\"><figcaption>" + html_escape(rel.generic_string()) +
               "</figcaption></figure>\n";
    }
    return out;
}

} // namespace

std::string svg_bar_chart(std::span<const Bar> bars, std::string_view unit, int width) {
    // The labels' column fits the longest label (about 7 px a character at 12 px sans-serif;
    // a fixed 150 px cut "residual samples (joint round 1)" off on the left), and the chart
    // widens to keep 160 px for the bars; the viewBox lets it shrink with the page.
    std::size_t longest = 0;
    for (const Bar& b : bars) longest = std::max(longest, b.label.size());
    const int row_h = 20, value_w = 80;
    const int label_w = std::max(150, static_cast<int>(longest) * 7 + 12);
    width = std::max(width, label_w + value_w + 160);
    const int height = row_h * static_cast<int>(bars.size()) + 10;
    double vmax = 0.0;
    for (const Bar& b : bars)
        if (std::isfinite(b.value)) vmax = std::max(vmax, b.value);
    const double scale = vmax > 0.0 ? (width - label_w - value_w) / vmax : 0.0;
    std::string out = "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" + std::to_string(width) + "\" height=\"" +
                      std::to_string(height) + "\" viewBox=\"0 0 " + std::to_string(width) + " " + std::to_string(height) +
                      "\" role=\"img\" font-family=\"sans-serif\" font-size=\"12\">\n";
    int y = 5;
    for (const Bar& b : bars) {
        const double w = std::isfinite(b.value) ? std::max(1.0, b.value * scale) : 0.0;
        out += "<text x=\"" + std::to_string(label_w - 6) + "\" y=\"" + std::to_string(y + 14) + "\" text-anchor=\"end\">" +
               html_escape(b.label) + "</text>";
        out += "<rect class=\"bar\" x=\"" + std::to_string(label_w) + "\" y=\"" + std::to_string(y + 3) + "\" width=\"" +
               format_text("%.1f", w) + "\" height=\"" + std::to_string(row_h - 6) + "\" fill=\"#4a78b5\"/>";
        out += "<text x=\"" + format_text("%.1f", label_w + w + 4) + "\" y=\"" + std::to_string(y + 14) + "\">" +
               format_text("%.3g", b.value) + " " + html_escape(unit) + "</text>\n";
        y += row_h;
    }
    return out + "</svg>\n";
}

std::string_view report_css() {
    return "body{font-family:sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222;line-height:1.4}"
           "table{border-collapse:collapse;margin:0.5em 0 1em}td,th{border:1px solid #ccc;padding:3px 8px;"
           "vertical-align:top;text-align:left}th{background:#eef}td small{color:#555}code{background:#f4f4f4}"
           ".skip{color:#555;font-style:italic}figure{margin:1em 0}img{max-width:100%;border:1px solid #ccc}"
           "nav a{margin-right:1em}h2{border-bottom:1px solid #ddd;margin-top:1.6em}"
           // Narrow screens: a wide table scrolls in its own box, charts shrink to fit.
           "table{display:block;overflow-x:auto;max-width:100%}svg{max-width:100%;height:auto}";
}

std::string report_html(const json& r, const ReportHtmlOptions& o) {
    std::string out = "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
                      "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n<title>Specula report</title>\n"
                      "<style>" + std::string(report_css()) + "</style>\n</head>\n<body>\n";
    out += "<h1>Specula reconstruction report</h1>\n";
    out += "<p>Capture <code>" + str(at(r, {"capture", "path"})) + "</code>: " + num(at(r, {"capture", "views"}), "%g") +
           " views, " + num(at(r, {"capture", "train_frames"}), "%g") + " train and " +
           num(at(r, {"capture", "test_frames"}), "%g") + " test frames, " + num(at(r, {"capture", "mesh_triangles"}), "%g") +
           " triangles. Specula " + str(r.value("specula_version", json())) + ". Outputs beside this page: "
           "<code>object.glb</code>, <code>albedo.png</code>, <code>albedo.exr</code>, <code>evaluation.json</code>, "
           "<code>sheets/</code>, <code>report.json</code>.</p>\n";
    out += "<nav><a href=\"#quality\">quality</a><a href=\"#viewer\">viewers</a><a href=\"#planner\">planner</a><a href=\"#left-out\">left out</a>"
           "<a href=\"#time\">time</a><a href=\"#counts\">counts</a><a href=\"#material\">material</a><a href=\"#lobe\">lobe</a><a href=\"#sheets\">sheets</a></nav>\n";
    out += quality_section(r);
    out += viewer_section(r);
    out += planner_section(r);
    out += left_out_section(r);
    out += time_section(r);
    out += counts_section(r);
    out += material_section(r);
    out += lobe_section(r);
    out += sheets_section(r, o);
    const json& tex = r.value("albedo_texture", json());
    if (tex.is_object())
        out += "<p>Albedo atlas (" + num(tex.value("width", json()), "%g") + " x " + num(tex.value("height", json()), "%g") +
               " texels, " + num(tex.value("solved", json()), "%g") +
               " solved): <a href=\"albedo.png\">albedo.png</a> (sRGB) and <a href=\"albedo.exr\">albedo.exr</a> (linear), "
               "beside this page.</p>\n";
    const json& w = r.value("warnings", json());
    if (w.is_array() && !w.empty()) {
        out += "<h2>Warnings</h2>\n<ul>\n";
        for (const json& x : w) out += "<li>" + str(x) + "</li>\n";
        out += "</ul>\n";
    }
    return out + "</body>\n</html>\n";
}

} // namespace specula::report
