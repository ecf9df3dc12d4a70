#include "physics/sensors.hpp"
#include "physics/forces.hpp"
#include "physics/world.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <vector>

namespace kugel::physics {
namespace {

// Event times are computed from the same doubles as the motion: a root of the boundary's
// polynomial bracketed to the last bit, then the step's start added. 1e-12 s allows for that
// rounding on times of order 1 s (a few hundred ulps), and is far below any step (1e-3 s and
// more): a time taken from the wrong piece of a path or from the step's ends misses by more.
constexpr double time_tolerance = 1e-12;

world_settings with_mode(collision_mode mode)
{
    world_settings s;
    s.collisions.mode = mode;
    return s;
}

std::vector<sensor_event> step_collecting(world& w, double dt, int steps)
{
    std::vector<sensor_event> all;
    for (int k = 0; k < steps; ++k) {
        w.step(dt);
        all.insert(all.end(), w.sensor_events().begin(), w.sensor_events().end());
    }
    return all;
}

TEST(SignChanges, FindsEachCrossingOnceAndNoGrazing)
{
    std::vector<double> roots;
    // (s − 1)(s − 2)(s − 3) = −6 + 11s − 6s² + s³
    double const cubic[] = {-6.0, 11.0, -6.0, 1.0};
    sign_changes(cubic, 3, 0.0, 10.0, roots);
    ASSERT_EQ(roots.size(), 3U);
    EXPECT_NEAR(roots[0], 1.0, 1e-15);
    EXPECT_NEAR(roots[1], 2.0, 1e-15);
    EXPECT_NEAR(roots[2], 3.0, 1e-15);
    // (s − 1)² touches zero without changing sign: no crossing
    roots.clear();
    double const square[] = {1.0, -2.0, 1.0};
    sign_changes(square, 2, 0.0, 5.0, roots);
    EXPECT_TRUE(roots.empty());
    // a quartic with four crossings, (s² − 1)(s² − 4)
    roots.clear();
    double const quartic[] = {4.0, 0.0, -5.0, 0.0, 1.0};
    sign_changes(quartic, 4, -3.0, 3.0, roots);
    ASSERT_EQ(roots.size(), 4U);
    EXPECT_NEAR(roots[0], -2.0, 1e-15);
    EXPECT_NEAR(roots[3], 2.0, 1e-15);
    // only inside the open interval
    roots.clear();
    sign_changes(cubic, 3, 1.0, 3.0, roots);
    ASSERT_EQ(roots.size(), 1U);
    EXPECT_NEAR(roots[0], 2.0, 1e-15);
}

// A body at constant velocity through a box: it enters where x reaches the box's min and
// leaves where it passes its max, (min − x₀)/v and (max − x₀)/v, both inside one step.
TEST(Sensors, AStraightPathThroughABoxEntersAndLeavesAtTheFacesInOneStep)
{
    world w(with_mode(collision_mode::off));
    w.add_sensor(sensor::of_box({vec3(0.0, -1.0, -1.0), vec3(1.0, 1.0, 1.0)}));
    body_id const id = w.add_body({vec3(-1.0, 0.0, 0.0), vec3(3.0, 0.0, 0.0), 1.0, 0.0});
    w.step(1.0); // to x = 2
    auto const events = w.sensor_events();
    ASSERT_EQ(events.size(), 2U);
    EXPECT_EQ(events[0].body, id);
    EXPECT_TRUE(events[0].entered);
    EXPECT_NEAR(events[0].time, 1.0 / 3.0, time_tolerance);
    EXPECT_FALSE(events[1].entered);
    EXPECT_NEAR(events[1].time, 2.0 / 3.0, time_tolerance);
    EXPECT_TRUE(w.bodies_in_sensor(0).empty());
}

// Falling from rest at height z₀ under g through a ball of radius R centred at height c on
// its line: the parabola z₀ − g t²/2 reaches c + R at t = √(2(z₀ − c − R)/g) and leaves at
// √(2(z₀ − c + R)/g), over many steps, in continuous mode where the sphere's own path is
// followed.
TEST(Sensors, AFallThroughABallSensorIsTimedOnTheParabola)
{
    double const g = 9.81, z0 = 10.0, c = 4.0, r = 1.5;
    world w(with_mode(collision_mode::continuous));
    w.add_force(std::make_unique<uniform_field>(vec3(0.0, 0.0, -g)));
    w.add_sensor(sensor::of_ball(vec3(0.0, 0.0, c), r));
    w.add_body({vec3(0.0, 0.0, z0), vec3::Zero(), 1.0, 0.1});
    auto const events = step_collecting(w, 1.0 / 60.0, 120);
    ASSERT_EQ(events.size(), 2U);
    EXPECT_TRUE(events[0].entered);
    EXPECT_NEAR(events[0].time, std::sqrt(2.0 * (z0 - c - r) / g), time_tolerance);
    EXPECT_FALSE(events[1].entered);
    EXPECT_NEAR(events[1].time, std::sqrt(2.0 * (z0 - c + r) / g), time_tolerance);
}

// A ball bounces off a wall inside a step (continuous mode, elastic): the sensor in front of
// the wall sees it enter on the way in and leave on the way out, at times taken from the
// piece of path before the contact and the piece after it, all inside one step.
TEST(Sensors, ABounceInsideAStepIsFollowedPieceByPiece)
{
    world w(with_mode(collision_mode::continuous));
    w.add_wall({make_plane(vec3(-1.0, 0.0, 0.0), -2.0), 0.0, 0.0}); // x <= 2
    w.add_sensor(sensor::of_box({vec3(1.0, -1.0, -1.0), vec3(1.9, 1.0, 1.0)}));
    double const r = 0.25, v = 10.0;
    w.add_body({vec3(0.5, 0.0, 0.0), vec3(v, 0.0, 0.0), 1.0, r});
    w.step(0.5);
    auto const events = w.sensor_events();
    ASSERT_EQ(events.size(), 2U);
    // in at x = 1 (t = 0.05); the sphere meets the wall when its centre is at 2 − r (t =
    // 0.125), inside the sensor, and comes back out at x = 1 at t = 0.125 + 0.75/10
    EXPECT_TRUE(events[0].entered);
    EXPECT_NEAR(events[0].time, 0.05, time_tolerance);
    EXPECT_FALSE(events[1].entered);
    EXPECT_NEAR(events[1].time, 0.125 + (2.0 - r - 1.0) / v, time_tolerance);
}

// Discrete mode has no path inside a step: the straight line from the step's start to its
// end is followed, so the body is still reported entering, at the chord's crossing.
TEST(Sensors, DiscreteModeTimesACrossingOnTheStepsChord)
{
    world w(with_mode(collision_mode::discrete));
    w.add_sensor(sensor::of_box({vec3(1.0, -1.0, -1.0), vec3(3.0, 1.0, 1.0)}));
    w.add_body({vec3(0.0, 0.0, 0.0), vec3(4.0, 0.0, 0.0), 1.0, 0.1});
    w.step(0.5); // from x = 0 to 2
    auto const events = w.sensor_events();
    ASSERT_EQ(events.size(), 1U);
    EXPECT_TRUE(events[0].entered);
    EXPECT_NEAR(events[0].time, 0.25, time_tolerance);
    ASSERT_EQ(w.bodies_in_sensor(0).size(), 1U);
}

// A body added inside a sensor, and one resting in it, enter at the start of the next step
// and then report nothing while they stay; a removed body leaves the sensor's list quietly.
TEST(Sensors, ABodyAddedInsideEntersAtTheNextStepsStartAndStaysQuiet)
{
    world w(with_mode(collision_mode::continuous));
    w.add_sensor(sensor::of_ball(vec3::Zero(), 1.0));
    w.step(0.1);
    body_id const id = w.add_body({vec3(0.2, 0.0, 0.0), vec3::Zero(), 1.0, 0.1});
    w.step(0.1);
    ASSERT_EQ(w.sensor_events().size(), 1U);
    EXPECT_TRUE(w.sensor_events()[0].entered);
    EXPECT_NEAR(w.sensor_events()[0].time, 0.1, time_tolerance);
    for (int k = 0; k < 10; ++k) {
        w.step(0.1);
        EXPECT_TRUE(w.sensor_events().empty());
    }
    ASSERT_EQ(w.bodies_in_sensor(0).size(), 1U);
    EXPECT_EQ(w.bodies_in_sensor(0)[0], id);
    w.remove_body(id);
    w.step(0.1);
    EXPECT_TRUE(w.sensor_events().empty());
    EXPECT_TRUE(w.bodies_in_sensor(0).empty());
}

// Substeps: the crossing is timed inside the substep it happens in, from the world's clock.
TEST(Sensors, SubstepsTimeTheCrossingFromTheWorldsClock)
{
    world_settings settings = with_mode(collision_mode::off);
    settings.substeps = 4;
    world w(settings);
    w.add_sensor(sensor::of_box({vec3(0.7, -1.0, -1.0), vec3(5.0, 1.0, 1.0)}));
    w.add_body({vec3::Zero(), vec3(1.0, 0.0, 0.0), 1.0, 0.0}); // a point mass
    auto const events = step_collecting(w, 0.5, 2);
    ASSERT_EQ(events.size(), 1U);
    EXPECT_NEAR(events[0].time, 0.7, time_tolerance);
}

TEST(Sensors, AreRefusedWhenTheyHaveNoVolumeOrAreNotFinite)
{
    world w;
    EXPECT_THROW(w.add_sensor(sensor::of_ball(vec3::Zero(), 0.0)), std::invalid_argument);
    EXPECT_THROW(w.add_sensor(sensor::of_ball(vec3(NAN, 0.0, 0.0), 1.0)), std::invalid_argument);
    EXPECT_THROW(w.add_sensor(sensor::of_box({vec3(1.0, 0.0, 0.0), vec3(0.0, 1.0, 1.0)})), std::invalid_argument);
    EXPECT_THROW(w.add_sensor(sensor::of_box({vec3::Zero(), vec3(INFINITY, 1.0, 1.0)})), std::invalid_argument);
    EXPECT_TRUE(w.sensors().empty());
    // a flat box is a sensor: a finish line
    EXPECT_EQ(w.add_sensor(sensor::of_box({vec3::Zero(), vec3(0.0, 1.0, 1.0)})), 0U);
}

// Sensors are not walls, and a world's motion does not depend on them: the same bodies with
// and without a sensor in their way end in the same bits.
TEST(Sensors, ChangeNothingInTheMotion)
{
    for (collision_mode mode : {collision_mode::discrete, collision_mode::continuous}) {
        world plain(with_mode(mode)), sensed(with_mode(mode));
        for (world* w : {&plain, &sensed}) {
            w->add_force(std::make_unique<uniform_field>(vec3(0.0, 0.0, -9.81)));
            w->add_wall({make_plane(vec3::UnitZ(), 0.0), 0.5, 0.5});
            for (int k = 0; k < 20; ++k)
                w->add_body({vec3(0.05 * k, 0.0, 0.3 + 0.25 * k), vec3(0.1, 0.0, 0.0), 1.0, 0.1});
        }
        sensed.add_sensor(sensor::of_box({vec3(-1.0, -1.0, 0.0), vec3(2.0, 1.0, 1.0)}));
        for (int k = 0; k < 120; ++k) {
            plain.step(1.0 / 60.0);
            sensed.step(1.0 / 60.0);
        }
        for (std::size_t i = 0; i < plain.bodies().size(); ++i) {
            EXPECT_EQ(plain.bodies().positions()[i], sensed.bodies().positions()[i]);
            EXPECT_EQ(plain.bodies().velocities()[i], sensed.bodies().velocities()[i]);
        }
        EXPECT_FALSE(sensed.bodies_in_sensor(0).empty());
    }
}

} // namespace
} // namespace kugel::physics
