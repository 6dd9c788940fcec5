#include "core/log.h"

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <thread>

#include <unistd.h>

namespace specula::log {

namespace {
Level g_level = Level::Normal;
// One lock for everything written to stderr here, so a ticker's redraw never splits a message.
std::mutex g_mutex;
bool g_line_open = false;   // a progress line is drawn without its newline
int g_progress_active = 0;  // Progress bars drawing (tickers pause meanwhile)

// Clears an open progress line; call with g_mutex held.
void close_line() {
    if (!g_line_open) return;
    std::fputs("\r\033[K", stderr);
    g_line_open = false;
}
} // namespace

void set_level(Level level) { g_level = level; }
Level level() { return g_level; }

bool progress_enabled() { return g_level != Level::Quiet && isatty(STDERR_FILENO) != 0; }

void info(std::string_view message) {
    if (g_level == Level::Quiet) return;
    const std::lock_guard lock(g_mutex);
    close_line();
    std::fprintf(stderr, "%.*s\n", static_cast<int>(message.size()), message.data());
}

void warn(std::string_view message) {
    const std::lock_guard lock(g_mutex);
    close_line();
    std::fprintf(stderr, "warning: %.*s\n", static_cast<int>(message.size()), message.data());
}

void debug(std::string_view message) {
    if (g_level != Level::Verbose) return;
    const std::lock_guard lock(g_mutex);
    close_line();
    std::fprintf(stderr, "debug: %.*s\n", static_cast<int>(message.size()), message.data());
}

Progress::Progress(std::string label, std::size_t total)
    : m_label(std::move(label)), m_total(total), m_enabled(progress_enabled()) {
    if (m_enabled) {
        const std::lock_guard lock(g_mutex);
        ++g_progress_active;
    }
}

Progress::~Progress() { finish(); }

void Progress::update(std::size_t done) {
    if (!m_enabled || m_total == 0 || m_finished) return;
    const int percent = static_cast<int>(100 * done / m_total);
    if (percent == m_last_percent) return;
    m_last_percent = percent;
    const std::lock_guard lock(g_mutex);
    std::fprintf(stderr, "\r\033[K%s: %3d%% (%zu/%zu)", m_label.c_str(), percent, done, m_total);
    std::fflush(stderr);
    g_line_open = true;
}

void Progress::finish() {
    if (!m_enabled || m_finished) return;
    m_finished = true;
    const std::lock_guard lock(g_mutex);
    --g_progress_active;
    if (m_last_percent >= 0) {
        std::fprintf(stderr, "\r\033[K%s: done\n", m_label.c_str());
        g_line_open = false;
    }
}

struct Ticker::Impl {
    std::string label;
    double delay = 1.0;
    std::mutex m;
    std::condition_variable cv;
    bool stop = false;
    std::thread thread;

    void run() {
        const auto start = std::chrono::steady_clock::now();
        std::unique_lock lock(m);
        while (!stop) {
            cv.wait_for(lock, std::chrono::milliseconds(250));
            if (stop) break;
            const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
            if (s < delay) continue;
            const std::lock_guard out(g_mutex);
            if (g_progress_active > 0) continue;
            std::fprintf(stderr, "\r\033[K%s: %.1f s", label.c_str(), s);
            std::fflush(stderr);
            g_line_open = true;
        }
    }
};

Ticker::Ticker(std::string label, double delay) {
    if (!progress_enabled()) return;
    m_impl = std::make_unique<Impl>();
    m_impl->label = std::move(label);
    m_impl->delay = delay;
    m_impl->thread = std::thread([impl = m_impl.get()] { impl->run(); });
}

Ticker::~Ticker() { stop(); }

void Ticker::stop() {
    if (m_impl == nullptr) return;
    {
        const std::lock_guard lock(m_impl->m);
        m_impl->stop = true;
    }
    m_impl->cv.notify_all();
    m_impl->thread.join();
    m_impl.reset();
    const std::lock_guard out(g_mutex);
    close_line();
}

} // namespace specula::log
