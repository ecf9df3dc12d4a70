#include "thread_pool.hpp"

#include <stdexcept>
#include <utility>

namespace kugel::physics {

namespace {

/// Checks `done` for about 50 µs, pausing between checks; whether it came true.
template <class Done>
bool spin_wait(Done const& done)
{
    constexpr int checks = 2000; // times a pause of some 25 ns
    for (int k = 0; k < checks; ++k) {
        if (done())
            return true;
#if defined(__x86_64__) || defined(__i386__)
        __builtin_ia32_pause();
#else
        std::this_thread::yield();
#endif
    }
    return done();
}

} // namespace

thread_pool::thread_pool(std::size_t threads)
{
    if (threads < 1)
        throw std::invalid_argument("thread_pool needs at least one thread");
    workers_.reserve(threads - 1);
    for (std::size_t k = 1; k < threads; ++k)
        workers_.emplace_back([this] { work(); });
}

thread_pool::~thread_pool()
{
    {
        std::lock_guard lock(mutex_);
        stopping_ = true;
    }
    job_posted_.notify_all();
    for (std::thread& t : workers_)
        t.join();
}

void thread_pool::run(std::size_t count, std::function<void(std::size_t)> const& task)
{
    {
        std::lock_guard lock(mutex_);
        task_ = &task;
        count_ = count;
        next_ = 0;
        helping_ = workers_.size();
        failure_ = nullptr;
        ++job_;
    }
    job_posted_.notify_all();
    drain();
    spin_wait([this] { return helping_.load(std::memory_order_acquire) == 0; });
    std::unique_lock lock(mutex_);
    job_done_.wait(lock, [this] { return helping_ == 0; });
    task_ = nullptr;
    if (failure_)
        std::rethrow_exception(std::exchange(failure_, nullptr));
}

void thread_pool::drain()
{
    // Iterations are handed out one at a time under the lock: the engine's loops have a few
    // dozen large iterations (slabs, chunks of bodies), so the lock is not the cost.
    std::unique_lock lock(mutex_);
    while (next_ < count_) {
        std::size_t const k = next_++;
        auto const& task = *task_;
        lock.unlock();
        try {
            task(k);
        } catch (...) {
            lock.lock();
            if (!failure_)
                failure_ = std::current_exception();
            next_ = count_; // hand out nothing more
            continue;
        }
        lock.lock();
    }
}

void thread_pool::work()
{
    std::uint64_t seen = 0;
    for (;;) {
        spin_wait([&] { return job_.load(std::memory_order_acquire) != seen; });
        {
            std::unique_lock lock(mutex_);
            job_posted_.wait(lock, [&] { return stopping_ || job_ != seen; });
            if (stopping_)
                return;
            seen = job_;
        }
        drain();
        {
            std::lock_guard lock(mutex_);
            --helping_;
        }
        job_done_.notify_one();
    }
}

} // namespace kugel::physics
