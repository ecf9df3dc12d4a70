// The discrete step as a whole: piles that settle, a gas that keeps its energy, and the same
// bits whatever the threads, the bodies' order in memory or the stamps.

#include "physics/collision_scenes.hpp"
#include "physics/diagnostics.hpp"
#include "physics/thread_pool.hpp"
#include "physics/world.hpp"
#include "support/state_hash.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <random>
#include <string>
#include <tuple>
#include <vector>

namespace kugel::physics {
namespace {

using test_support::state_hash;

// A pile settles instead of sinking into itself: after 300 steps the deepest overlap in the
// 200-sphere pile stays under 30% of a radius. Measured: 22% with four velocity passes and
// four position passes over every near pair; 43% when the position passes saw only the pairs
// touching at the start (a push can bring neighbours into overlap). The bound sits between
// the two. (In the pile scene, a single velocity pass left 85% of a radius.)
TEST(DiscretePile, SettlesWithoutSinkingIntoItself)
{
    world const w = settled_pile(collision_mode::discrete, broadphase_kind::uniform_grid);
    EXPECT_LT(w.max_overlap(), 0.30 * 0.08);
    EXPECT_EQ(w.escaped(), 0U);
}

// An elastic gas (e = 1, walls with α = μ = 0, no forces) in discrete mode keeps its kinetic
// energy: every sphere–sphere response and every meeting with a wall, including a sphere
// pushed into a wall by a neighbour, keeps |v| up to rounding, so 600 steps of 2,000 spheres
// (about 10⁵ responses) drift by a random walk of ulps, ~1e-14; 1e-12 leaves room for that
// and none for a real loss. (When a pushed sphere lost its speed into the wall instead, this
// gas lost several per cent; the 10,000-sphere gas scene 29 % in 600 steps.)
TEST(ElasticGas, DiscreteModeConservesEnergyAndHoldsEveryone)
{
    world w = discrete_gas(2000);
    double const e0 = measure(w).kinetic;
    for (int i = 0; i < 600; ++i)
        w.step(1.0 / 60.0);
    EXPECT_LE(std::abs(measure(w).kinetic - e0), 1e-12 * e0) << measure(w).kinetic / e0 - 1.0;
    EXPECT_EQ(w.escaped(), 0U);
    EXPECT_GT(w.collisions().sphere_contacts, 2000U);
    EXPECT_GT(w.collisions().wall_contacts, 100U);
}

// The discrete step splits its loops over slabs and chunks of bodies, but a pool of threads
// changes its speed only (lent here from the first body on, so that small worlds use it too): the same bits with no pool and with pools of one to three threads,
// for the pile (gravity, resting contacts) and for a gas large enough for several chunks of
// bodies and every slab. Bit for bit, no tolerance: the order of every update is fixed.
TEST(DiscreteThreads, AnyNumberOfThreadsGivesTheSameBits)
{
    std::uint64_t const pile = state_hash(settled_pile(collision_mode::discrete, broadphase_kind::uniform_grid));
    auto gas_after_steps = [](parallel_for* loops, broadphase_kind broadphase) {
        world w = discrete_gas(9000, broadphase);
        w.set_parallel_for(loops, 0);
        for (int i = 0; i < 40; ++i)
            w.step(1.0 / 60.0);
        EXPECT_GT(w.collisions().sphere_contacts, 1000U);
        return state_hash(w);
    };
    std::uint64_t const gas = gas_after_steps(nullptr, broadphase_kind::uniform_grid);
    for (std::size_t const threads : std::initializer_list<std::size_t>{1, 2, 3}) {
        thread_pool pool(threads);
        EXPECT_EQ(state_hash(settled_pile(collision_mode::discrete, broadphase_kind::uniform_grid, &pool)), pile)
            << threads << " threads";
        EXPECT_EQ(gas_after_steps(&pool, broadphase_kind::uniform_grid), gas) << threads << " threads";
    }
    thread_pool pool(2);
    EXPECT_EQ(gas_after_steps(&pool, broadphase_kind::sweep_and_prune), gas);
}

// A lent parallel_for is used from world::bodies_worth_sharing bodies on (or from the count
// the owner names), and below it every loop runs on the calling thread.
TEST(DiscreteThreads, SmallWorldsKeepTheirLoopsOnTheCallingThread)
{
    struct counting_loops final : parallel_for
    {
        std::size_t runs = 0;
        void run(std::size_t count, std::function<void(std::size_t)> const& task) override
        {
            ++runs;
            for (std::size_t k = 0; k < count; ++k)
                task(k);
        }
    };
    auto runs_in_ten_steps = [](int bodies, std::optional<std::size_t> from) {
        counting_loops loops;
        world w = discrete_gas(bodies);
        if (from)
            w.set_parallel_for(&loops, *from);
        else
            w.set_parallel_for(&loops);
        for (int i = 0; i < 10; ++i)
            w.step(1.0 / 60.0);
        return loops.runs;
    };
    EXPECT_EQ(runs_in_ten_steps(9000, std::nullopt), 0U);
    EXPECT_GT(runs_in_ten_steps(9000, 9000), 0U);
    EXPECT_GT(runs_in_ten_steps(static_cast<int>(world::bodies_worth_sharing), std::nullopt), 0U);
}

// With two threads the pile still settles (the bound of SettlesWithoutSinkingIntoItself) and
// the gas keeps everyone in.
TEST(DiscreteThreads, PileAndGasBehaveWithTwoThreads)
{
    thread_pool pool(2);
    world const pile = settled_pile(collision_mode::discrete, broadphase_kind::uniform_grid, &pool);
    EXPECT_LT(pile.max_overlap(), 0.30 * 0.08);
    EXPECT_EQ(pile.escaped(), 0U);

    world gas = discrete_gas(9000);
    gas.set_parallel_for(&pool, 0);
    for (int i = 0; i < 300; ++i)
        gas.step(1.0 / 60.0);
    EXPECT_EQ(gas.escaped(), 0U);
    EXPECT_GT(gas.collisions().sphere_contacts, 10000U);
}

// The order in which a step resolves contacts depends on the state alone, not on how the
// world got there: a world rebuilt from another's bodies (as a checkpoint restores one, in
// slot order) steps on exactly like it.
TEST(DiscreteThreads, RebuiltWorldStepsOnLikeTheOriginal)
{
    world original = discrete_gas(3000);
    for (int i = 0; i < 30; ++i)
        original.step(1.0 / 60.0);
    world rebuilt(original.settings());
    for (wall const& w : original.walls())
        rebuilt.add_wall(w);
    for (std::size_t slot = 0; slot < original.bodies().size(); ++slot)
        rebuilt.add_body(original.bodies().describe(slot));
    for (int i = 0; i < 30; ++i) {
        original.step(1.0 / 60.0);
        rebuilt.step(1.0 / 60.0);
    }
    EXPECT_EQ(state_hash(rebuilt), state_hash(original));
}

// A world of world::bodies_worth_sorting bodies or more in discrete mode moves its bodies into
// the grid's cell order (x-major) on its first step and every sort_interval-th after. The
// gas is added with x varying fastest, so before the sort x falls back by the box's width
// every row; after it, x never falls back by more than the spheres' pushes and a cell.
// Every id keeps its body, and the results are still a function of the state alone: with
// two threads the same bits, and a world rebuilt from another's bodies in slot order, with
// its clock (as a checkpoint restores one), steps on like it through the next sort.
TEST(SortedBodies, LargeWorldsKeepTheirBodiesInCellOrderAndTheirResults)
{
    int const n = static_cast<int>(world::bodies_worth_sorting);
    world original = discrete_gas(n);
    std::vector<vec3> added(original.bodies().positions().begin(), original.bodies().positions().end());
    std::vector<body_id> ids(original.bodies().ids().begin(), original.bodies().ids().end());
    auto largest_fall_in_x = [](world const& w) {
        double fall = 0.0;
        auto const x = w.bodies().positions();
        for (std::size_t k = 1; k < x.size(); ++k)
            fall = std::max(fall, x[k - 1].x() - x[k].x());
        return fall;
    };
    double const diameter = 0.1;
    ASSERT_GT(largest_fall_in_x(original), 10.0 * diameter);
    double const dt = 1.0 / 60.0;
    original.step(dt);
    EXPECT_LT(largest_fall_in_x(original), 2.0 * diameter);
    // Each id names the body it named: one step from where it was added, at most 1 m/s·√3·dt
    // away (plus a push far below that).
    double farthest = 0.0;
    for (std::size_t i = 0; i < ids.size(); ++i) {
        auto const slot = original.bodies().slot_of(ids[i]);
        ASSERT_TRUE(slot.has_value());
        farthest = std::max(farthest, (original.bodies().positions()[*slot] - added[i]).norm());
    }
    EXPECT_LT(farthest, 2.0 * dt);
    EXPECT_NE(original.bodies().ids()[1], ids[1]); // the slots did change

    for (int i = 1; i < 10; ++i)
        original.step(dt);
    world rebuilt(original.settings());
    for (wall const& w : original.walls())
        rebuilt.add_wall(w);
    for (std::size_t slot = 0; slot < original.bodies().size(); ++slot)
        rebuilt.add_body(original.bodies().describe(slot));
    rebuilt.restore_clock(original.time(), original.time_compensation(), original.steps());
    thread_pool pool(2);
    world shared = discrete_gas(n);
    shared.set_parallel_for(&pool);
    for (int i = 0; i < 10; ++i)
        shared.step(dt);
    for (int i = 0; i < 2 * static_cast<int>(world::sort_interval); ++i) {
        original.step(dt);
        rebuilt.step(dt);
        shared.step(dt);
    }
    EXPECT_GT(original.collisions().sphere_contacts, 10000U);
    EXPECT_EQ(state_hash(rebuilt), state_hash(original));
    EXPECT_EQ(state_hash(shared), state_hash(original));
    EXPECT_EQ(original.escaped(), 0U);
}

// One sphere flung far away: the grid holds the sparse scene (it searches its sorted keys),
// and one flung beyond 2^47 cells from the origin makes it decline, so that the step falls
// back to the broadphase in slot order. Either way every broadphase and any pool give the
// same bits.
TEST(DiscreteThreads, FarFlungSphereStaysDeterministic)
{
    for (double far : {4e4, 1e14}) {
        auto run = [&](broadphase_kind broadphase, parallel_for* loops) {
            world w = discrete_gas(2000, broadphase);
            w.set_parallel_for(loops, 0);
            w.add_body(ball({far, far, 0.0}, {1, 0, 0}, 0.05, 0.5));
            for (int i = 0; i < 30; ++i)
                w.step(1.0 / 60.0);
            EXPECT_GT(w.collisions().sphere_contacts, 100U);
            return state_hash(w);
        };
        std::uint64_t const reference = run(broadphase_kind::uniform_grid, nullptr);
        thread_pool pool(2);
        EXPECT_EQ(run(broadphase_kind::uniform_grid, &pool), reference) << far;
        EXPECT_EQ(run(broadphase_kind::brute_force, nullptr), reference) << far;
    }
}

// The discrete step marks the spheres each pass lists with stamps that grow from step to step,
// so that the table of marks is never cleared; just before they would wrap, it is cleared
// once and they start again. A workspace whose stamps are about to wrap must step the same
// gas to the same bits as a fresh one, on the step of the wrap and after it.
TEST(DiscreteCollisions, MarksThatWrapChangeNothing)
{
    world const gas = discrete_gas(2000);
    std::vector<double> inverse_mass, radius;
    for (std::size_t i = 0; i < gas.bodies().size(); ++i) {
        inverse_mass.push_back(gas.bodies().inverse_masses()[i]);
        radius.push_back(gas.bodies().radii()[i]);
    }
    collision_settings settings = gas.settings().collisions;
    auto const run = [&](std::uint32_t first_stamp) {
        std::vector<vec3> x(gas.bodies().positions().begin(), gas.bodies().positions().end());
        std::vector<vec3> v(gas.bodies().velocities().begin(), gas.bodies().velocities().end());
        collision_workspace workspace;
        workspace.discrete.stamp = first_stamp;
        collision_stats stats;
        step_timings timings;
        std::vector<std::uint32_t> stamps;
        for (int step = 0; step < 40; ++step) {
            resolve_collisions(settings, gas.walls(), {}, {x, v, x, v, inverse_mass, radius, false, true},
                               1.0 / 60.0, workspace, stats, timings);
            stamps.push_back(workspace.discrete.stamp);
            // What the next step relies on: no mark is at or above its first stamp.
            EXPECT_LE(*std::max_element(workspace.discrete.mark.begin(), workspace.discrete.mark.end()),
                      workspace.discrete.stamp)
                << step;
        }
        EXPECT_GT(stats.sphere_contacts, 1000U);
        return std::make_tuple(x, v, stamps);
    };
    auto const [x, v, fresh_stamps] = run(0);
    auto const [x_wrapped, v_wrapped, stamps] = run(std::numeric_limits<std::uint32_t>::max() - 100);
    EXPECT_LT(stamps.back(), stamps.front()) << "the stamps never wrapped";
    EXPECT_LT(fresh_stamps.front(), fresh_stamps.back());
    for (std::size_t i = 0; i < x.size(); ++i) {
        ASSERT_EQ(x[i], x_wrapped[i]) << i;
        ASSERT_EQ(v[i], v_wrapped[i]) << i;
    }
}

// Without forces the discrete step makes the drift itself, in its wall pass, and keeps no x₀
// or v₀; with a field of zero strength the world integrates first and keeps both, and the wall
// pass computes every free acceleration (all zero). The same motion, so the same bits, walls
// and pairs included, on one thread and on two.
TEST(DiscreteThreads, DriftInTheWallPassMatchesIntegratingFirst)
{
    auto run = [](bool zero_field, parallel_for* loops) {
        world w = discrete_gas(2000);
        if (zero_field)
            w.add_force(std::make_unique<uniform_field>(vec3::Zero()));
        w.set_parallel_for(loops, 0);
        for (int i = 0; i < 60; ++i)
            w.step(1.0 / 60.0);
        EXPECT_GT(w.collisions().sphere_contacts, 100U);
        EXPECT_GT(w.collisions().wall_contacts, 10U);
        return state_hash(w);
    };
    thread_pool pool(2);
    std::uint64_t const reference = run(true, nullptr);
    EXPECT_EQ(run(false, nullptr), reference);
    EXPECT_EQ(run(false, &pool), reference);
}

/// Ten spheres (radius 0.05 m, 0.52 kg) stacked on a floor, touching, under gravity:
/// restitution 0.5, the floor damping 0.5 and friction 0.5, one step of 1/60 s per tick.
world column_on_the_floor()
{
    world_settings s = pile_settings();
    s.collisions.friction = 0.0;
    return stack_on_the_floor(10, 0.05, s);
}

/// A sphere of radius 0.05 m and density 1000 kg/m³ at x, at rest.
body_desc pile_sphere(vec3 const& x)
{
    return ball(x, vec3::Zero(), 0.05, 1000 * 4.0 / 3.0 * 3.141592653589793 * 0.05 * 0.05 * 0.05);
}

/// A pile sphere of radius r resting on a fixed one, its centre `degrees` from the top of it,
/// under gravity, restitution and sphere friction 0.5: the world so far (the caller adds the
/// upper sphere, after any wall) and where that sphere starts.
struct on_a_fixed_sphere
{
    world w;
    vec3 start;
    double theta;
    static constexpr double r = 0.05;
};

on_a_fixed_sphere sphere_on_a_fixed_one(double degrees, bool sleep = true)
{
    world_settings s = pile_settings();
    s.collisions.sleep = sleep;
    world w(s);
    w.add_force(std::make_unique<uniform_field>(vec3(0, 0, -9.81)));
    body_desc fixed = pile_sphere(vec3::Zero());
    fixed.is_static = true;
    w.add_body(fixed);
    double const theta = degrees * 3.141592653589793 / 180.0;
    vec3 const start = 2 * on_a_fixed_sphere::r * vec3(std::sin(theta), 0.0, std::cos(theta));
    return {std::move(w), start, theta};
}

// Static friction between spheres: a sphere resting on a fixed sphere, its centre θ from the
// top, under gravity, with the scene's μ = 0.5. Below the friction angle (tan θ < μ: 20°) the
// contact holds it where it is for 5 s: measured, it does not move at all and its speed stays
// below 1e-18 m/s; the bounds, 1e-6 r and the resting-pile figure 1e-3 m/s, are far above
// rounding and far below any slip (the walls' rule, a share of the sliding speed per step,
// let it creep off at about g·h·sin θ). Above it (35°: tan θ = 0.7) it slides off the sphere,
// more than a radius in 5 s.
TEST(DiscretePile, SpheresStickOnSlopesShallowerThanTheFrictionAngle)
{
    for (double const degrees : {20.0, 35.0}) {
        auto [w, start, theta] = sphere_on_a_fixed_one(degrees);
        double const r = on_a_fixed_sphere::r;
        body_id const top = w.add_body(pile_sphere(start));
        double moved = 0.0, fastest = 0.0;
        for (int step = 0; step < 300; ++step) {
            w.step(1.0 / 60.0);
            std::size_t const i = *w.bodies().slot_of(top);
            moved = std::max(moved, (w.bodies().positions()[i] - start).norm());
            fastest = std::max(fastest, w.bodies().velocities()[i].norm());
        }
        if (std::tan(theta) < w.settings().collisions.friction) {
            EXPECT_LE(moved, 1e-6 * r) << degrees;
            EXPECT_LE(fastest, 1e-3) << degrees;
        } else {
            EXPECT_GT(moved, r) << degrees;
        }
    }
}

// A sphere in the hollow of three on the floor (a tetrahedron of touching spheres) stays: the
// three do not slide apart under its weight and it does not sink between them. Measured over
// 10 s: the top moves 2.4e-10 m and no sphere is faster than 2.4e-11 m/s. Before its supports
// were solved together (each stop taken in turn, once, with friction at each), the top crept
// 3 mm at up to 0.025 m/s. Bounds: 1e-3 r, and the resting-pile figure 1e-3 m/s; the same
// with the pile scene's 8 support sweeps as with the default 16.
TEST(DiscretePile, ATetrahedronOnTheFloorStaysStill)
{
    for (int const sweeps : {16, 8}) { // the default, and the pile scene's
        SCOPED_TRACE(std::to_string(sweeps) + " support sweeps");
        world_settings s = pile_settings();
        s.collisions.support_sweeps = sweeps;
        world w = on_the_floor(s);
        double const r = 0.05, side = 2 * r, pi = 3.141592653589793;
        double const out = side / std::sqrt(3.0); // from the triangle's centre to a corner
        for (int k = 0; k < 3; ++k)
            w.add_body(pile_sphere({out * std::cos(2 * pi * k / 3), out * std::sin(2 * pi * k / 3), r}));
        vec3 const start(0, 0, r + side * std::sqrt(2.0 / 3.0));
        body_id const top = w.add_body(pile_sphere(start));
        double fastest = 0.0;
        for (int step = 0; step < 600; ++step) {
            w.step(1.0 / 60.0);
            for (vec3 const& v : w.bodies().velocities())
                fastest = std::max(fastest, v.norm());
        }
        std::size_t const i = *w.bodies().slot_of(top);
        EXPECT_LE((w.bodies().positions()[i] - start).norm(), 1e-3 * r);
        EXPECT_LE(fastest, 1e-3);
        EXPECT_LE(w.max_overlap(), 1e-3 * r);
    }
}

// A column of four touching spheres on the floor stays still whatever the integrator: the
// contacts stop each sphere on the one below, and it ends the step where it started (x₀ + h·v,
// v = 0), not where free motion took it less the change of velocity times h, which holds for
// semi-implicit Euler alone. With the parabola, Verlet or Runge–Kutta (free motion ½·a·h²
// down), the upper three rose by ½·g·h² and fell back every other step, at g·h = 0.16 m/s, and
// a pile of them never came to rest. Sleep off, so that the contacts alone hold it. Bounds:
// 1e-3 r of movement and the resting-pile figure of 1e-3 m/s, over 5 s.
TEST(DiscretePile, AColumnStaysStillWithEveryIntegrator)
{
    for (integrator_kind const integrator :
         {integrator_kind::explicit_euler, integrator_kind::semi_implicit_euler, integrator_kind::exact_constant_force,
          integrator_kind::velocity_verlet, integrator_kind::rk4, integrator_kind::dormand_prince}) {
        double const r = 0.05;
        world w = stack_on_the_floor(4, r, false, integrator);
        std::vector<vec3> const start(w.bodies().positions().begin(), w.bodies().positions().end());
        double fastest = 0.0, moved = 0.0;
        for (int step = 0; step < 300; ++step) {
            w.step(1.0 / 60.0);
            for (std::size_t i = 0; i < start.size(); ++i) {
                fastest = std::max(fastest, w.bodies().velocities()[i].norm());
                moved = std::max(moved, (w.bodies().positions()[i] - start[i]).norm());
            }
        }
        SCOPED_TRACE(std::string(info(integrator).name));
        EXPECT_LE(fastest, 1e-3);
        EXPECT_LE(moved, 1e-3 * r);
        EXPECT_LE(w.max_overlap(), 1e-3 * r);
    }
}

// A sphere leaning between a fixed sphere below it and a side wall stays where it is: the wall
// is one of the stops its support is solved against (with the wall's friction by Coulomb's
// law), so the push of the sphere below into the wall is answered in the same solve. Before,
// the wall met it only in the passes after, and at 70° from the vertical it sank into the
// sphere and the wall, 6.3e-5 m in 5 s, overlaps 2.1e-5 m (sleeping off). Measured now: at
// most 2.5e-9 m, the deepest overlap 8.7e-10 m (in the first steps; 2.2e-14 m at the end).
// Bounds: 1e-6 r for both, far above that and far below the old sinking.
TEST(DiscretePile, ASphereLeaningOnASideWallStaysPut)
{
    for (double const degrees : {30.0, 45.0, 70.0}) {
        [[maybe_unused]] auto [w, start, theta] = sphere_on_a_fixed_one(degrees, false); // awake, step after step
        double const r = on_a_fixed_sphere::r;
        w.add_wall({make_plane(vec3(-1, 0, 0), -(start.x() + r)), 0.5, 0.5});
        body_id const leaning = w.add_body(pile_sphere(start));
        double moved = 0.0, deepest = 0.0;
        for (int step = 0; step < 300; ++step) {
            w.step(1.0 / 60.0);
            moved = std::max(moved, (w.bodies().positions()[*w.bodies().slot_of(leaning)] - start).norm());
            deepest = std::max(deepest, w.max_overlap());
        }
        EXPECT_LE(moved, 1e-6 * r) << degrees;
        EXPECT_LE(deepest, 1e-6 * r) << degrees;
    }
}

// Support reaches the top of a column in the step it is needed: the velocity passes alone
// (four Gauss–Seidel passes) left the upper spheres with most of each step of gravity, and
// the column sank into itself, its centre 14 cm lower after 10 s and its deepest overlap
// 1.2 radii. With support passed up from the floor it sank 1.3 mm (overlap 0.009 r): a sphere
// whose contact below ended free motion a rounding error apart was not a contact that step
// and fell for it. With contacts found within a margin (speculative contacts) it keeps its
// height to rounding: measured, the centre 1.1e-16 m lower, the deepest overlap 2.8e-17 m and
// every sphere at rest. The bounds, 1e-6 r, are far above the rounding of its coordinates and
// far below the 1.3 mm of before; speed: the resting-pile figure 1e-3 m/s.
TEST(DiscretePile, AColumnOnTheFloorKeepsItsHeight)
{
    world w = column_on_the_floor();
    double const r = 0.05, start = measure_motion(w).centre_of_mass.z();
    for (int step = 0; step < 600; ++step)
        w.step(1.0 / 60.0);
    EXPECT_LE(start - measure_motion(w).centre_of_mass.z(), 1e-6 * r);
    EXPECT_LE(w.max_overlap(), 1e-6 * r);
    EXPECT_LE(measure(w).largest_speed, 1e-3);
}

// The position passes leave an overlap within the slop (a share of r_a + r_b) where it is and
// push a deeper one apart: two spheres at rest without forces, 1 % of the way into each other,
// keep their positions to the bit under a slop of 2 % and are pushed out to touching (to the
// rounding the passes leave, 2^-42 of r_a + r_b) without one; 3 % into each other, they are
// pushed out under the slop too.
TEST(DiscretePositionSlop, OverlapsWithinTheSlopAreLeftAndDeeperOnesPushedApart)
{
    auto overlap_after_a_step = [](double overlap, double slop) {
        world_settings s = colliding(collision_mode::discrete, integrator_kind::semi_implicit_euler);
        s.collisions.position_slop = slop;
        world w(s);
        double const r = 0.05;
        w.add_body(ball({0, 0, 0}, vec3::Zero(), r, 1.0));
        w.add_body(ball({2 * r * (1.0 - overlap), 0, 0}, vec3::Zero(), r, 1.0));
        vec3 const before = w.bodies().positions()[1];
        w.step(1.0 / 60.0);
        auto const x = w.bodies().positions();
        return std::make_pair(2 * r - (x[1] - x[0]).norm(), x[1] == before);
    };
    double const rounding = 0x1p-42 * 0.1;
    auto [kept, unmoved] = overlap_after_a_step(0.01, 0.02);
    EXPECT_TRUE(unmoved);
    EXPECT_NEAR(kept, 0.01 * 0.1, 1e-15);
    EXPECT_LE(overlap_after_a_step(0.01, 0.0).first, rounding);
    EXPECT_LE(overlap_after_a_step(0.03, 0.02).first, rounding);
}

// Under gravity a column resting under a slop stays still and sleeps, its overlaps within the
// slop: resting contacts close by the support solve's tolerance each step, which the slop
// leaves where the passes without it pushed them out again every pass. Bounds: the slop's
// 1 % of r_a + r_b (with the rounding of the coordinates on top), and the resting-pile
// figure of 1e-3 m/s.
TEST(DiscretePositionSlop, AColumnUnderASlopRestsWithinIt)
{
    double const r = 0.05, slop = 0.01;
    world_settings s = pile_settings();
    s.collisions.position_slop = slop;
    world w = stack_on_the_floor(10, r, s);
    for (int step = 0; step < 600; ++step)
        w.step(1.0 / 60.0);
    EXPECT_LE(w.max_overlap(), slop * 2 * r * (1.0 + 1e-9));
    EXPECT_LE(measure(w).largest_speed, 1e-3);
    EXPECT_EQ(w.sleeping_bodies(), 10U);
}

// Support comes from walls only: spheres that nothing static carries keep the momentum the
// velocity passes leave them. Two touching spheres falling under gravity with nothing below
// them gain exactly the momentum gravity gives, M·g·t, to rounding (1e-14 of it), as
// without support.
TEST(DiscretePile, ClustersInFreeFallKeepTheirMomentum)
{
    world_settings s = colliding(collision_mode::discrete, integrator_kind::semi_implicit_euler);
    world w(s);
    w.add_force(std::make_unique<uniform_field>(vec3(0, 0, -9.81)));
    w.add_body(ball({0, 0, 10.0}, vec3(0, 0, -1), 0.05, 1.0));
    w.add_body(ball({0, 0, 10.1}, vec3(0, 0, -3), 0.05, 2.0)); // closing on the lower one
    for (int step = 0; step < 60; ++step)
        w.step(1.0 / 60.0);
    ASSERT_GT(w.collisions().sphere_contacts, 0U);
    double const expected = 1.0 * -1 + 2.0 * -3 - 3.0 * 9.81 * 1.0;
    EXPECT_NEAR(measure_motion(w).momentum.z(), expected, 1e-14 * std::abs(expected));
}

} // namespace
} // namespace kugel::physics
