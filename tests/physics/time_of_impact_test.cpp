#include "physics/time_of_impact.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace kugel::physics {
namespace {

// Tolerances: a result computed from exact inputs through a handful of roundings (a dot
// product, a square root, a division) is within a few units in the last place, so "exact"
// answers are checked to 4 ulps relative (ulps below); anything looser says why.
constexpr double epsilon = 0x1p-52;
double ulps(double expected, int n) { return n * epsilon * std::abs(expected); }

plane const floor_plane = make_plane(vec3::UnitZ(), 0.0); // z = 0, free side above
vec3 const gravity(0.0, 0.0, -9.81);                      // m/s²
vec3 const still = vec3::Zero(); // a velocity or acceleration of zero (vec3{} is uninitialised)

// ---- spheres_overlap -------------------------------------------------------------------

TEST(SpheresOverlap, TouchingCountsAndAGapDoesNot)
{
    EXPECT_TRUE(spheres_overlap({0, 0, 0}, 1.0, {3, 0, 0}, 2.0));                 // touching
    EXPECT_TRUE(spheres_overlap({0, 0, 0}, 1.0, {2.5, 0, 0}, 2.0));               // overlapping
    EXPECT_FALSE(spheres_overlap({0, 0, 0}, 1.0, {std::nextafter(3.0, 4.0), 0, 0}, 2.0));
    EXPECT_TRUE(spheres_overlap({1, 2, 3}, 0.0, {1, 2, 3}, 0.0)); // two equal points
}

// ---- sphere_time_of_impact -------------------------------------------------------------

TEST(SphereTimeOfImpact, HeadOnSpheresMeetAtGapOverClosingSpeed)
{
    // Centres 10 m apart, radii 1 and 2 m: gap 7 m; closing speed 3 + 1 m/s: t = 1.75 s.
    vec3 const x1(0, 0, 0), v1(3, 0, 0), x2(10, 0, 0), v2(-1, 0, 0);
    auto const t = sphere_time_of_impact(x1, v1, 1.0, x2, v2, 2.0, 10.0);
    ASSERT_TRUE(t);
    EXPECT_NEAR(*t, 1.75, ulps(1.75, 4));
    EXPECT_NEAR(((x1 + *t * v1) - (x2 + *t * v2)).norm(), 3.0, ulps(3.0, 8));
}

TEST(SphereTimeOfImpact, MissWhenClosestApproachExceedsSumOfRadii)
{
    // Passing along x at a distance h from the other centre, radii sum 3 m.
    vec3 const v1(5, 0, 0);
    EXPECT_FALSE(sphere_time_of_impact({0, 3.0001, 0}, v1, 1.0, {10, 0, 0}, still, 2.0, 100.0));
    EXPECT_TRUE(sphere_time_of_impact({0, 2.9999, 0}, v1, 1.0, {10, 0, 0}, still, 2.0, 100.0));
}

TEST(SphereTimeOfImpact, GlancingHitMatchesAnalyticTime)
{
    // Offset h = 1.2 m, radii sum R = 2 m, centres 10 m apart along x, closing at 4 m/s:
    // contact when the x-distance is √(R² − h²) = 1.6 m, t = (10 − 1.6) / 4 = 2.1 s.
    auto const t = sphere_time_of_impact({0, 1.2, 0}, {3, 0, 0}, 0.5, {10, 0, 0}, {-1, 0, 0},
                                         1.5, 10.0);
    ASSERT_TRUE(t);
    // 2.1 and 1.6 are not exact in binary, so a few more roundings: 8 ulps.
    EXPECT_NEAR(*t, 2.1, ulps(2.1, 8));
}

TEST(SphereTimeOfImpact, GrazingContactCountsAsHit)
{
    // Closest approach exactly R = 2 m (the discriminant is exactly 0), reached at t = 10 s.
    auto const t = sphere_time_of_impact({0, 2, 0}, {1, 0, 0}, 1.0, {10, 0, 0}, still, 1.0, 20.0);
    ASSERT_TRUE(t);
    EXPECT_EQ(*t, 10.0);
}

TEST(SphereTimeOfImpact, SeparatingPairNeverCollides)
{
    EXPECT_FALSE(sphere_time_of_impact({0, 0, 0}, {-1, 0, 0}, 1.0, {5, 0, 0}, {1, 0, 0}, 1.0, 1e9));
    // Moving at right angles to the line of centres: d·v = 0, no approach.
    EXPECT_FALSE(sphere_time_of_impact({0, 0, 0}, {0, 1, 0}, 1.0, {5, 0, 0}, still, 1.0, 1e9));
}

TEST(SphereTimeOfImpact, ZeroRelativeVelocityNeverCollides)
{
    vec3 const v(3, -2, 7);
    EXPECT_FALSE(sphere_time_of_impact({0, 0, 0}, v, 1.0, {5, 0, 0}, v, 1.0, 1e9));
    // Even overlapping: no approach, no new contact.
    EXPECT_FALSE(sphere_time_of_impact({0, 0, 0}, v, 1.0, {1, 0, 0}, v, 1.0, 1e9));
}

TEST(SphereTimeOfImpact, OverlappingAndApproachingCollidesAtZero)
{
    EXPECT_EQ(sphere_time_of_impact({0, 0, 0}, {1, 0, 0}, 1.0, {1.5, 0, 0}, still, 1.0, 1.0), 0.0);
    // Exactly touching and approaching.
    EXPECT_EQ(sphere_time_of_impact({0, 0, 0}, {1, 1, 0}, 1.0, {2, 0, 0}, still, 1.0, 1.0), 0.0);
    // Overlapping but separating: nothing.
    EXPECT_FALSE(sphere_time_of_impact({0, 0, 0}, {-1, 0, 0}, 1.0, {1.5, 0, 0}, still, 1.0, 1.0));
}

TEST(SphereTimeOfImpact, ImpactAfterTMaxIsNone)
{
    vec3 const x1(0, 0, 0), v1(3, 0, 0), x2(10, 0, 0), v2(-1, 0, 0); // meets at 1.75 s
    EXPECT_FALSE(sphere_time_of_impact(x1, v1, 1.0, x2, v2, 2.0, 1.7));
    EXPECT_TRUE(sphere_time_of_impact(x1, v1, 1.0, x2, v2, 2.0, 1.75)); // t_max is inclusive
    EXPECT_FALSE(sphere_time_of_impact(x1, v1, 1.0, x2, v2, 2.0, -1.0));
}

/// The lecture's t_coll as printed, for the reduced problem (point x₁ moving with v, sphere
/// of radius R at x₂), evaluated naively.
double textbook_time(vec3 const& x1, vec3 const& v, vec3 const& x2, double reach)
{
    double const vd = v.dot(x2 - x1);
    double const discriminant =
        std::pow(v.dot(x1 - x2), 2) - v.squaredNorm() * ((x1 - x2).squaredNorm() - reach * reach);
    return (vd - std::sqrt(discriminant)) / v.squaredNorm();
}

TEST(SphereTimeOfImpact, StableFormKeepsDigitsTheTextbookFormulaLoses)
{
    // Two spheres of radius 1e8 m, a gap of 2^-25 m (~3e-8 m, one ulp at 2e8), far from the
    // origin, closing at 1e6 m/s. Exact answer: gap / speed. The textbook numerator
    // v·(x₂ − x₁) − √(…) subtracts two numbers near 2e14 that agree in every digit but the
    // last, and d·d − R² has lost the gap below the ulp of 4e16 (8 m²).
    double const r = 1e8;
    double const gap = 0x1p-25;
    vec3 const offset(0.0, 1e8, -3e8);
    vec3 const x1 = offset;
    vec3 const x2 = offset + vec3(2 * r + gap, 0, 0); // exact: 2e8 + 2^-25 is a double
    vec3 const v1(6e5, 0, 0), v2(-4e5, 0, 0);
    double const exact = gap / 1e6;

    double const naive = textbook_time(x1, v1 - v2, x2, 2 * r);
    EXPECT_GT(std::abs(naive - exact), 1e-2 * exact); // the case is a real trap

    auto const t = sphere_time_of_impact(x1, v1, r, x2, v2, r, 1.0);
    ASSERT_TRUE(t);
    EXPECT_NEAR(*t, exact, 1e-12 * exact);
}

TEST(SphereTimeOfImpact, TinyGapAtHugeSpeedIsAccurate)
{
    // Unit spheres 2^-30 m (~1e-9 m) apart, closing at 1e6 m/s: t = 2^-30 / 1e6 s. The
    // inputs are exact, so the answer is too, to the last few ulps.
    double const gap = 0x1p-30;
    auto const t =
        sphere_time_of_impact({0, 0, 0}, {1e6, 0, 0}, 1.0, {2 + gap, 0, 0}, still, 1.0, 1.0);
    ASSERT_TRUE(t);
    EXPECT_NEAR(*t, gap / 1e6, 1e-12 * gap / 1e6);
}

TEST(SphereTimeOfImpact, HugeSpeedsAreStillCaught)
{
    // 0.1 m spheres, 1e6 radii per second: the pair is 100 m apart and would pass through
    // each other within one 1/60 s step. Contact when the gap of 99.8 m is closed.
    double const r = 0.1;
    double const speed = 1e6 * r;
    auto const t = sphere_time_of_impact({0, 0, 0}, {speed, 0, 0}, r, {100, 0.05, 0}, still, r, 1.0 / 60);
    ASSERT_TRUE(t);
    double const along = std::sqrt(4 * r * r - 0.05 * 0.05); // x-distance at contact
    double const expected = (100 - along) / speed;
    // 100 − along loses nothing (|along| << 100): 8 ulps.
    EXPECT_NEAR(*t, expected, ulps(expected, 8));
}

TEST(SphereTimeOfImpact, FarApartPairKeepsDigitsInTheDiscriminant)
{
    // 0.1 m spheres 1e5 m apart, offset 0.05 m sideways. b² − a c computed as written
    // subtracts two numbers near 1e10·v² that differ by 0.0375·v², losing ~11 digits of
    // the discriminant; a R² − ‖d × v‖² keeps them. Expected time as in the test above.
    double const r = 0.1;
    auto const t = sphere_time_of_impact({0, 0, 0}, {3, 0, 0}, r, {1e5, 0.05, 0}, {-1, 0, 0}, r,
                                         1e6);
    ASSERT_TRUE(t);
    double const along = std::sqrt(4 * r * r - 0.05 * 0.05);
    double const expected = (1e5 - along) / 4.0;
    EXPECT_NEAR(*t, expected, ulps(expected, 8));
}

TEST(SphereTimeOfImpact, RandomHitsPutTheSpheresInContact)
{
    // Sphere 1 aimed roughly at sphere 2: at every reported time the centres are r₁ + r₂
    // apart. The check recomputes positions in plain double: error ~1e-15 of the 10 m
    // scene, so 1e-12 m.
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> u(-10.0, 10.0);
    std::uniform_real_distribution<double> jitter(-1.0, 1.0);
    std::uniform_real_distribution<double> radius(0.1, 2.0);
    int hits = 0;
    int misses = 0;
    for (int i = 0; i < 2000; ++i) {
        vec3 const x1(u(rng), u(rng), u(rng)), x2(u(rng), u(rng), u(rng));
        vec3 const v2(jitter(rng), jitter(rng), jitter(rng));
        vec3 const v1 = 0.5 * (x2 - x1) + 3.0 * vec3(jitter(rng), jitter(rng), jitter(rng));
        double const r1 = radius(rng), r2 = radius(rng);
        auto const t = sphere_time_of_impact(x1, v1, r1, x2, v2, r2, 10.0);
        if (!t) {
            ++misses;
            continue;
        }
        if (*t == 0.0)
            continue;
        ++hits;
        EXPECT_NEAR(((x1 + *t * v1) - (x2 + *t * v2)).norm(), r1 + r2, 1e-12);
        EXPECT_FALSE(spheres_overlap(x1, r1, x2, r2)); // started apart
    }
    EXPECT_GT(hits, 200);
    EXPECT_GT(misses, 200);
}

// ---- contact_point ---------------------------------------------------------------------

TEST(ContactPoint, LiesOnBothSurfacesWithUnequalRadii)
{
    // Radii 1 and 2 m, centres 3 m apart: the point is 1 m from the first centre. (With the
    // weights swapped it would be at x = 2, 2 m from the first and 1 m from the second.)
    EXPECT_EQ(contact_point({0, 0, 0}, 1.0, {3, 0, 0}, 2.0), vec3(1, 0, 0));
}

TEST(ContactPoint, LiesOnBothSurfacesAtTimeOfImpact)
{
    // Moving spheres in a random direction: at the time of impact the contact point is r₁
    // from centre 1 and r₂ from centre 2 (1e-12 m: plain double on a 10 m scene).
    std::mt19937_64 rng(8);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (int i = 0; i < 100; ++i) {
        vec3 const direction = vec3(u(rng), u(rng), u(rng)).normalized();
        vec3 const x1(1, 2, 3), v1 = 4.0 * direction;
        vec3 const x2 = x1 + 8.0 * direction + vec3(0.3 * u(rng), 0.3 * u(rng), 0.3 * u(rng));
        double const r1 = 0.7, r2 = 1.9;
        auto const t = sphere_time_of_impact(x1, v1, r1, x2, still, r2, 10.0);
        ASSERT_TRUE(t);
        vec3 const c1 = x1 + *t * v1;
        vec3 const c2 = x2;
        vec3 const p = contact_point(c1, r1, c2, r2);
        EXPECT_NEAR((p - c1).norm(), r1, 1e-12);
        EXPECT_NEAR((p - c2).norm(), r2, 1e-12);
    }
}

TEST(ContactPoint, TwoPointsGiveTheMidpoint)
{
    EXPECT_EQ(contact_point({0, 0, 0}, 0.0, {2, 4, -6}, 0.0), vec3(1, 2, -3));
}

// ---- make_plane ------------------------------------------------------------------------

TEST(MakePlane, NormalisesAndKeepsTheSameWall)
{
    plane const wall = make_plane({0, 0, 2}, 4.0); // 2z = 4, i.e. z = 2
    EXPECT_EQ(wall.normal, vec3(0, 0, 1));
    EXPECT_EQ(wall.offset, 2.0);
    plane const tilted = make_plane({3, 4, 0}, 10.0); // 3x + 4y = 10
    EXPECT_NEAR(tilted.normal.norm(), 1.0, ulps(1.0, 2));
    EXPECT_NEAR(tilted.normal.dot(vec3(2, 1, 0)), tilted.offset, ulps(2.0, 4)); // on the wall
}

TEST(MakePlane, RejectsZeroAndNonFiniteNormals)
{
    EXPECT_THROW(make_plane({0, 0, 0}, 1.0), std::invalid_argument);
    EXPECT_THROW(make_plane({NAN, 0, 1}, 1.0), std::invalid_argument);
    EXPECT_THROW(make_plane({INFINITY, 0, 0}, 1.0), std::invalid_argument);
    EXPECT_THROW(make_plane({0, 0, 1}, INFINITY), std::invalid_argument);
    EXPECT_NO_THROW(make_plane({1e300, 1e300, 0}, 1.0)); // huge but finite: no overflow
}

// ---- plane_time_of_impact --------------------------------------------------------------

TEST(PlaneTimeOfImpact, StraightLineHitsAtGapOverNormalSpeed)
{
    // Radius 0.5 m at height 10.5 m: gap 10 m, falling at 2 m/s (and drifting sideways).
    auto const t = plane_time_of_impact(floor_plane, 0.5, {1, 2, 10.5}, {3, 0, -2}, still, 10.0);
    ASSERT_TRUE(t);
    EXPECT_NEAR(*t, 5.0, ulps(5.0, 4));
}

TEST(PlaneTimeOfImpact, NonUnitNormalMeansTheSameWall)
{
    // {n·x = d} with n = (0, 0, 2), d = 0 is the floor; the lecture's d + r‖n‖ handles it.
    plane const scaled{vec3(0, 0, 2), 0.0};
    auto const t = plane_time_of_impact(scaled, 0.5, {1, 2, 10.5}, {3, 0, -2}, still, 10.0);
    ASSERT_TRUE(t);
    EXPECT_NEAR(*t, 5.0, ulps(5.0, 4));
}

TEST(PlaneTimeOfImpact, ThrownBallHitsTheFloorAtTheQuadraticFormulaTime)
{
    // Thrown from 2 m at 5 m/s upwards (and 3 m/s sideways), radius 0.1 m: the centre
    // reaches 0.1 m when 1.9 + 5 t − g t²/2 = 0, t = (5 + √(25 + 2 g · 1.9)) / g.
    double const g = 9.81;
    double const expected = (5.0 + std::sqrt(25.0 + 2.0 * g * 1.9)) / g;
    auto const t = plane_time_of_impact(floor_plane, 0.1, {0, 0, 2}, {3, 0, 5}, gravity, 10.0);
    ASSERT_TRUE(t);
    // Both sides round 2 − 0.1 and g·1.9 differently: 16 ulps.
    EXPECT_NEAR(*t, expected, ulps(expected, 16));
}

TEST(PlaneTimeOfImpact, BallDroppedFromRestFallsForRootOfTwoHOverG)
{
    auto const t = plane_time_of_impact(floor_plane, 0.5, {0, 0, 20.5}, still, gravity, 10.0);
    ASSERT_TRUE(t);
    double const expected = std::sqrt(2.0 * 20.0 / 9.81);
    EXPECT_NEAR(*t, expected, ulps(expected, 8));
}

TEST(PlaneTimeOfImpact, MovingAwayIsNone)
{
    EXPECT_FALSE(plane_time_of_impact(floor_plane, 0.5, {0, 0, 3}, {1, 0, 2}, still, 1e6));
    EXPECT_FALSE(plane_time_of_impact(floor_plane, 0.5, {0, 0, 3}, {0, 0, 2}, {0, 0, 1}, 1e6));
    // Parallel to the floor, no acceleration.
    EXPECT_FALSE(plane_time_of_impact(floor_plane, 0.5, {0, 0, 3}, {1, 0, 0}, still, 1e6));
}

TEST(PlaneTimeOfImpact, ImpactAfterTMaxIsNone)
{
    EXPECT_FALSE(plane_time_of_impact(floor_plane, 0.5, {1, 2, 10.5}, {3, 0, -2}, still, 4.99));
    EXPECT_TRUE(plane_time_of_impact(floor_plane, 0.5, {1, 2, 10.5}, {3, 0, -2}, still, 5.0));
}

TEST(PlaneTimeOfImpact, RestingOnThePlane)
{
    vec3 const resting(0, 0, 0.5); // radius 0.5 m, touching the floor
    // At rest, no force: nothing happens.
    EXPECT_FALSE(plane_time_of_impact(floor_plane, 0.5, resting, still, still, 10.0));
    // Sliding along it: nothing happens.
    EXPECT_FALSE(plane_time_of_impact(floor_plane, 0.5, resting, {2, 0, 0}, still, 10.0));
    // At rest under gravity: pressed into the floor now.
    EXPECT_EQ(plane_time_of_impact(floor_plane, 0.5, resting, still, gravity, 10.0), 0.0);
    // At rest, pulled upwards: lifts off, no impact.
    EXPECT_FALSE(plane_time_of_impact(floor_plane, 0.5, resting, still, {0, 0, 1}, 10.0));
    // Moving into it: impact now.
    EXPECT_EQ(plane_time_of_impact(floor_plane, 0.5, resting, {0, 0, -1}, still, 10.0), 0.0);
}

TEST(PlaneTimeOfImpact, BounceFromTheFloorComesBackAfterTwoVOverG)
{
    // Leaving the floor at 4.905 m/s under g = 9.81: back after exactly 1 s; the contact at
    // t = 0 is a departure, not an impact.
    auto const t =
        plane_time_of_impact(floor_plane, 0.5, {0, 0, 0.5}, {0, 0, 4.905}, gravity, 10.0);
    ASSERT_TRUE(t);
    EXPECT_NEAR(*t, 1.0, ulps(1.0, 4));
}

TEST(PlaneTimeOfImpact, PenetratingCases)
{
    vec3 const inside(0, 0, 0.3); // radius 0.5 m: 0.2 m deep
    EXPECT_EQ(plane_time_of_impact(floor_plane, 0.5, inside, {0, 0, -1}, still, 1.0), 0.0);
    EXPECT_EQ(plane_time_of_impact(floor_plane, 0.5, inside, still, gravity, 1.0), 0.0);
    EXPECT_FALSE(plane_time_of_impact(floor_plane, 0.5, inside, {0, 0, 1}, still, 1.0));
    // Leaving upwards at 2 m/s under gravity: the gap −0.2 + 2 t − g t²/2 is zero on the way
    // out (~0.11 s) and again on the way back in, at t = (2 + √(4 − 2 g · 0.2)) / g.
    auto const t = plane_time_of_impact(floor_plane, 0.5, inside, {0, 0, 2}, gravity, 1.0);
    ASSERT_TRUE(t);
    double const expected = (2.0 + std::sqrt(4.0 - 2.0 * 9.81 * 0.2)) / 9.81;
    // 0.3 − 0.5 and 2·g·0.2 round differently on each side: 64 ulps (~1e-14 s).
    EXPECT_NEAR(*t, expected, ulps(expected, 64));
}

TEST(PlaneTimeOfImpact, GrazingParabolaCounts)
{
    // Gap 1 m, falling at 2 m/s, pushed up at 2 m/s²: gap(t) = 1 − 2t + t² = (t − 1)², which
    // touches zero at t = 1 with zero normal speed. A slightly larger gap misses.
    auto const t = plane_time_of_impact(floor_plane, 0.5, {0, 0, 1.5}, {0, 0, -2}, {0, 0, 2}, 5.0);
    ASSERT_TRUE(t);
    EXPECT_EQ(*t, 1.0);
    EXPECT_FALSE(plane_time_of_impact(floor_plane, 0.5, {0, 0, 1.5001}, {0, 0, -2}, {0, 0, 2}, 5.0));
}

TEST(PlaneTimeOfImpact, TinyAccelerationBehavesLikeAStraightLine)
{
    // n·a/2 = −5e-21 against a 10 m gap closed at 2 m/s: the straight-line answer 5 s moves by
    // ~6e-19 s. The textbook root (−B − √(B² − 4AC)) / 2A would divide roundoff by 1e-20.
    auto const t = plane_time_of_impact(floor_plane, 0.5, {0, 0, 10.5}, {0, 0, -2},
                                        {0, 0, -1e-20}, 10.0);
    ASSERT_TRUE(t);
    EXPECT_NEAR(*t, 5.0, ulps(5.0, 4));
}

TEST(PlaneTimeOfImpact, AgreesWithTheLinearCaseOnATiltedWall)
{
    // Wall 3x + 4y = 10, i.e. n = (0.6, 0.8, 0), d = 2. A sphere of radius 0.25 m whose
    // centre is 2.4 m beyond contact (n·x = 2 + 0.25 + 2.4) moves along −n at 1 m/s: t = 2.4 s.
    plane const wall = make_plane({3, 4, 0}, 10.0);
    vec3 const x = wall.normal * (2.0 + 0.25 + 2.4) + vec3(0, 0, 7); // offset 2, radius 0.25
    auto const t = plane_time_of_impact(wall, 0.25, x, -wall.normal, still, 10.0);
    ASSERT_TRUE(t);
    // The normal is not exact in binary (0.6, 0.8): 16 ulps.
    EXPECT_NEAR(*t, 2.4, ulps(2.4, 16));
}

// ---- plane_contact_time_linear ---------------------------------------------------------

TEST(PlaneContactTimeLinear, MatchesTheLectureFormula)
{
    // Non-unit normal on purpose: the lecture's formula uses d + r‖n‖.
    plane const wall{vec3(1, 2, 2), 3.0}; // ‖n‖ = 3
    double const r = 0.4;
    vec3 const x_i(1, 1, 2), x_next(0.2, -0.5, 0.1);
    double const t_i = 3.0, t_next = 3.25;
    double const s_i = wall.normal.dot(x_i), s_next = wall.normal.dot(x_next);
    double const contact = wall.offset + r * wall.normal.norm();
    ASSERT_GT(s_i, contact);     // precondition: clear at t_i
    ASSERT_LE(s_next, contact);  // and touching or inside at t_{i+1}
    double const lecture = (contact - s_next) / (s_i - s_next) * t_i +
                           (s_i - contact) / (s_i - s_next) * t_next;
    double const t = plane_contact_time_linear(wall, r, x_i, t_i, x_next, t_next);
    EXPECT_NEAR(t, lecture, ulps(t_next, 4)); // two equivalent forms: a few ulps of t
    EXPECT_GE(t, t_i);
    EXPECT_LE(t, t_next);
}

TEST(PlaneContactTimeLinear, IsExactForStraightLineMotion)
{
    // On a straight line at constant speed, interpolation between the two steps finds the
    // same time as the exact solver.
    vec3 const x0(0.3, -1, 4), v(1, 2, -3);
    double const t_i = 1.0, t_next = 1.5, radius = 0.2;
    vec3 const x_i = x0 + t_i * v, x_next = x0 + t_next * v;
    auto const exact = plane_time_of_impact(floor_plane, radius, x0, v, still, 10.0);
    ASSERT_TRUE(exact);
    ASSERT_GT(*exact, t_i);
    ASSERT_LT(*exact, t_next);
    double const t = plane_contact_time_linear(floor_plane, radius, x_i, t_i, x_next, t_next);
    // (4 − 0.2) / 3 = 1.2666… s; the positions carry roundings of their own: 8 ulps.
    EXPECT_NEAR(t, *exact, ulps(*exact, 8));
    EXPECT_NEAR(t, 3.8 / 3.0, ulps(1.27, 8));
}

TEST(PlaneContactTimeLinear, NoMotionAlongTheNormalReturnsTi)
{
    EXPECT_EQ(plane_contact_time_linear(floor_plane, 0.5, {0, 0, 0.2}, 2.0, {5, 0, 0.2}, 3.0), 2.0);
}

TEST(PlaneContactTimeLinear, EndsOfTheIntervalAreHitExactly)
{
    // Touching exactly at t_{i+1}: the result is t_{i+1}.
    EXPECT_EQ(plane_contact_time_linear(floor_plane, 0.5, {0, 0, 1.5}, 2.0, {0, 0, 0.5}, 3.0), 3.0);
}

} // namespace
} // namespace kugel::physics
