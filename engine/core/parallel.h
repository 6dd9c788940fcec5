#pragma once
// The engine's one parallel loop. Every CPU-parallel stage (image decoding, visibility,
// the synthetic renderer) runs through it, so that a throw in any worker reaches the
// caller instead of ending the process (an exception escaping a std::thread calls
// std::terminate), and so that the error a caller sees does not depend on the schedule.
//
// Work is cut into chunks of consecutive indices and handed out in increasing order to
// whichever worker is free (a shared counter: a dynamic schedule, since rows of an image
// or particles of a mesh cost very different amounts). The calling thread is worker 0;
// threads are started per call (the loops it serves run for milliseconds to minutes, so
// a thread start, about 50 us, does not matter and no pool has to outlive the call).
//
// Errors: when a body throws, no chunk after the failing one is started (the ones before
// it were already handed out and finish), every worker is joined, then the exception of
// the lowest failing chunk is rethrown, the original object (type and message kept).
// That is the exception a plain serial loop would have thrown first, whatever the thread
// count, as long as the body itself is deterministic.
#include <cstddef>
#include <memory>
#include <type_traits>

namespace specula {

/// How many workers the loops below use for `count` indices in chunks of `chunk`:
/// min(threads, number of chunks), at least 1 (threads 0 counts as 1). Size per-worker
/// state (counters, scratch buffers) with it; `worker` is always below it.
[[nodiscard]] unsigned parallel_workers(std::size_t count, unsigned threads, std::size_t chunk = 1) noexcept;

namespace detail {
using ChunkBody = void (*)(void* body, unsigned worker, std::size_t begin, std::size_t end);
void parallel_run(std::size_t count, unsigned threads, std::size_t chunk, ChunkBody call, void* body);
} // namespace detail

/// body(worker, begin, end) for the consecutive chunks [begin, end) that cover [0, count),
/// `chunk` indices each (the last may be shorter; chunk 0 counts as 1), on
/// parallel_workers(count, threads, chunk) workers. With one worker every chunk runs
/// inline on the calling thread, in order, and no thread is started. Errors: see above.
template <class F>
void parallel_for_chunks(std::size_t count, unsigned threads, std::size_t chunk, F&& body) {
    using Body = std::remove_reference_t<F>;
    detail::parallel_run(
        count, threads, chunk,
        [](void* b, unsigned worker, std::size_t begin, std::size_t end) { (*static_cast<Body*>(b))(worker, begin, end); },
        const_cast<void*>(static_cast<const void*>(std::addressof(body))));
}

/// body(i) for every i in [0, count), one index per chunk (each index is its own unit of
/// work: a frame to decode, a row to trace). Errors: see above.
template <class F>
void parallel_for(std::size_t count, unsigned threads, F&& body) {
    parallel_for_chunks(count, threads, 1, [&body](unsigned, std::size_t begin, std::size_t end) {
        for (std::size_t i = begin; i < end; ++i) body(i);
    });
}

} // namespace specula
