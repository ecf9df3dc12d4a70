#pragma once

#include "vec.hpp"

#include <span>

namespace kugel::physics {

/// Axis-aligned bounding box (lecture: x_min, x_max, y_min, y_max, z_min, z_max).
struct aabb
{
    vec3 min = vec3::Zero(); ///< m, lower corner
    vec3 max = vec3::Zero(); ///< m, upper corner, >= min on every axis

    vec3 centre() const { return 0.5 * (min + max); }
    vec3 extent() const { return max - min; }
};

/// [xᵢ − r, xᵢ + r] on every axis (lecture: "Abmessung der AABB").
inline aabb aabb_of_sphere(vec3 const& centre, double radius)
{
    vec3 const r = vec3::Constant(radius);
    return {centre - r, centre + r};
}

/// The smallest box holding every point; an empty span gives the empty box at the origin.
aabb aabb_of_points(std::span<vec3 const> points);

/// The smallest box holding both.
inline aabb merge(aabb const& a, aabb const& b)
{
    return {a.min.cwiseMin(b.min), a.max.cwiseMax(b.max)};
}

/// The lecture's 1D rule on every axis: the intervals [aᵢ, bᵢ] meet exactly when
/// max{aᵢ} <= min{bᵢ}. Touching boxes overlap.
inline bool overlaps(aabb const& a, aabb const& b)
{
    return (a.min.cwiseMax(b.min).array() <= a.max.cwiseMin(b.max).array()).all();
}

} // namespace kugel::physics
