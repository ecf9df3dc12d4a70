// Phase 2 of the discrete step: spheres against the static boxes.

#include "passes.hpp"

#include <algorithm>

namespace kugel::physics::discrete {

// A sphere overlapping a box is pushed out along the contact normal and bounces by the wall
// rule; pushed into a wall on the way, it meets that too.
void obstacle_pass(step_context const& step, free_accelerations free_a, discrete_workspace& ws,
                   collision_stats& stats)
{
    collision_bodies const& b = step.bodies;
    for (obstacle const& o : step.obstacles) {
        aabb const bounds = aabb_of(o.box);
        for (std::uint32_t i = 0; i < b.x.size(); ++i) {
            double const r = b.radius[i];
            if (r <= 0.0 || b.inverse_mass[i] == 0.0 || !overlaps(bounds, aabb_of_sphere(b.x[i], r)))
                continue;
            auto const contact = sphere_vs_obb(b.x[i], r, o.box);
            if (!contact.touching)
                continue;
            body_path path{b.x[i] - contact.distance * contact.normal, b.v[i], free_a[i], step.h};
            if (detail::respond_to_surface(path, contact.normal, path.x.dot(contact.normal), o.damping,
                                           o.friction, step.settings, step.h))
                ++stats.obstacle_contacts;
            b.x[i] = path.x;
            b.v[i] = path.v;
            detail::push_out_and_meet_walls(step.walls, b.x[i], b.v[i], r, b.inverse_mass[i], free_a[i],
                                            step.settings, step.h);
            ws.moved.push_back(i);
        }
    }
    if (!step.obstacles.empty()) { // a sphere a wall moved may also have met a box, or two boxes
        std::sort(ws.moved.begin(), ws.moved.end());
        ws.moved.erase(std::unique(ws.moved.begin(), ws.moved.end()), ws.moved.end());
    }
}

} // namespace kugel::physics::discrete
