// The engine's parallel loop (core/parallel.h): every index exactly once, chunks that tile
// the range, one worker runs inline, and a throw in a worker thread reaches the caller
// as the same exception, the one a serial loop would have thrown, after every worker joined.
#include "core/parallel.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace specula {
namespace {

// A type no library code throws, so catching it proves the original object came through.
struct WorkerFailure : std::runtime_error {
    WorkerFailure(const std::string& what, std::size_t index) : std::runtime_error(what), index(index) {}
    std::size_t index;
};

TEST(ParallelWorkers, CappedByChunksAndAtLeastOne) {
    EXPECT_EQ(parallel_workers(0, 4), 1u);
    EXPECT_EQ(parallel_workers(3, 8), 3u);
    EXPECT_EQ(parallel_workers(100, 8), 8u);
    EXPECT_EQ(parallel_workers(100, 0), 1u);
    EXPECT_EQ(parallel_workers(2048, 8, 1024), 2u);
    EXPECT_EQ(parallel_workers(2049, 8, 1024), 3u);
    EXPECT_EQ(parallel_workers(5, 4, 0), 4u); // chunk 0 counts as 1
}

TEST(ParallelFor, VisitsEveryIndexExactlyOnce) {
    for (unsigned threads : {1u, 2u, 3u, 8u})
        for (std::size_t count : {std::size_t(0), std::size_t(1), std::size_t(7), std::size_t(10007)}) {
            std::vector<std::atomic<int>> visits(count);
            parallel_for(count, threads, [&](std::size_t i) { ++visits[i]; });
            for (std::size_t i = 0; i < count; ++i)
                ASSERT_EQ(visits[i].load(), 1) << "index " << i << " of " << count << ", " << threads << " threads";
        }
}

TEST(ParallelForChunks, ChunksTileTheRangeAndWorkersStayInRange) {
    for (unsigned threads : {1u, 3u, 8u})
        for (std::size_t chunk : {std::size_t(1), std::size_t(7), std::size_t(1000), std::size_t(20000)}) {
            const std::size_t count = 10007;
            const unsigned workers = parallel_workers(count, threads, chunk);
            std::vector<std::atomic<int>> visits(count);
            std::atomic<bool> bad_chunk{false}, bad_worker{false};
            parallel_for_chunks(count, threads, chunk, [&](unsigned worker, std::size_t begin, std::size_t end) {
                if (worker >= workers) bad_worker = true;
                // Every chunk starts on a multiple of `chunk` and is full, except the last.
                if (begin % chunk != 0 || !(begin < end) || (end - begin != chunk && end != count)) bad_chunk = true;
                for (std::size_t i = begin; i < end; ++i) ++visits[i];
            });
            EXPECT_FALSE(bad_chunk) << "chunk " << chunk << ", " << threads << " threads";
            EXPECT_FALSE(bad_worker) << "chunk " << chunk << ", " << threads << " threads";
            for (std::size_t i = 0; i < count; ++i) ASSERT_EQ(visits[i].load(), 1) << "index " << i << ", chunk " << chunk;
        }
}

TEST(ParallelFor, OneThreadRunsInlineInOrder) {
    for (unsigned threads : {0u, 1u}) {
        const std::thread::id caller = std::this_thread::get_id();
        std::vector<std::size_t> order;
        bool other_thread = false;
        parallel_for_chunks(10, threads, 3, [&](unsigned worker, std::size_t begin, std::size_t end) {
            if (std::this_thread::get_id() != caller || worker != 0) other_thread = true;
            for (std::size_t i = begin; i < end; ++i) order.push_back(i); // unsynchronized: only safe inline
        });
        EXPECT_FALSE(other_thread) << threads << " threads";
        ASSERT_EQ(order.size(), 10u);
        for (std::size_t i = 0; i < order.size(); ++i) EXPECT_EQ(order[i], i);
    }
    // Also when more threads are asked for than there are chunks of work.
    const std::thread::id caller = std::this_thread::get_id();
    bool other_thread = false;
    parallel_for(1, 8, [&](std::size_t) { other_thread = std::this_thread::get_id() != caller; });
    EXPECT_FALSE(other_thread);
}

TEST(ParallelFor, InlineThrowStopsTheLoopLikeAPlainFor) {
    std::vector<std::size_t> seen;
    try {
        parallel_for(10, 1, [&](std::size_t i) {
            seen.push_back(i);
            if (i == 4) throw WorkerFailure("index 4", i);
        });
        FAIL() << "nothing was thrown";
    } catch (const WorkerFailure& e) {
        EXPECT_EQ(e.index, 4u);
        EXPECT_STREQ(e.what(), "index 4");
    }
    EXPECT_EQ(seen, (std::vector<std::size_t>{0, 1, 2, 3, 4}));
}

// The calling thread (worker 0) takes index 0 and waits there until a started thread has
// thrown, so the exception certainly comes from a thread other than the caller's.
TEST(ParallelFor, ThrowInAWorkerThreadReachesTheCallerAfterEveryWorkerJoined) {
    const std::thread::id caller = std::this_thread::get_id();
    std::mutex m;
    std::condition_variable thrown_cv;
    std::vector<std::size_t> thrown; // indices that threw, all from other threads
    std::atomic<int> running{0};
    std::atomic<bool> caller_timed_out{false};
    try {
        parallel_for(64, 4, [&](std::size_t i) {
            ++running;
            struct Leave {
                std::atomic<int>& r;
                ~Leave() { --r; }
            } leave{running};
            if (std::this_thread::get_id() == caller) {
                std::unique_lock lock(m);
                if (!thrown_cv.wait_for(lock, std::chrono::seconds(20), [&] { return !thrown.empty(); })) caller_timed_out = true;
                return;
            }
            std::this_thread::sleep_for(std::chrono::milliseconds(2)); // still running when the caller wakes
            {
                const std::lock_guard lock(m);
                thrown.push_back(i);
            }
            thrown_cv.notify_all();
            throw WorkerFailure("worker failed at index " + std::to_string(i), i);
        });
        FAIL() << "nothing was thrown";
    } catch (const WorkerFailure& e) {
        EXPECT_EQ(running.load(), 0) << "a body was still running when the exception reached the caller";
        const std::lock_guard lock(m);
        ASSERT_FALSE(thrown.empty());
        const std::size_t lowest = *std::min_element(thrown.begin(), thrown.end());
        EXPECT_EQ(e.index, lowest);
        EXPECT_EQ(std::string(e.what()), "worker failed at index " + std::to_string(lowest));
    }
    EXPECT_FALSE(caller_timed_out) << "no started thread ever ran a body";
}

// Two failing indices: whichever fails first in time, the caller always gets the lower one,
// as a serial loop would; and it is the same object (a non-std type too).
TEST(ParallelFor, RethrowsTheLowestFailingIndexWhateverTheSchedule) {
    for (int round = 0; round < 20; ++round) {
        try {
            parallel_for(400, 4, [&](std::size_t i) {
                if (i == 300) throw WorkerFailure("low", i); // usually fails after 350: later in time
                if (i == 350) throw WorkerFailure("high", i);
                if (i < 300) std::this_thread::sleep_for(std::chrono::microseconds(50));
            });
            FAIL() << "nothing was thrown";
        } catch (const WorkerFailure& e) {
            ASSERT_EQ(e.index, 300u) << "round " << round << ": " << e.what();
        }
    }
    try {
        parallel_for(100, 3, [&](std::size_t i) {
            if (i == 57) throw 57;
        });
        FAIL() << "nothing was thrown";
    } catch (int v) {
        EXPECT_EQ(v, 57);
    }
}

TEST(ParallelFor, StopsHandingOutWorkAfterAFailure) {
    std::atomic<std::size_t> visited{0};
    EXPECT_THROW(parallel_for(10000, 4,
                              [&](std::size_t i) {
                                  ++visited;
                                  if (i == 0) throw std::runtime_error("first index");
                                  std::this_thread::sleep_for(std::chrono::microseconds(100));
                              }),
                 std::runtime_error);
    // Without the stop all 10000 would run (0.25 s on 4 threads); with it, a handful.
    EXPECT_LT(visited.load(), 5000u);
}

} // namespace
} // namespace specula
