#include "report/svg_plot.h"

#include "report/report_html.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

namespace specula::report {

namespace {

std::string f1(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.1f", v);
    return buf;
}

std::string g3(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.3g", v);
    return buf;
}

// Round tick step (1, 2 or 5 x 10^k) giving about `count` ticks over span.
double tick_step(double span, int count) {
    const double raw = span / std::max(1, count);
    const double mag = std::pow(10.0, std::floor(std::log10(raw)));
    for (const double m : {1.0, 2.0, 5.0, 10.0})
        if (m * mag >= raw) return m * mag;
    return 10.0 * mag;
}

} // namespace

std::string svg_pareto_plot(std::span<const PlotPoint> points, std::string_view title, std::string_view x_label,
                            std::string_view y_label, int width, int height) {
    const double left = 70, right = 20, top = 40, bottom = 55;
    double x0 = 0.0, x1 = 1.0, y0 = 0.0, y1 = 1.0;
    bool any = false;
    for (const PlotPoint& p : points) {
        if (!std::isfinite(p.x) || !std::isfinite(p.y)) continue;
        if (!any) x0 = x1 = p.x, y0 = y1 = p.y, any = true;
        x0 = std::min(x0, p.x), x1 = std::max(x1, p.x), y0 = std::min(y0, p.y), y1 = std::max(y1, p.y);
    }
    // Axes from 0 in time; error axis padded by 10 % of its span.
    x0 = 0.0;
    x1 = x1 > 0.0 ? x1 * 1.08 : 1.0;
    const double ypad = y1 > y0 ? 0.1 * (y1 - y0) : std::max(0.1 * std::abs(y1), 0.01);
    y0 = std::max(0.0, y0 - ypad);
    y1 = y1 + ypad;
    const double pw = width - left - right, ph = height - top - bottom;
    const auto sx = [&](double x) { return left + (x - x0) / (x1 - x0) * pw; };
    const auto sy = [&](double y) { return top + (1.0 - (y - y0) / (y1 - y0)) * ph; };

    std::string out = "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" + std::to_string(width) + "\" height=\"" +
                      std::to_string(height) + "\" font-family=\"sans-serif\" font-size=\"12\">\n";
    out += "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
    out += "<text x=\"" + f1(width / 2.0) + "\" y=\"22\" text-anchor=\"middle\" font-size=\"15\">" + html_escape(title) + "</text>\n";
    // Ticks and grid.
    const double xs = tick_step(x1 - x0, 8), ys = tick_step(y1 - y0, 6);
    for (double x = std::ceil(x0 / xs) * xs; x <= x1 + 1e-12; x += xs)
        out += "<line x1=\"" + f1(sx(x)) + "\" y1=\"" + f1(top) + "\" x2=\"" + f1(sx(x)) + "\" y2=\"" + f1(top + ph) +
               "\" stroke=\"#eee\"/><text x=\"" + f1(sx(x)) + "\" y=\"" + f1(top + ph + 16) + "\" text-anchor=\"middle\">" +
               g3(x) + "</text>\n";
    for (double y = std::ceil(y0 / ys) * ys; y <= y1 + 1e-12; y += ys)
        out += "<line x1=\"" + f1(left) + "\" y1=\"" + f1(sy(y)) + "\" x2=\"" + f1(left + pw) + "\" y2=\"" + f1(sy(y)) +
               "\" stroke=\"#eee\"/><text x=\"" + f1(left - 6) + "\" y=\"" + f1(sy(y) + 4) + "\" text-anchor=\"end\">" +
               g3(y) + "</text>\n";
    out += "<rect x=\"" + f1(left) + "\" y=\"" + f1(top) + "\" width=\"" + f1(pw) + "\" height=\"" + f1(ph) +
           "\" fill=\"none\" stroke=\"#888\"/>\n";
    out += "<text x=\"" + f1(left + pw / 2) + "\" y=\"" + f1(height - 12.0) + "\" text-anchor=\"middle\">" + html_escape(x_label) +
           "</text>\n";
    out += "<text transform=\"translate(16," + f1(top + ph / 2) + ") rotate(-90)\" text-anchor=\"middle\">" + html_escape(y_label) +
           "</text>\n";
    // The front: a staircase through its points in increasing time (each step: the error
    // reachable at that time or more).
    std::vector<PlotPoint> front;
    for (const PlotPoint& p : points)
        if (p.on_front && std::isfinite(p.x) && std::isfinite(p.y)) front.push_back(p);
    std::sort(front.begin(), front.end(), [](const PlotPoint& a, const PlotPoint& b) { return a.x < b.x; });
    if (!front.empty()) {
        std::string path = "M" + f1(sx(front[0].x)) + "," + f1(sy(front[0].y));
        for (std::size_t i = 1; i < front.size(); ++i)
            path += " H" + f1(sx(front[i].x)) + " V" + f1(sy(front[i].y));
        path += " H" + f1(left + pw);
        out += "<path d=\"" + path + "\" fill=\"none\" stroke=\"#d62728\" stroke-width=\"1.5\"/>\n";
    }
    for (const PlotPoint& p : points) {
        if (!std::isfinite(p.x) || !std::isfinite(p.y)) continue;
        const std::string cx = f1(sx(p.x)), cy = f1(sy(p.y));
        out += "<circle cx=\"" + cx + "\" cy=\"" + cy + "\" r=\"4\" fill=\"" + (p.on_front ? "#d62728" : "#4a78b5") +
               "\"><title>" + html_escape(p.label) + ": " + g3(p.x) + " s, " + g3(p.y) + "</title></circle>\n";
        if (p.is_default)
            out += "<circle cx=\"" + cx + "\" cy=\"" + cy + "\" r=\"9\" fill=\"none\" stroke=\"black\" stroke-width=\"1.5\"/>"
                   "<text x=\"" + f1(sx(p.x) + 11) + "\" y=\"" + f1(sy(p.y) - 8) + "\" font-weight=\"bold\">default</text>\n";
        if (p.on_front)
            out += "<text x=\"" + f1(sx(p.x) + 6) + "\" y=\"" + f1(sy(p.y) + 15) + "\" font-size=\"10\" fill=\"#555\">" +
                   html_escape(p.label) + "</text>\n";
    }
    // Legend.
    const double lx = left + pw - 190, ly = top + 8;
    out += "<rect x=\"" + f1(lx) + "\" y=\"" + f1(ly) + "\" width=\"182\" height=\"54\" fill=\"white\" stroke=\"#ccc\"/>";
    out += "<circle cx=\"" + f1(lx + 12) + "\" cy=\"" + f1(ly + 12) + "\" r=\"4\" fill=\"#4a78b5\"/><text x=\"" + f1(lx + 22) +
           "\" y=\"" + f1(ly + 16) + "\">grid point</text>";
    out += "<line x1=\"" + f1(lx + 4) + "\" y1=\"" + f1(ly + 28) + "\" x2=\"" + f1(lx + 20) + "\" y2=\"" + f1(ly + 28) +
           "\" stroke=\"#d62728\" stroke-width=\"1.5\"/><circle cx=\"" + f1(lx + 12) + "\" cy=\"" + f1(ly + 28) +
           "\" r=\"4\" fill=\"#d62728\"/><text x=\"" + f1(lx + 22) + "\" y=\"" + f1(ly + 32) + "\">Pareto front</text>";
    out += "<circle cx=\"" + f1(lx + 12) + "\" cy=\"" + f1(ly + 44) + "\" r=\"8\" fill=\"none\" stroke=\"black\"/><text x=\"" +
           f1(lx + 22) + "\" y=\"" + f1(ly + 48) + "\">default settings</text>\n";
    return out + "</svg>\n";
}

} // namespace specula::report
