#include "core/output_dir.h"

#include "core/error.h"

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdio> // renameat2, RENAME_EXCHANGE (glibc 2.28, _GNU_SOURCE)
#include <cstring>
#include <fcntl.h>
#include <optional>
#include <string_view>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

namespace specula {

namespace fs = std::filesystem;

namespace {

std::string errno_text(int error) { return std::strerror(error); }

std::string quoted(const fs::path& p) { return "'" + p.string() + "'"; }

// Whether `child` lies strictly inside `parent` (both canonical or both lexically normal).
bool strictly_inside(const fs::path& child, const fs::path& parent) {
    auto c = child.begin();
    for (auto p = parent.begin(); p != parent.end(); ++p, ++c) {
        if (p->empty()) continue; // a trailing separator
        if (c == child.end() || *c != *p) return false;
    }
    return c != child.end() && !c->empty();
}

// The path with every symbolic link of its existing part resolved; the path itself when that fails.
fs::path resolved(const fs::path& p) {
    std::error_code ec;
    fs::path r = fs::weakly_canonical(fs::absolute(p, ec), ec);
    return ec ? fs::absolute(p).lexically_normal() : r;
}

// "<digits>-<digits>": the tag of a staging or old folder (pid and counter). Anything else
// beside OUT that starts like one belongs to someone else and is never touched.
bool is_tag(std::string_view s) {
    const std::size_t dash = s.find('-');
    if (dash == std::string_view::npos || dash == 0 || dash + 1 == s.size()) return false;
    const auto digits = [](std::string_view d) { return std::all_of(d.begin(), d.end(), [](char c) { return c >= '0' && c <= '9'; }); };
    return digits(s.substr(0, dash)) && digits(s.substr(dash + 1));
}

// Why `dir` cannot be created, when the reason is a file standing where a folder must be
// (OUT under a regular file): the first existing ancestor that is not a folder.
std::optional<fs::path> file_in_the_way(const fs::path& dir) {
    std::error_code ec;
    for (fs::path p = dir; !p.empty(); p = p.parent_path()) {
        const fs::file_status st = fs::status(p, ec);
        if (fs::exists(st)) return fs::is_directory(st) ? std::nullopt : std::optional<fs::path>(p);
        if (p == p.parent_path()) break;
    }
    return std::nullopt;
}

// ".NAME<kind><tag>" for OUT = .../NAME, built by appending (GCC 12 warns falsely,
// -Wrestrict, on the chained + form).
std::string hidden_name(const fs::path& out, const char* kind, const std::string& tag) {
    std::string name(".");
    name += out.filename().string();
    name += kind;
    name += tag;
    return name;
}

} // namespace

fs::path output_folder_path(const fs::path& out) {
    fs::path p = fs::absolute(out).lexically_normal();
    if (p.filename().empty() && p.has_parent_path() && p != p.root_path()) p = p.parent_path(); // "dir/" names dir
    return p;
}

OutputFolder::OutputFolder(const fs::path& out_arg, OutputFolderOptions options) : m_options(std::move(options)) {
    const std::string& opt = m_options.option;
    if (out_arg.empty()) throw UsageError(opt + ": no output folder given");
    m_out = output_folder_path(out_arg);
    if (m_out == m_out.root_path() || m_out.filename().empty())
        throw UsageError(opt + ": " + quoted(m_out) + " cannot be an output folder (it is a file system root)");

    // OUT itself: a folder or nothing (a file or a device such as /dev/null is refused).
    std::error_code ec;
    const fs::file_status st = fs::status(m_out, ec);
    if (fs::exists(st) && !fs::is_directory(st))
        throw UsageError(opt + ": " + quoted(m_out) + " exists and is not a folder" +
                         (fs::is_character_file(st) || fs::is_block_file(st) ? " (it is a device)" : ""));

    // OUT may not be, or hold, what this run reads: replacing OUT would delete it.
    const fs::path out_real = resolved(m_out);
    for (const fs::path& input : m_options.inputs) {
        if (input.empty() || !fs::exists(fs::symlink_status(input, ec))) continue; // nothing there to lose
        const fs::path in_real = resolved(input);
        if (in_real == out_real)
            throw UsageError(opt + ": " + quoted(m_out) + " is an input of this run; the output folder is replaced " +
                             "as a whole, so it must be another folder");
        if (strictly_inside(in_real, out_real))
            throw UsageError(opt + ": " + quoted(m_out) + " contains an input of this run (" + input.string() +
                             "); the output folder is replaced as a whole, so it must be another folder");
    }

    // The parent folder: made now, so that a path that cannot be created is refused before any work.
    const fs::path parent = m_out.parent_path();
    fs::create_directories(parent, ec);
    if (ec) {
        if (const auto file = file_in_the_way(parent))
            throw InputError(m_out, opt, "cannot create the output folder: " + quoted(*file) + " is a file, not a folder");
        throw InputError(m_out, opt, "cannot create the output folder's parent " + quoted(parent) + ": " + ec.message());
    }

    lock();
    try {
        recover();
        if (fs::is_directory(m_out, ec) && !fs::is_empty(m_out, ec) && !m_options.force &&
            !(m_options.is_previous && m_options.is_previous(m_out)))
            throw UsageError(opt + ": folder " + quoted(m_out) + " is not empty" +
                             (m_options.is_previous ? " and holds no earlier result of this command" : "") +
                             " (use --force to replace it; it is replaced only once the new result is complete)");
        static std::atomic<unsigned> counter{0};
        m_tag = std::to_string(::getpid()) + "-" + std::to_string(counter++);
        m_staging = parent / hidden_name(m_out, ".tmp-", m_tag);
        fs::remove_all(m_staging, ec);
        if (!fs::create_directory(m_staging, ec) || ec)
            throw InputError(m_out, opt, "cannot create the staging folder " + quoted(m_staging) + ": " + ec.message());
    } catch (...) {
        unlock();
        throw;
    }
}

OutputFolder::~OutputFolder() {
    if (!m_committed && !m_staging.empty()) {
        std::error_code ec;
        fs::remove_all(m_staging, ec);
    }
    unlock();
}

void OutputFolder::lock() {
    const std::string& opt = m_options.option;
    m_lock_path = m_out.parent_path() / hidden_name(m_out, ".lock", "");
    // The holder removes the lock file when it ends; a run that opened the file just before
    // that and then got the lock holds a removed file: it checks that the file it locked is
    // still the one at the path, and tries again when not.
    for (int attempt = 0; attempt < 100; ++attempt) {
        const int fd = ::open(m_lock_path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644);
        if (fd < 0) {
            const int error = errno;
            if (const auto file = file_in_the_way(m_out.parent_path()))
                throw InputError(m_out, opt, "cannot create the output folder: " + quoted(*file) + " is a file, not a folder");
            throw InputError(m_out, opt, "cannot create the output folder here (" + m_lock_path.string() + ": " +
                                             errno_text(error) + ")");
        }
        if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
            const int error = errno;
            char holder[32] = {};
            const ssize_t got = ::pread(fd, holder, sizeof holder - 1, 0);
            ::close(fd);
            std::string pid = got > 0 ? std::string(holder, static_cast<std::size_t>(got)) : std::string();
            pid.erase(std::remove(pid.begin(), pid.end(), '\n'), pid.end());
            if (error == EWOULDBLOCK)
                throw InputError(m_out, opt,
                                 "another specula run" + (pid.empty() ? std::string() : " (pid " + pid + ")") +
                                     " is writing this output folder (it holds " + m_lock_path.string() +
                                     "); wait for it to end, or choose another folder");
            throw InputError(m_out, opt, "cannot lock " + m_lock_path.string() + ": " + errno_text(error));
        }
        struct stat held {};
        struct stat named {};
        if (::fstat(fd, &held) == 0 && ::stat(m_lock_path.c_str(), &named) == 0 && held.st_dev == named.st_dev &&
            held.st_ino == named.st_ino) {
            m_lock_fd = fd;
            const std::string pid = std::to_string(::getpid()) + "\n";
            if (::ftruncate(fd, 0) != 0 || ::pwrite(fd, pid.data(), pid.size(), 0) < 0) {
                // The pid only improves a second run's message; the lock holds without it.
            }
            return;
        }
        ::close(fd);
    }
    throw InputError(m_out, opt, "cannot lock " + m_lock_path.string() + ": it keeps being replaced");
}

