// Forces and step sizes at the extremes: coincident bodies under 1/r² laws, dt = 0 and
// dt = 1e6 s, a close encounter at 1e-9 m, and a run of a million steps.

#include "extremes.hpp"

#include "physics/barnes_hut.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <numbers>
#include <string>
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
    // continuous mode may hit its event cap and finish the step discretely (counted). The
    // adaptive integrator, which would follow the bodies' mutual orbits for the whole 1e6 s,
    // may refuse the step at its cap of steps instead (step_control_error), changing nothing.
    for (auto const& info : integrator_table()) {
        for (collision_mode const mode : {collision_mode::discrete, collision_mode::continuous}) {
            world w = busy_world(info.kind, mode);
            for (int i = 0; i < 5; ++i) {
                auto const x = copy(w.bodies().positions());
                try {
                    w.step(1e6);
                } catch (step_control_error const&) {
                    EXPECT_TRUE(info.adaptive) << info.name;
                    EXPECT_EQ(copy(w.bodies().positions()), x) << info.name;
                }
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
    // two bodies on one point, refuses with singular_force_error and changes nothing. The
    // adaptive integrator follows the orbits instead, and refuses at its cap of steps
    // (step_control_error), changing nothing too.
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
            } catch (step_control_error const&) {
                EXPECT_TRUE(info.adaptive) << info.name;
                EXPECT_EQ(copy(w.bodies().positions()), x);
            }
            ASSERT_TRUE(state_is_finite(w)) << info.name << " " << i;
        }
    }
}

// ---------------------------------------------------------------------------------------------
// A close encounter

/// Two unit masses on a Kepler orbit of semi-major axis 1 m and periapsis 1e-9 m
/// (e = 1 − 1e-9), started at apoapsis with the centre of mass at rest; G = π²/2 makes the
/// period 2 s, so 120 world steps of 1/60 s are one period and bring the pair back to
/// apoapsis. At periapsis the bodies pass at 7e4 m/s each, within ~1e-14 s.
struct close_encounter
{
    static constexpr double G = std::numbers::pi * std::numbers::pi / 2.0;
    static constexpr double e = 1.0 - 1e-9;
    static constexpr double period = 2.0;
    static constexpr int ticks = 120;

