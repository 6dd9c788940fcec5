#include "core/log.h"

#include <unistd.h>

namespace specula::log {

namespace {
Level g_level = Level::Normal;
}

void set_level(Level level) { g_level = level; }
Level level() { return g_level; }

void info(std::string_view message) {
    if (g_level == Level::Quiet) return;
    std::fprintf(stderr, "%.*s\n", static_cast<int>(message.size()), message.data());
}

void warn(std::string_view message) {
    std::fprintf(stderr, "warning: %.*s\n", static_cast<int>(message.size()), message.data());
}

void debug(std::string_view message) {
    if (g_level != Level::Verbose) return;
    std::fprintf(stderr, "debug: %.*s\n", static_cast<int>(message.size()), message.data());
}

Progress::Progress(std::string label, std::size_t total)
    : m_label(std::move(label)), m_total(total), m_enabled(g_level != Level::Quiet && isatty(STDERR_FILENO) != 0) {}

Progress::~Progress() { finish(); }

void Progress::update(std::size_t done) {
    if (!m_enabled || m_total == 0) return;
    const int percent = static_cast<int>(100 * done / m_total);
    if (percent == m_last_percent) return;
    m_last_percent = percent;
    std::fprintf(stderr, "\r%s: %3d%% (%zu/%zu)", m_label.c_str(), percent, done, m_total);
    std::fflush(stderr);
}

void Progress::finish() {
    if (!m_enabled || m_finished) return;
    m_finished = true;
    if (m_last_percent >= 0) std::fprintf(stderr, "\r%s: done%*s\n", m_label.c_str(), 20, "");
}

} // namespace specula::log
