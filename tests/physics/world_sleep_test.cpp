// Sleeping (world_sleep.cpp): bodies at rest in discrete mode fall asleep as islands, keep
// their state exactly while asleep, and wake when something touches them.

#include "physics/collision_scenes.hpp"
#include "physics/diagnostics.hpp"
#include "physics/world.hpp"
#include "support/state_hash.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace kugel::physics {
namespace {

using test_support::state_hash;

constexpr double dt = 1.0 / 60.0;
constexpr double pi = 3.141592653589793;

void step(world& w, int steps)
{
    for (int i = 0; i < steps; ++i)
        w.step(dt);
}

bool every_velocity_is_zero(world const& w)
{
    for (vec3 const& v : w.bodies().velocities())
        if (!(v.array() == 0.0).all())
            return false;
    return true;
}

// A column at rest falls asleep once every sphere has been slower than sleep_speed for
// sleep_time (0.5 s: 30 steps), and asleep it stays exactly still: every velocity is 0 (a
// snapshot shows no motion) and 10 s more change no bit of the state.
TEST(Sleep, AColumnAtRestFallsAsleepAndStaysExactlyStill)
{
    world w = stack_on_the_floor(10, 0.05);
    step(w, 29);
    EXPECT_EQ(w.sleeping_bodies(), 0U) << "asleep before sleep_time";
    step(w, 31);
    ASSERT_EQ(w.sleeping_bodies(), 10U);
    EXPECT_TRUE(every_velocity_is_zero(w));
    std::uint64_t const asleep = state_hash(w);
    step(w, 600);
    EXPECT_EQ(state_hash(w), asleep);
    EXPECT_EQ(w.sleeping_bodies(), 10U);
}

// Sleeping can be turned off: the same column then never sleeps, and its spheres still rest
// (the resting-pile figure, 1e-3 m/s).
TEST(Sleep, TurnedOffNothingSleeps)
{
    world w = stack_on_the_floor(10, 0.05, false);
    step(w, 120);
    EXPECT_EQ(w.sleeping_bodies(), 0U);
    EXPECT_LE(measure(w).largest_speed, 1e-3);
}

// An impulse on one sleeping sphere wakes its whole island: the sphere moves off, and the
// column it leaves is awake again (until it has been calm for sleep_time once more).
TEST(Sleep, AnImpulseWakesTheIsland)
{
    world w = stack_on_the_floor(10, 0.05);
    step(w, 60);
    ASSERT_EQ(w.sleeping_bodies(), 10U);
    body_id const top = w.bodies().ids()[9];
    vec3 const before = w.bodies().positions()[9];
    ASSERT_TRUE(w.apply_impulse(top, vec3(0.2, 0, 0)));
    EXPECT_EQ(w.sleeping_bodies(), 0U);
    step(w, 1);
    EXPECT_GT(w.bodies().positions()[*w.bodies().slot_of(top)].x(), before.x());
}

// Setting a sleeping sphere's state wakes its island, as an impulse does: the top sphere
// set moving sideways moves off; the top one lifted away leaves its column awake, and the
// lifted one falls back onto it.
TEST(Sleep, SettingAStateWakesTheIsland)
{
    world w = stack_on_the_floor(10, 0.05);
    step(w, 60);
    ASSERT_EQ(w.sleeping_bodies(), 10U);
    body_id const top = w.bodies().ids()[9];
    vec3 const before = w.bodies().positions()[9];
    ASSERT_TRUE(w.set_state(top, std::nullopt, vec3(0.2, 0, 0)));
    EXPECT_EQ(w.sleeping_bodies(), 0U);
    step(w, 1);
    EXPECT_GT(w.bodies().positions()[*w.bodies().slot_of(top)].x(), before.x());

    world lifted = stack_on_the_floor(10, 0.05);
    step(lifted, 60);
    ASSERT_EQ(lifted.sleeping_bodies(), 10U);
    body_id const lid = lifted.bodies().ids()[9];
    ASSERT_TRUE(lifted.set_state(lid, vec3(0, 0, 1.5), std::nullopt));
    EXPECT_EQ(lifted.sleeping_bodies(), 0U);
    step(lifted, 1);
    EXPECT_LT(lifted.bodies().positions()[*lifted.bodies().slot_of(lid)].z(), 1.5) << "it falls";
}

// A sphere dropped onto a sleeping column wakes it when it touches the top: before, the
// column sleeps; the step the dropped sphere touches it, it is awake; and the whole lot,
// dropped sphere included, comes to rest on top and sleeps again.
TEST(Sleep, ASphereDroppedOntoASleepingColumnWakesIt)
{
    world w = stack_on_the_floor(10, 0.05);
    step(w, 60);
    ASSERT_EQ(w.sleeping_bodies(), 10U);
    body_id const dropped = w.add_body(ball({0, 0, 1.5}, vec3::Zero(), 0.05, 1000 * 4.0 / 3.0 * pi * 0.05 * 0.05 * 0.05));
    EXPECT_EQ(w.sleeping_bodies(), 10U) << "added far from it: nothing woke";
    bool woke = false;
    for (int i = 0; i < 120 && !woke; ++i) {
        w.step(dt);
        woke = w.sleeping_bodies() == 0;
    }
    EXPECT_TRUE(woke);
    step(w, 300);
    EXPECT_EQ(w.sleeping_bodies(), 11U);
    // On top of the column, which kept its height: 1.05 m, to the overlap bound of a pile.
    EXPECT_NEAR(w.bodies().positions()[*w.bodies().slot_of(dropped)].z(), 1.05, 1e-3 * 0.05);
}

// Removing the sphere at the bottom of a sleeping column wakes what it carried: the rest
// falls one diameter onto the floor and comes to rest there.
TEST(Sleep, ARemovedSupporterWakesWhatItCarried)
{
    world w = stack_on_the_floor(10, 0.05);
    step(w, 60);
    ASSERT_EQ(w.sleeping_bodies(), 10U);
    ASSERT_TRUE(w.remove_body(w.bodies().ids()[0]));
    EXPECT_EQ(w.sleeping_bodies(), 0U);
    step(w, 300);
    double lowest = 1e9;
    for (vec3 const& x : w.bodies().positions())
        lowest = std::min(lowest, x.z());
    EXPECT_NEAR(lowest, 0.05, 1e-6); // on the floor
}

// A sleeping sphere is taken as static by the awake ones: a sphere resting on it stays put
// while awake, and the step of a world whose every body sleeps moves nothing (time goes on).
TEST(Sleep, AWorldAsleepStepsOnlyItsClock)
{
    world w = stack_on_the_floor(10, 0.05);
    step(w, 60);
    ASSERT_EQ(w.sleeping_bodies(), 10U);
    std::uint64_t const asleep = state_hash(w);
    double const time = w.time();
    w.step(dt);
    EXPECT_EQ(state_hash(w), asleep);
    EXPECT_GT(w.time(), time);
}

// Nothing sleeps without forces (a gas keeps its bits) or in free fall (nothing static
// carries it): two touching spheres falling with nothing below them stay awake.
TEST(Sleep, NothingSleepsWithoutForcesOrInFreeFall)
{
    world gas = discrete_gas(500);
    step(gas, 120);
    EXPECT_EQ(gas.sleeping_bodies(), 0U);

    world_settings s = colliding(collision_mode::discrete, integrator_kind::semi_implicit_euler);
    s.collisions.sleep_time = 0.0;
    world falling(s);
    falling.add_force(std::make_unique<uniform_field>(vec3(0, 0, -9.81)));
    falling.add_body(ball({0, 0, 10.0}, vec3::Zero(), 0.05, 1.0));
    falling.add_body(ball({0, 0, 10.1}, vec3::Zero(), 0.05, 1.0));
    for (int i = 0; i < 60; ++i) {
        falling.step(dt);
        EXPECT_EQ(falling.sleeping_bodies(), 0U) << i;
    }
}

// A world keeps its sleeping state only from the first step sleeping applies to (a gas never
// pays for it). Bodies added and removed before then, and steps without forces, leave a
// world that sleeps exactly as one built with its forces: the same bits once asleep, and an
// impulse and a removal after it wake what they should.
TEST(Sleep, AWorldThatGainsItsForcesLateSleepsAsOneBuiltWithThem)
{
    world_settings s = colliding(collision_mode::discrete, integrator_kind::semi_implicit_euler);
    s.collisions.restitution = 0.5;
    s.collisions.friction = 0.5;
    world late(s);
    late.add_wall({make_plane(vec3::UnitZ(), 0.0), 0.5, 0.5});
    double const r = 0.05, m = 1000 * 4.0 / 3.0 * pi * r * r * r;
    for (int i = 0; i < 10; ++i)
        late.add_body(ball({0, 0, r + 2 * r * i}, vec3::Zero(), r, m));
    body_id const extra = late.add_body(ball({5, 5, 5}, vec3::Zero(), r, m));
    step(late, 3); // at rest without forces, far from the column: nothing moves, nothing sleeps
    ASSERT_TRUE(late.remove_body(extra)); // the last slot: no body moves into its hole
    EXPECT_FALSE(late.asleep(0));
    late.add_force(std::make_unique<uniform_field>(vec3(0, 0, -9.81)));

    world built = stack_on_the_floor(10, r);
    step(late, 60);
    step(built, 60);
    ASSERT_EQ(late.sleeping_bodies(), 10U);
    EXPECT_EQ(state_hash(late), state_hash(built));
    for (std::size_t i = 0; i < 10; ++i)
        EXPECT_TRUE(late.asleep(i)) << i;

    ASSERT_TRUE(late.apply_impulse(late.bodies().ids()[9], vec3(0, 0, 1e-3)));
    EXPECT_EQ(late.sleeping_bodies(), 0U) << "an impulse wakes its island";
    step(late, 60);
    EXPECT_EQ(late.sleeping_bodies(), 10U);
    body_id const added = late.add_body(ball({1, 1, r}, vec3::Zero(), r, m)); // after the columns exist
    EXPECT_FALSE(late.asleep(*late.bodies().slot_of(added)));
    ASSERT_TRUE(late.remove_body(late.bodies().ids()[0]));
    EXPECT_EQ(late.sleeping_bodies(), 0U) << "a removed supporter wakes what it carried";
}

} // namespace
} // namespace kugel::physics
