#pragma once

#include "parallel_for.hpp"

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace kugel::physics {

/// A parallel_for on a fixed set of std::threads. The engine never makes one: a world's owner
/// (a room, a headless run, a benchmark) does, and lends it to the world. run() uses the
/// calling thread as one of the `threads`, so thread_pool(1) starts no thread at all.
/// One run() at a time; not itself shared between worlds stepping at once.
///
/// A step makes some thirty run() calls, and thirty wake-ups of a sleeping thread through a
/// condition variable cost more than a whole step of 10^4 spheres (bench/README.md,
/// decisions), so a
/// thread that waits, for a job or for the others to finish one, first spins for a while
/// (spin_wait) and sleeps only after.
class thread_pool final : public parallel_for
{
public:
    /// threads >= 1, counting the thread that calls run().
    explicit thread_pool(std::size_t threads);
    ~thread_pool() override;
    thread_pool(thread_pool const&) = delete;
    thread_pool& operator=(thread_pool const&) = delete;

    void run(std::size_t count, std::function<void(std::size_t)> const& task) override;
    std::size_t threads() const { return workers_.size() + 1; }

private:
    void work();  ///< a worker thread: waits for a job, helps with it, reports done
    void drain(); ///< takes iterations of the current job until none is left

    std::vector<std::thread> workers_;
    std::mutex mutex_;
    std::condition_variable job_posted_;
    std::condition_variable job_done_;
    // Guarded by mutex_ (the atomics are written under it, and may be read without it by a
    // thread that spins before it sleeps):
    std::function<void(std::size_t)> const* task_ = nullptr;
    std::size_t count_ = 0;
    std::size_t next_ = 0;                ///< the next iteration to hand out
    std::atomic<std::size_t> helping_{0}; ///< workers still inside the current job
    std::atomic<std::uint64_t> job_{0};   ///< bumped per run(), so a worker joins each job once
    std::exception_ptr failure_;
    bool stopping_ = false;
};

} // namespace kugel::physics
