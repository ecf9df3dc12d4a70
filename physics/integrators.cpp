#include "integrators.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <string>

namespace kugel::physics {

namespace {

constexpr std::array<integrator_info, 6> table{{
    {integrator_kind::explicit_euler, "explicit_euler", 1, 1, false, false,
     "the lecture's explicit Euler; energy grows on orbits"},
    {integrator_kind::semi_implicit_euler, "semi_implicit_euler", 1, 1, true, false,
     "velocity first, then position with the new velocity; bounded energy error"},
    {integrator_kind::exact_constant_force, "exact_constant_force", 1, 1, false, false,
     "the lecture's parabola x0 + v0 t + a t^2/2; exact when every force is constant"},
    {integrator_kind::velocity_verlet, "velocity_verlet", 2, 1, true, false,
     "kick-drift-kick; reuses the last step's forces"},
    {integrator_kind::rk4, "rk4", 4, 4, false, false, "classical Runge-Kutta; most accurate per step"},
    {integrator_kind::dormand_prince, "dormand_prince", 5, 6, false, true,
     "Dormand-Prince 5(4): steps of its own inside each step, sized to a tolerance; "
     "6 force evaluations per step it takes"},
}};

} // namespace

std::span<integrator_info const> integrator_table() { return table; }

integrator_info const& info(integrator_kind kind)
{
    return table[static_cast<std::size_t>(kind)];
}

std::optional<integrator_kind> integrator_from_name(std::string_view name)
{
    for (auto const& entry : table)
        if (entry.name == name)
            return entry.kind;
    return std::nullopt;
}

void integrator_workspace::resize(std::size_t n)
{
    if (current_.size() != n) {
        current_.resize(n);
        current_valid_ = false;
    }
}

std::span<vec3 const> integrator_workspace::current_accelerations(std::span<vec3 const> x,
                                                                  acceleration_fn const& a)
{
    if (!current_valid_) {
        a(x, current_);
        current_valid_ = true;
    }
    return current_;
}

namespace {

void explicit_euler(std::span<vec3> x, std::span<vec3> v, std::span<vec3 const> a, double h)
{
    for (std::size_t i = 0; i < x.size(); ++i) {
        x[i] += h * v[i]; // x(tᵢ₊₁) = x(tᵢ) + h·v(tᵢ)
        v[i] += h * a[i]; // v(tᵢ₊₁) = v(tᵢ) + h·a(tᵢ)
    }
}

void semi_implicit_euler(std::span<vec3> x, std::span<vec3> v, std::span<vec3 const> a, double h)
{
    for (std::size_t i = 0; i < x.size(); ++i) {
        v[i] += h * a[i];
        x[i] += h * v[i];
    }
}

void exact_constant_force(std::span<vec3> x, std::span<vec3> v, std::span<vec3 const> a, double h)
{
    for (std::size_t i = 0; i < x.size(); ++i) {
        x[i] += h * v[i] + (0.5 * h * h) * a[i]; // x(t) = x₀ + t·v₀ + t²/2·a
        v[i] += h * a[i];                        // v(t) = v₀ + t·a
    }
}

// Dormand–Prince 5(4) (Hairer, Nørsett, Wanner, Solving ODE I, table 5.2): the 7-stage
// Butcher tableau, whose last stage is at the new state (first same as last), and the weights
// of the error estimate e = b − b̂ (fifth-order minus embedded fourth-order solution).
constexpr std::array<std::array<double, 6>, 7> dp_a{{
    {},
    {1.0 / 5},
    {3.0 / 40, 9.0 / 40},
    {44.0 / 45, -56.0 / 15, 32.0 / 9},
    {19372.0 / 6561, -25360.0 / 2187, 64448.0 / 6561, -212.0 / 729},
    {9017.0 / 3168, -355.0 / 33, 46732.0 / 5247, 49.0 / 176, -5103.0 / 18656},
    {35.0 / 384, 0.0, 500.0 / 1113, 125.0 / 192, -2187.0 / 6784, 11.0 / 84}, // = b
}};
constexpr std::array<double, 7> dp_e{71.0 / 57600,   0.0,          -71.0 / 16695, 71.0 / 1920,
                                     -17253.0 / 339200, 22.0 / 525, -1.0 / 40};

// The step size controller (Hairer I, II.4): h_new = h · safety · err^(−1/5), the growth and
// the shrinking of one step bounded so that one odd estimate cannot swing it far.
constexpr double safety = 0.9;
constexpr double max_growth = 5.0;
constexpr double max_shrink = 0.2;

std::string seconds(double s)
{
    char buffer[32];
    std::snprintf(buffer, sizeof buffer, "%.3g", s);
    return buffer;
}

} // namespace

/// Dormand–Prince 5(4) over h for x'' = a(x): y = (x, v), y' = (v, a(x)). Steps of its own
/// inside h, each accepted when its error estimate meets the tolerance (step_control), the
/// last one shortened to land on h exactly; the fifth-order solution is kept (local
/// extrapolation). Works on inner_x_, inner_v_ and commits to x, v at the end.
void dormand_prince(std::span<vec3> x, std::span<vec3> v, double h, acceleration_fn const& accelerations,
                    integrator_workspace& ws, step_control const& control)
{
    std::size_t const n = x.size();
    if (!(h > 0.0))
        return; // nothing to do, and no step to learn from
    // The first stage of a step is a(x) at its start: the cache, then the last stage of the
    // step before (first same as last), so a step costs 6 evaluations.
    auto const a0 = ws.current_accelerations(x, accelerations);
    ws.inner_x_.assign(x.begin(), x.end());
    ws.inner_v_.assign(v.begin(), v.end());
    for (std::size_t j = 0; j < 7; ++j) {
        ws.stage_v_[j].resize(n);
        ws.stage_a_[j].resize(n);
    }
    std::ranges::copy(a0, ws.stage_a_[0].begin());
    ws.trial_x_.resize(n);

    double done = 0.0, done_compensation = 0.0; // s into h, a compensated sum
    double step = ws.next_step_ > 0.0 ? std::min(ws.next_step_, h) : h;
    // The smallest step: one unit in the last place of h, below which the step is lost in the
    // rounding of the step it is part of (its clock is a compensated sum, which resolves less).
    double const floor = std::numeric_limits<double>::epsilon() * h;
    bool rejected_last = false;
    std::uint64_t tries = 0;
    for (;;) {
        // The last step lands on h; a step that would leave a sliver takes it along.
        double const left = h - done;
        bool const last = 1.01 * step >= left;
        if (last)
            step = left;

        // Stages 2..7: x_j = x + step·Σ a_jl·v_l, v_j = v + step·Σ a_jl·a_l, a_j = a(x_j).
        ws.stage_v_[0] = ws.inner_v_;
        for (std::size_t j = 1; j < 7; ++j) {
            for (std::size_t i = 0; i < n; ++i) {
                vec3 xj = ws.inner_x_[i];
                vec3 vj = ws.inner_v_[i];
                for (std::size_t l = 0; l < j; ++l) {
                    double const w = step * dp_a[j][l];
                    xj += w * ws.stage_v_[l][i];
                    vj += w * ws.stage_a_[l][i];
                }
                ws.trial_x_[i] = xj;
                ws.stage_v_[j][i] = vj;
            }
            accelerations(ws.trial_x_, ws.stage_a_[j]);
        }
        // Stage 7 is the new state (trial_x_, stage_v_[6]). The error of each body, relative
        // to its speed: the displacement's per unit of the step, and the velocity change's.
        double error = 0.0;
        std::size_t worst = 0;
        for (std::size_t i = 0; i < n; ++i) {
            vec3 dx = vec3::Zero(), dv = vec3::Zero();
            for (std::size_t l = 0; l < 7; ++l) {
                dx += dp_e[l] * ws.stage_v_[l][i];
                dv += dp_e[l] * ws.stage_a_[l][i];
            }
            double const off = std::max(dx.norm(), step * dv.norm()); // |δx|/step, |δv|
            if (off == 0.0)
                continue; // at rest, or under a constant force (exact)
            double const speed = std::max(ws.inner_v_[i].norm(), ws.stage_v_[6][i].norm());
            double const relative = off / speed; // +inf for a speed of 0, NaN for a NaN
            if (!(relative <= error)) {
                error = std::isnan(relative) ? std::numeric_limits<double>::infinity() : relative;
                worst = i;
            }
        }
        error /= control.tolerance;

        ++tries;
        if (error <= 1.0) {
            // Accept: the new state, and its accelerations as the next step's first stage.
            std::swap(ws.inner_x_, ws.trial_x_);
            std::swap(ws.inner_v_, ws.stage_v_[6]);
            std::swap(ws.stage_a_[0], ws.stage_a_[6]);
            ++ws.steps_.accepted;
            ws.steps_.smallest = std::min(ws.steps_.smallest, step);
            ws.steps_.largest = std::max(ws.steps_.largest, step);
            double const grow = error == 0.0 ? max_growth : std::min(max_growth, safety * std::pow(error, -0.2));
            double const next = step * (rejected_last ? std::min(1.0, grow) : grow);
            rejected_last = false;
            if (last) {
                ws.next_step_ = next; // carried to the next call
                break;
            }
            double const y = step - done_compensation; // Kahan: the clock of this step
            double const t = done + y;
            done_compensation = (t - done) - y;
            done = t;
            step = next;
        } else {
            ++ws.steps_.rejected;
            rejected_last = true;
            step *= std::isfinite(error) ? std::max(max_shrink, safety * std::pow(error, -0.2)) : max_shrink;
        }
        if (step < floor)
            throw step_control_error("dormand_prince needs a step below " + seconds(floor) + " s to meet its tolerance " +
                                         seconds(control.tolerance) + " (at " + seconds(done) + " s of a " +
                                         seconds(h) + " s step): the step cannot resolve it; give a larger tolerance, a "
                                         "smaller dt, or a softening",
                                     worst);
        if (tries >= control.max_steps)
            throw step_control_error("dormand_prince took " + std::to_string(tries) + " steps in one " + seconds(h) +
                                         " s step without meeting its tolerance " + seconds(control.tolerance) +
                                         " (reached " + seconds(done) + " s): give a larger tolerance or a smaller dt",
                                     worst);
    }
    // Commit; the accelerations at the new positions are the cache.
    std::ranges::copy(ws.inner_x_, x.begin());
    std::ranges::copy(ws.inner_v_, v.begin());
    std::swap(ws.current_, ws.stage_a_[0]);
    ws.current_valid_ = true;
}

void advance(integrator_kind kind, std::span<vec3> x, std::span<vec3> v, double h,
             acceleration_fn const& accelerations, integrator_workspace& ws, step_control const& control)
{
    std::size_t const n = x.size();
    ws.resize(n);
    if (n == 0)
        return;
    auto const a = ws.current_accelerations(x, accelerations);

    switch (kind) {
    case integrator_kind::explicit_euler:
        explicit_euler(x, v, a, h);
        ws.invalidate();
        return;
    case integrator_kind::semi_implicit_euler:
        semi_implicit_euler(x, v, a, h);
        ws.invalidate();
        return;
    case integrator_kind::exact_constant_force:
        exact_constant_force(x, v, a, h);
        ws.invalidate();
        return;
    case integrator_kind::velocity_verlet: {
        // drift with the half kick folded in, then the forces at the new positions
        ws.trial_x_.resize(n);
        ws.trial_a_.resize(n);
        for (std::size_t i = 0; i < n; ++i)
            ws.trial_x_[i] = x[i] + h * v[i] + (0.5 * h * h) * a[i];
        accelerations(ws.trial_x_, ws.trial_a_);
        // commit: the second half kick uses a(x_{n+1}), which becomes the cache
        for (std::size_t i = 0; i < n; ++i) {
            v[i] += (0.5 * h) * (a[i] + ws.trial_a_[i]);
            x[i] = ws.trial_x_[i];
        }
        std::swap(ws.current_, ws.trial_a_);
        return; // current_ stays valid
    }
    case integrator_kind::rk4: {
        // For x'' = a(x): stage k = (velocity, acceleration). Sums are accumulated with the
        // weights 1, 2, 2, 1 so only one trial state is kept at a time.
        ws.trial_x_.resize(n);
        ws.trial_v_.resize(n);
        ws.trial_a_.resize(n);
        ws.sum_x_.assign(v.begin(), v.end());
        ws.sum_v_.assign(a.begin(), a.end());
        auto stage = [&](double step, std::span<vec3 const> kv, std::span<vec3 const> ka,
                         double weight) {
            for (std::size_t i = 0; i < n; ++i) {
                ws.trial_x_[i] = x[i] + step * kv[i];
                ws.trial_v_[i] = v[i] + step * ka[i];
            }
            accelerations(ws.trial_x_, ws.trial_a_);
            for (std::size_t i = 0; i < n; ++i) {
                ws.sum_x_[i] += weight * ws.trial_v_[i];
                ws.sum_v_[i] += weight * ws.trial_a_[i];
            }
        };
        // A stage may read the previous stage's trial arrays while overwriting them: each
        // element is read before it is written, and a() runs after both loops.
        stage(0.5 * h, std::span<vec3 const>(v.data(), n), a, 2.0); // k2 from k1
        stage(0.5 * h, ws.trial_v_, ws.trial_a_, 2.0);             // k3 from k2
        stage(h, ws.trial_v_, ws.trial_a_, 1.0);                   // k4 from k3
        for (std::size_t i = 0; i < n; ++i) {
            x[i] += (h / 6.0) * ws.sum_x_[i];
            v[i] += (h / 6.0) * ws.sum_v_[i];
        }
        ws.invalidate();
        return;
    }
    case integrator_kind::dormand_prince:
        dormand_prince(x, v, h, accelerations, ws, control);
        return;
    }
}

} // namespace kugel::physics