    static world make(integrator_kind kind, double tolerance = 1e-9, std::uint64_t max_steps = 100'000)
    {
        double const r = 1.0 + e;                            // apoapsis distance (a = 1)
        double const v = std::sqrt(G * 2.0 * (1.0 - e) / r); // relative speed there
        world w({.integrator = kind, .adaptive = {.tolerance = tolerance, .max_steps = max_steps}});
        w.add_force(std::make_unique<newtonian_gravity>(G, 0.0));
        w.add_body(body_at({-r / 2, 0, 0}, {0, -v / 2, 0}, 1.0));
        w.add_body(body_at({r / 2, 0, 0}, {0, v / 2, 0}, 1.0));
        return w;
    }
};

/// The relative orbit's elements, from the separation and relative velocity.
struct elements
{
    double energy;         ///< J, the pair's total energy
    double semi_major;     ///< m, −G·m₁m₂/(2E); negative once unbound
    double eccentricity;   ///< |e|, from the Laplace–Runge–Lenz vector
    vec3 angular_momentum; ///< kg·m²/s, about the centre of mass
    vec3 separation;       ///< m, x₂ − x₁
};

elements elements_of(world const& w)
{
    vec3 const r = w.bodies().positions()[1] - w.bodies().positions()[0];
    vec3 const v = w.bodies().velocities()[1] - w.bodies().velocities()[0];
    double const mu = close_encounter::G * 2.0, reduced_mass = 0.5;
    double const energy = measure(w).total;
    vec3 const h = r.cross(v);
    return {energy, -close_encounter::G / (2.0 * energy), (v.cross(h) / mu - r.normalized()).norm(),
            reduced_mass * h, r};
}

TEST(CloseEncounter, FixedStepsLoseThePairAtA1e9MetrePeriapsis)
{
    // At 1/60 s per step the periapsis passage (~1e-14 s) falls inside one step: velocity
    // Verlet and RK4 kick the pair with the force at a point of the orbit that is not where
    // it passes, and the pair leaves unbound (its energy changes sign). What the adaptive
    // integrator below is for.
    for (auto const kind : {integrator_kind::velocity_verlet, integrator_kind::rk4}) {
        world w = close_encounter::make(kind);
        for (int i = 0; i < close_encounter::ticks; ++i)
            w.step(close_encounter::period / close_encounter::ticks);
        ASSERT_TRUE(state_is_finite(w));
        EXPECT_GT(elements_of(w).energy, 0.0) << info(kind).name;
    }
}

TEST(CloseEncounter, DormandPrinceKeepsTheOrbitThroughA1e9MetrePeriapsis)
{
    // Over one period at 1/60 s per step, with tolerance 1e-12. Energy: at periapsis the
    // kinetic and potential energies are each 1/(1 − e) = 1e9 times |E|, so a relative error
    // of the speeds there moves E by 2e9 times as much: rounding alone (1.1e-16 per operation)
    // over the ~10⁴ steps the passage takes costs ~1e-5 of |E| if it adds up as a random walk
    // (√10⁴ · 1.1e-16 · 2e9 ≈ 2e-5). Measured 4.6e-6; the bound 1e-4 is what doubles allow in
    // this frame with room, and six orders of magnitude below the fixed-step failure above.
    // Angular momentum and the Laplace–Runge–Lenz vector do not go through the cancellation:
    // 1e-9 of their size (measured ~1e-12). The pair is back at apoapsis within the same
    // relative error as its energy (the period depends on a only: δP/P = 1.5·δa/a).
    world w = close_encounter::make(integrator_kind::dormand_prince, 1e-12);
    elements const start = elements_of(w);
    for (int i = 0; i < close_encounter::ticks; ++i)
        w.step(close_encounter::period / close_encounter::ticks);
    ASSERT_TRUE(state_is_finite(w));
    elements const end = elements_of(w);
    EXPECT_LT(end.energy, 0.0); // still bound
    EXPECT_LE(std::abs(end.energy / start.energy - 1.0), 1e-4);
    EXPECT_LE(std::abs(end.semi_major / start.semi_major - 1.0), 1e-4);
    EXPECT_LE((end.angular_momentum - start.angular_momentum).norm(), 1e-9 * start.angular_momentum.norm());
    EXPECT_NEAR(end.semi_major * (1.0 - end.eccentricity), 1e-9, 1e-9 * 1e-9 / (1.0 - close_encounter::e)); // periapsis
    EXPECT_LE((end.separation - start.separation).norm(), 1e-4 * start.separation.norm());
    // It did so with steps of its own far below the world's: the passage needs ~1e-16 s.
    EXPECT_LT(w.integration_steps().smallest, 1e-15);
    EXPECT_GT(w.integration_steps().accepted, 1000U);
}

TEST(CloseEncounter, ATooLooseToleranceIsRefusedNotAnsweredWrongly)
{
    // At tolerance 1e-6 the passage's energy error (1e-6 · 2e9 · |E|) is far more than the
    // energy: the pair falls into an orbit of nanometres that the step cannot cover in the
    // rest of the tick. The integrator stops at its cap of steps, and the world step refuses
    // with step_control_error, the world as it was before the step.
    world w = close_encounter::make(integrator_kind::dormand_prince, 1e-6, 20'000);
    double const dt = close_encounter::period / close_encounter::ticks;
    for (int i = 0; i < close_encounter::ticks; ++i) {
        auto const x = copy(w.bodies().positions());
        auto const v = copy(w.bodies().velocities());
        double const time = w.time();
        try {
            w.step(dt);
        } catch (step_control_error const& error) {
            std::string const what = error.what();
            EXPECT_NE(what.find("tolerance 1e-06"), std::string::npos) << what;
            EXPECT_NE(what.find("20000 steps"), std::string::npos) << what;
            EXPECT_EQ(copy(w.bodies().positions()), x);
            EXPECT_EQ(copy(w.bodies().velocities()), v);
            EXPECT_EQ(w.time(), time);
            EXPECT_LT(error.body_slot, 2U);
            return;
        }
    }
    ADD_FAILURE() << "the pair went through the passage at tolerance 1e-6 without a refusal";
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
