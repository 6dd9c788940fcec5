#pragma once
/// \file
/// A scatter plot of error against run time as one standalone SVG document (the
/// sweep's plot): every point, the default marked, the Pareto front drawn as a step
/// line through its points and listed. Linear axes with round ticks; strings escaped.
#include <span>
#include <string>
#include <string_view>

namespace specula::report {

struct PlotPoint {
    double x = 0.0;          ///< run time (s)
    double y = 0.0;          ///< error
    std::string label;       ///< shown beside front points and the default
    bool is_default = false; ///< drawn as a larger ring
    bool on_front = false;   ///< joined by the front line (in increasing x)
};

[[nodiscard]] std::string svg_pareto_plot(std::span<const PlotPoint> points, std::string_view title, std::string_view x_label,
                                          std::string_view y_label, int width = 760, int height = 480);

} // namespace specula::report
