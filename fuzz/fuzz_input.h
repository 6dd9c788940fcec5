#pragma once
// Shared by the fuzz targets: a scratch file for readers that take a path, and the rule for
// what a reader may throw.
#include "core/error.h"

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <string>

namespace specula::fuzz {

/// A private, empty folder (in /dev/shm when there is one: the input is rewritten per run);
/// removed at exit.
inline const std::filesystem::path& scratch_dir() {
    static const std::filesystem::path dir = [] {
        const std::filesystem::path base = std::filesystem::exists("/dev/shm") ? "/dev/shm" : std::filesystem::temp_directory_path();
        std::filesystem::path d = base / ("specula-fuzz-" + std::to_string(::getpid()));
        std::filesystem::create_directories(d);
        return d;
    }();
    static const struct Cleanup {
        ~Cleanup() {
            std::error_code ec;
            std::filesystem::remove_all(dir, ec);
        }
    } cleanup;
    return dir;
}

/// Writes the input to scratch_dir()/name and returns the path.
inline std::filesystem::path write_input(const std::uint8_t* data, std::size_t size, const std::string& name) {
    const std::filesystem::path path = scratch_dir() / name;
    std::FILE* f = std::fopen(path.c_str(), "wb");
    if (f == nullptr) __builtin_trap();
    if (size > 0 && std::fwrite(data, 1, size, f) != size) __builtin_trap();
    std::fclose(f);
    return path;
}

} // namespace specula::fuzz
