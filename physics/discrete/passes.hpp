#pragma once

// Internal to the discrete step (discrete_step.cpp): its phases, each in a file named after
// what it does, and what they share.

#include "physics/collision_rules.hpp"
#include "physics/collisions.hpp"
#include "physics/discrete/workspace.hpp"
#include "physics/parallel_for.hpp"

#include <optional>
#include <span>
#include <utility>

namespace kugel::physics::discrete {

/// What every phase of one step reads: the scene's rules, its walls and boxes, the bodies.
struct step_context
{
    collision_settings const& settings;
    detail::wall_set const& walls;
    std::span<obstacle const> obstacles;
    collision_bodies const& bodies;
    double h;             ///< s, the step's length
    parallel_for* loops;  ///< or none: every loop on the calling thread
};

/// Each body's acceleration over the step from free motion alone, by body slot: none after a
/// drift, when nothing was written.
struct free_accelerations
{
    std::span<vec3 const> a; ///< empty when no body accelerated

    vec3 operator[](std::size_t i) const { return a.empty() ? vec3::Zero() : a[i]; }
    bool any() const { return !a.empty(); }
};

/// What the wall pass found besides what it changed.
struct wall_pass_result
{
    free_accelerations free_a;
    sphere_extent extent;                  ///< of the bodies where it left them
    double contact_margin = 0.0;           ///< m, for the sphere grid's contacts
    std::optional<cell_frame> keying_frame; ///< when it numbered the spheres' cells in it
};

/// 1. Each body on its own: a pending drift, its free acceleration noted, a bounce off any wall
///    it is found inside, and its cell numbered in the grid's last frame (wall_pass.cpp).
wall_pass_result wall_pass(step_context const& step, discrete_workspace& ws, collision_stats& stats);
/// 1b. The bodies that moved farther than the sweep's share of their radius, and the spheres
///     near them, taken through the continuous mode's events (swept_pass.cpp); with the sweep
///     off, only counted. Updates the extent and the cell keys for where they end.
void swept_pass(step_context const& step, wall_pass_result& walls, discrete_workspace& ws, collision_stats& stats);
/// 2. Spheres that overlap a box are pushed out and bounce by the wall rule (obstacle_pass.cpp).
void obstacle_pass(step_context const& step, free_accelerations free_a, discrete_workspace& ws,
                   collision_stats& stats);
/// 3. The spheres sorted into the grid's cells, and each slab's near pairs and contacts
///    (sort_into_cells.cpp). Returns the number of slabs.
std::size_t sort_into_cells(step_context const& step, wall_pass_result const& walls, discrete_workspace& ws);
/// 4. Momentum exchanged at the contacts until no velocity changes (velocity_passes.cpp); the
///    velocities go back to the bodies at the end.
void velocity_passes(step_context const& step, free_accelerations free_a, discrete_workspace& ws);
/// 5. Overlapping near pairs pushed apart, walls pushing back (position_passes.cpp).
void position_passes(step_context const& step, free_accelerations free_a, discrete_workspace& ws);
/// 6. The moved positions back to the bodies; the spheres walls and boxes moved clamped to the
///    walls once more (write_back.cpp).
void write_back(step_context const& step, free_accelerations free_a, discrete_workspace& ws,
                collision_stats& stats);

/// Runs work(slab) for the even slabs, then for the odd ones, the slabs of one parity at the
/// same time: they share no sphere (sphere_grid.hpp), so the outcome is that of one order.
template <class Work>
void by_parity(discrete_workspace& ws, parallel_for* loops, Work const& work)
{
    std::size_t const slabs = ws.slabs.size();
    for (std::size_t parity = 0; parity < 2; ++parity)
        run_loop(loops, (slabs + 1 - parity) / 2, [&](std::size_t k) { work(ws.slabs[2 * k + parity]); });
}

/// Runs work(slab) for every slab at the same time: for work that touches its own slab's
/// lists alone, or each sphere on its own.
template <class Work>
void each_slab(discrete_workspace& ws, parallel_for* loops, Work const& work)
{
    run_loop(loops, ws.slabs.size(), [&](std::size_t s) { work(ws.slabs[s]); });
}

/// In a loop over a list of spheres in cell order that reads or writes each one's body by
/// slot, in no order: fetches the body of the sphere 8 entries further on (address(rank)
/// gives it), so that the loop does not wait on a cache miss for nearly every entry.
template <class Address>
void fetch_ahead(std::vector<std::uint32_t> const& list, std::size_t at, Address const& address)
{
    constexpr std::size_t distance = 8;
    if (at + distance < list.size())
        __builtin_prefetch(address(list[at + distance]), 1);
}

/// Lists a sphere once per pass: marks are stamps that only grow, from step to step too, so
/// that every mark left by an earlier pass is below this pass's stamp and the table need not
/// be cleared (4 MB at 10^6 spheres, on one thread).
struct once_per_pass
{
    std::vector<std::uint32_t>& mark;
    std::uint32_t stamp;

    void list(std::vector<std::uint32_t>& list, std::uint32_t k) const
    {
        if (std::exchange(mark[k], stamp) != stamp)
            list.push_back(k);
    }
};

/// The next pass's stamp, the mark table sized for `spheres` (new entries 0, below every
/// stamp) and cleared only before the stamps would wrap.
inline std::uint32_t next_stamp(discrete_workspace& ws, std::uint32_t spheres)
{
    if (ws.stamp > std::numeric_limits<std::uint32_t>::max() - 64) {
        ws.mark.assign(spheres, 0);
        ws.stamp = 0;
    }
    ws.mark.resize(spheres);
    return ++ws.stamp;
}

} // namespace kugel::physics::discrete
