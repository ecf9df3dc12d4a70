#include "integrators.hpp"

#include <algorithm>
#include <array>

namespace kugel::physics {

namespace {

constexpr std::array<integrator_info, 5> table{{
    {integrator_kind::explicit_euler, "explicit_euler", 1, 1, false,
     "the lecture's explicit Euler; energy grows on orbits"},
    {integrator_kind::semi_implicit_euler, "semi_implicit_euler", 1, 1, true,
     "velocity first, then position with the new velocity; bounded energy error"},
    {integrator_kind::exact_constant_force, "exact_constant_force", 1, 1, false,
     "the lecture's parabola x0 + v0 t + a t^2/2; exact when every force is constant"},
    {integrator_kind::velocity_verlet, "velocity_verlet", 2, 1, true,
     "kick-drift-kick; reuses the last step's forces"},
    {integrator_kind::rk4, "rk4", 4, 4, false, "classical Runge-Kutta; most accurate per step"},
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

} // namespace

void advance(integrator_kind kind, std::span<vec3> x, std::span<vec3> v, double h,
             acceleration_fn const& accelerations, integrator_workspace& ws)
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
    }
}

} // namespace kugel::physics
