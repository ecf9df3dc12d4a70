// The continuous mode's step-by-step event loop, pinned bit for bit on scenes that reach each of its
// paths: a dilute gas (few events a step), a fast gas (paths many radii long), spheres of
// very different sizes (boxes too large for the grid's cells), a uniform field (parabolas,
// the exact time of impact), Coulomb forces (curved relative paths, conservative
// advancement) and static spheres. The hashes were recorded with the event loop that
// predicted against a broadphase of whole-step swept boxes; a faster loop must find the same
// events in the same order, so any change to them is a change of results, made on purpose
// and said so in its commit.

#include "physics/diagnostics.hpp"
#include "physics/thread_pool.hpp"
#include "physics/world.hpp"
#include "support/state_hash.hpp"
#include "physics/collision_scenes.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>
#include <tuple>
#include <utility>

namespace kugel::physics {
namespace {

using test_support::state_hash;

struct gas_options
{
    int n = 1000;
    double max_speed = 1.0;
    double big_share = 0.0; ///< share of spheres 8 times the radius
    bool gravity = false;
    bool charged = false;
    int statics = 0; ///< static spheres among the first
    double restitution = 1.0;
    /// The calendar (continuous/calendar.hpp) where the world is one it takes; the pins
    /// below are the step-by-step loop's.
    bool calendar = false;
    std::uint64_t max_events_per_step = collision_settings{}.max_events_per_step;
    std::uint64_t max_events_per_body = collision_settings{}.max_events_per_body;
};

/// n spheres of radius 0.05 m on a lattice filling 10% of a box, speeds up to max_speed in
/// random directions, drawn from a fixed seed one statement at a time.
world gas(gas_options const& o)
{
    world_settings s = colliding(collision_mode::continuous, integrator_kind::velocity_verlet);
    s.collisions.restitution = o.restitution;
    s.collisions.event_calendar = o.calendar;
    s.collisions.max_events_per_step = o.max_events_per_step;
    s.collisions.max_events_per_body = o.max_events_per_body;
    world w(s);
    double const r = 0.05;
    double const side = std::cbrt(o.n * 4.0 / 3.0 * 3.141592653589793 * r * r * r / 0.1);
    add_box(w, side / 2);
    if (o.gravity)
        w.add_force(std::make_unique<uniform_field>(vec3(0, 0, -9.81)));
    if (o.charged)
        w.add_force(std::make_unique<coulomb>(1e-3, 0.0));
    int const per_axis = static_cast<int>(std::ceil(std::cbrt(o.n)));
    double const spacing = side / per_axis;
    std::mt19937_64 rng(11);
    auto unit = [&] { return static_cast<double>(rng() >> 11U) * 0x1.0p-53; };
    for (int i = 0; i < o.n; ++i) {
        vec3 const cell(i % per_axis, (i / per_axis) % per_axis, i / (per_axis * per_axis));
        vec3 const x = (cell.array() + 0.5).matrix() * spacing - vec3::Constant(side / 2);
        double const vx = unit() - 0.5;
        double const vy = unit() - 0.5;
        double const vz = unit() - 0.5;
        double const speed = o.max_speed * unit();
        double const pick = unit();
        vec3 const dir = vec3(vx, vy, vz).normalized();
        bool const big = pick < o.big_share;
        double const radius = big ? std::min(8 * r, 0.45 * spacing) : r;
        bool const fixed = i < o.statics;
        body_desc d{x, fixed ? vec3(vec3::Zero()) : vec3(speed * dir), 1.0 + pick, radius, 0.0, fixed};
        if (o.charged)
            d.charge = (i % 2 == 0 ? 1.0 : -1.0) * 1e-2;
        w.add_body(d);
    }
    return w;
}

/// The state's hash after `steps` steps; and the run's counts in `counts`, if given.
std::uint64_t pinned(gas_options const& o, int steps, parallel_for* loops = nullptr,
                     collision_stats* counts = nullptr)
{
    world w = gas(o);
    w.set_parallel_for(loops, 0);
    for (int i = 0; i < steps; ++i)
        w.step(1.0 / 60.0);
    EXPECT_EQ(w.escaped(), 0U);
    EXPECT_GT(w.collisions().sphere_contacts, 50U); // the scene reaches the event loop
    if (w.collisions().capped_steps == 0) { // past a cap a step finishes discretely
        EXPECT_LE(w.max_overlap(), 1e-9);
    }
    if (counts)
        *counts = w.collisions();
    return state_hash(w);
}

TEST(ContinuousEvents, DiluteGasIsPinned)
{
    EXPECT_EQ(pinned({}, 300), 0xe0a742c8be4595f3ULL);
}

gas_options const fast_gas{.n = 300, .max_speed = 50.0};
gas_options const mixed_sizes{.n = 500, .max_speed = 3.0, .big_share = 0.1, .statics = 20};

TEST(ContinuousEvents, FastGasIsPinned)
{
    EXPECT_EQ(pinned(fast_gas, 120), 0x4ebf790147a8b558ULL);
}

TEST(ContinuousEvents, MixedSizesArePinned)
{
    EXPECT_EQ(pinned(mixed_sizes, 200), 0xef7562b697bd3ef2ULL);
}

TEST(ContinuousEvents, UniformFieldIsPinned)
{
    EXPECT_EQ(pinned({.n = 300, .gravity = true, .restitution = 0.9}, 60), 0x97f49e95c5e90e7eULL);
}

TEST(ContinuousEvents, CoulombForcesArePinned)
{
    EXPECT_EQ(pinned({.n = 200, .charged = true}, 120), 0x9c878af91f8976e2ULL);
}

// The work at a step's and a slice's start (paths, walls, the grid's pairs and their
// predictions) is spread over lent threads, each part into a list of its own; the queue
// orders events by time and indices alone, so the result is the same bits for any count.
// The calendar with threads lent cuts the box into halves, each taken by a lane of its own,
// and undoes a lane's events past a seam event found late (continuous/calendar.hpp): the
// same bits too, on one thread (the lanes one after the other) and on two or three.
//  - kept: a gas of 3,000 at up to 5 m/s;
//  - kept_fast: at up to 50 m/s (each sphere crosses a cell in about a step), where lanes
//    find seam events late and undo events (checked on one thread, where the lanes take their
//    rounds one after the other and the count is the same every run);
//  - kept_capped, kept_body_capped: steps that reach the step's cap of contacts or a body's,
//    which the lanes leave to the seam's hand, and which then finish discretely.
// The events taken and the contacts are the same counts too (those undone are not counted
// twice); the calendar takes rounds only with threads lent.
TEST(ContinuousThreads, AnyNumberOfThreadsGivesTheSameBits)
{
    gas_options const dilute{.n = 3000};
    gas_options const kept{.n = 3000, .max_speed = 5.0, .calendar = true};
    gas_options const kept_fast{.n = 3000, .max_speed = 50.0, .calendar = true};
    gas_options const kept_capped{.n = 3000, .max_speed = 5.0, .calendar = true, .max_events_per_step = 300};
    gas_options const kept_body_capped{.n = 3000, .max_speed = 50.0, .calendar = true, .max_events_per_body = 3};
    struct run
    {
        gas_options o;
        int steps;
        bool undoes = false; ///< events undone on one thread
    };
    for (auto const& [o, steps, undoes] : {run{dilute, 40}, run{fast_gas, 30}, run{mixed_sizes, 40}, run{kept, 40},
                                           run{kept_fast, 20, true}, run{kept_capped, 10}, run{kept_body_capped, 10}}) {
        collision_stats alone_counts;
        std::uint64_t const alone = pinned(o, steps, nullptr, &alone_counts);
        EXPECT_EQ(alone_counts.rounds, 0U);
        for (std::size_t const threads : {1U, 2U, 3U}) {
            thread_pool pool(threads);
            collision_stats counts;
            EXPECT_EQ(pinned(o, steps, &pool, &counts), alone)
                << threads << " threads, " << o.n << " spheres at up to " << o.max_speed << " m/s";
            EXPECT_EQ(counts.events, alone_counts.events) << threads << " threads";
            EXPECT_EQ(counts.contacts(), alone_counts.contacts()) << threads << " threads";
            if (o.calendar) {
                EXPECT_GT(counts.rounds, 0U) << threads << " threads";
            }
            if (undoes && threads == 1) {
                EXPECT_GT(counts.events_undone, 0U);
            }
        }
    }
}

// Threads lent to a world and taken back between steps: the calendar files its waiting
// events again, by halves or for one lane, and goes on with the same bits.
TEST(ContinuousThreads, ThreadsLentAndTakenBackBetweenStepsGiveTheSameBits)
{
    gas_options const kept{.n = 3000, .max_speed = 20.0, .calendar = true};
    std::uint64_t const alone = pinned(kept, 30);
    thread_pool pool(2);
    world w = gas(kept);
    for (int i = 0; i < 30; ++i) {
        w.set_parallel_for(i / 10 == 1 ? nullptr : &pool, 0); // lent, taken back, lent again
        w.step(1.0 / 60.0);
    }
    EXPECT_EQ(state_hash(w), alone);
}

// Commands between steps reach the calendar's lanes too: impulses, and spheres set down
// elsewhere (across the seam), noticed and predicted again; the same bits on one thread
// and on two.
TEST(ContinuousThreads, CommandsBetweenStepsGiveTheSameBitsOnAnyNumberOfThreads)
{
    gas_options const kept{.n = 3000, .max_speed = 5.0, .calendar = true};
    auto const run = [&](parallel_for* loops) {
        world w = gas(kept);
        w.set_parallel_for(loops, 0);
        for (int i = 0; i < 30; ++i) {
            if (i % 10 == 5) {
                std::span<body_id const> const ids = w.bodies().ids();
                for (std::size_t k = 0; k < ids.size(); k += 97)
                    w.apply_impulse(ids[k], vec3(0.3, -0.2, 0.1));
                // a sphere near one side set down at the middle, where the seam runs, and on
                w.set_state(ids[0], vec3(0.0013, 0.0021, 0.0034), vec3(-2.0, 0.5, 0.0));
            }
            w.step(1.0 / 60.0);
        }
        EXPECT_EQ(w.escaped(), 0U);
        return state_hash(w);
    };
    std::uint64_t const alone = run(nullptr);
    for (std::size_t const threads : {1U, 2U}) {
        thread_pool pool(threads);
        EXPECT_EQ(run(&pool), alone) << threads << " threads";
    }
}

// A room of the continuous mode starts empty, or holds point masses only: a step then has no
// sphere to slice by (a step once divided 0 by 0 for its slice count and looped for ever).
TEST(ContinuousEvents, AWorldWithoutSpheresSteps)
{
    world w(colliding(collision_mode::continuous));
    w.add_force(std::make_unique<uniform_field>(vec3(0, 0, -9.81)));
    add_box(w, 1.0);
    for (int i = 0; i < 10; ++i)
        w.step(1.0 / 60.0);
    body_id const point = w.add_body({vec3(0, 0, 0.5), vec3::Zero(), 1.0, 0.0, 0.0, false});
    for (int i = 0; i < 10; ++i)
        w.step(1.0 / 60.0);
    // a point mass never collides: it falls freely, on the exact parabola
    double const t = 10.0 / 60.0;
    EXPECT_NEAR(w.bodies().positions()[*w.bodies().slot_of(point)].z(), 0.5 - 0.5 * 9.81 * t * t, 1e-12);
    EXPECT_EQ(w.collisions().events, 0U);
}


// The calendar (continuous/calendar.hpp) keeps events from step to step in a world without
// forces inside a closed box. It answers the same contacts as the step-by-step loop at the
// same times; the two differ by rounding only (a path is kept from its last change rather
// than from each step's start: about 1e-16 of a coordinate), and in a dilute gas each
// contact magnifies a difference by about the mean free path over the radius (here about
// 10), so over a few contacts per sphere they agree far closer than 1e-9 m, and every
// contact is the same one.
double largest_difference(world const& a, world const& b)
{
    double worst = 0.0;
    for (std::size_t i = 0; i < a.bodies().size(); ++i) {
        worst = std::max(worst, (a.bodies().positions()[i] - b.bodies().positions()[i]).norm());
        worst = std::max(worst, (a.bodies().velocities()[i] - b.bodies().velocities()[i]).norm());
    }
    return worst;
}

TEST(ContinuousCalendar, AgreesWithTheStepwiseLoop)
{
    // The fast gas makes about 2.6 contacts per sphere in each step and magnifies a difference
    // about 17 times in each (its path over its radius): one step, and 1e-7 m.
    struct case_
    {
        gas_options options;
        int steps;
        double tolerance;
    };
    for (auto [o, steps, tolerance] : {case_{{.n = 1000}, 40, 1e-9}, case_{{.n = 400, .restitution = 0.8}, 40, 1e-9},
                                       case_{fast_gas, 1, 1e-7}}) {
        world stepwise = gas(o);
        o.calendar = true;
        world kept = gas(o);
        for (int i = 0; i < steps; ++i) {
            stepwise.step(1.0 / 60.0);
            kept.step(1.0 / 60.0);
        }
        EXPECT_LE(largest_difference(stepwise, kept), tolerance) << o.n << " spheres";
        EXPECT_EQ(kept.collisions().sphere_contacts, stepwise.collisions().sphere_contacts) << o.n;
        EXPECT_EQ(kept.collisions().wall_contacts, stepwise.collisions().wall_contacts) << o.n;
        EXPECT_GT(kept.collisions().sphere_contacts, 100U);
        EXPECT_LE(kept.max_overlap(), 1e-9);
    }
}

// Commands between steps change paths the calendar predicted from: an impulse (a velocity),
// a body added or removed (the slots), a wall added. Each is noticed, and the world goes on
// as the step-by-step loop's does with the same commands (to rounding, magnified about ten
// times in ten steps of this gas: 1e-9 m after 30).
TEST(ContinuousCalendar, FollowsCommandsBetweenSteps)
{
    world stepwise = gas({.n = 500});
    world kept = gas({.n = 500, .calendar = true});
    auto both = [&](auto command) {
        command(stepwise);
        command(kept);
        for (int i = 0; i < 5; ++i) {
            stepwise.step(1.0 / 60.0);
            kept.step(1.0 / 60.0);
        }
        EXPECT_LE(largest_difference(stepwise, kept), 1e-9);
        EXPECT_EQ(kept.collisions().sphere_contacts, stepwise.collisions().sphere_contacts);
    };
    both([](world&) {});
    both([](world& w) { w.apply_impulse(w.bodies().ids()[7], vec3(3.0, -2.0, 1.0)); });
    both([](world& w) {
        for (std::size_t k = 0; k < 40; ++k) // many at once: the calendar starts afresh
            w.apply_impulse(w.bodies().ids()[k * 11], vec3(0.5, 0.5, 0.0));
    });
    both([](world& w) { w.remove_body(w.bodies().ids()[3]); });
    both([](world& w) { w.add_body(ball({0.0, 0.0, 0.0}, {1.0, 0.0, 0.0}, 0.05, 1.0)); });
    both([](world& w) { w.add_wall({make_plane(vec3(1, 0, 0), -5.0), 0.0, 0.0}); }); // beyond the box
    EXPECT_EQ(kept.bodies().size(), 500U);
}

// A world whose collision memory was released (at a run's end, before its summary) builds its
// calendar again at the next step and goes on with the same contacts, to rounding (as after
// a checkpoint: the tolerance of FollowsCommandsBetweenSteps, for the same gas and steps).
TEST(ContinuousCalendar, StartsAfreshAfterItsMemoryIsReleased)
{
    world kept = gas({.n = 500, .calendar = true});
    world released = gas({.n = 500, .calendar = true});
    for (int i = 0; i < 10; ++i) {
        kept.step(1.0 / 60.0);
        released.step(1.0 / 60.0);
    }
    released.release_collision_memory();
    for (int i = 0; i < 20; ++i) {
        kept.step(1.0 / 60.0);
        released.step(1.0 / 60.0);
    }
    EXPECT_LE(largest_difference(kept, released), 1e-9);
    EXPECT_EQ(released.collisions().sphere_contacts, kept.collisions().sphere_contacts);
    EXPECT_GT(released.collisions().sphere_contacts, 100U);
    EXPECT_LE(released.max_overlap(), 1e-9);
}

// A box far longer on one axis than the others: its cells along that axis would number more
// than the 65,535 a sphere's cell coordinates hold (6 bytes), so they are made wider. 10,000
// spheres of radius 1 mm in a tube 3.9 mm across and 200 m long (cells of a diameter would
// be 100,000 along it; the cap of 8 cells a sphere leaves 80,064), moving along its axis
// (head-on contacts of equal masses, which magnify no rounding: a tube with sideways motion
// too bounces each sphere off its sides hundreds of times a second, and the two loops part
// by chaos): every contact is still the step-by-step loop's, to the rounding
// FollowsCommandsBetweenSteps allows, and no sphere leaves the tube or overlaps another.
TEST(ContinuousCalendar, ALongBoxGetsWiderCellsAlongIt)
{
    auto tube = [](bool calendar) {
        world_settings s = colliding(collision_mode::continuous, integrator_kind::velocity_verlet);
        s.collisions.event_calendar = calendar;
        world w(s);
        double const across = 0.00195, along = 100.0, r = 0.001;
        for (int axis = 0; axis < 3; ++axis)
            for (double sign : {1.0, -1.0}) {
                vec3 n = vec3::Zero();
                n[axis] = sign;
                w.add_wall({make_plane(n, axis == 2 ? -along : -across), 0.0, 0.0});
            }
        std::mt19937_64 rng(5);
        auto unit = [&] { return static_cast<double>(rng() >> 11U) * 0x1.0p-53 - 0.5; };
        for (int i = 0; i < 10000; ++i)
            w.add_body(ball({0.0, 0.0, -along + 0.02 * (i + 0.5)}, {0.0, 0.0, 2.0 * unit()}, r, 1.0));
        return w;
    };
    world stepwise = tube(false), kept = tube(true);
    for (int i = 0; i < 10; ++i) {
        stepwise.step(1.0 / 60.0);
        kept.step(1.0 / 60.0);
    }
    EXPECT_GT(kept.collisions().sphere_contacts, 1000U);
    EXPECT_GT(kept.collisions().wall_contacts, 0U); // the tube's two ends
    EXPECT_EQ(kept.collisions().sphere_contacts, stepwise.collisions().sphere_contacts);
    EXPECT_EQ(kept.collisions().wall_contacts, stepwise.collisions().wall_contacts);
    EXPECT_LE(largest_difference(stepwise, kept), 1e-9);
    EXPECT_EQ(kept.escaped(), 0U);
    EXPECT_LE(kept.max_overlap(), 1e-9);
}

// A gas run across several of the calendar's spans (it starts afresh before a step that would
// end after 16 s of its clock) keeps its energy to rounding and everyone in. Regression: events
// beyond the span were dropped while the last step before a fresh start still reached past it,
// so contacts in that step's tail were missed, and walls then clamped the escapees.
TEST(ContinuousCalendar, KeepsEnergyAcrossItsSpans)
{
    world w = gas({.n = 500, .max_speed = 2.0, .calendar = true});
    double const e0 = measure(w).kinetic;
    for (int i = 0; i < 60 * 40; ++i)
        w.step(1.0 / 60.0);
    // each contact keeps |v| to an ulp or so: a random walk of 1e-16 per contact
    EXPECT_LE(std::abs(measure(w).kinetic - e0), 1e-11 * e0);
    EXPECT_EQ(w.escaped(), 0U);
    EXPECT_LE(w.max_overlap(), 1e-9);
    EXPECT_GT(w.collisions().sphere_contacts, 5000U);
}

// Static spheres in the calendar are obstacles: a sphere sent head on at one comes straight
// back with its speed (equal radii, along the axis: the normal is ±x exactly).
TEST(ContinuousCalendar, StaticSpheresHold)
{
    world w(colliding(collision_mode::continuous));
    add_box(w, 2.0);
    w.add_body({vec3::Zero(), vec3::Zero(), 1.0, 0.1, 0.0, true});
    body_id const moving = w.add_body(ball({-1.0, 0.0, 0.0}, {2.0, 0.0, 0.0}, 0.1));
    for (int i = 0; i < 30; ++i) // it meets the static one at 0.4 s
        w.step(1.0 / 60.0);
    auto const slot = w.bodies().slot_of(moving);
    ASSERT_TRUE(slot);
    EXPECT_EQ(w.bodies().velocities()[*slot], vec3(-2.0, 0.0, 0.0));
    EXPECT_EQ(w.collisions().sphere_contacts, 1U);
}

// The calendar predicts a sphere's walls only in the cells beside them (its cells are wider
// than a diameter, so no sphere reaches a wall from further in), and again when it crosses
// into them. A sphere sent from the middle of a box eight cells wide along its diagonal
// meets the three walls of a corner at once, comes back with its velocity reversed exactly
// (elastic walls along the axes), and meets the opposite corner. The other spheres are
// static, well off the diagonal, and only give the calendar its cells. The positions are
// the analytic ones to 1e-12 m: a path is x + (t − t₀)·v from its last contact, so only a
// few roundings of numbers below 3 enter.
TEST(ContinuousCalendar, MeetsWallsFromTheCellsBesideThem)
{
    world w(colliding(collision_mode::continuous));
    add_box(w, 1.0);
    for (double x : {-0.75, -0.25, 0.25, 0.75})
        for (double y : {-0.75, -0.25, 0.25, 0.75})
            for (double z : {-0.75, -0.25, 0.25, 0.75}) {
                vec3 const p(x, y, z);
                if ((p - p.dot(vec3::Ones()) / 3.0 * vec3::Ones()).norm() > 0.3) // off the diagonal
                    w.add_body({p, vec3::Zero(), 1.0, 0.05, 0.0, true});
            }
    body_id const moving = w.add_body(ball(vec3::Zero(), vec3::Ones(), 0.05));
    auto velocity_and_position = [&] {
        auto const slot = w.bodies().slot_of(moving);
        return std::pair{w.bodies().velocities()[*slot], w.bodies().positions()[*slot]};
    };
    for (int i = 0; i < 120; ++i) // the corner (0.95, 0.95, 0.95) at 0.95 s
        w.step(1.0 / 60.0);
    auto [v, x] = velocity_and_position();
    EXPECT_EQ(v, vec3(-1.0, -1.0, -1.0));
    EXPECT_LE((x - vec3::Constant(0.95 - 1.05)).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_EQ(w.collisions().wall_contacts, 3U);
    for (int i = 0; i < 60; ++i) // the opposite corner at 2.85 s
        w.step(1.0 / 60.0);
    std::tie(v, x) = velocity_and_position();
    EXPECT_EQ(v, vec3(1.0, 1.0, 1.0));
    EXPECT_LE((x - vec3::Constant(-0.95 + 0.15)).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_EQ(w.collisions().wall_contacts, 6U);
    EXPECT_EQ(w.collisions().sphere_contacts, 0U);
}

// Pinned as the step-by-step loop is: a change to the calendar's results is made on purpose.
TEST(ContinuousCalendar, DiluteGasIsPinned)
{
    EXPECT_EQ(pinned({.calendar = true}, 300), 0x73e1d68b76175429ULL);
}

} // namespace
} // namespace kugel::physics
