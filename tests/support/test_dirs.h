#pragma once
// Per-test scratch folders under the build tree's temp area, removed at the end of the test.
#include <filesystem>
#include <string>

namespace specula::test {

/// A fresh, empty folder, removed (with its content) on destruction.
class TempDir {
public:
    explicit TempDir(const std::string& tag = "t");
    ~TempDir();
    TempDir(const TempDir&) = delete;
    TempDir& operator=(const TempDir&) = delete;
    [[nodiscard]] const std::filesystem::path& path() const noexcept { return m_path; }
    [[nodiscard]] std::filesystem::path operator/(const std::string& name) const { return m_path / name; }

private:
    std::filesystem::path m_path;
};

/// The repository root (SPECULA_SOURCE_DIR, set by ctest).
[[nodiscard]] std::filesystem::path source_dir();

} // namespace specula::test
