#include "test_dirs.h"

#include <atomic>
#include <cstdlib>
#include <stdexcept>
#include <unistd.h>

namespace specula::test {

namespace fs = std::filesystem;

TempDir::TempDir(const std::string& tag) {
    static std::atomic<unsigned> counter{0};
    m_path = fs::temp_directory_path() /
             ("specula-test-" + tag + "-" + std::to_string(getpid()) + "-" + std::to_string(counter++));
    fs::remove_all(m_path);
    fs::create_directories(m_path);
}

TempDir::~TempDir() {
    std::error_code ec;
    if (std::getenv("SPECULA_KEEP_TEST_DIRS") == nullptr) fs::remove_all(m_path, ec);
}

fs::path source_dir() {
    const char* dir = std::getenv("SPECULA_SOURCE_DIR");
    if (dir == nullptr) throw std::runtime_error("SPECULA_SOURCE_DIR is not set (run the tests through ctest)");
    return dir;
}

} // namespace specula::test
