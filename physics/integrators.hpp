#pragma once

#include "vec.hpp"

#include <array>
#include <cstdint>
#include <functional>
#include <limits>
#include <optional>
#include <span>
#include <stdexcept>
#include <string_view>
#include <vector>

namespace kugel::physics {

enum class integrator_kind {
    explicit_euler,       ///< the lecture's Euler: x += h·v(tᵢ), v += h·a(tᵢ)
    semi_implicit_euler,  ///< v += h·a(x); x += h·v_new (symplectic Euler)
    exact_constant_force, ///< the lecture's parabola: exact when every force is constant
    velocity_verlet,      ///< kick(h/2), drift(h), kick(h/2)
    rk4,                  ///< classical fourth-order Runge–Kutta
    dormand_prince,       ///< Dormand–Prince 5(4): adaptive steps to a tolerance inside each step
};

/// What a scene can know about an integrator before choosing it.
struct integrator_info
{
    integrator_kind kind;
    std::string_view name;  ///< the scene's name for it
    int order;              ///< global order of accuracy for smooth, position-dependent forces
    int force_evaluations;  ///< per step, in steady state
    bool symplectic;        ///< energy error stays bounded over long runs
    bool adaptive;          ///< chooses its own steps inside a step to meet step_control::tolerance
    std::string_view summary;
};

/// Every integrator, in the order above.
std::span<integrator_info const> integrator_table();
integrator_info const& info(integrator_kind kind);
std::optional<integrator_kind> integrator_from_name(std::string_view name);

/// How the adaptive integrator (dormand_prince) controls its error.
struct step_control
{
    /// The relative error allowed in one of its steps, for every body: the error estimate of
    /// the velocity change, and of the displacement divided by the step, each relative to the
    /// body's speed (the larger of its speeds at the two ends of the step). In
    /// [min_tolerance, 1).
    double tolerance = 1e-9;
    /// The most steps (accepted or rejected) one advance() may take; more throws
    /// step_control_error.
    std::uint64_t max_steps = 100'000;

    /// Below this the error estimate, a difference of sums of size h·|a|, is mostly rounding
    /// (about 1e-15 of them): the controller would shrink the step without end.
    static constexpr double min_tolerance = 1e-13;
};

/// The adaptive integrator could not meet its tolerance: its step fell below what the step's
/// clock can resolve, or it needed more than step_control::max_steps steps. `body` is the
/// one whose error was the largest at the last try.
class step_control_error : public std::runtime_error
{
public:
    step_control_error(std::string const& what, std::size_t slot) : std::runtime_error(what), body_slot(slot) {}
    std::size_t body_slot; ///< slot of the body with the largest error
};

/// What the adaptive integrator has done since its workspace was made.
struct adaptive_steps
{
    std::uint64_t accepted = 0;
    std::uint64_t rejected = 0;
    double smallest = std::numeric_limits<double>::infinity(); ///< s, the smallest accepted step
    double largest = 0.0;                                       ///< s, the largest accepted step
};

/// a(x): fills `a` with the accelerations of all bodies at positions `x`.
using acceleration_fn = std::function<void(std::span<vec3 const> x, std::span<vec3> a)>;

/// Scratch arrays reused from step to step, and the accelerations at the current positions
/// when they are known (velocity Verlet leaves them behind, saving one force evaluation per
/// step). Whoever moves bodies, adds or removes one, or changes the forces calls invalidate().
class integrator_workspace
{
public:
    void invalidate() { current_valid_ = false; }

    /// The adaptive integrator's steps so far.
    adaptive_steps const& steps() const { return steps_; }

private:
    friend void advance(integrator_kind, std::span<vec3>, std::span<vec3>, double,
                        acceleration_fn const&, integrator_workspace&, step_control const&);
    friend void dormand_prince(std::span<vec3>, std::span<vec3>, double, acceleration_fn const&,
                               integrator_workspace&, step_control const&);

    std::span<vec3 const> current_accelerations(std::span<vec3 const> x, acceleration_fn const& a);
    void resize(std::size_t n);

    std::vector<vec3> current_; ///< a(x) at the current positions, when current_valid_
    bool current_valid_ = false;
    std::vector<vec3> trial_x_, trial_v_, trial_a_, sum_x_, sum_v_;
    // Dormand–Prince: the stages' velocities and accelerations, the state inside the step
    std::array<std::vector<vec3>, 7> stage_v_, stage_a_;
    std::vector<vec3> inner_x_, inner_v_;
    double next_step_ = 0.0; ///< s, the step the controller proposes next (0: none yet)
    adaptive_steps steps_;
};

/// Advances positions `x` and velocities `v` by one step of `h` seconds (the adaptive
/// integrator: by as many steps of its own as `control` asks, landing on h exactly). On an
/// exception from `accelerations` (a singular force) or a step_control_error, `x` and `v` are
/// left as they were: every integrator works in scratch space and commits at the end.
void advance(integrator_kind kind, std::span<vec3> x, std::span<vec3> v, double h,
             acceleration_fn const& accelerations, integrator_workspace& workspace,
             step_control const& control = {});

} // namespace kugel::physics
