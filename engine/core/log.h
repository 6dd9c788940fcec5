#pragma once
// Minimal leveled logging to stderr. Quiet mode silences info and progress;
// warnings are also collected by the caller where a report needs them.
#include <cstdio>
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

} // namespace specula::log
