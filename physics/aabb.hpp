#pragma once

#include "vec.hpp"

#include <algorithm>

#include <cstdint>
#include <span>
#include <vector>

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

/// Replaces `boxes` by the box of every sphere (radius > 0) at x, grown by `margin` on every
/// side, and `members` by each box's body slot: what a broadphase is given for a world's
/// spheres.
void boxes_of_spheres(std::span<vec3 const> x, std::span<double const> radius, std::vector<aabb>& boxes,
                      std::vector<std::uint32_t>& members, double margin = 0.0);

/// The smallest box holding every point; an empty span gives the empty box at the origin.
aabb aabb_of_points(std::span<vec3 const> points);

/// The smallest box holding both.
inline aabb merge(aabb const& a, aabb const& b)
{
    return {a.min.cwiseMin(b.min), a.max.cwiseMax(b.max)};
}

/// The lecture's 1D rule on every axis: the intervals [aᵢ, bᵢ] meet exactly when
/// max{aᵢ} <= min{bᵢ}. Touching boxes overlap. The engine's one box test: the three axes are
/// combined by & rather than &&, so that it compiles without branches (the broadphases run it
/// on every candidate pair); discrete/kernels.hpp has its form for two spheres' boxes.
inline bool overlaps(aabb const& a, aabb const& b)
{
    bool const x = std::max(a.min.x(), b.min.x()) <= std::min(a.max.x(), b.max.x());
    bool const y = std::max(a.min.y(), b.min.y()) <= std::min(a.max.y(), b.max.y());
    bool const z = std::max(a.min.z(), b.min.z()) <= std::min(a.max.z(), b.max.z());
    return x & y & z;
}

} // namespace kugel::physics
