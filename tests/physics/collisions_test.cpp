#include "physics/diagnostics.hpp"
#include "physics/thread_pool.hpp"
#include "physics/world.hpp"
#include "support/state_hash.hpp"
#include "physics/collision_scenes.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <optional>
#include <random>
#include <tuple>

namespace kugel::physics {
namespace {

vec3 position(world const& w, body_id id) { return w.bodies().positions()[*w.bodies().slot_of(id)]; }
vec3 velocity(world const& w, body_id id) { return w.bodies().velocities()[*w.bodies().slot_of(id)]; }

wall floor_wall(double damping = 0.0, double friction = 0.0)
{
    return {make_plane(vec3::UnitZ(), 0.0), damping, friction};
}

class BothModes : public ::testing::TestWithParam<collision_mode>
{};

INSTANTIATE_TEST_SUITE_P(Collisions, BothModes,
                         ::testing::Values(collision_mode::discrete, collision_mode::continuous),
                         [](auto const& p) { return std::string(name(p.param)); });

TEST_P(BothModes, EqualMassesHeadOnSwapVelocities)
{
    world w(colliding(GetParam()));
    body_id const a = w.add_body(ball({-2, 0, 0}, {1, 0, 0}));
    body_id const b = w.add_body(ball({2, 0, 0}, {-0.5, 0, 0}));
    for (int i = 0; i < 300; ++i)
        w.step(0.01);
    EXPECT_NEAR(velocity(w, a).x(), -0.5, 1e-12);
    EXPECT_NEAR(velocity(w, b).x(), 1.0, 1e-12);
    EXPECT_EQ(w.collisions().sphere_contacts, 1U);
}

TEST_P(BothModes, OffModeLetsBodiesPassThrough)
{
    world w;
    body_id const a = w.add_body(ball({-2, 0, 0}, {1, 0, 0}));
    for (int i = 0; i < 300; ++i)
        w.step(0.01);
    EXPECT_NEAR(velocity(w, a).x(), 1.0, 0.0);
    EXPECT_EQ(w.collisions().contacts(), 0U);
}

// Five equal balls in a row, touching: the striker's momentum passes down the chain and the
// last ball leaves with the striker's speed while the others stop (the lecture's rule applied
// pair by pair; exact here because the contacts are simultaneous and exactly touching).
TEST_P(BothModes, NewtonsCradlePassesTheMomentumThroughTheChain)
{
    world w(colliding(GetParam()));
    body_id const striker = w.add_body(ball({-3, 0, 0}, {2, 0, 0}));
    std::vector<body_id> chain;
    for (int k = 0; k < 4; ++k)
        chain.push_back(w.add_body(ball({static_cast<double>(k), 0, 0}, {0, 0, 0})));
    for (int i = 0; i < 100; ++i)
        w.step(0.01);
    EXPECT_NEAR(velocity(w, striker).x(), 0.0, 1e-12);
    for (int k = 0; k < 3; ++k)
        EXPECT_NEAR(velocity(w, chain[static_cast<std::size_t>(k)]).x(), 0.0, 1e-12) << k;
    EXPECT_NEAR(velocity(w, chain[3]).x(), 2.0, 1e-12);
}

/// Apex height (above the resting height r) of a ball on its way up: z − r + v_z²/(2g).
double apex(world const& w, body_id id, double g)
{
    double const vz = velocity(w, id).z();
    return position(w, id).z() - 0.5 + vz * vz / (2 * g);
}

/// Drops a ball from 1 m above its resting height onto a floor with damping α and returns
/// the apex after each of the first `bounces` bounces, taken just after each bounce.
std::vector<double> apexes(collision_mode mode, double alpha, int bounces, double dt)
{
    world w(colliding(mode, integrator_kind::exact_constant_force));
    double const g = 9.81;
    w.add_force(std::make_unique<uniform_field>(vec3(0, 0, -g)));
    w.add_wall(floor_wall(alpha));
    body_id const id = w.add_body(ball({0, 0, 1.5}, {0, 0, 0}));
    std::vector<double> out;
    double previous_vz = 0.0;
    while (static_cast<int>(out.size()) < bounces && w.steps() < 1'000'000) {
        w.step(dt);
        double const vz = velocity(w, id).z();
        if (previous_vz < 0.0 && vz > 0.0)
            out.push_back(apex(w, id, g));
        previous_vz = vz;
    }
    return out;
}

// A box's six walls face in: a point inside is above each (n·x − d > 0) by its distance to
// that face, a point outside is below one; each wall carries the given damping and friction.
TEST(BoxWalls, FaceInwardOnEveryAxisAtTheRegionsFaces)
{
    aabb const region{vec3(-1.0, 0.0, 2.0), vec3(3.0, 0.5, 6.0)};
    auto const walls = box_walls(region, 0.25, 0.75);
    ASSERT_EQ(walls.size(), 6U);
    vec3 const inside(0.0, 0.125, 5.0);
    std::array<double, 6> const distance{1.0, 3.0, 0.125, 0.375, 3.0, 1.0}; // min x, max x, min y, ...
    for (std::size_t k = 0; k < walls.size(); ++k) {
        EXPECT_EQ(walls[k].surface.normal.dot(inside) - walls[k].surface.offset, distance[k]) << "wall " << k;
        EXPECT_EQ(walls[k].damping, 0.25);
        EXPECT_EQ(walls[k].friction, 0.75);
    }
    vec3 const outside(0.0, 0.125, 7.0); // above the top
    EXPECT_LT(walls[5].surface.normal.dot(outside) - walls[5].surface.offset, 0.0);
}

// Continuous mode finds each contact on the exact parabola, so the apex after bounce k is
// exactly (1−α)^(2k) of the drop height: 1e-9 relative is rounding over thousands of steps.
TEST(Bounce, ApexHeightsShrinkByOneMinusAlphaSquaredPerBounce)
{
    double const alpha = 0.2;
    auto const heights = apexes(collision_mode::continuous, alpha, 5, 1e-3);
    ASSERT_EQ(heights.size(), 5U);
    for (std::size_t k = 0; k < heights.size(); ++k)
        EXPECT_NEAR(heights[k], std::pow(1 - alpha, 2.0 * static_cast<double>(k + 1)),
                    1e-9 * heights[k])
            << k;
}

// Discrete mode finds the contact time by the lecture's linear interpolation, so the speed
// it reflects is off by up to g·dt: apex ratios within 2·g·dt / v_impact ≈ 1% at dt = 1 ms.
TEST(Bounce, DiscreteModeApproximatesTheSameRatios)
{
    double const alpha = 0.2;
    auto const heights = apexes(collision_mode::discrete, alpha, 5, 1e-3);
    ASSERT_EQ(heights.size(), 5U);
    for (std::size_t k = 0; k < heights.size(); ++k)
        EXPECT_NEAR(heights[k], std::pow(1 - alpha, 2.0 * static_cast<double>(k + 1)), 1e-2) << k;
}

// With α = 0 the reflection keeps |v| wherever on the path it happens, so no bounce adds the
// energy that integrating g·dt before reflecting would: the apex stays at 1 m for 100 bounces.
TEST_P(BothModes, ElasticBallKeepsItsApexHeight)
{
    auto const heights = apexes(GetParam(), 0.0, 100, 1.0 / 60.0);
    ASSERT_EQ(heights.size(), 100U);
    double const tolerance = GetParam() == collision_mode::continuous ? 1e-9 : 1e-3;
    for (std::size_t k = 0; k < heights.size(); ++k)
        EXPECT_NEAR(heights[k], 1.0, tolerance) << k;
}

TEST_P(BothModes, BallAtRestOnTheFloorStaysThere)
{
    world w(colliding(GetParam()));
    w.add_force(std::make_unique<uniform_field>(vec3(0, 0, -9.81)));
    w.add_wall(floor_wall(0.3, 0.1));
    body_id const id = w.add_body(ball({0, 0, 0.5}, {0, 0, 0}));
    double worst = 0.0;
    for (int i = 0; i < 10000; ++i) {
        w.step(1.0 / 60.0);
        worst = std::max(worst, std::abs(position(w, id).z() - 0.5));
    }
    EXPECT_LE(worst, 1e-9);
}

TEST_P(BothModes, DampedBallComesToRestOnTheFloor)
{
    world w(colliding(GetParam()));
    w.add_force(std::make_unique<uniform_field>(vec3(0, 0, -9.81)));
    w.add_wall(floor_wall(0.5));
    body_id const id = w.add_body(ball({0, 0, 3}, {0, 0, 0}));
    for (int i = 0; i < 600; ++i) {
        w.step(1.0 / 60.0);
        ASSERT_GE(position(w, id).z(), 0.5 - 1e-12) << "sank into the floor at step " << i;
    }
    EXPECT_NEAR(position(w, id).z(), 0.5, 1e-9);
    EXPECT_EQ(velocity(w, id), vec3::Zero()); // at rest, not micro-bouncing
}

TEST_P(BothModes, FrictionSlowsASlidingBall)
{
    world w(colliding(GetParam()));
    w.add_force(std::make_unique<uniform_field>(vec3(0, 0, -9.81)));
    w.add_wall(floor_wall(0.3, 0.05));
    body_id const id = w.add_body(ball({0, 0, 0.5}, {2, 0, 0}));
    w.step(0.01);
    // The lecture's rule scales the tangential speed by (1 − μ) per contact.
    EXPECT_NEAR(velocity(w, id).x(), 2.0 * 0.95, 1e-12);
}

// The trade: at 1,000 radii per step, continuous mode still finds every contact; discrete
// mode only sees where bodies are at the end of a step and lets them pass.
// A thousand radii per step: discrete mode passes through unless it sweeps (the default), and
// then says how many fast bodies it did not sweep; the sweep and continuous mode never pass.
struct tunnelling_case
{
    collision_mode mode;
    bool sweep;
};
constexpr std::array tunnelling_cases{tunnelling_case{collision_mode::discrete, false},
                                      tunnelling_case{collision_mode::discrete, true},
                                      tunnelling_case{collision_mode::continuous, true}};

TEST(Tunnelling, FastSpheresPassInDiscreteModeOnlyWithoutTheSweep)
{
    double const r = 0.01, dt = 0.01, speed = 1000 * r / dt;
    for (auto const [mode, sweep] : tunnelling_cases) {
        world_settings s = colliding(mode);
        s.collisions.sweep = sweep;
        world w(s);
        body_id const a = w.add_body(ball({-0.5, 0, 0}, {speed, 0, 0}, r));
        body_id const b = w.add_body(ball({0.5, 0, 0}, {-speed, 0, 0}, r));
        for (int i = 0; i < 3; ++i)
            w.step(dt);
        bool const passed = position(w, a).x() > position(w, b).x();
        EXPECT_EQ(passed, !sweep) << name(mode) << ", sweep " << sweep;
        EXPECT_EQ(w.collisions().unswept_fast_bodies, sweep ? 0U : 6U) << name(mode);
    }
}

TEST(Tunnelling, FastSphereCrossesAThinBoxInDiscreteModeOnlyWithoutTheSweep)
{
    double const r = 0.01, dt = 0.01, speed = 1000 * r / dt;
    for (auto const [mode, sweep] : tunnelling_cases) {
        world_settings s = colliding(mode);
        s.collisions.sweep = sweep;
        world w(s);
        w.add_obstacle({obb_from_box(vec3::Zero(), vec3(0.005, 1, 1), Eigen::Matrix3d::Identity())});
        body_id const a = w.add_body(ball({-0.5, 0.2, 0.1}, {speed, 0, 0}, r));
        for (int i = 0; i < 3; ++i)
            w.step(dt);
        bool const crossed = position(w, a).x() > 0.0;
        EXPECT_EQ(crossed, !sweep) << name(mode) << ", sweep " << sweep;
    }
}

TEST(Tunnelling, WallsHoldAtAnySpeedInBothModes)
{
    for (auto mode : {collision_mode::discrete, collision_mode::continuous}) {
        world w(colliding(mode));
        w.add_wall(floor_wall());
        body_id const a = w.add_body(ball({0, 0, 1}, {0, 0, -1e6}, 0.01));
        for (int i = 0; i < 10; ++i) {
            w.step(0.01);
            EXPECT_GE(position(w, a).z(), 0.01 - 1e-9) << name(mode);
        }
        EXPECT_GT(velocity(w, a).z(), 0.0);
    }
}

// 1,000 elastic spheres in a box for 10⁴ steps: continuous mode conserves kinetic energy to
// rounding (each response and each wall reflection keeps |v| up to an ulp, so the drift is a
// random walk of ~1e-16 per contact) and lets nothing out.
TEST(ElasticGas, ContinuousModeConservesEnergyAndHoldsEveryone)
{
    world w(colliding(collision_mode::continuous));
    double const L = 5.0, r = 0.1;
    add_box(w, L);
    std::mt19937_64 rng(42);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    // on a lattice with spacing 0.9 > 2r: no overlaps at the start
    int placed = 0;
    for (int i = 0; i < 10 && placed < 1000; ++i)
        for (int j = 0; j < 10 && placed < 1000; ++j)
            for (int k = 0; k < 10 && placed < 1000; ++k, ++placed)
                w.add_body(ball({-4.05 + 0.9 * i, -4.05 + 0.9 * j, -4.05 + 0.9 * k},
                                {u(rng), u(rng), u(rng)}, r, 1.0 + 0.5 * u(rng)));
    double const e0 = measure(w).kinetic;
    for (int i = 0; i < 10000; ++i)
        w.step(0.01);
    EXPECT_LE(std::abs(measure(w).kinetic - e0), 1e-9 * e0);
    for (auto const& x : w.bodies().positions())
        EXPECT_TRUE((x.array().abs() <= L - r + 1e-9).all()) << x.transpose();
    EXPECT_GT(w.collisions().sphere_contacts, 1000U);
    EXPECT_EQ(w.collisions().capped_steps, 0U);
    EXPECT_LE(w.max_overlap(), 1e-9);
}

// A resting stack in continuous mode makes contact after contact (each ball is pressed onto
// the next by gravity); past the cap the step finishes in discrete mode, the step is counted,
// and nothing ends up inside the floor.
TEST(EventCap, IsReportedAndTheStepStillFinishesSafely)
{
    world_settings s = colliding(collision_mode::continuous);
    s.collisions.max_events_per_step = 20;
    world w(s);
    w.add_force(std::make_unique<uniform_field>(vec3(0, 0, -9.81)));
    w.add_wall(floor_wall(0.5));
    for (int k = 0; k < 6; ++k)
        w.add_body(ball({0, 0, 0.5 + 1.0 * k}, {0, 0, 0}));
    for (int i = 0; i < 120; ++i)
        w.step(1.0 / 60.0);
    EXPECT_GT(w.collisions().capped_steps, 0U);
    for (auto const& x : w.bodies().positions()) {
        EXPECT_TRUE(x.allFinite());
        EXPECT_GE(x.z(), 0.5 - 1e-12);
    }
}

// A 1 g sphere squeezed between a wall and a 10⁹ kg sphere collides about π·√(M/m) ≈ 10⁵·π
// times before the heavy one turns, faster each time; a client could set that up in any
// continuous room. The per-body cap ends such a step after the light sphere's share of
// events, not after the step's 10⁵: each event involves one of the two bodies, so a step
// handles at most twice the per-body cap. The step still finishes safely (discretely).
TEST(EventCap, OneBodysShareEndsASqueezeLongBeforeTheStepsCap)
{
    world_settings s = colliding(collision_mode::continuous);
    ASSERT_EQ(s.collisions.max_events_per_body, 1000U);
    ASSERT_EQ(s.collisions.max_events_per_step, 100'000U);
    world w(s);
    w.add_wall({make_plane({1, 0, 0}, -4.0), 0.0, 0.0}); // the plane x = -4
    w.add_body(ball({-3.7, 0, 0}, {0, 0, 0}, 0.2, 1e-3));
    w.add_body(ball({-3.0, 0, 0}, {-1, 0, 0}, 0.4, 1e9));
    std::uint64_t most_in_a_step = 0;
    for (int i = 0; i < 60 && w.collisions().capped_steps == 0; ++i) {
        std::uint64_t const before = w.collisions().events;
        w.step(1.0 / 60.0);
        most_in_a_step = std::max(most_in_a_step, w.collisions().events - before);
    }
    EXPECT_GT(w.collisions().capped_steps, 0U);
    EXPECT_LE(most_in_a_step, 2 * s.collisions.max_events_per_body);
    for (auto const& x : w.bodies().positions())
        EXPECT_TRUE(x.allFinite());
    EXPECT_GE(w.bodies().positions()[0].x(), -4.0 + 0.2 - 1e-12); // not inside the wall
}

TEST(Obstacles, BallBouncesOffARotatedBox)
{
    world w(colliding(collision_mode::continuous));
    Eigen::Matrix3d const rotation = Eigen::AngleAxisd(0.3, vec3::UnitZ()).toRotationMatrix();
    w.add_obstacle({obb_from_box(vec3::Zero(), vec3(1, 1, 1), rotation), 0.0, 0.0});
    body_id const id = w.add_body(ball({0, 0, 3}, {0, 0, -2}, 0.5));
    for (int i = 0; i < 200; ++i)
        w.step(0.01);
    // straight down onto the top face (normal +z): straight back up at the same speed
    EXPECT_NEAR(velocity(w, id).z(), 2.0, 1e-9);
    EXPECT_EQ(w.collisions().obstacle_contacts, 1U);
}

TEST(CollisionStatic, StaticSphereActsAsAnObstacle)
{
    for (auto mode : {collision_mode::discrete, collision_mode::continuous}) {
        world w(colliding(mode));
        w.add_body({vec3::Zero(), vec3::Zero(), 1.0, 1.0, 0.0, true});
        body_id const id = w.add_body(ball({-3, 0, 0}, {1, 0, 0}));
        for (int i = 0; i < 300; ++i)
            w.step(0.01);
        EXPECT_NEAR(velocity(w, id).x(), -1.0, 1e-12) << name(mode);
    }
}

using test_support::state_hash;

// The broadphase is a speed setting only: all three find the same pairs, and the discrete
// step resolves them in the sphere grid's order whichever found them, so a whole simulation
// comes out bit for bit the same whichever the scene picks.
TEST(Broadphases, GiveTheSameSimulationBitForBit)
{
    for (auto mode : {collision_mode::discrete, collision_mode::continuous}) {
        std::uint64_t const grid = state_hash(settled_pile(mode, broadphase_kind::uniform_grid));
        EXPECT_EQ(state_hash(settled_pile(mode, broadphase_kind::sweep_and_prune)), grid) << name(mode);
        EXPECT_EQ(state_hash(settled_pile(mode, broadphase_kind::brute_force)), grid) << name(mode);
    }
}

// Golden values recorded when this test was written, as for World.SameSceneGivesTheSameBits:
// a change that alters collision results on purpose updates them in the same commit and
// says why; any other change must leave them alone.
TEST(Collisions, SameSceneGivesTheSameBits)
{
    std::uint64_t const discrete = state_hash(settled_pile(collision_mode::discrete, broadphase_kind::uniform_grid));
    std::uint64_t const continuous = state_hash(settled_pile(collision_mode::continuous, broadphase_kind::uniform_grid));
    EXPECT_EQ(discrete, 0xc22ed7b038409509ULL) << std::hex << "discrete 0x" << discrete;
    EXPECT_EQ(continuous, 0xc7a58b5b4199ff1dULL) << std::hex << "continuous 0x" << continuous;
}

} // namespace
} // namespace kugel::physics

namespace kugel::physics {
namespace {

/// Every pair, plainly: what max_overlap() must find however it files the spheres.
double deepest_overlap_of_every_pair(std::span<vec3 const> x, std::span<double const> r)
{
    double worst = 0.0;
    for (std::size_t i = 0; i < x.size(); ++i)
        for (std::size_t j = i + 1; j < x.size(); ++j)
            if (r[i] > 0.0 && r[j] > 0.0)
                worst = std::max(worst, r[i] + r[j] - (x[i] - x[j]).norm());
    return worst;
}

// max_overlap() files centres by cell and scans each cell's half shell of neighbours, and
// falls back to the broadphase where cells cannot be numbered. Both must give exactly the
// plain answer over every pair (the same formula on the same pair: equal bits), for crowded
// and sparse spheres of mixed sizes, point masses among them, near the origin and far out.
TEST(MaxOverlap, IsTheDeepestOverlapOfEveryPairExactly)
{
    std::mt19937_64 rng(20261206);
    for (double const centre : {0.0, -3.7e6, 1e300}) {
        for (double const spread : {0.5, 4.0, 40.0}) {
            std::uniform_real_distribution<double> at(-spread, spread);
            std::uniform_real_distribution<double> size(0.0, 0.3);
            std::vector<vec3> x;
            std::vector<double> r;
            for (int k = 0; k < 400; ++k) {
                x.push_back(vec3::Constant(centre) + vec3(at(rng), at(rng), at(rng)));
                r.push_back(k % 17 == 0 ? 0.0 : size(rng));
            }
            collision_workspace ws;
            EXPECT_EQ(max_overlap({}, {}, x, r, ws), deepest_overlap_of_every_pair(x, r))
                << "centre " << centre << ", spread " << spread;
        }
    }
}

TEST(MaxOverlap, SeparateSpheresAndNoSpheresOverlapByNothing)
{
    collision_workspace ws;
    std::vector<vec3> const x{vec3(0, 0, 0), vec3(1, 0, 0), vec3(0, 0, 1)};
    EXPECT_EQ(max_overlap({}, {}, x, std::vector<double>{0.1, 0.1, 0.0}, ws), 0.0);
    EXPECT_EQ(max_overlap({}, {}, x, std::vector<double>{0.0, 0.0, 0.0}, ws), 0.0);
    EXPECT_EQ(max_overlap({}, {}, {}, {}, ws), 0.0);
    // touching across a cell's corner: the neighbour in (−1, −1, −1) is found from the other side
    std::vector<vec3> const corner{vec3(0, 0, 0), vec3(-0.1, -0.1, -0.1)};
    EXPECT_EQ(max_overlap({}, {}, corner, std::vector<double>{0.1, 0.1}, ws), 0.1 + 0.1 - (corner[0] - corner[1]).norm());
    EXPECT_GT(max_overlap({}, {}, corner, std::vector<double>{0.1, 0.1}, ws), 0.026); // 0.2 − √0.03
}

} // namespace
} // namespace kugel::physics
