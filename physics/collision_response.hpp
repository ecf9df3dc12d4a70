#pragma once

#include "vec.hpp"

namespace kugel::physics {

/// Sphere meets wall (lecture, "Kugel trifft Ebene"): split v into its normal part
/// v_n = (v·n)·n and tangential part v_t = v − v_n, then
///     w = (1 − μ)·v_t − (1 − α)·v_n,      0 <= α, μ <= 1,
/// with damping α (α = 0 reflects elastically, α = 1 stops the normal motion) and friction μ.
/// `normal` is the wall's unit outer normal. Only a body moving into the wall (v·n < 0) is
/// changed; one moving away or along it is returned as it is.
///
/// This friction scales the tangential velocity at each contact rather than capping the
/// friction impulse by μ times the normal impulse (Coulomb friction). We keep the lecture's
/// rule: it is what the lecture teaches, it never reverses the tangential motion, and its
/// effect is easy to predict. The price: a body resting on a floor loses the factor (1 − μ)
/// of its sliding speed at every step it touches, so its deceleration depends on dt.
vec3 reflect_off_plane(vec3 const& velocity, vec3 const& normal, double damping, double friction);

/// New velocities of two spheres after they collide.
struct sphere_velocities
{
    vec3 first;
    vec3 second;
};

/// Two spheres meet (lecture, "Kollision zweier Kugeln"): along the collision normal
/// n = (x₁ − x₂)/|x₁ − x₂| the normal components follow the 1D rule of momentum
/// conservation with restitution e (e = 1 is the lecture's elastic rule
///     w₁ = (m₁ − m₂)/(m₁ + m₂)·v₁ + 2m₂/(m₁ + m₂)·v₂,  w₂ = 2m₁/(m₁ + m₂)·v₁ + (m₂ − m₁)/(m₁ + m₂)·v₂),
/// and the tangential components are unchanged.
///
/// Written with inverse masses as the impulse J = −(1 + e)·(u₁ − u₂)/(1/m₁ + 1/m₂) along n,
/// which is the same rule but also holds for a static body (1/m = 0: it acts as a wall) and
/// for mass ratios of 1e12, where m₁ + m₂ would swallow the small mass. Pairs that are not
/// approaching ((v₁ − v₂)·n >= 0) are returned unchanged.
sphere_velocities collide_spheres(vec3 const& v1, double inverse_mass1, vec3 const& v2,
                                  double inverse_mass2, vec3 const& normal, double restitution);

} // namespace kugel::physics
