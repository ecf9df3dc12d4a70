#pragma once

#include "plane.hpp"
#include "vec.hpp"

#include <cmath>
#include <optional>

namespace kugel::physics {

/// Lecture: two spheres meet exactly when ‖x₁ − x₂‖² <= (r₁ + r₂)². Touching counts. The one
/// sphere-contact test of the engine: the discrete step's contacts, a room's spawn check.
inline bool spheres_overlap(vec3 const& x1, double r1, vec3 const& x2, double r2)
{
    double const reach = r1 + r2;
    return (x1 - x2).squaredNorm() <= reach * reach;
}

/// The lecture's time of contact with a wall by linear interpolation between two steps:
///   t_coll = (d + r‖n‖ − n·x_{i+1}) / (n·x_i − n·x_{i+1}) · t_i
///          + (n·x_i − d − r‖n‖)     / (n·x_i − n·x_{i+1}) · t_{i+1}
/// Preconditions: the sphere is clear of the wall at t_i (n·x_i > d + r‖n‖) and touching or
/// inside it at t_{i+1} (n·x_{i+1} <= d + r‖n‖); then the result lies in [t_i, t_{i+1}] and
/// is exact when the sphere moved on a straight line at constant speed. When n·x_i equals
/// n·x_{i+1} (no motion along the normal) it returns t_i.
double plane_contact_time_linear(plane const& wall, double radius, vec3 const& x_i, double t_i,
                                 vec3 const& x_next, double t_next);

/// The earliest t in [0, t_max] at which a sphere on the lecture's parabola
/// x(t) = x + v·t + a·t²/2 touches the wall while moving into it (normal velocity
/// n·(v + a·t) <= 0 at that t), or nullopt. a = 0 is straight-line motion.
///  - Touching or inside the wall at t = 0 and approaching (n·v < 0, or n·v = 0 and
///    n·a < 0): 0.
///  - Touching or inside and not approaching (resting, lifting off, moving out): only a
///    later re-entry counts, e.g. a ball that leaves the floor upwards and falls back.
///  - A path that only grazes the wall (touches it with zero normal velocity) counts.
/// Works for a non-unit normal (the lecture's d + r‖n‖). t_max < 0 gives nullopt.
std::optional<double> plane_time_of_impact(plane const& wall, double radius, vec3 const& x,
                                           vec3 const& v, vec3 const& a, double t_max);

/// Whether two spheres d = x₁ − x₂ apart with relative velocity v = v₁ − v₂ surely never touch
/// on their straight lines (they move apart, or pass each other farther than `reach` = r₁ +
/// r₂), judged plainly with bounds on the rounding: what sphere_time_of_impact answers first,
/// inline, so that a caller offering many pairs pays no call for those. False when only the
/// careful arithmetic can tell.
inline bool surely_misses(vec3 const& d, vec3 const& v, double reach)
{
    // Most pairs a broadphase offers move apart, and d·v says so long before any care is
    // needed: computed plainly, its error is below 3u·Σ|d_k·v_k| (u = 2^-53), so a sum above
    // 2^-50 times that is positive whatever the rounding, and so is the careful d·v. That one
    // uses v scaled by a power of two, which keeps every sign and, for components between
    // 2^-500 and 2^500 (or 0), every bit; the sum stays far from under- and overflow. Outside
    // those ranges the careful path alone decides.
    auto const moderate = [](double x) { return x == 0.0 || (std::abs(x) > 0x1p-500 && std::abs(x) < 0x1p500); };
    double const magnitude = d.cwiseAbs().dot(v.cwiseAbs());
    if (!(magnitude > 0x1p-900 && magnitude < 0x1p900 && moderate(v.x()) && moderate(v.y()) && moderate(v.z())))
        return false;
    double const b = d.dot(v);
    if (b > 0x1p-50 * magnitude)
        return true;
    // Approaching pairs mostly pass each other by: b² − a c (a = v·v, c = d·d − R²) computed
    // plainly errs by less than about 20u·a·(d·d + R²) (‖d·v‖ <= √a·‖d‖), so a value below
    // 2^-40 times that is negative whatever the rounding, and so is the careful one. Overflow
    // or underflow only makes the test fail, and the careful path decide.
    double const a = v.squaredNorm(), dd = d.squaredNorm();
    return b * b - a * (dd - reach * reach) < -0x1p-40 * (a * (dd + reach * reach));
}

/// The earliest t in [0, t_max] at which two spheres moving on straight lines with constant
/// velocities touch, or nullopt. By the lecture's reduction: a point at x₁ moving with
/// v₁ − v₂ against a resting sphere of radius r₁ + r₂ at x₂. The centres at that time are
/// [x₁]_coll = x₁ + t·v₁ and [x₂]_coll = x₂ + t·v₂ (the lecture prints
/// [x₁]_coll = x_coll − t_coll·v₂; with the reduced point x_coll = x₁ + t_coll·(v₁ − v₂) the
/// sign must be +).
///  - No approach (d·(v₁ − v₂) >= 0 with d = x₁ − x₂: separating, or no relative motion):
///    nullopt, even when overlapping; there is no new contact to resolve.
///  - Touching or overlapping and approaching: 0.
///  - A grazing path (closest approach exactly r₁ + r₂) counts as a hit at the moment of
///    closest approach, as touching counts for spheres_overlap.
/// t_max < 0 gives nullopt.
std::optional<double> sphere_time_of_impact(vec3 const& x1, vec3 const& v1, double r1,
                                            vec3 const& x2, vec3 const& v2, double r2,
                                            double t_max);

/// The lecture's contact point of two touching spheres,
///   x_coll = r₂/(r₁ + r₂) · [x₁]_coll + r₁/(r₁ + r₂) · [x₂]_coll,
/// which lies on both surfaces: it is [x₁]_coll moved by r₁ towards [x₂]_coll. Two points
/// (r₁ = r₂ = 0) give the midpoint.
vec3 contact_point(vec3 const& x1_at_contact, double r1, vec3 const& x2_at_contact, double r2);

} // namespace kugel::physics
