#include "core/file_util.h"

#include "core/error.h"

#include <atomic>
#include <cerrno>
#include <cstring>
#include <fcntl.h>
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
        fs::rename(tmp, path, ec);
        if (ec) throw InputError(path, "", "cannot write file (renaming " + tmp.string() + " onto it): " + ec.message());
    } catch (...) {
        fs::remove(tmp, ec);
        throw;
    }
}

namespace {
// What errno says, for messages.
std::string errno_text(int error) { return std::strerror(error); }
} // namespace

void write_text_file(const fs::path& path, std::string_view text) {
    write_atomically(path, [&](const fs::path& tmp) {
        // POSIX calls, not a stream, so a failure says why (a full disk: "No space left on
        // device"; a file size limit: "File too large"), from errno.
        const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
        if (fd < 0) throw InputError(path, "", "cannot write file: " + errno_text(errno));
        std::size_t done = 0;
        int error = 0;
        while (done < text.size()) {
            const ssize_t put = ::write(fd, text.data() + done, text.size() - done);
            if (put < 0 && errno == EINTR) continue;
            if (put <= 0) {
                error = put < 0 ? errno : ENOSPC;
                break;
            }
            done += static_cast<std::size_t>(put);
        }
        // close() reports errors of a delayed write (NFS, a full disk found late).
        if (::close(fd) != 0 && error == 0) error = errno;
        if (error != 0) throw InputError(path, "", "cannot write file: " + errno_text(error));
    });
}

std::string read_text_file(const fs::path& path, const std::string& field) {
    std::ifstream in(path, std::ios::binary);
    if (!in) {
        const int error = errno;
        std::error_code ec;
        if (!fs::exists(path, ec)) throw InputError(path, field, "file not found");
        throw InputError(path, field, "cannot read file" + (error != 0 ? ": " + errno_text(error) : std::string()));
    }
    std::ostringstream ss;
    ss << in.rdbuf();
    if (in.bad()) throw InputError(path, field, "cannot read file: " + errno_text(errno));
    return ss.str();
}

std::string path_relative_to(const fs::path& target, const fs::path& from) {
    // An empty path is the current folder (a file named without a folder has an empty parent).
    const auto absolute = [](const fs::path& p) { return fs::absolute(p.empty() ? fs::path(".") : p).lexically_normal(); };
    const fs::path t = absolute(target);
    const fs::path rel = t.lexically_relative(absolute(from));
    if (rel.empty()) return folder_name(t); // no relative path between them (another root)
    std::string s = rel.generic_string();
    if (s.size() > 1 && s.back() == '/') s.pop_back();
    return s;
}

std::string folder_name(const fs::path& folder) {
    fs::path p = fs::absolute(folder.empty() ? fs::path(".") : folder).lexically_normal();
    if (p.filename().empty()) p = p.parent_path(); // a trailing '/'
    return p.filename().string();
}

} // namespace specula
