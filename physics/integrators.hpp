#pragma once

#include "vec.hpp"

#include <functional>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

namespace kugel::physics {

enum class integrator_kind {
    explicit_euler,       ///< the lecture's Euler: x += h·v(tᵢ), v += h·a(tᵢ)
    semi_implicit_euler,  ///< v += h·a(x); x += h·v_new (symplectic Euler)
    exact_constant_force, ///< the lecture's parabola: exact when every force is constant
    velocity_verlet,      ///< kick(h/2), drift(h), kick(h/2)
    rk4,                  ///< classical fourth-order Runge–Kutta
};

/// What a scene can know about an integrator before choosing it.
struct integrator_info
{
    integrator_kind kind;
    std::string_view name;  ///< the scene's name for it
    int order;              ///< global order of accuracy for smooth, position-dependent forces
    int force_evaluations;  ///< per step, in steady state
    bool symplectic;        ///< energy error stays bounded over long runs
    std::string_view summary;
};

/// Every integrator, in the order above.
std::span<integrator_info const> integrator_table();
integrator_info const& info(integrator_kind kind);
std::optional<integrator_kind> integrator_from_name(std::string_view name);

/// a(x): fills `a` with the accelerations of all bodies at positions `x`.
using acceleration_fn = std::function<void(std::span<vec3 const> x, std::span<vec3> a)>;

/// Scratch arrays reused from step to step, and the accelerations at the current positions
/// when they are known (velocity Verlet leaves them behind, saving one force evaluation per
/// step). Whoever moves bodies, adds or removes one, or changes the forces calls invalidate().
class integrator_workspace
{
public:
    void invalidate() { current_valid_ = false; }

private:
    friend void advance(integrator_kind, std::span<vec3>, std::span<vec3>, double,
                        acceleration_fn const&, integrator_workspace&);

    std::span<vec3 const> current_accelerations(std::span<vec3 const> x, acceleration_fn const& a);
    void resize(std::size_t n);

    std::vector<vec3> current_; ///< a(x) at the current positions, when current_valid_
    bool current_valid_ = false;
    std::vector<vec3> trial_x_, trial_v_, trial_a_, sum_x_, sum_v_;
};

/// Advances positions `x` and velocities `v` by one step of `h` seconds. On an exception from
/// `accelerations` (a singular force), `x` and `v` are left as they were: every integrator
/// works in scratch space and commits at the end.
void advance(integrator_kind kind, std::span<vec3> x, std::span<vec3> v, double h,
             acceleration_fn const& accelerations, integrator_workspace& workspace);

} // namespace kugel::physics
