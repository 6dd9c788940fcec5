#pragma once
// printf-style formatting of a few numbers into a std::string (report text, decisions,
// tables), one definition for every stage.
#include <cstdio>
#include <sstream>
#include <string>

namespace specula {

/// `format` applied by snprintf to the numbers `args`, each passed as a double (so the
/// format's conversions are the floating-point ones: %f, %g, %e); text longer than 255
/// characters is cut.
template <typename... Args>
[[nodiscard]] std::string format_text(const char* format, Args... args) {
    char buf[256];
    std::snprintf(buf, sizeof buf, format, static_cast<double>(args)...);
    return buf;
}

/// A number for messages: "1e+15", "0.001", "2.5" (6 significant digits, no trailing zeros).
[[nodiscard]] inline std::string short_number(double v) {
    std::ostringstream s;
    s.precision(6);
    s << v;
    return s.str();
}

} // namespace specula
