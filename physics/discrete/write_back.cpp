// Phase 6 of the discrete step: the moved positions back to the bodies.

#include "passes.hpp"

namespace kugel::physics::discrete {

void write_back(step_context const& step, free_accelerations free_a, discrete_workspace& ws, collision_stats& stats)
{
    sphere_grid const& grid = ws.grid;
    std::span<vec3> const x = step.bodies.x;
    // A sphere may be on the lists of two slabs (each moved it in some pass), always
    // neighbours: so the even slabs write back, then the odd ones, never one body at once.
    by_parity(ws, step.loops, [&](contact_slab& slab) {
        for (std::size_t listed = 0; listed < slab.pushed.size(); ++listed) {
            fetch_ahead(slab.pushed, listed, [&](std::uint32_t later) { return &x[grid.slot(later)]; });
            std::uint32_t const k = slab.pushed[listed];
            x[grid.slot(k)] = grid.sphere(k).x;
        }
    });
    for (contact_slab const& slab : ws.slabs)
        stats.sphere_contacts += slab.responses;
    // No sphere is left inside a wall: the spheres walls and boxes moved are clamped here, once
    // each, and the position passes clamp every sphere they move after each pass (the velocity
    // passes move none); every other sphere was clear of every wall when the wall pass looked
    // at it and has not moved since, so clamping it would change nothing. (Clamping a bounced
    // sphere before the pair passes instead of after them left stacks settling four times
    // worse.)
    collision_bodies const& b = step.bodies;
    for (std::uint32_t i : ws.moved)
        detail::push_out_and_meet_walls(step.walls, b.x[i], b.v[i], b.radius[i], b.inverse_mass[i], free_a[i],
                                        step.settings, step.h);
}

} // namespace kugel::physics::discrete
