#pragma once

#include <algorithm>
#include <cstddef>
#include <functional>

namespace kugel::physics {

/// Runs the iterations of a loop, several at a time. The engine owns no threads: whoever owns
/// a world may lend it one of these for its hot loops (world::set_parallel_for), e.g. a
/// thread_pool. The engine hands it only loops whose iterations touch disjoint data, so a
/// result never depends on how many iterations ran at once.
class parallel_for
{
public:
    virtual ~parallel_for() = default;

    /// Calls task(k) once for every k in [0, count), in any order and on any of its threads,
    /// and returns when every call has returned. If calls throw, one of the exceptions is
    /// rethrown here after all have finished.
    virtual void run(std::size_t count, std::function<void(std::size_t)> const& task) = 0;
};

/// run() on `loops`, or a plain loop on this thread when there is none.
template <class Task>
void run_loop(parallel_for* loops, std::size_t count, Task&& task)
{
    if (loops == nullptr || count < 2) {
        for (std::size_t k = 0; k < count; ++k)
            task(k);
        return;
    }
    loops->run(count, std::function<void(std::size_t)>(std::forward<Task>(task)));
}

/// Bodies per iteration of a loop over bodies: large enough that handing out an iteration
/// costs nothing beside it, small enough that two threads share 10⁵ bodies evenly.
inline constexpr std::size_t bodies_per_chunk = 4096;

/// How many chunks of bodies_per_chunk cover n bodies.
inline std::size_t chunk_count(std::size_t n) { return (n + bodies_per_chunk - 1) / bodies_per_chunk; }

/// run_loop over [0, n) in chunks: task(chunk, begin, end) for each chunk of bodies.
template <class Task>
void run_chunks(parallel_for* loops, std::size_t n, Task&& task)
{
    run_loop(loops, chunk_count(n), [&](std::size_t c) {
        std::size_t const begin = c * bodies_per_chunk;
        task(c, begin, std::min(n, begin + bodies_per_chunk));
    });
}

} // namespace kugel::physics
