#pragma once

// Sensors: static volumes (a box or a ball) that report the bodies entering and leaving them,
// with the time inside the step: a goal, a zone, a finish line. A sensor is not a wall:
// bodies pass through it, and a scene that names none pays nothing for them.
//
// A body is in a sensor while its centre is inside the volume, boundary included. Between
// two steps a body's centre moves along a path; each time it crosses the sensor's boundary
// (not where it only grazes it) is an event, so a body that passes through a sensor inside
// one step enters and leaves in that step, in that order. The path is
//  - in continuous mode, the sphere's own pieces of path between its contacts (the
//    lecture's parabola or straight line, continuous/workspace.hpp's segments): the times
//    are exact to rounding;
//  - elsewhere, for a body the contacts did not move, the lecture's parabola from the step's
//    start, x₀ + v₀·t + a·t²/2 with a = (v₁ − v₀)/h: exact under a uniform field or no force;
//  - in discrete mode, the straight line from the step's start to its end: the step's own
//    answer has no path in between, so the times are the chord's.
// A body whose centre is inside at the start of its path but was not before (spawned there,
// or moved there by a command) enters at the start; one that is found outside at the end of
// its path although its path ended inside (rounding, or pushed out of a wall) leaves at the
// end. So the events of a body and a sensor always alternate, starting with an entry.

#include "aabb.hpp"
#include "body_id.hpp"
#include "body_path.hpp"
#include "vec.hpp"

#include <cstdint>
#include <optional>
#include <vector>

namespace kugel::physics {

/// A static volume that reports bodies entering and leaving it.
struct sensor
{
    enum class shape : std::uint8_t { box, ball };
    shape kind = shape::box;
    aabb box;                      ///< m, the box (kind box)
    vec3 centre = vec3::Zero();    ///< m, the ball's centre (kind ball)
    double radius = 0.0;           ///< m, the ball's radius, > 0 (kind ball)

    static sensor of_box(aabb const& b) { return {shape::box, b, vec3::Zero(), 0.0}; }
    static sensor of_ball(vec3 const& c, double r) { return {shape::ball, {}, c, r}; }

    /// Whether a centre at x is in it (boundary included).
    bool contains(vec3 const& x) const;
    /// The box around the volume.
    aabb bounds() const;
    /// Why the sensor cannot be used (non-finite numbers, min above max, radius <= 0), or
    /// nothing.
    std::optional<const char*> invalid() const;
};

/// A body entering or leaving a sensor.
struct sensor_event
{
    double time;          ///< s, world time at which the centre crossed the boundary
    std::uint32_t sensor; ///< the sensor's index, in the order the world's were added
    body_id body;
    bool entered;         ///< true: entered; false: left

    friend bool operator==(sensor_event const&, sensor_event const&) = default;
};

/// Follows a body's centre along `path` from path time `from` to `until`, given whether it was
/// in the sensor before: appends an event for every change of that (at world time `offset` +
/// the path time) and returns whether it is in at `until`. `end`, when given, is where the
/// body really is at `until` (its stored position), which decides the last answer.
bool follow_sensor(sensor const& s, std::uint32_t index, body_id body, body_path const& path, double from,
                   double until, bool inside, double offset, std::vector<sensor_event>& out,
                   std::optional<vec3> const& end = std::nullopt);

/// The real roots of c[0] + c[1]·s + ... + c[degree]·s^degree (degree <= 4) strictly inside
/// (lo, hi) where the polynomial changes sign, appended in increasing order to `out`, each
/// to the precision of its bracketing (a double root, where the sign does not change, is not
/// a crossing and is not reported).
void sign_changes(double const* c, int degree, double lo, double hi, std::vector<double>& out);

} // namespace kugel::physics
