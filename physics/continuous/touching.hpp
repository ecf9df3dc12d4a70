#pragma once

// When two surfaces count as touching, for both of the continuous mode's loops.

#include "physics/vec.hpp"

#include <algorithm>
#include <limits>

namespace kugel::physics::continuous {

/// Relative gap below which two surfaces count as touching (and above which an event is only
/// a checkpoint on the way): 1e-9 of the contact distance, far above rounding in positions
/// yet far below anything visible.
inline constexpr double touching_tolerance = 1e-9;

/// How far apart surfaces may still count as touching because positions are only known to
/// their rounding: a few units in the last place of the largest coordinate of either body.
/// Far from the origin that exceeds the relative tolerance above (at 1e9 m a position is
/// known to 1.2e-7 m, against 2e-13 m for spheres of 1e-4 m), and an event moved there
/// would otherwise find them apart, predict them again a rounding error later, and never
/// answer the contact.
inline double position_slack(vec3 const& a, vec3 const& b)
{
    double const largest = std::max(a.cwiseAbs().maxCoeff(), b.cwiseAbs().maxCoeff());
    return 8.0 * std::numeric_limits<double>::epsilon() * largest;
}

} // namespace kugel::physics::continuous
