#pragma once

// Internal to the collision code: the contact rules both modes share.

#include "body_path.hpp"
#include "collision_response.hpp"
#include "collisions.hpp"
#include "wall_set.hpp"

#include <algorithm>
#include <cmath>

namespace kugel::physics::detail {

/// The outgoing normal speed below which a contact rests instead of bouncing: the scene's
/// rest_speed, or twice the normal speed one step of the body's acceleration adds.
inline double rest_threshold(collision_settings const& s, vec3 const& a, vec3 const& n, double h)
{
    return s.rest_speed ? *s.rest_speed : 2.0 * std::abs(a.dot(n)) * h;
}

/// The discrete step's rest threshold at a contact in a pile: the scene's rest_speed, or twice
/// the speed one step of either body's own acceleration adds, whatever the contact's
/// direction. Under uniform gravity a pair's relative acceleration is zero, and a contact's
/// normal may lie across gravity (a sphere against a side wall, or beside another), where the
/// acceleration along it is zero too: each step's fall, passed sideways through a pile, then
/// bounced at e for ever and kept the pile from coming to rest.
inline double resting_threshold(collision_settings const& s, vec3 const& a_a, vec3 const& a_b, double h)
{
    return s.rest_speed ? *s.rest_speed : 2.0 * std::max(a_a.norm(), a_b.norm()) * h;
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

/// The unit normal of a contact between spheres whose centres are d = x_a − x_b apart, from b
/// to a (+z when the centres coincide, so that a pair always has one).
inline vec3 contact_normal(vec3 const& d, double distance)
{
    return distance > 0.0 ? vec3(d / distance) : vec3(vec3::UnitZ());
}

/// Coulomb friction between two spheres at a contact with unit normal n that has just changed
/// their relative normal speed by `normal_change` (m/s, >= 0): their relative tangential
/// speed loses at most μ times that, and all of it when it is smaller (the contact sticks).
/// Spheres here do not spin, so both impulses act through the same reduced mass and the cone
/// |J_t| <= μ·J_n is the same bound on the speeds. Momentum is kept. Unlike the walls' rule
/// (a share of the sliding speed at every touch), a sphere resting in a hollow or on a slope
/// shallower than atan μ stays where it is: a pile can stand.
inline void apply_sphere_friction(vec3& v_a, double inverse_mass_a, vec3& v_b, double inverse_mass_b,
                                  vec3 const& n, double friction, double normal_change)
{
    double const total = inverse_mass_a + inverse_mass_b;
    if (!(friction > 0.0 && total > 0.0 && normal_change > 0.0))
        return;
    vec3 const relative = v_a - v_b;
    vec3 const tangential = relative - relative.dot(n) * n;
    double const sliding = tangential.norm();
    if (!(sliding > 0.0))
        return;
    double const removed = std::min(sliding, friction * normal_change); // m/s
    vec3 const impulse = (removed / (sliding * total)) * tangential; // kg·m/s
    v_a -= inverse_mass_a * impulse;
    v_b += inverse_mass_b * impulse;
}

/// The two-sphere response both modes give a contact with unit normal n (from b to a): if the
/// spheres close along n, the lecture's collision of two spheres with the scene's restitution
/// e, or e = 0 when the outgoing normal speed e·|closing| would be below the rest threshold of
/// their relative acceleration a_a − a_b. Then the scene's friction acts by Coulomb's law
/// (apply_sphere_friction).
/// Returns false when they do not close.
inline bool respond_to_sphere_contact(vec3& v_a, double inverse_mass_a, vec3& v_b, double inverse_mass_b,
                                      vec3 const& n, collision_settings const& settings, double threshold)
{
    double const closing = (v_a - v_b).dot(n);
    if (!(closing < 0.0))
        return false;
    double const e = -closing * settings.restitution < threshold ? 0.0 : settings.restitution;
    auto const w = collide_spheres(v_a, inverse_mass_a, v_b, inverse_mass_b, n, e);
    v_a = w.first;
    v_b = w.second;
    apply_sphere_friction(v_a, inverse_mass_a, v_b, inverse_mass_b, n, settings.friction, -(1.0 + e) * closing);
    return true;
}

/// A resting contact between two spheres held together by their forces (opposite charges,
/// gravity between them), as respond_to_surface makes one on a wall: after a contact that
/// left them no normal speed, their accelerations lose the part that presses them together,
/// split by inverse mass so that momentum is kept, and they move on touching for the rest of
/// the step. Otherwise each approach a rounding error later would be another contact of no
/// speed, without end (the event caps, and the energy those steps lose). Found a little
/// overlapped (a pair touching with no normal speed is looked at again a moment later), they
/// are set touching, each moved by its share of inverse mass (the centre of mass stays), as
/// a body resting on a wall is set on its surface: an overlap would grow step by step.
inline void hold_resting_pair(body_path& a, double inverse_mass_a, body_path& b, double inverse_mass_b,
                              vec3 const& n, double reach)
{
    double const pressing = (a.a - b.a).dot(n);
    double const total = inverse_mass_a + inverse_mass_b;
    if (!(pressing < 0.0 && total > 0.0))
        return;
    a.a -= (inverse_mass_a / total * pressing) * n;
    b.a += (inverse_mass_b / total * pressing) * n;
    double const overlap = reach - (a.x - b.x).dot(n);
    if (overlap > 0.0) {
        a.x += (inverse_mass_a / total * overlap) * n;
        b.x -= (inverse_mass_b / total * overlap) * n;
    }
}

/// The same with the rest threshold of the pair's relative acceleration a_a − a_b.
inline bool respond_to_sphere_contact(vec3& v_a, double inverse_mass_a, vec3 const& a_a, vec3& v_b,
                                      double inverse_mass_b, vec3 const& a_b, vec3 const& n,
                                      collision_settings const& settings, double h)
{
    return respond_to_sphere_contact(v_a, inverse_mass_a, v_b, inverse_mass_b, n, settings,
                                     rest_threshold(settings, a_a - a_b, n, h));
}

/// A speculative contact (the discrete step's, discrete/velocity_passes.cpp): spheres apart
/// that may still approach at `allowed` (m/s, >= 0) and end the step touching. Closing faster,
/// they lose the excess along n in proportion to their inverse masses (momentum kept, no
/// bounce: they have not met), and the scene's friction acts as at a contact, as they will
/// touch. Returns false when they do not close faster than allowed.
inline bool respond_to_speculative_contact(vec3& v_a, double inverse_mass_a, vec3& v_b, double inverse_mass_b,
                                           vec3 const& n, double allowed, collision_settings const& settings)
{
    double const closing = (v_a - v_b).dot(n);
    double const total = inverse_mass_a + inverse_mass_b;
    if (!(closing < -allowed) || total == 0.0)
        return false;
    double const excess = -allowed - closing; // m/s, > 0
    v_a += (excess * inverse_mass_a / total) * n;
    v_b -= (excess * inverse_mass_b / total) * n;
    apply_sphere_friction(v_a, inverse_mass_a, v_b, inverse_mass_b, n, settings.friction, excess);
    return true;
}

/// Pushes a sphere (radius r, inverse mass 1/m) at x out of every wall it is inside; at each
/// such wall, meet(wall) answers for its velocity.
template <class Meet>
void push_out_of_walls(wall_set const& walls, vec3& x, double r, double inverse_mass, Meet const& meet)
{
    if (r <= 0.0 || inverse_mass == 0.0 || walls.clear(x, r))
        return;
    for (wall const& w : walls.all) {
        double const depth = w.surface.offset + r - w.surface.normal.dot(x);
        if (depth <= 0.0)
            continue;
        x += depth * w.surface.normal;
        meet(w);
    }
}

/// Pushes a sphere out of every wall it is inside and removes its velocity v into that wall
/// (the guarantee, after a continuous step, that rounding left no sphere inside a wall).
inline void clamp_to_walls(wall_set const& walls, vec3& x, vec3& v, double r, double inverse_mass)
{
    push_out_of_walls(walls, x, r, inverse_mass, [&](wall const& w) {
        vec3 const& n = w.surface.normal;
        double const vn = v.dot(n);
        if (vn < 0.0)
            v -= vn * n;
    });
}

/// A sphere (free acceleration a) moving into a wall it touches meets it by the wall's rule,
/// as a bounce in the wall pass does: it leaves with the lecture's
/// w = (1 − μ)·v_t − (1 − α)·v_n or, slower than the rest threshold (resting_threshold: of
/// its acceleration whatever the wall's direction), rests on the wall (no normal speed). Removing the normal speed outright would make every such meeting
/// perfectly inelastic (bench/README.md, decisions). Returns whether v changed.
inline bool meet_wall(wall const& w, vec3& v, vec3 const& a, collision_settings const& settings, double h)
{
    vec3 const& n = w.surface.normal;
    if (!(v.dot(n) < 0.0))
        return false;
    v = reflect_off_plane(v, n, w.damping, w.friction);
    double const outgoing = v.dot(n);
    if (outgoing < resting_threshold(settings, a, a, h))
        v -= outgoing * n;
    return true;
}

/// The discrete step's clamp: pushed out of every wall it is inside, the sphere meets it
/// (meet_wall) instead of losing its speed into it.
inline void push_out_and_meet_walls(wall_set const& walls, vec3& x, vec3& v, double r, double inverse_mass,
                                    vec3 const& a, collision_settings const& settings, double h)
{
    push_out_of_walls(walls, x, r, inverse_mass, [&](wall const& w) { meet_wall(w, v, a, settings, h); });
}

} // namespace kugel::physics::detail
