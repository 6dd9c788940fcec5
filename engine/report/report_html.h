#pragma once
/// \file
/// The one-page report (pipeline.md section 8): report.json made readable, in one
/// self-contained HTML file (inline CSS, inline SVG charts, sheets embedded as base64
/// PNG data URIs; nothing is fetched). Every string from the report is HTML-escaped.
///
///   const std::string html = report_html(report_json, {.out_dir = out});
///   write_text_file(out / "report.html", html);
///
/// Sections: quality (train/test x masked/full), planner decisions, left out, stage
/// times (bar chart) and GPU dispatch times, counts, the fitted lobe with its standard
/// errors and the factorization, sheets, warnings.
#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace specula::report {

/// &, <, >, " and ' as entities.
[[nodiscard]] std::string html_escape(std::string_view text);

/// RFC 4648 base64 (with padding).
[[nodiscard]] std::string base64(std::span<const std::uint8_t> bytes);

/// "data:image/png;base64,..." of a file (InputError naming it when unreadable).
[[nodiscard]] std::string data_uri(const std::filesystem::path& png);

struct Bar {
    std::string label;
    double value = 0.0;
};
/// A horizontal bar chart as an inline <svg> element: one bar per entry, the value
/// printed after it with `unit`. `width` is the least width in px: the chart widens until
/// the longest label fits, and scales down with the page (viewBox).
[[nodiscard]] std::string svg_bar_chart(std::span<const Bar> bars, std::string_view unit, int width = 640);

struct ReportHtmlOptions {
    /// Folder of report.json; sheets named in report["evaluation"]["sheets"] are read from
    /// here (or their absolute path) and embedded, up to max_embed_bytes in all (the rest linked).
    std::filesystem::path out_dir;
    std::uint64_t max_embed_bytes = 24u << 20;
};

/// The page for a report.json object (fields absent or null are shown as such).
[[nodiscard]] std::string report_html(const nlohmann::json& report, const ReportHtmlOptions& options = {});

/// The page's stylesheet (also used by the sweep's page).
[[nodiscard]] std::string_view report_css();

} // namespace specula::report