void OutputFolder::unlock() noexcept {
    if (m_lock_fd < 0) return;
    ::unlink(m_lock_path.c_str()); // while still held: see lock()
    ::close(m_lock_fd);
    m_lock_fd = -1;
}

void OutputFolder::recover() {
    // With the lock held no other run writes OUT, so every staging or old folder of OUT is
    // left over from a run that was killed.
    const fs::path parent = m_out.parent_path();
    const std::string tmp_prefix = hidden_name(m_out, ".tmp-", "");
    const std::string old_prefix = hidden_name(m_out, ".old-", "");
    std::vector<fs::path> stale, olds;
    std::error_code ec;
    for (fs::directory_iterator it(parent, ec), end; !ec && it != end; it.increment(ec)) {
        const std::string name = it->path().filename().string();
        if (name.rfind(tmp_prefix, 0) == 0 && is_tag(std::string_view(name).substr(tmp_prefix.size())))
            stale.push_back(it->path());
        else if (name.rfind(old_prefix, 0) == 0 && is_tag(std::string_view(name).substr(old_prefix.size())))
            olds.push_back(it->path());
    }
    // A run killed between the two renames of the fallback: OUT is gone and its previous
    // content is complete in .NAME.old-*: it goes back (the newest, should there be several).
    if (!olds.empty() && !fs::exists(fs::symlink_status(m_out, ec))) {
        std::sort(olds.begin(), olds.end(), [](const fs::path& a, const fs::path& b) {
            std::error_code e;
            return fs::last_write_time(a, e) < fs::last_write_time(b, e);
        });
        fs::rename(olds.back(), m_out, ec);
        if (ec)
            throw InputError(m_out, m_options.option, "a killed run left the previous result in " + quoted(olds.back()) +
                                                          " and it cannot be moved back: " + ec.message());
        m_recovered.push_back("restored " + m_out.string() + " from " + olds.back().string() +
                              " (a run was killed while replacing it)");
        olds.pop_back();
    }
    stale.insert(stale.end(), olds.begin(), olds.end());
    for (const fs::path& p : stale) {
        fs::remove_all(p, ec);
        m_recovered.push_back(ec ? "cannot remove " + p.string() + ", left by a killed run: " + ec.message()
                                 : "removed " + p.string() + ", left by a killed run");
    }
}

