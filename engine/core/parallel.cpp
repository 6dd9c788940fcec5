#include "core/parallel.h"

#include <algorithm>
#include <atomic>
#include <exception>
#include <limits>
#include <mutex>
#include <system_error>
#include <thread>
#include <vector>

namespace specula {

namespace {

std::size_t chunk_count(std::size_t count, std::size_t chunk) { return count / chunk + (count % chunk != 0 ? 1 : 0); }

} // namespace

unsigned parallel_workers(std::size_t count, unsigned threads, std::size_t chunk) noexcept {
    const std::size_t chunks = chunk_count(count, std::max<std::size_t>(chunk, 1));
    return static_cast<unsigned>(std::clamp<std::size_t>(chunks, 1, std::max(threads, 1u)));
}

namespace detail {

void parallel_run(std::size_t count, unsigned threads, std::size_t chunk, ChunkBody call, void* body) {
    chunk = std::max<std::size_t>(chunk, 1);
    const std::size_t chunks = chunk_count(count, chunk);
    const unsigned workers = parallel_workers(count, threads, chunk);
    if (workers == 1) { // inline, in order: the first throw ends the loop, as in a plain for
        for (std::size_t c = 0; c < chunks; ++c) call(body, 0, c * chunk, std::min(count, (c + 1) * chunk));
        return;
    }

    constexpr std::size_t kNone = std::numeric_limits<std::size_t>::max();
    std::atomic<std::size_t> next{0};
    std::atomic<std::size_t> first_failed{kNone}; // lowest failing chunk so far
    std::exception_ptr failure;                   // its exception
    std::mutex failure_mutex;

    auto work = [&](unsigned worker) noexcept {
        // Chunks are taken in increasing order, so once chunk k failed every chunk below k
        // has already been taken (and finishes) and every later one can be left out.
        for (std::size_t c = next++; c < chunks && c < first_failed.load(); c = next++) {
            try {
                call(body, worker, c * chunk, std::min(count, (c + 1) * chunk));
            } catch (...) {
                const std::lock_guard lock(failure_mutex);
                if (c < first_failed.load()) {
                    first_failed = c;
                    failure = std::current_exception();
                }
            }
        }
    };

    std::vector<std::thread> pool;
    pool.reserve(workers - 1);
    try {
        for (unsigned w = 1; w < workers; ++w) pool.emplace_back(work, w);
    } catch (const std::system_error&) {
        // No thread could be started (resource limits): the threads that did start and the
        // calling thread share the work; the result is the same, only slower.
    }
    work(0);
    for (std::thread& t : pool) t.join();
    if (failure) std::rethrow_exception(failure);
}

} // namespace detail

} // namespace specula
