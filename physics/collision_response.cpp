#include "collision_response.hpp"

namespace kugel::physics {

vec3 reflect_off_plane(vec3 const& velocity, vec3 const& normal, double damping, double friction)
{
    double const vn = velocity.dot(normal);
    if (vn >= 0.0)
        return velocity;
    vec3 const v_normal = vn * normal;
    vec3 const v_tangential = velocity - v_normal;
    return (1.0 - friction) * v_tangential - (1.0 - damping) * v_normal;
}

sphere_velocities collide_spheres(vec3 const& v1, double inverse_mass1, vec3 const& v2,
                                  double inverse_mass2, vec3 const& normal, double restitution)
{
    double const closing = (v1 - v2).dot(normal);
    double const inverse_mass_sum = inverse_mass1 + inverse_mass2;
    if (closing >= 0.0 || inverse_mass_sum == 0.0)
        return {v1, v2};
    double const impulse = -(1.0 + restitution) * closing / inverse_mass_sum;
    return {v1 + (impulse * inverse_mass1) * normal, v2 - (impulse * inverse_mass2) * normal};
}

} // namespace kugel::physics
