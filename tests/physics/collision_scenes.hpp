#pragma once

// Scenes the collision tests share (tests/physics/collisions_test.cpp, the discrete step's
// tests/physics/discrete/discrete_step_test.cpp and the sleeping islands' world_sleep_test.cpp).

#include "physics/forces.hpp"
#include "physics/parallel_for.hpp"
#include "physics/world.hpp"

#include <cmath>
#include <memory>
#include <random>

namespace kugel::physics {

inline world_settings colliding(collision_mode mode, integrator_kind integrator = integrator_kind::velocity_verlet)
{
    world_settings s{.integrator = integrator};
    s.collisions.mode = mode;
    return s;
}

inline body_desc ball(vec3 x, vec3 v, double r = 0.5, double m = 1.0) { return {x, v, m, r, 0.0, false}; }

/// Six walls around [-L, L]³, normals pointing in.
inline void add_box(world& w, double L)
{
    for (int axis = 0; axis < 3; ++axis) {
        for (double sign : {1.0, -1.0}) {
            vec3 n = vec3::Zero();
            n[axis] = sign;
            w.add_wall({make_plane(n, -L), 0.0, 0.0});
        }
    }
}

/// Discrete mode, restitution 0.5 and friction 0.5 between spheres: the piles' settings.
inline world_settings pile_settings(integrator_kind integrator = integrator_kind::semi_implicit_euler)
{
    world_settings s = colliding(collision_mode::discrete, integrator);
    s.collisions.restitution = 0.5;
    s.collisions.friction = 0.5;
    return s;
}

/// A world of these settings under gravity (9.81 m/s² down z) above a floor at z = 0 with
/// damping 0.5 and friction 0.5, and no bodies yet.
inline world on_the_floor(world_settings const& s)
{
    world w(s);
    w.add_force(std::make_unique<uniform_field>(vec3(0, 0, -9.81)));
    w.add_wall({make_plane(vec3::UnitZ(), 0.0), 0.5, 0.5});
    return w;
}

/// n spheres of radius r (density 1000) stacked on the floor of on_the_floor(s), touching.
inline world stack_on_the_floor(int n, double r, world_settings const& s)
{
    world w = on_the_floor(s);
    for (int i = 0; i < n; ++i)
        w.add_body(ball({0, 0, r + 2 * r * i}, vec3::Zero(), r, 1000 * 4.0 / 3.0 * 3.141592653589793 * r * r * r));
    return w;
}

/// The same with the piles' settings, sleeping or not, by the integrator given.
inline world stack_on_the_floor(int n, double r, bool sleep = true,
                                integrator_kind integrator = integrator_kind::semi_implicit_euler)
{
    world_settings s = pile_settings(integrator);
    s.collisions.sleep = sleep;
    return stack_on_the_floor(n, r, s);
}

/// Discrete mode: 200 spheres dropped into a box under gravity. Continuous mode: the same
/// spheres as an elastic gas without gravity (a resting pile is discrete mode's job).
/// Stepped 300 times.
inline world settled_pile(collision_mode mode, broadphase_kind broadphase, parallel_for* loops = nullptr)
{
    world_settings s = colliding(mode, integrator_kind::semi_implicit_euler);
    s.collisions.broadphase = broadphase;
    s.collisions.restitution = mode == collision_mode::discrete ? 0.5 : 1.0;
    world w(s);
    w.set_parallel_for(loops, 0);
    if (mode == collision_mode::discrete)
        w.add_force(std::make_unique<uniform_field>(vec3(0, 0, -9.81)));
    add_box(w, 1.0);
    std::mt19937_64 rng(77);
    auto unit = [&] { return static_cast<double>(rng() >> 11U) * 0x1.0p-53; };
    for (int i = 0; i < 200; ++i) {
        // Drawn one statement at a time: the order in which a call's arguments are evaluated
        // is the compiler's choice, and GCC and Clang choose differently.
        double const mass = 1.0 + unit();
        double const vx = unit() - 0.5;
        double const vy = unit() - 0.5;
        w.add_body(ball({-0.85 + 0.17 * (i % 10), -0.85 + 0.17 * ((i / 10) % 10), -0.5 + 0.17 * (i / 100) + 0.3},
                        {vx, vy, 0.0}, 0.08, mass));
    }
    for (int i = 0; i < 300; ++i)
        w.step(1.0 / 60.0);
    return w;
}

/// An elastic gas in discrete mode: n spheres of radius 0.05 m on a lattice filling 10% of a
/// box, speeds up to 1 m/s in random directions (the benchmark's gas_step scene).
inline world discrete_gas(int n, broadphase_kind broadphase = broadphase_kind::uniform_grid)
{
    world_settings s = colliding(collision_mode::discrete);
    s.collisions.broadphase = broadphase;
    world w(s);
    double const r = 0.05;
    double const side = std::cbrt(n * 4.0 / 3.0 * 3.141592653589793 * r * r * r / 0.1);
    add_box(w, side / 2);
    int const per_axis = static_cast<int>(std::ceil(std::cbrt(n)));
    double const spacing = side / per_axis;
    std::mt19937_64 rng(3);
    auto unit = [&] { return static_cast<double>(rng() >> 11U) * 0x1.0p-53; };
    for (int i = 0; i < n; ++i) {
        vec3 const cell(i % per_axis, (i / per_axis) % per_axis, i / (per_axis * per_axis));
        vec3 const v(unit() - 0.5, unit() - 0.5, unit() - 0.5);
        w.add_body(ball((cell.array() + 0.5).matrix() * spacing - vec3::Constant(side / 2), 2.0 * v, r, 0.5));
    }
    return w;
}

} // namespace kugel::physics
