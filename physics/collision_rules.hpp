#pragma once

// Internal to the collision code: the contact rules both modes share.

#include "body_path.hpp"
#include "collision_response.hpp"
#include "collisions.hpp"

#include <cmath>

namespace kugel::physics::detail {

/// The outgoing normal speed below which a contact rests instead of bouncing: the scene's
/// rest_speed, or twice the normal speed one step of the body's acceleration adds.
inline double rest_threshold(collision_settings const& s, vec3 const& a, vec3 const& n, double h)
{
    return s.rest_speed ? *s.rest_speed : 2.0 * std::abs(a.dot(n)) * h;
}

/// Applies the lecture's wall rule to a body on its path at a contact with unit normal n
/// (pointing out of the wall, towards the body), where the body's surface should sit at
/// n·x = surface. A body moving into the wall is reflected with damping and friction; a body
/// pressed against it (no normal speed, acceleration into it) feels the friction only. If
/// the outgoing normal speed is below the rest threshold the body comes to rest on the wall
/// for the rest of the step: no normal speed, no normal acceleration (the wall carries the
/// load), and its position on the surface. Returns false when there was no contact to answer.
inline bool respond_to_surface(body_path& path, vec3 const& n, double surface, double damping,
                               double friction, collision_settings const& settings, double h)
{
    double const vn = path.v.dot(n);
    double const an = path.a.dot(n);
    if (vn < 0.0) {
        path.v = reflect_off_plane(path.v, n, damping, friction);
    } else if (vn == 0.0 && an < 0.0) {
        path.v = (1.0 - friction) * path.v; // v has no normal part here
    } else {
        return false;
    }
    double const outgoing = path.v.dot(n);
    if (outgoing < rest_threshold(settings, path.a, n, h)) {
        path.v -= outgoing * n;
        if (an < 0.0)
            path.a -= an * n;
        path.x += (surface - path.x.dot(n)) * n;
    }
    return true;
}

} // namespace kugel::physics::detail
