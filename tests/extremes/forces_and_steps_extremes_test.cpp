// Forces and step sizes at the extremes: coincident bodies under 1/r² laws, dt = 0 and
// dt = 1e6 s, and a run of a million steps.

#include "extremes.hpp"

#include "physics/barnes_hut.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <vector>

namespace kugel::extremes {
namespace {

using namespace physics;

body_desc body_at(vec3 x, vec3 v, double m, double r = 0.0, double q = 0.0)
{
    return {x, v, m, r, q, false};
}

std::vector<vec3> copy(std::span<vec3 const> s) { return {s.begin(), s.end()}; }

// ---------------------------------------------------------------------------------------------
// Coincident bodies

TEST(Coincident, UnsoftenedGravityOfCoincidentBodiesRefusesTheStepAndChangesNothing)
{
    // 1/r² at r = 0 has no value: the step throws singular_force_error naming the problem
    // and the fix, and the world is bit for bit as it was (state, clock, step count), for
    // every integrator and for Coulomb too.
    for (auto const& info : integrator_table()) {
        for (bool const charged : {false, true}) {
            world w({.integrator = info.kind});
            if (charged)
                w.add_force(std::make_unique<coulomb>(1.0, 0.0));
            else
                w.add_force(std::make_unique<newtonian_gravity>(1.0, 0.0));
            w.add_body(body_at({1, 2, 3}, {0.5, 0, 0}, 1.0, 0.0, 1.0));
            w.add_body(body_at({1, 2, 3}, {-0.5, 0, 0}, 2.0, 0.0, 1.0));
            w.add_body(body_at({9, 0, 0}, {0, 0, 0}, 1.0, 0.0, 1.0));
            auto const x = copy(w.bodies().positions());
            auto const v = copy(w.bodies().velocities());
            try {
                w.step(0.01);
                ADD_FAILURE() << info.name << ": no singular_force_error";
            } catch (singular_force_error const& e) {
                std::string const what = e.what();
                EXPECT_NE(what.find("singular"), std::string::npos) << what;
                EXPECT_NE(what.find("softening"), std::string::npos) << what;
            }
            EXPECT_EQ(copy(w.bodies().positions()), x) << info.name;
            EXPECT_EQ(copy(w.bodies().velocities()), v) << info.name;
            EXPECT_EQ(w.time(), 0.0);
            EXPECT_EQ(w.steps(), 0U);
            EXPECT_THROW(measure(w), singular_force_error);
            EXPECT_TRUE(motion_summary_is_finite(w)); // what a snapshot reports still is
        }
    }
}

TEST(Coincident, SoftenedGravityOfCoincidentBodiesIsFinite)
{
    // With softening ε the force is G·m₁m₂·d/(r² + ε²)^{3/2}: zero at r = 0 and at most
    // G·m₁m₂·2/(3√3 ε²) anywhere. A thousand steps stay finite, and momentum is conserved to
    // rounding (pairwise forces cancel exactly; the bound 1e-12 of Σ m·|v| allows 1000 steps
    // of velocity rounding).
    for (double const softening : {1e-9, 1e-3, 1.0}) {
        world w;
        w.add_force(std::make_unique<newtonian_gravity>(1.0, softening));
        w.add_force(std::make_unique<coulomb>(1.0, softening));
        w.add_body(body_at({0, 0, 0}, {0, 0, 0}, 1.0, 0.0, 0.5));
        w.add_body(body_at({0, 0, 0}, {0, 0, 0}, 1.0, 0.0, -0.5));
        w.add_body(body_at({0, 0, 0}, {1e-3, 0, 0}, 1e-6, 0.0, 0.0));
        for (int i = 0; i < 1000; ++i)
            w.step(1e-3);
        ASSERT_TRUE(state_is_finite(w)) << softening;
        diagnostics const d = measure(w);
        EXPECT_TRUE(std::isfinite(d.potential));
        momentum_sum const p = momentum_of(w);
        EXPECT_LE(p.total.norm() - 1e-9, 1e-12 * std::max(p.scale, 1e-9));
    }
}

TEST(Coincident, TreeGravityOfCoincidentBodiesIsFiniteWithSoftening)
{
    // Barnes–Hut caps its depth, so 100 coincident bodies share one leaf instead of splitting
    // forever; with softening the forces between them are finite (zero, by symmetry, to
    // rounding: bound 1e-9 of the force one far body exerts).
    body_storage bodies;
    for (int i = 0; i < 100; ++i)
        bodies.add(body_at({1, 1, 1}, {0, 0, 0}, 1.0));
    bodies.add(body_at({100, 1, 1}, {0, 0, 0}, 1.0));
    tree_gravity const gravity(1.0, 1e-3, 0.5);
    std::vector<vec3> f(bodies.size(), vec3::Zero());
    gravity.add_forces(bodies, bodies.positions(), f);
    for (vec3 const& fi : f)
        ASSERT_TRUE(fi.allFinite());
    EXPECT_NEAR(f[0].x(), 1.0 / (99.0 * 99.0), 1e-9);
}

// ---------------------------------------------------------------------------------------------
// dt = 0 and dt absurdly large

world busy_world(integrator_kind integrator, collision_mode mode)
{
    world_settings s;
    s.integrator = integrator;
    s.collisions.mode = mode;
    // At dt = 1e6 s the spheres pile on the floor and press on each other for the whole step;
    // continuous mode then meets contact after contact and finishes the step discretely at the
    // cap. The default cap (1e5 events) costs seconds per step; 2000 shows the same fallback.
    s.collisions.max_events_per_step = 2000;
    world w(s);
    w.add_force(std::make_unique<uniform_field>(vec3(0, 0, -9.81)));
    w.add_force(std::make_unique<newtonian_gravity>(1.0, 0.1));
    w.add_wall({make_plane({0, 0, 1}, 0.0), 0.1, 0.1});
    w.add_wall({make_plane({0, 0, -1}, -100.0)});
    w.add_wall({make_plane({1, 0, 0}, -50.0)});
    w.add_wall({make_plane({-1, 0, 0}, -50.0)});
    w.add_wall({make_plane({0, 1, 0}, -50.0)});
    w.add_wall({make_plane({0, -1, 0}, -50.0)});
    for (int i = 0; i < 5; ++i)
        w.add_body(body_at({i * 5.0 - 10, 0, 10.0 + i}, {1, -2, 3}, 1.0 + i, 1.0));
    return w;
}

TEST(StepSize, ZeroStepChangesNoStateInAnyMode)
{
    // dt = 0 advances nothing: positions and velocities keep their bits in every integrator
    // and collision mode (collisions are skipped for a zero step).
    for (auto const& info : integrator_table()) {
        for (collision_mode const mode :
             {collision_mode::off, collision_mode::discrete, collision_mode::continuous}) {
            world w = busy_world(info.kind, mode);
            auto const x = copy(w.bodies().positions());
            auto const v = copy(w.bodies().velocities());
            for (int i = 0; i < 10; ++i)
                w.step(0.0);
            EXPECT_EQ(copy(w.bodies().positions()), x) << info.name << " " << name(mode);
            EXPECT_EQ(copy(w.bodies().velocities()), v) << info.name << " " << name(mode);
            EXPECT_EQ(w.time(), 0.0);
        }
    }
}

TEST(StepSize, AMillionSecondStepIsFiniteAndKeepsSpheresInTheBox)
{
    // dt = 1e6 s in a 100 m box under g = 9.81: a step lets a body fall ~5e12 m, which the
    // walls must stop. The integrator's answer is meaningless at this dt, but the state stays
    // finite, no sphere leaves the box (clamp_to_walls guarantees it in both modes), and the
    // continuous mode may hit its event cap and finish the step discretely (counted).
    for (auto const& info : integrator_table()) {
        for (collision_mode const mode : {collision_mode::discrete, collision_mode::continuous}) {
            world w = busy_world(info.kind, mode);
            for (int i = 0; i < 5; ++i) {
                w.step(1e6);
                ASSERT_TRUE(state_is_finite(w)) << info.name << " " << name(mode) << " " << i;
                ASSERT_TRUE(motion_summary_is_finite(w));
                ASSERT_EQ(w.escaped(), 0U) << info.name << " " << name(mode);
            }
            EXPECT_TRUE(std::isfinite(measure(w).total));
        }
    }
}

TEST(StepSize, AMillionSecondStepOfAnOrbitIsFiniteOrRefused)
{
    // A Kepler pair stepped at 1e6 s (1.6e5 orbits per step) with softening 0: the bodies fly
    // apart or land anywhere. Each step either succeeds with a finite state or, if it lands
    // two bodies on one point, refuses with singular_force_error and changes nothing.
    for (auto const& info : integrator_table()) {
        world w({.integrator = info.kind});
        w.add_force(std::make_unique<newtonian_gravity>(1.0, 0.0));
        w.add_body(body_at({0, 0, 0}, {0, 0, 0}, 1.0));
        w.add_body(body_at({1, 0, 0}, {0, 1, 0}, 1e-3));
        for (int i = 0; i < 20; ++i) {
            auto const x = copy(w.bodies().positions());
            try {
                w.step(1e6);
            } catch (singular_force_error const&) {
                EXPECT_EQ(copy(w.bodies().positions()), x);
            }
            ASSERT_TRUE(state_is_finite(w)) << info.name << " " << i;
        }
    }
}

// ---------------------------------------------------------------------------------------------
// A million steps

TEST(LongRun, KeplerOrbitStaysFiniteWithBoundedEnergyErrorForAMillionSteps)
{
    // e = 0.5 orbit (G = M = 1, a = 1), velocity Verlet at 500 steps per orbit for 10⁶ steps
    // (2000 orbits). Verlet is symplectic: its energy error oscillates with an amplitude of
    // O(h²) and does not drift. Measured amplitude about 2e-4 of |E| for this h at e = 0.5;
    // the bound 1e-3 of |E| allows for that and fails on a secular drift of 1e-9 per step.
    world w({.integrator = integrator_kind::velocity_verlet});
    w.add_force(std::make_unique<newtonian_gravity>(1.0, 0.0));
    double const e = 0.5;
    // Perihelion at r = a(1 − e) with speed √((1 + e)/(1 − e)) (vis-viva, G·M = 1).
    w.add_body(body_at({0, 0, 0}, {0, 0, 0}, 1.0));
    w.add_body(body_at({1 - e, 0, 0}, {0, std::sqrt((1 + e) / (1 - e)), 0}, 1e-9));
    double const energy = measure(w).total;
    double worst = 0.0;
    double const h = 2 * M_PI / 500;
    for (int i = 0; i < 1'000'000; ++i) {
        w.step(h);
        if (i % 1000 == 999) {
            ASSERT_TRUE(state_is_finite(w)) << i;
            worst = std::max(worst, std::abs(measure(w).total - energy));
        }
    }
    EXPECT_LE(worst, 1e-3 * std::abs(energy));
    EXPECT_EQ(w.steps(), 1'000'000U);
    EXPECT_NEAR(w.time(), 1e6 * h, 1e-9 * 1e6 * h); // the clock is a compensated sum
}

TEST(LongRun, BouncingBallStaysFiniteAndNeverGainsEnergyForAMillionSteps)
{
    // An elastic ball on an elastic floor in continuous mode, 10⁶ steps of 1/600 s (1667 s):
    // the event loop times each bounce exactly on the parabola, so the apex height (energy)
    // drifts only by rounding per bounce. Bound: the energy stays within 1e-6 of its start
    // over the ~1950 bounces (a 0.9 m drop: 0.857 s per bounce) and the ball never sinks into
    // the floor by more than 1e-9 m.
    world_settings s;
    s.integrator = integrator_kind::velocity_verlet;
    s.collisions.mode = collision_mode::continuous;
    world w(s);
    w.add_force(std::make_unique<uniform_field>(vec3(0, 0, -9.81)));
    w.add_wall({make_plane({0, 0, 1}, 0.0)});
    w.add_body(body_at({0, 0, 1.0}, {0, 0, 0}, 1.0, 0.1));
    double const energy = measure(w).total;
    for (int i = 0; i < 1'000'000; ++i) {
        w.step(1.0 / 600);
        if (i % 1000 == 999) {
            ASSERT_TRUE(state_is_finite(w)) << i;
            ASSERT_LE(w.max_overlap(), 1e-9) << i;
        }
    }
    EXPECT_NEAR(measure(w).total, energy, 1e-6 * std::abs(energy));
    EXPECT_GT(w.collisions().wall_contacts, 1900U);
}

} // namespace
} // namespace kugel::extremes
