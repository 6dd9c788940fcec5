#pragma once
// Wall-clock timing of stages. Every stage is timed and reported next to its error figure.
#include <chrono>
#include <string>
#include <vector>

namespace specula {

class Stopwatch {
public:
    Stopwatch() : m_start(std::chrono::steady_clock::now()) {}
    void restart() { m_start = std::chrono::steady_clock::now(); }
    [[nodiscard]] double seconds() const {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - m_start).count();
    }

private:
    std::chrono::steady_clock::time_point m_start;
};

struct StageTime {
    std::string name;
    double seconds = 0.0;
};

} // namespace specula
