#pragma once

#include "vec.hpp"

#include <cmath>
#include <stdexcept>

namespace kugel::physics {

/// The lecture's wall {x : n·x = d}, n the outer normal: it points into the free side, where
/// the spheres are. A sphere of radius r at x is clear of the wall while n·x > d + r·‖n‖.
///
/// make_plane() stores a unit normal. The functions that take a plane (time_of_impact.hpp)
/// still use the lecture's d + r·‖n‖, so a plane written as an aggregate with a non-unit
/// normal means the same wall; only a zero normal is meaningless.
struct plane
{
    vec3 normal = vec3::UnitZ(); ///< outer normal, unit length when made by make_plane
    double offset = 0.0;         ///< m times ‖normal‖: the wall is normal · x = offset
};

/// The wall normal · x = offset, rescaled to a unit normal (offset divided by ‖normal‖, so
/// the wall is the same set of points). Throws std::invalid_argument for a zero or
/// non-finite normal, a non-finite offset, or one that overflows when rescaled.
inline plane make_plane(vec3 const& normal, double offset)
{
    if (!normal.allFinite() || !std::isfinite(offset))
        throw std::invalid_argument("plane: normal and offset must be finite");
    double const length = normal.stableNorm(); // no overflow for components near 1e308
    if (!(length > 0.0))
        throw std::invalid_argument("plane: normal must not be zero");
    plane const wall{normal / length, offset / length};
    if (!std::isfinite(wall.offset))
        throw std::invalid_argument("plane: offset too large for this normal");
    return wall;
}

} // namespace kugel::physics
