#pragma once

// Where a world's steps spend their time, phase by phase: what the headless summary and a
// room's /metrics report, so that a slow scene shows which of its models it pays for.

#include <array>
#include <chrono>
#include <cstddef>
#include <string_view>

namespace kugel::physics {

enum class step_phase : std::size_t {
    free_motion,     ///< forces where the integrator needs them, and the integrator
    walls,           ///< discrete: each body on its own against the walls (and a drift)
    obstacles,       ///< discrete: spheres against boxes
    cells,           ///< discrete: spheres sorted into cells, and their near pairs
    velocity_passes, ///< discrete: momentum exchanged at contacts
    position_passes, ///< discrete: overlapping pairs pushed apart
    write_back,      ///< discrete: positions back to the bodies, the last wall clamp
    continuous,      ///< continuous: every event of the step in time order
    reorder,         ///< bodies moved into cell order (a large discrete world)
    swept,           ///< discrete: the fast bodies' paths swept, and the spheres near them
};
inline constexpr std::size_t step_phase_count = 10;
inline constexpr std::array<std::string_view, step_phase_count> step_phase_names{
    "free_motion", "walls",      "obstacles",  "cells", "velocity_passes",
    "position_passes", "write_back", "continuous", "reorder", "swept"};

/// Seconds spent in each phase since the world was made (wall-clock, on the calling thread:
/// a phase on two threads counts once), while `on`. Off by default: a phase's clock reads
/// cost more than a whole step of a two-body orbit (bench/README.md, decisions).
struct step_timings
{
    std::array<double, step_phase_count> seconds{};
    bool on = false;

    double operator[](step_phase p) const { return seconds[static_cast<std::size_t>(p)]; }
};

/// Times consecutive phases: lap(p) adds the time since the last lap (or since it was made)
/// to phase p. One clock read per phase; none while the timings are off.
class phase_clock
{
public:
    explicit phase_clock(step_timings& into) : into_(into), last_(into.on ? clock::now() : clock::time_point{}) {}

    void lap(step_phase p)
    {
        if (!into_.on)
            return;
        auto const now = clock::now();
        into_.seconds[static_cast<std::size_t>(p)] += std::chrono::duration<double>(now - last_).count();
        last_ = now;
    }

private:
    using clock = std::chrono::steady_clock;
    step_timings& into_;
    clock::time_point last_;
};

} // namespace kugel::physics
