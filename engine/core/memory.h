#pragma once
// How much memory this process may still take, so a stage can refuse an input that cannot
// fit before it allocates (and fails with a bare std::bad_alloc, or is killed), naming the
// numbers and what would help.
#include <cstdint>
#include <string>

namespace specula {

struct MemoryAvailable {
    std::uint64_t bytes = 0; ///< the smallest of the limits below
    std::string limit;       ///< which limit that is, for messages (e.g. "the address-space limit (ulimit -v)")
};

/// The memory this process can still allocate: the smallest of the machine's available memory
/// (MemAvailable in /proc/meminfo: free memory plus what the kernel can reclaim, without
/// swapping), the control group's limit less its usage (cgroup v2 memory.max, or v1
/// memory.limit_in_bytes) and the address-space limit (RLIMIT_AS, `ulimit -v`) less this
/// process's address space (VmSize). A limit that cannot be read counts as none.
[[nodiscard]] MemoryAvailable available_memory();

/// Caps the C library's malloc arenas at kMallocArenas (glibc; elsewhere nothing). glibc gives
/// each new thread an arena of its own (up to 8 per core), and memory freed into one stays
/// there: the parallel loops start fresh threads, so freed scratch piled up in many arenas.
/// Knot 384 px, reconstruct: peak RSS 1.021 -> 0.978 GB, the same time. Call once, early in main.
void cap_malloc_arenas() noexcept;
inline constexpr int kMallocArenas = 2;

/// "32.7 GB", "512 MB", "20 KB", "12 bytes" (decimal units, 3 significant digits).
[[nodiscard]] std::string format_bytes(std::uint64_t bytes);

} // namespace specula
