#pragma once
// Minimal leveled logging to stderr. Quiet mode silences info and progress;
// warnings are also collected by the caller where a report needs them.
#include <cstdio>
#include <memory>
#include <string>
#include <string_view>

namespace specula::log {

enum class Level { Quiet, Normal, Verbose };
void set_level(Level level);
[[nodiscard]] Level level();

void info(std::string_view message);
void warn(std::string_view message);
void debug(std::string_view message);

/// Progress for long work: a single self-overwriting line on a terminal,
/// nothing when stderr is not a terminal or in quiet mode.
class Progress {
public:
    Progress(std::string label, std::size_t total);
    ~Progress();
    Progress(const Progress&) = delete;
    Progress& operator=(const Progress&) = delete;
    void update(std::size_t done);
    void finish();

private:
    std::string m_label;
    std::size_t m_total;
    int m_last_percent = -1;
    bool m_enabled;
    bool m_finished = false;
};

/// Progress for a stage with no natural count: after `delay` seconds, a self-overwriting
/// line "label: 3.2 s" redrawn four times a second by a background thread, on a terminal
/// only (nothing when stderr is not a terminal or in quiet mode). While a Progress bar is
/// drawing, the ticker stays silent so the two never fight over the line; log messages
/// clear the line before they print.
class Ticker {
public:
    explicit Ticker(std::string label, double delay = 1.0);
    ~Ticker();
    Ticker(const Ticker&) = delete;
    Ticker& operator=(const Ticker&) = delete;
    /// Stops the thread and ends the line (idempotent).
    void stop();

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

/// True when progress lines are drawn (stderr is a terminal and the level is not quiet).
[[nodiscard]] bool progress_enabled();

} // namespace specula::log
