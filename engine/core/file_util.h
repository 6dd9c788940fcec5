#pragma once
// File helpers: outputs are written to a temporary sibling and renamed into
// place, so a failure never leaves a half-written file behind.
#include <filesystem>
#include <functional>
#include <string>
#include <string_view>

namespace specula {

/// Calls write(tmp_path), then renames tmp_path onto path. On any exception the
/// temporary is removed and the exception propagates; path is untouched.
void write_atomically(const std::filesystem::path& path,
                      const std::function<void(const std::filesystem::path& tmp)>& write);

/// Writes text to path atomically. Throws InputError naming the file on failure.
void write_text_file(const std::filesystem::path& path, std::string_view text);

/// Reads a whole file. Throws InputError(path, field, ...) when missing or unreadable.
[[nodiscard]] std::string read_text_file(const std::filesystem::path& path, const std::string& field = {});

} // namespace specula
