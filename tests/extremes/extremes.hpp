#pragma once

// Test support for the extremes suite: finiteness checks over a whole world and momentum
// sums that do not lose the small bodies next to the large ones.

#include "physics/diagnostics.hpp"
#include "physics/world.hpp"

#include <cmath>
#include <cstddef>

namespace kugel::extremes {

using physics::vec3;

/// Every position and velocity finite.
inline bool state_is_finite(physics::world const& w)
{
    for (vec3 const& x : w.bodies().positions())
        if (!x.allFinite())
            return false;
    for (vec3 const& v : w.bodies().velocities())
        if (!v.allFinite())
            return false;
    return std::isfinite(w.time());
}

/// Every number of the summary measure_motion() gives (what a snapshot or a headless summary
/// reports besides the state) finite.
inline bool motion_summary_is_finite(physics::world const& w)
{
    physics::diagnostics const d = physics::measure_motion(w);
    return std::isfinite(d.kinetic) && std::isfinite(d.total) && d.momentum.allFinite() &&
           d.angular_momentum.allFinite() && d.centre_of_mass.allFinite() &&
           std::isfinite(d.mass);
}

/// Σ m·v of the dynamic bodies, summed in long double.
struct momentum_sum
{
    vec3 total = vec3::Zero(); ///< kg·m/s
    double scale = 0.0;        ///< kg·m/s, Σ m·|v|: what rounding errors are relative to
};

inline momentum_sum momentum_of(physics::world const& w)
{
    auto const v = w.bodies().velocities();
    auto const m = w.bodies().masses();
    auto const inverse_mass = w.bodies().inverse_masses();
    long double sum[3] = {0, 0, 0};
    long double scale = 0;
    for (std::size_t i = 0; i < v.size(); ++i) {
        if (inverse_mass[i] == 0.0)
            continue;
        for (int k = 0; k < 3; ++k)
            sum[k] += static_cast<long double>(m[i]) * static_cast<long double>(v[i][k]);
        scale += static_cast<long double>(m[i]) * static_cast<long double>(v[i].norm());
    }
    return {vec3(static_cast<double>(sum[0]), static_cast<double>(sum[1]),
                 static_cast<double>(sum[2])),
            static_cast<double>(scale)};
}

inline vec3 position_of(physics::world const& w, physics::body_id id)
{
    return w.bodies().positions()[*w.bodies().slot_of(id)];
}

inline vec3 velocity_of(physics::world const& w, physics::body_id id)
{
    return w.bodies().velocities()[*w.bodies().slot_of(id)];
}

inline physics::world colliding_world(physics::collision_mode mode, double restitution = 1.0)
{
    physics::world_settings s;
    s.collisions.mode = mode;
    s.collisions.restitution = restitution;
    return physics::world(s);
}

} // namespace kugel::extremes
