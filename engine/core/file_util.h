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

/// `target` as written in a file that travels with an output folder, which must hold no
/// machine path: relative to the folder `from` (both taken absolute, "." and ".." folded),
/// in '/' form; an empty path is the current folder ("out.json"'s parent). An output's staging
/// folder sits beside it (core/output_dir.h), so a path relative to the staging folder holds for
/// the output folder too.
[[nodiscard]] std::string path_relative_to(const std::filesystem::path& target, const std::filesystem::path& from);

/// The last name of a folder's path ("captures/can/" and "captures/can" give "can").
[[nodiscard]] std::string folder_name(const std::filesystem::path& folder);

} // namespace specula
