#include "core/memory.h"

#include <sys/resource.h>
#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>

namespace specula {

namespace {

constexpr std::uint64_t kNone = std::numeric_limits<std::uint64_t>::max();

// The value in kB of "key:" in a /proc file such as /proc/meminfo, in bytes; kNone if absent.
std::uint64_t proc_kb(const char* file, const std::string& key) {
    std::ifstream in(file);
    std::string line;
    while (std::getline(in, line)) {
        if (line.compare(0, key.size(), key) != 0) continue;
        std::istringstream fields(line.substr(key.size()));
        std::uint64_t kb = 0;
        if (fields >> kb) return kb * 1024u;
    }
    return kNone;
}

// The first number in a file (cgroup files hold one number, or "max"); kNone if none.
std::uint64_t file_number(const std::string& path) {
    std::ifstream in(path);
    std::uint64_t v = 0;
    if (in >> v) return v;
    return kNone;
}

// Memory the control group lets this process still use: limit less usage.
std::uint64_t cgroup_room() {
    // cgroup v2: "0::/path" in /proc/self/cgroup, the files under /sys/fs/cgroup/path.
    std::ifstream in("/proc/self/cgroup");
    std::string line, v2_path, v1_path;
    while (std::getline(in, line)) {
        if (line.rfind("0::", 0) == 0) v2_path = line.substr(3);
        const auto at = line.find(":memory:");
        if (at != std::string::npos) v1_path = line.substr(at + 8);
    }
    auto room = [](std::uint64_t limit, std::uint64_t used) {
        if (limit == kNone || used == kNone) return kNone;
        return limit > used ? limit - used : 0;
    };
    std::uint64_t best = kNone;
    for (const std::string& base : {"/sys/fs/cgroup" + v2_path, std::string("/sys/fs/cgroup")}) {
        if (v2_path.empty()) break;
        best = std::min(best, room(file_number(base + "/memory.max"), file_number(base + "/memory.current")));
        if (best != kNone) break;
    }
    if (!v1_path.empty())
        for (const std::string& base : {"/sys/fs/cgroup/memory" + v1_path, std::string("/sys/fs/cgroup/memory")}) {
            const std::uint64_t r = room(file_number(base + "/memory.limit_in_bytes"), file_number(base + "/memory.usage_in_bytes"));
            if (r != kNone) {
                best = std::min(best, r);
                break;
            }
        }
    return best;
}

} // namespace

MemoryAvailable available_memory() {
    MemoryAvailable m{kNone, "no limit found"};
    auto consider = [&](std::uint64_t bytes, const char* what) {
        if (bytes < m.bytes) m = {bytes, what};
    };
    consider(proc_kb("/proc/meminfo", "MemAvailable:"), "the machine's available memory (MemAvailable)");
    consider(cgroup_room(), "the control group's memory limit");
    rlimit as{};
    if (::getrlimit(RLIMIT_AS, &as) == 0 && as.rlim_cur != RLIM_INFINITY) {
        const std::uint64_t used = proc_kb("/proc/self/status", "VmSize:");
        const std::uint64_t limit = static_cast<std::uint64_t>(as.rlim_cur);
        consider(used == kNone ? limit : (limit > used ? limit - used : 0), "the address-space limit (ulimit -v)");
    }
    return m;
}

void cap_malloc_arenas() noexcept {
#if defined(__GLIBC__)
    (void)mallopt(M_ARENA_MAX, kMallocArenas);
#endif
}

std::string format_bytes(std::uint64_t bytes) {
    static const char* const units[] = {"KB", "MB", "GB", "TB", "PB", "EB"};
    if (bytes < 1000) return std::to_string(bytes) + " bytes";
    double v = static_cast<double>(bytes) / 1000.0;
    std::size_t u = 0;
    while (v >= 1000.0 && u + 1 < std::size(units)) {
        v /= 1000.0;
        ++u;
    }
    char text[32];
    std::snprintf(text, sizeof text, v < 10.0 ? "%.2f %s" : v < 100.0 ? "%.1f %s" : "%.0f %s", v, units[u]);
    return text;
}

} // namespace specula
