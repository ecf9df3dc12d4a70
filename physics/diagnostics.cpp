#include "diagnostics.hpp"

#include "world.hpp"

#include <algorithm>

namespace kugel::physics {

diagnostics measure_motion(world const& w)
{
    diagnostics d;
    auto const& bodies = w.bodies();
    auto const x = bodies.positions();
    auto const v = bodies.velocities();
    auto const m = bodies.masses();
    auto const inverse_mass = bodies.inverse_masses();
    vec3 weighted_position = vec3::Zero();
    for (std::size_t i = 0; i < bodies.size(); ++i) {
        d.mass += m[i];
        weighted_position += m[i] * x[i];
        if (inverse_mass[i] == 0.0)
            continue; // static: at rest by definition
        d.kinetic += 0.5 * m[i] * v[i].squaredNorm();
        d.largest_speed = std::max(d.largest_speed, v[i].norm());
        d.momentum += m[i] * v[i];
        d.angular_momentum += m[i] * x[i].cross(v[i]);
    }
    if (d.mass > 0.0)
        d.centre_of_mass = weighted_position / d.mass;
    d.total = d.kinetic;
    d.bodies = bodies.size();
    return d;
}

diagnostics measure(world const& w)
{
    diagnostics d = measure_motion(w);
    for (auto const& model : w.forces()) {
        double const u = model->potential_energy(w.bodies(), w.bodies().positions());
        d.potential += u;
        if (!model->is_constant()) { // between bodies: a constant force's depends on the origin
            d.pair_potential += u;
            d.has_pair_potential = true;
        }
    }
    d.total = d.kinetic + d.potential;
    return d;
}

} // namespace kugel::physics
