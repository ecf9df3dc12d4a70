// The discrete mode's sweep (collisions.sweep): bodies that move farther than a share of their
// radius in one step are taken through the step's events in time order, so that at 1e4 m/s
// they meet what lies between where they start and where they end, and what they would have
// missed without it is counted.

#include "extremes.hpp"

#include "physics/forces.hpp"
#include "physics/obb.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <memory>
#include <random>

namespace kugel::extremes {
namespace {

using namespace physics;

body_desc sphere_at(vec3 x, vec3 v, double m, double r) { return {x, v, m, r, 0.0, false}; }

world discrete_world(bool sweep)
{
    world_settings s;
    s.collisions.mode = collision_mode::discrete;
    s.collisions.sweep = sweep;
    return world(s);
}

double kinetic_energy(world const& w)
{
    double sum = 0.0;
    for (std::size_t i = 0; i < w.bodies().size(); ++i)
        sum += 0.5 * w.bodies().masses()[i] * w.bodies().velocities()[i].squaredNorm();
    return sum;
}

constexpr double h = 1.0 / 60.0;

TEST(DiscreteSweep, HeadOnPairAt1e4MetresPerSecondBouncesAsTheElasticRuleSays)
{
    // Unit spheres of 1 kg and 3 kg, 100 m apart, closing at 2e4 m/s: they touch at
    // t = 98 m / 2e4 m/s = 4.9 ms, 166 m of travel each in a 1/60 s step. The lecture's elastic
    // rule, w₁ = ((m₁ − m₂)·v₁ + 2m₂·v₂)/(m₁ + m₂), gives the light one −2e4 m/s and stops the
    // heavy one at x = 1. Times of impact are exact to rounding and contacts are answered within
    // 1e-9 of the contact distance, so positions hold to 1e-6 m (a millionth of the radius
    // whose passing is at stake) and speeds to 1e-6 m/s.
    world w = discrete_world(true);
    body_id const a = w.add_body(sphere_at({-50, 0, 0}, {1e4, 0, 0}, 1.0, 1.0));
    body_id const b = w.add_body(sphere_at({50, 0, 0}, {-1e4, 0, 0}, 3.0, 1.0));
    momentum_sum const before = momentum_of(w);
    double const energy_before = kinetic_energy(w);
    w.step(h);
    ASSERT_TRUE(state_is_finite(w));
    EXPECT_EQ(w.collisions().sphere_contacts, 1U);
    EXPECT_EQ(w.collisions().swept_bodies, 2U);
    EXPECT_EQ(w.collisions().unswept_fast_bodies, 0U);
    double const t = 98.0 / 2e4;
    EXPECT_NEAR(velocity_of(w, a).x(), -2e4, 1e-6);
    EXPECT_NEAR(velocity_of(w, b).x(), 0.0, 1e-6);
    EXPECT_NEAR(position_of(w, a).x(), -1.0 - 2e4 * (h - t), 1e-6);
    EXPECT_NEAR(position_of(w, b).x(), 1.0, 1e-6);
    // Momentum and energy of an elastic pair, to the rounding of sums of products of 1e4
    // (16 ε of Σ m·|v|, 16 ε of the energy).
    EXPECT_LE((momentum_of(w).total - before.total).norm(), 16 * std::numeric_limits<double>::epsilon() * before.scale);
    EXPECT_NEAR(kinetic_energy(w), energy_before, 16 * std::numeric_limits<double>::epsilon() * energy_before);
    // They part, never overlapping, and never meet again.
    for (int i = 0; i < 10; ++i) {
        w.step(h);
        EXPECT_LT(position_of(w, a).x(), position_of(w, b).x() - 2.0);
    }
    EXPECT_EQ(w.collisions().sphere_contacts, 1U);
}

TEST(DiscreteSweep, WithTheSweepOffTheHeadOnPairPassesThroughAndIsCounted)
{
    // The same pair without the sweep: at the step's end they are 233 m past each other and
    // no overlap shows it. Each was fast and not swept: two contacts that may have been missed.
    world w = discrete_world(false);
    body_id const a = w.add_body(sphere_at({-50, 0, 0}, {1e4, 0, 0}, 1.0, 1.0));
    body_id const b = w.add_body(sphere_at({50, 0, 0}, {-1e4, 0, 0}, 3.0, 1.0));
    w.step(h);
    EXPECT_GT(position_of(w, a).x(), position_of(w, b).x());
    EXPECT_EQ(w.collisions().sphere_contacts, 0U);
    EXPECT_EQ(w.max_overlap(), 0.0);
    EXPECT_EQ(w.collisions().swept_bodies, 0U);
    EXPECT_EQ(w.collisions().unswept_fast_bodies, 2U);
}

TEST(DiscreteSweep, FastSphereHitsARestingRowAndMomentumPassesAlongIt)
{
    // A unit sphere at 1e4 m/s towards two resting ones of equal mass at x = 50 and x = 150: it
    // stops at x = 48 (t₁ = 4.8 ms), the second runs on and stops at x = 148 (t₂ = 14.6 ms),
    // the third leaves at 1e4 m/s from x = 150. The resting spheres are slow and not fast
    // themselves: they are swept because their paths lie in the fast one's path box.
    // Tolerances as in the head-on case.
    world w = discrete_world(true);
    body_id const a = w.add_body(sphere_at({0, 0, 0}, {1e4, 0, 0}, 1.0, 1.0));
    body_id const b = w.add_body(sphere_at({50, 0, 0}, {0, 0, 0}, 1.0, 1.0));
    body_id const c = w.add_body(sphere_at({150, 0, 0}, {0, 0, 0}, 1.0, 1.0));
    w.step(h);
    EXPECT_EQ(w.collisions().sphere_contacts, 2U);
    EXPECT_EQ(w.collisions().unswept_fast_bodies, 0U);
    double const t2 = 48.0 / 1e4 + 98.0 / 1e4;
    EXPECT_NEAR(position_of(w, a).x(), 48.0, 1e-6);
    EXPECT_NEAR(position_of(w, b).x(), 148.0, 1e-6);
    EXPECT_NEAR(position_of(w, c).x(), 150.0 + 1e4 * (h - t2), 1e-6);
    EXPECT_NEAR(velocity_of(w, a).x(), 0.0, 1e-6);
    EXPECT_NEAR(velocity_of(w, b).x(), 0.0, 1e-6);
    EXPECT_NEAR(velocity_of(w, c).x(), 1e4, 1e-6);
}

TEST(DiscreteSweep, FastSphereBouncesAtAWallAndAtAThinBox)
{
    // A unit sphere at 1e4 m/s from x = 0: a wall at x = 50 with α = 0.5 (the lecture's rule
    // leaves −(1 − α)·1e4) is met at t = 4.9 ms; a box 0.2 m thick at x = 50, which the end of
    // the step would never see, at t = 4.89 ms, elastically. Each ends on its side, at the
    // position the meeting time and the new velocity give (to 1e-6 m, as above).
    {
        world w = discrete_world(true);
        w.add_wall({make_plane({-1, 0, 0}, -50), 0.5, 0.0});
        body_id const s = w.add_body(sphere_at({0, 0, 0}, {1e4, 0, 0}, 1.0, 1.0));
        w.step(h);
        EXPECT_EQ(w.collisions().wall_contacts, 1U);
        EXPECT_NEAR(velocity_of(w, s).x(), -5e3, 1e-6);
        EXPECT_NEAR(position_of(w, s).x(), 49.0 - 5e3 * (h - 49.0 / 1e4), 1e-6);
        EXPECT_EQ(w.collisions().unswept_fast_bodies, 0U);
    }
    for (bool const sweep : {true, false}) {
        world w = discrete_world(sweep);
        w.add_obstacle({obb_from_box({50, 0, 0}, {0.1, 10, 10}, Eigen::Matrix3d::Identity()), 0.0, 0.0});
        body_id const s = w.add_body(sphere_at({0, 0, 0}, {1e4, 0, 0}, 1.0, 1.0));
        w.step(h);
        if (sweep) {
            EXPECT_EQ(w.collisions().obstacle_contacts, 1U);
            EXPECT_NEAR(velocity_of(w, s).x(), -1e4, 1e-6);
            EXPECT_NEAR(position_of(w, s).x(), 48.9 - 1e4 * (h - 48.9 / 1e4), 1e-6);
            EXPECT_EQ(w.collisions().unswept_fast_bodies, 0U);
        } else { // through the box, and said so
            EXPECT_GT(position_of(w, s).x(), 50.0);
            EXPECT_EQ(w.collisions().unswept_fast_bodies, 1U);
        }
    }
}

/// 200 spheres of radius 0.05 m in a closed 1 m box at 1e4 m/s in random directions, dt =
/// 1e-4 s: every sphere crosses the box once a step, 20 radii. Continuous mode takes it step by
/// step (not by its calendar of events): the sweep runs that loop, so the two find the same
/// events, where the calendar would find the same physics on paths that part in the last
/// bits, and this gas, 6 contacts a sphere a step, magnifies that into other contacts.
world fast_gas(collision_mode mode, bool sweep)
{
    world_settings s;
    s.collisions.mode = mode;
    s.collisions.sweep = sweep;
    s.collisions.event_calendar = false;
    world w(s);
    for (int axis = 0; axis < 3; ++axis) {
        for (double const sign : {1.0, -1.0}) {
            vec3 normal = vec3::Zero();
            normal[axis] = sign;
            w.add_wall({make_plane(normal, -0.5)});
        }
    }
    std::mt19937_64 rng(7);
    std::normal_distribution<double> gauss;
    for (int i = 0; i < 200; ++i) {
        vec3 const cell(i % 6, (i / 6) % 6, i / 36);
        vec3 const v(gauss(rng), gauss(rng), gauss(rng));
        w.add_body(sphere_at(cell * (1.0 / 6.0) - vec3::Constant(0.5 - 1.0 / 12.0), 1e4 * v.normalized(), 1.0, 0.05));
    }
    return w;
}

TEST(DiscreteSweep, FastGasStaysInItsBoxKeepsItsEnergyAndCollides)
{
    // Every sphere is fast: the sweep takes them all through the step's events, as continuous
    // mode does. None leaves the box or ends overlapping beyond rounding (1e-9 of a radius),
    // elastic contacts keep the energy to 1e-9 (rounding over some 10^4 contacts is 1e-12),
    // and the sphere contacts are those continuous mode finds, to 1 %: the events are the
    // same, and the discrete passes after them may answer a pair rounding leaves closing.
    world w = fast_gas(collision_mode::discrete, true);
    world exact = fast_gas(collision_mode::continuous, true);
    double const energy = kinetic_energy(w);
    for (int i = 0; i < 20; ++i) {
        w.step(1e-4);
        exact.step(1e-4);
        ASSERT_TRUE(state_is_finite(w));
        ASSERT_EQ(w.escaped(), 0U) << "step " << i;
        ASSERT_LE(w.max_overlap(), 1e-9 * 0.05) << "step " << i;
    }
    EXPECT_EQ(w.collisions().unswept_fast_bodies, 0U);
    EXPECT_EQ(w.collisions().capped_steps, 0U);
    EXPECT_GT(w.collisions().swept_bodies, 20U * 150U);
    EXPECT_NEAR(kinetic_energy(w), energy, 1e-9 * energy);
    EXPECT_GT(w.collisions().sphere_contacts, 1000U);
    EXPECT_NEAR(static_cast<double>(w.collisions().sphere_contacts),
                static_cast<double>(exact.collisions().sphere_contacts),
                0.01 * static_cast<double>(exact.collisions().sphere_contacts));

    // Without the sweep the same gas misses most of them, and says how many fast bodies went
    // unswept: every sphere in every step.
    world blind = fast_gas(collision_mode::discrete, false);
    for (int i = 0; i < 20; ++i)
        blind.step(1e-4);
    EXPECT_LT(blind.collisions().sphere_contacts, w.collisions().sphere_contacts / 2);
    EXPECT_GT(blind.collisions().unswept_fast_bodies, 20U * 150U);
}

TEST(DiscreteSweep, FastSphereLandingOnARestingStackIsSweptToTheEnd)
{
    // A column of four spheres (r = 0.05 m) resting on the floor under gravity, e = 0.5, and a
    // fifth falling onto it at 5 m/s, 1.7 radii a step: the sweep takes it and the column
    // through the step's events. Resting on each other under gravity, the column's spheres
    // met again and again at ever smaller speeds (inelastic collapse) until the sweep reached
    // its event cap and left the step to the discrete passes, the fast sphere unswept. Pairs
    // that move against each other slower than a swept body must move are now left to the
    // discrete step: nothing is capped, every fast body is swept, and after 1 s the five stand
    // in a column at rest (overlaps within 1 % of a radius, the position passes' slop for a
    // stack of five, and no sphere faster than 1e-3 m/s, the pile figure's bound).
    world_settings s;
    s.integrator = integrator_kind::semi_implicit_euler;
    s.collisions.mode = collision_mode::discrete;
    s.collisions.restitution = 0.5;
    world w(s);
    w.add_force(std::make_unique<uniform_field>(vec3(0, 0, -9.81)));
    w.add_wall({make_plane({0, 0, 1}, 0.0), 0.5, 0.5});
    for (int k = 0; k < 4; ++k)
        w.add_body(sphere_at({0, 0, 0.05 + 0.1 * k}, {0, 0, 0}, 1.0, 0.05));
    w.add_body(sphere_at({0, 0, 0.6}, {0, 0, -5}, 1.0, 0.05));
    for (int i = 0; i < 60; ++i) {
        w.step(h);
        ASSERT_TRUE(state_is_finite(w));
    }
    EXPECT_EQ(w.collisions().capped_steps, 0U);
    EXPECT_EQ(w.collisions().unswept_fast_bodies, 0U);
    EXPECT_GE(w.collisions().swept_bodies, 1U);
    EXPECT_GE(w.collisions().sphere_contacts, 4U);
    EXPECT_EQ(w.escaped(), 0U);
    EXPECT_LE(w.max_overlap(), 0.01 * 0.05);
    for (std::size_t i = 0; i < w.bodies().size(); ++i) {
        EXPECT_LT(w.bodies().velocities()[i].norm(), 1e-3) << "sphere " << i;
        EXPECT_NEAR(w.bodies().positions()[i].z(), 0.05 + 0.1 * static_cast<double>(i), 0.01 * 0.05) << "sphere " << i;
    }
}

TEST(DiscreteSweep, OneFastSphereInARestingLatticeMeetsItOnItsWay)
{
    // 512 resting spheres on a lattice and one at 1e3 m/s starting between them, 17 m of
    // travel in the step (a mean free path is 0.5 m here): only that one is fast, it meets the
    // lattice on its way, and leaves nobody overlapping or behind a wall, and no fast body
    // goes unswept.
    world_settings s;
    s.collisions.mode = collision_mode::discrete;
    world w(s);
    for (int axis = 0; axis < 3; ++axis) {
        for (double const sign : {1.0, -1.0}) {
            vec3 normal = vec3::Zero();
            normal[axis] = sign;
            w.add_wall({make_plane(normal, -1.0)});
        }
    }
    for (int i = 0; i < 512; ++i) {
        vec3 const cell(i % 8, (i / 8) % 8, i / 64);
        w.add_body(sphere_at(cell * 0.25 - vec3::Constant(0.875), {0, 0, 0}, 1.0, 0.05));
    }
    w.add_body(sphere_at({-0.75, -0.75, -0.75}, 1e3 * vec3(1.0, 0.3, 0.2).normalized(), 1.0, 0.05));
    w.step(h);
    EXPECT_GE(w.collisions().sphere_contacts, 1U);
    EXPECT_EQ(w.collisions().swept_bodies, 1U);
    EXPECT_EQ(w.collisions().unswept_fast_bodies, 0U);
    EXPECT_EQ(w.escaped(), 0U);
    EXPECT_LE(w.max_overlap(), 1e-9 * 0.05);
}

TEST(DiscreteSweep, AChainOfContactsLeavingTheFastPathIsFollowedToItsEnd)
{
    // A sphere at 60 m/s grazes a resting one (centres 0.07 m apart across its path, radii
    // 0.05 m): that one leaves at about 43 m/s at 44° to the path, and in the rest of the step
    // runs into a third sphere that lies well clear of the fast one's path. Neither resting
    // sphere is fast, and the third shares no box with the fast path: only the sweep's second
    // round, from the path the second one took after its contact, draws it in. Twenty more
    // spheres rest far away, so that not every sphere is swept at once.
    //
    // Continuous mode takes the same events on the same paths, so the sweep's answer is its
    // answer: positions to 1e-12 m (rounding of a few products of 60 m/s and a step), and
    // momentum and energy of elastic contacts to 16 ε.
    std::array<body_id, 3> ids; // the same in both worlds
    auto const build = [&](collision_mode mode) {
        world_settings s;
        s.collisions.mode = mode;
        world w(s);
        ids[0] = w.add_body(sphere_at({-0.2, 0, 0}, {60, 0, 0}, 1.0, 0.05));
        vec3 const second(0, 0.07, 0);
        vec3 const n = vec3(std::sqrt(0.01 - 0.07 * 0.07), 0.07, 0).normalized(); // the contact normal
        ids[1] = w.add_body(sphere_at(second, {0, 0, 0}, 1.0, 0.05));
        ids[2] = w.add_body(sphere_at(second + 0.3 * n, {0, 0, 0}, 1.0, 0.05));
        for (int i = 0; i < 20; ++i)
            w.add_body(sphere_at({10.0 + 0.5 * i, 10, 10}, {0, 0, 0}, 1.0, 0.05));
        return w;
    };
    world w = build(collision_mode::discrete);
    world exact = build(collision_mode::continuous);
    momentum_sum const before = momentum_of(w);
    double const energy_before = kinetic_energy(w);
    w.step(h);
    exact.step(h);
    EXPECT_EQ(w.collisions().sphere_contacts, 2U);
    EXPECT_EQ(exact.collisions().sphere_contacts, 2U);
    EXPECT_EQ(w.collisions().swept_bodies, 1U);
    EXPECT_EQ(w.collisions().unswept_fast_bodies, 0U);
    EXPECT_GT(velocity_of(w, ids[2]).norm(), 10.0); // the third was hit
    for (std::size_t i = 0; i < ids.size(); ++i) {
        EXPECT_LE((position_of(w, ids[i]) - position_of(exact, ids[i])).norm(), 1e-12) << "body " << i;
        EXPECT_LE((velocity_of(w, ids[i]) - velocity_of(exact, ids[i])).norm(), 1e-12) << "body " << i;
    }
    EXPECT_LE((momentum_of(w).total - before.total).norm(), 16 * std::numeric_limits<double>::epsilon() * before.scale);
    EXPECT_NEAR(kinetic_energy(w), energy_before, 16 * std::numeric_limits<double>::epsilon() * energy_before);
    EXPECT_LE(w.max_overlap(), 1e-9 * 0.05);
}

} // namespace
} // namespace kugel::extremes
