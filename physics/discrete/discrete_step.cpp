#include "discrete_step.hpp"

#include "passes.hpp"

namespace kugel::physics {

// One discrete step, phase by phase. Free motion (a drift, or the integrator) has moved every
// body to the end of the step, or, when the drift is pending, the wall pass makes it on its
// way. Walls and boxes answer first, each body on its own, and the bodies that moved far are
// swept through the step's events with the spheres near them; then the spheres are sorted into
// cells and their pairs found at the end positions; the velocity passes exchange momentum at
// the contacts, the position passes push apart what still overlaps; the positions go back.
// Pairs are visited slab by slab, the even slabs and then the odd ones, each in cell order
// (discrete/sphere_grid.hpp), so the outcome is one order's, whatever the number of threads.
void resolve_discrete(collision_settings const& settings, std::span<wall const> walls,
                      std::span<obstacle const> obstacles, collision_bodies const& bodies, double h,
                      discrete_workspace& ws, collision_stats& stats, step_timings& timings, parallel_for* loops)
{
    detail::wall_set const wall_tests(walls);
    discrete::step_context const step{settings, wall_tests, obstacles, bodies, h, loops};
    phase_clock clock(timings);
    auto walls_done = discrete::wall_pass(step, ws, stats);              // 1. each body on its own
    clock.lap(step_phase::walls);
    if (!ws.swept.fast.empty()) {
        discrete::swept_pass(step, walls_done, ws, stats);                // 1b. fast bodies swept
        clock.lap(step_phase::swept);
    }
    if (!obstacles.empty()) {
        discrete::obstacle_pass(step, walls_done.free_a, ws, stats);      // 2. spheres out of boxes
        clock.lap(step_phase::obstacles);
    }
    discrete::sort_into_cells(step, walls_done, ws);                      // 3. cells, near pairs
    clock.lap(step_phase::cells);
    discrete::velocity_passes(step, walls_done.free_a, ws);               // 4. momentum at contacts
    clock.lap(step_phase::velocity_passes);
    discrete::position_passes(step, walls_done.free_a, ws);               // 5. overlaps pushed apart
    clock.lap(step_phase::position_passes);
    discrete::write_back(step, walls_done.free_a, ws, stats);             // 6. positions to the bodies
    clock.lap(step_phase::write_back);
}

} // namespace kugel::physics
