#include "core/file_util.h"

#include "core/error.h"

#include <atomic>
#include <fstream>
#include <sstream>
#include <unistd.h>

namespace specula {

namespace fs = std::filesystem;

void write_atomically(const fs::path& path, const std::function<void(const fs::path& tmp)>& write) {
    static std::atomic<unsigned> counter{0};
    const fs::path parent = path.has_parent_path() ? path.parent_path() : fs::path(".");
    std::error_code ec;
    fs::create_directories(parent, ec);
    if (ec) throw InputError(parent, "", "cannot create directory: " + ec.message());
    // Keep the extension last: OpenImageIO picks the format from it.
    const fs::path tmp = parent / (".tmp-" + std::to_string(getpid()) + "-" + std::to_string(counter++) + "-" +
                                   path.filename().string());
    try {
        write(tmp);
        fs::rename(tmp, path);
    } catch (...) {
        fs::remove(tmp, ec);
        throw;
    }
}

void write_text_file(const fs::path& path, std::string_view text) {
    write_atomically(path, [&](const fs::path& tmp) {
        std::ofstream out(tmp, std::ios::binary);
        out.write(text.data(), static_cast<std::streamsize>(text.size()));
        out.close();
        if (!out) throw InputError(path, "", "cannot write file");
    });
}

std::string read_text_file(const fs::path& path, const std::string& field) {
    std::ifstream in(path, std::ios::binary);
    if (!in) {
        std::error_code ec;
        throw InputError(path, field, fs::exists(path, ec) ? "cannot read file" : "file not found");
    }
    std::ostringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

} // namespace specula
