// Property tests: seeded random scenes whose masses, radii and speeds span many orders of
// magnitude, stepped in every collision mode. Every state stays finite; momentum is conserved
// where nothing external acts.

#include "extremes.hpp"

#include "support/random_source.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <memory>

namespace kugel::extremes {
namespace {

using namespace physics;

double log_uniform(test_support::random_source& random, double lo_exp, double hi_exp)
{
    return std::pow(10.0, random.uniform(lo_exp, hi_exp));
}

/// 30 spheres with masses 10^U(−12, 12) kg, radii 10^U(−3, 0) m and speeds 10^U(−6, 3) m/s
/// in a 20 m cube; a few point masses too (radius 0: they never collide).
void add_random_bodies(world& w, test_support::random_source& random)
{
    for (int i = 0; i < 30; ++i) {
        double const r = i % 10 == 9 ? 0.0 : log_uniform(random, -3, 0);
        vec3 const x = random.in_cube(9.0);
        vec3 const v = random.on_sphere(log_uniform(random, -6, 3));
        w.add_body({x, v, log_uniform(random, -12, 12), r, 0.0, false});
    }
}

TEST(RandomScenes, FreeSpheresKeepMomentumAndStayFinite)
{
    // No walls and no forces: only sphere–sphere impulses act, each equal and opposite, so
    // Σ m·v changes by rounding only. Tolerance 1e-12 of Σ m·|v|: each contact adds a few ε
    // of the impulse, which is at most 2·Σ m·|v|, and there are at most a few hundred
    // contacts. Discrete mode's position passes move bodies but never change velocities.
    for (std::uint64_t seed = 1; seed <= 50; ++seed) {
        for (collision_mode const mode : {collision_mode::discrete, collision_mode::continuous}) {
            test_support::random_source random(seed);
            world_settings s;
            s.collisions.mode = mode;
            s.collisions.restitution = random.uniform(0.0, 1.0);
            s.collisions.broadphase = static_cast<broadphase_kind>(seed % 3);
            world w(s);
            add_random_bodies(w, random);
            momentum_sum const before = momentum_of(w);
            for (int i = 0; i < 100; ++i) {
                w.step(0.01);
                ASSERT_TRUE(state_is_finite(w)) << "seed " << seed << " " << name(mode);
            }
            ASSERT_TRUE(motion_summary_is_finite(w));
            momentum_sum const after = momentum_of(w);
            EXPECT_LE((after.total - before.total).norm(),
                      1e-12 * std::max(before.scale, after.scale))
                << "seed " << seed << " " << name(mode);
        }
    }
}

TEST(RandomScenes, BoxedSpheresUnderGravityStayFiniteAndInside)
{
    // Walls (with random damping and friction), a uniform field and softened mutual gravity
    // (G = 1e-3, ε = 0.01 m, so the largest mutual acceleration is bounded): momentum is not
    // conserved, but every state is finite, no sphere leaves the box, and the potential
    // energy is finite. 50 seeds in discrete mode; 10 in continuous mode, whose capped steps
    // cost about 0.1 ms per event here (see the cap below), to keep the suite fast.
    for (std::uint64_t seed = 1; seed <= 50; ++seed) {
        for (collision_mode const mode : {collision_mode::discrete, collision_mode::continuous}) {
            if (mode == collision_mode::continuous && seed > 10)
                continue;
            test_support::random_source random(seed + 1000);
            world_settings s;
            s.integrator = static_cast<integrator_kind>(seed % 5);
            s.collisions.mode = mode;
            s.collisions.restitution = random.uniform(0.0, 1.0);
            // A light sphere caught between a wall and one 1e20 times heavier bounces about
            // π·√(M/m) = 3e10 times before the heavy one turns (the billiard that counts the
            // digits of π): real physics, which continuous mode meets with its event cap and
            // a discrete finish. The default cap costs seconds per step; 100 keeps the suite
            // fast and exercises the same fallback.
            s.collisions.max_events_per_step = 100;
            world w(s);
            w.add_force(std::make_unique<uniform_field>(vec3(0, 0, -9.81)));
            w.add_force(std::make_unique<newtonian_gravity>(1e-3, 0.01));
            for (int axis = 0; axis < 3; ++axis) {
                for (double const sign : {1.0, -1.0}) {
                    vec3 n = vec3::Zero();
                    n[axis] = sign;
                    w.add_wall({make_plane(n, -10.0), random.uniform(0, 1), random.uniform(0, 1)});
                }
            }
            add_random_bodies(w, random);
            for (int i = 0; i < 100; ++i) {
                w.step(0.01);
                ASSERT_TRUE(state_is_finite(w)) << "seed " << seed << " " << name(mode);
                ASSERT_EQ(w.escaped(), 0U) << "seed " << seed << " " << name(mode);
            }
            EXPECT_TRUE(std::isfinite(measure(w).total));
        }
    }
}

} // namespace
} // namespace kugel::extremes