void OutputFolder::commit() {
    const std::string& opt = m_options.option;
    if (m_committed) throw Error("OutputFolder::commit called twice for " + m_out.string());
    std::error_code ec;
    if (!fs::exists(fs::symlink_status(m_out, ec))) {
        fs::rename(m_staging, m_out, ec);
        if (ec) throw InputError(m_out, opt, "cannot move the new result into place: " + ec.message());
        m_committed = true;
        return;
    }
    // One atomic swap where the file system has it: OUT is never missing.
    if (m_options.exchange) {
        if (::renameat2(AT_FDCWD, m_staging.c_str(), AT_FDCWD, m_out.c_str(), RENAME_EXCHANGE) == 0) {
            m_committed = true;
            fs::remove_all(m_staging, ec); // now the previous result
            return;
        }
        const int error = errno;
        // No exchange on this file system (EINVAL; overlayfs may say EXDEV): the two renames.
        if (error != EINVAL && error != ENOSYS && error != EOPNOTSUPP && error != EXDEV)
            throw InputError(m_out, opt, "cannot move the new result into place: " + errno_text(error));
    }
    const fs::path old = m_out.parent_path() / hidden_name(m_out, ".old-", m_tag);
    fs::rename(m_out, old, ec);
    if (ec) throw InputError(m_out, opt, "cannot move the previous result aside: " + ec.message());
    // A crash here leaves `old` and the staging folder; the next run restores `old` (recover()).
    fs::rename(m_staging, m_out, ec);
    if (ec) {
        std::error_code back;
        fs::rename(old, m_out, back);
        throw InputError(m_out, opt, "cannot move the new result into place: " + ec.message());
    }
    m_committed = true;
    fs::remove_all(old, ec);
}

fs::path write_folder_atomically(const fs::path& out, const OutputFolderOptions& options,
                                 const std::function<void(const fs::path& staging)>& write) {
    OutputFolder folder(out, options);
    write(folder.staging());
    folder.commit();
    return folder.path();
}

} // namespace specula
