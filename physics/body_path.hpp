#pragma once

#include "aabb.hpp"
#include "vec.hpp"

namespace kugel::physics {

/// A body's motion inside one step as collision handling sees it: the lecture's parabola
/// x(t) = x₀ + v₀·t + a·t²/2 with constant acceleration a = (v₁ − v₀)/h taken from the
/// integrator's velocity change. Exact under a uniform field (every integrator then changes v
/// by g·h), a straight line without forces, and second order otherwise.
struct body_path
{
    vec3 x; ///< m, at time t
    vec3 v; ///< m/s, at time t
    vec3 a; ///< m/s², constant
    double t = 0.0;

    vec3 position_at(double time) const
    {
        double const s = time - t;
        return x + s * v + (0.5 * s * s) * a;
    }
    vec3 velocity_at(double time) const { return v + (time - t) * a; }

    /// Moves the state to `time` along the path.
    void advance_to(double time)
    {
        x = position_at(time);
        v = velocity_at(time);
        t = time;
    }

    /// The box swept by a sphere of radius r on this path from t to `until`: the ends and,
    /// per axis, the parabola's vertex when it lies inside the interval.
    aabb swept_box(double until, double r) const
    {
        vec3 const end = position_at(until);
        aabb box{x.cwiseMin(end), x.cwiseMax(end)};
        double const span = until - t;
        for (int axis = 0; axis < 3; ++axis) {
            if (a[axis] == 0.0)
                continue;
            double const s = -v[axis] / a[axis];
            if (s > 0.0 && s < span) {
                double const vertex = x[axis] + 0.5 * s * v[axis];
                box.min[axis] = std::min(box.min[axis], vertex);
                box.max[axis] = std::max(box.max[axis], vertex);
            }
        }
        vec3 const inflate = vec3::Constant(r);
        return {box.min - inflate, box.max + inflate};
    }
};

} // namespace kugel::physics
