#include "physics/contact_events.hpp"
#include "physics/forces.hpp"
#include "physics/world.hpp"

#include "collision_scenes.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <vector>

namespace kugel::physics {
namespace {

// Continuous mode and the sweep time a contact at its event: the root of the pair's distance
// along straight paths, then the step's start added. 1e-12 s allows for that rounding on
// times of order 1 s and is far below a step (1e-2 s here): a time taken from the step's
// ends, or from the wrong step, misses by more.
constexpr double time_tolerance = 1e-12;

std::vector<contact_event> step_collecting(world& w, double dt, int steps)
{
    std::vector<contact_event> all;
    for (int k = 0; k < steps; ++k) {
        w.step(dt);
        all.insert(all.end(), w.contact_events().begin(), w.contact_events().end());
    }
    return all;
}

void report(world& w, std::initializer_list<body_id> ids)
{
    for (body_id id : ids)
        ASSERT_TRUE(w.report_contacts(id, true));
}

// Two spheres of radius 0.25 head on at 2 m/s each, centres 2 m apart: they touch when the
// gap of 2 − 0.5 m is closed at 4 m/s, at t = 0.375 s, once, and part.
TEST(ContactEvents, AHeadOnPairIsReportedOnceAtItsTimeOfImpact)
{
    world w(colliding(collision_mode::continuous));
    body_id const a = w.add_body(ball({-1, 0, 0}, {2, 0, 0}, 0.25));
    body_id const b = w.add_body(ball({1, 0, 0}, {-2, 0, 0}, 0.25));
    report(w, {a, b});
    auto const events = step_collecting(w, 0.1, 20);
    ASSERT_EQ(events.size(), 1U);
    EXPECT_NEAR(events[0].time, 0.375, time_tolerance);
    EXPECT_EQ(events[0].a, a);
    EXPECT_EQ(events[0].b, b);
    EXPECT_EQ(w.collisions().sphere_contacts, 1U);
}

// The same pair inside a closed box of walls, a force-free gas that the calendar would take:
// a world that reports contacts takes it through the step-by-step loop, which notes them.
// The box is large enough that no wall is met before the impact; after it each sphere
// bounces off a wall and they meet again, each meeting a new contact.
TEST(ContactEvents, AForceFreeGasInABoxIsReportedToo)
{
    world w(colliding(collision_mode::continuous));
    add_box(w, 2.0);
    body_id const a = w.add_body(ball({-1, 0, 0}, {2, 0, 0}, 0.25));
    body_id const b = w.add_body(ball({1, 0, 0}, {-2, 0, 0}, 0.25));
    report(w, {a, b});
    // after the impact, with centres at ∓0.25, each goes back 1.5 m to its wall (centre at
    // ∓1.75) and 1.5 m back at 2 m/s: they meet again 1.5 s after the first time
    auto const events = step_collecting(w, 0.1, 20);
    ASSERT_EQ(events.size(), 2U);
    EXPECT_NEAR(events[0].time, 0.375, time_tolerance);
    EXPECT_NEAR(events[1].time, 0.375 + 1.5, time_tolerance);
}

// Only pairs whose bodies are both reported: the third sphere, not reported, meets a
// reported one and nothing is said.
TEST(ContactEvents, OnlyPairsOfReportedBodiesAreReported)
{
    world w(colliding(collision_mode::continuous));
    body_id const a = w.add_body(ball({-1, 0, 0}, {2, 0, 0}, 0.25));
    body_id const b = w.add_body(ball({1, 0, 0}, {-2, 0, 0}, 0.25));
    w.add_body(ball({-1, 3, 0}, {2, 0, 0}, 0.25));
    body_id const d = w.add_body(ball({1, 3, 0}, {-2, 0, 0}, 0.25));
    report(w, {a, b, d});
    auto const events = step_collecting(w, 0.1, 20);
    ASSERT_EQ(events.size(), 1U);
    EXPECT_EQ(events[0].a, a);
    EXPECT_EQ(w.collisions().sphere_contacts, 2U);
    EXPECT_FALSE(w.report_contacts(body_id{99, 1}, true));
    ASSERT_TRUE(w.report_contacts(b, false));
    EXPECT_FALSE(w.reports_contacts(b));
}

// Discrete mode under gravity: a ball dropped on the top of a fixed sphere, exactly above its
// centre, lands at t* = √(2·(z₀ − (R + r))/g) and, with restitution 0, stays. The discrete mode
// answers at the end of the step in which they meet, so the contact is timed in
// [t*, t* + dt]; it is reported once while the ball rests, and sleeps, on the sphere. Pushed
// up, the ball leaves and lands again: a second contact.
TEST(ContactEvents, DiscreteModeReportsALandingOnceWhileTheBallRests)
{
    world_settings s = colliding(collision_mode::discrete, integrator_kind::semi_implicit_euler);
    s.collisions.restitution = 0.0;
    world w(s);
    double const g = 9.81, R = 0.5, r = 0.25, z0 = 2.0, dt = 1.0 / 60.0;
    w.add_force(std::make_unique<uniform_field>(vec3(0, 0, -g)));
    body_id const post = w.add_body({vec3::Zero(), vec3::Zero(), 0.0, R, 0.0, true});
    body_id const b = w.add_body(ball({0, 0, z0}, vec3::Zero(), r));
    report(w, {post, b});
    auto const landing = step_collecting(w, dt, 180);
    ASSERT_EQ(landing.size(), 1U);
    double const t_star = std::sqrt(2.0 * (z0 - (R + r)) / g);
    EXPECT_GE(landing[0].time, t_star - dt); // semi-implicit Euler runs ahead of the parabola by g·dt·t
    EXPECT_LE(landing[0].time, t_star + dt);
    EXPECT_EQ(landing[0].a, post);
    EXPECT_EQ(w.sleeping_bodies(), 1U) << "the ball rests on the post";
    ASSERT_TRUE(w.apply_impulse(b, vec3(0, 0, 2.0)));
    auto const again = step_collecting(w, dt, 120);
    ASSERT_EQ(again.size(), 1U);
    // up at 2 m/s and down again: back after about 2·v/g
    EXPECT_NEAR(again[0].time - w.time() + 120 * dt, 2.0 * 2.0 / g, 2.0 * dt);
}

// A fast ball (100 m/s, 1.7 m a step) at a fixed sphere in discrete mode: the sweep takes it
// through the continuous mode's events, so it bounces off inside the step and ends it far
// from the sphere, where the overlaps at the step's end never see it. The contact is the
// sweep's, at its exact time: the gap of 1 − 0.2 m closed at 100 m/s.
TEST(ContactEvents, TheSweepReportsAFastBallThatBouncesInsideTheStep)
{
    world w(colliding(collision_mode::discrete));
    body_id const post = w.add_body({vec3::Zero(), vec3::Zero(), 0.0, 0.1, 0.0, true});
    body_id const b = w.add_body(ball({-1, 0, 0}, {100, 0, 0}, 0.1));
    report(w, {post, b});
    auto const events = step_collecting(w, 1.0 / 60.0, 3);
    ASSERT_EQ(events.size(), 1U);
    EXPECT_NEAR(events[0].time, 0.8 / 100.0, time_tolerance);
    EXPECT_GT(w.collisions().swept_bodies, 0U);
    EXPECT_LT(w.bodies().velocities()[1].x(), 0.0) << "it bounced";
}

// Reporting only watches: a pile in discrete mode and a gas in continuous mode (out of a box,
// so the step-by-step loop runs either way) move to the same bits with every body reported
// as with none.
TEST(ContactEvents, ChangeNothingInTheMotion)
{
    auto run = [](collision_mode mode, bool reported) {
        world_settings s = colliding(mode, integrator_kind::semi_implicit_euler);
        s.collisions.restitution = 0.5;
        world w(s);
        if (mode == collision_mode::discrete) {
            w.add_force(std::make_unique<uniform_field>(vec3(0, 0, -9.81)));
            w.add_wall({make_plane(vec3(0, 0, 1), -1.0), 0.5, 0.5});
        }
        for (int i = 0; i < 60; ++i) {
            body_id const id = w.add_body(ball({0.3 * (i % 4) + 0.01 * (i % 7), 0.3 * ((i / 4) % 4), 0.3 * (i / 16)},
                                               {0.2 * ((i % 3) - 1.0), 0.1 * ((i % 5) - 2.0), 0.0}, 0.14));
            if (reported)
                w.report_contacts(id, true);
        }
        std::size_t events = 0;
        for (int k = 0; k < 200; ++k) {
            w.step(1.0 / 60.0);
            events += w.contact_events().size();
        }
        return std::pair(std::vector<vec3>(w.bodies().positions().begin(), w.bodies().positions().end()), events);
    };
    for (collision_mode mode : {collision_mode::discrete, collision_mode::continuous}) {
        auto const [quiet, none] = run(mode, false);
        auto const [watched, some] = run(mode, true);
        EXPECT_EQ(none, 0U);
        EXPECT_GT(some, 0U) << name(mode);
        ASSERT_EQ(quiet.size(), watched.size());
        for (std::size_t k = 0; k < quiet.size(); ++k)
            EXPECT_TRUE((quiet[k].array() == watched[k].array()).all()) << name(mode) << " body " << k;
    }
}

// A body removed while it touches another ends the contact without an event, and the pair's
// slot reused by a new body starts afresh.
TEST(ContactEvents, ARemovedBodyEndsItsContacts)
{
    world_settings s = colliding(collision_mode::discrete, integrator_kind::semi_implicit_euler);
    s.collisions.restitution = 0.0;
    world w(s);
    w.add_force(std::make_unique<uniform_field>(vec3(0, 0, -9.81)));
    body_id const post = w.add_body({vec3::Zero(), vec3::Zero(), 0.0, 0.5, 0.0, true});
    body_id const b = w.add_body(ball({0, 0, 0.76}, vec3::Zero(), 0.25));
    report(w, {post, b});
    EXPECT_EQ(step_collecting(w, 1.0 / 60.0, 30).size(), 1U);
    ASSERT_TRUE(w.remove_body(b));
    EXPECT_FALSE(w.reports_contacts(b));
    EXPECT_TRUE(step_collecting(w, 1.0 / 60.0, 5).empty());
    body_id const c = w.add_body(ball({0, 0, 0.76}, vec3::Zero(), 0.25));
    EXPECT_FALSE(w.reports_contacts(c)) << "a new body is not reported until asked";
    report(w, {c});
    auto const events = step_collecting(w, 1.0 / 60.0, 30);
    ASSERT_EQ(events.size(), 1U);
    EXPECT_EQ(events[0].b, c);
}

} // namespace
} // namespace kugel::physics
