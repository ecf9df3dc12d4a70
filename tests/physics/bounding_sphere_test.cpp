#include "physics/bounding_sphere.hpp"
#include "support/random_source.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <gtest/gtest.h>
#include <numbers>
#include <optional>
#include <random>
#include <vector>

namespace kugel::physics {
namespace {

using test_support::random_source;

/// Every point p has (p − centre).norm() <= radius·(1 + 1e-14). Both functions guarantee the
/// comparison without slack for their own evaluation of the distance; 1e-14 (~50 ulps) only
/// allows for this test's evaluation being compiled differently.
void expect_contains_all(sphere const& s, std::vector<vec3> const& points)
{
    for (vec3 const& p : points)
        ASSERT_LE((p - s.centre).norm(), s.radius * (1.0 + 1e-14)) << "point " << p.transpose();
}

// --- A brute-force minimum, independent of the implementation under test -------------------

/// Circumcircle of a triangle from the closed form
///   centre = a + ((|u|²v − |v|²u) × (u×v)) / (2|u×v|²);  nothing when collinear.
std::optional<sphere> circumcircle(vec3 const& a, vec3 const& b, vec3 const& c)
{
    vec3 const u = b - a;
    vec3 const v = c - a;
    vec3 const n = u.cross(v);
    if (n.squaredNorm() <= 1e-24 * u.squaredNorm() * v.squaredNorm())
        return std::nullopt;
    vec3 const offset =
        (u.squaredNorm() * v - v.squaredNorm() * u).cross(n) / (2.0 * n.squaredNorm());
    return sphere{a + offset, offset.norm()};
}

/// Circumsphere of a tetrahedron from Cramer's rule:
///   centre = a + (|u|²(v×w) + |v|²(w×u) + |w|²(u×v)) / (2·u·(v×w));  nothing when coplanar.
std::optional<sphere> circumsphere(vec3 const& a, vec3 const& b, vec3 const& c, vec3 const& d)
{
    vec3 const u = b - a;
    vec3 const v = c - a;
    vec3 const w = d - a;
    double const det = u.dot(v.cross(w));
    if (std::abs(det) <= 1e-12 * u.norm() * v.norm() * w.norm())
        return std::nullopt;
    vec3 const offset = (u.squaredNorm() * v.cross(w) + v.squaredNorm() * w.cross(u) +
                         w.squaredNorm() * u.cross(v)) /
                        (2.0 * det);
    return sphere{a + offset, offset.norm()};
}

/// The minimum enclosing sphere is the circumsphere of its support set of 1 to 4 points, so the
/// smallest of all circumspheres of 1, 2, 3 and 4 points that holds every point is the minimum.
/// "Holds" allows 1e-12 relative plus 1e-14 absolute for the candidates' own rounding (the sets
/// have coordinates of order 1): a candidate accepted this way is at most 1e-12 relative smaller
/// than the true minimum, far inside the 1e-9 the comparisons below use.
sphere brute_force_minimum(std::vector<vec3> const& p)
{
    std::vector<sphere> candidates;
    std::size_t const n = p.size();
    for (std::size_t a = 0; a < n; ++a) {
        candidates.push_back({p[a], 0.0});
        for (std::size_t b = a + 1; b < n; ++b) {
            candidates.push_back({0.5 * (p[a] + p[b]), 0.5 * (p[b] - p[a]).norm()});
            for (std::size_t c = b + 1; c < n; ++c) {
                if (auto const s = circumcircle(p[a], p[b], p[c]))
                    candidates.push_back(*s);
                for (std::size_t d = c + 1; d < n; ++d) {
                    if (auto const s4 = circumsphere(p[a], p[b], p[c], p[d]))
                        candidates.push_back(*s4);
                }
            }
        }
    }
    std::optional<sphere> best;
    for (sphere const& s : candidates) {
        bool const holds_all = std::all_of(p.begin(), p.end(), [&](vec3 const& q) {
            return (q - s.centre).norm() <= s.radius * (1.0 + 1e-12) + 1e-14;
        });
        if (holds_all && (!best || s.radius < best->radius))
            best = s;
    }
    return *best;
}

/// Welzl against the brute force. Radii agree to 1e-9 relative: Welzl is within ~2e-10 of the
/// minimum (its documented inside tolerance), the brute force within 1e-12. Two enclosing
/// spheres of radii R and R(1 + δ) have centres at most 2R·√(2δ + δ²) apart (both contain the
/// minimum sphere's support), which for δ = 1e-9 is 9e-5·R; the centres are compared to 1e-4·R.
void expect_equals_brute_force(std::vector<vec3> const& points)
{
    sphere const welzl = minimum_bounding_sphere(points);
    sphere const brute = brute_force_minimum(points);
    expect_contains_all(welzl, points);
    double const scale = std::max(brute.radius, 1e-300);
    EXPECT_NEAR(welzl.radius, brute.radius, 1e-9 * scale);
    EXPECT_LE((welzl.centre - brute.centre).norm(), 1e-4 * scale);
}

TEST(MinimumBoundingSphere, EqualsBruteForceOnSmallSets)
{
    random_source random(1);
    for (int set = 0; set < 2000; ++set) {
        std::size_t const n = 2 + random.below(7); // 2..8 points
        std::vector<vec3> points;
        for (std::size_t i = 0; i < n; ++i)
            points.push_back(random.in_cube(1.0));
        SCOPED_TRACE(set);
        expect_equals_brute_force(points);
    }
}

TEST(MinimumBoundingSphere, EqualsBruteForceOnCosphericalSets)
{
    // Points on one sphere: many near-ties between candidate supports.
    random_source random(2);
    for (int set = 0; set < 500; ++set) {
        std::size_t const n = 3 + random.below(6); // 3..8 points
        vec3 const centre = random.in_cube(2.0);
        std::vector<vec3> points;
        for (std::size_t i = 0; i < n; ++i)
            points.push_back(centre + random.on_sphere(1.5));
        SCOPED_TRACE(set);
        expect_equals_brute_force(points);
    }
}

TEST(MinimumBoundingSphere, EqualsBruteForceOnCoplanarSets)
{
    // A tilted plane, so the points are coplanar only up to rounding.
    random_source random(3);
    for (int set = 0; set < 500; ++set) {
        Eigen::Matrix3d const frame = random.rotation();
        vec3 const origin = random.in_cube(1.0);
        std::size_t const n = 4 + random.below(5); // 4..8 points
        std::vector<vec3> points;
        for (std::size_t i = 0; i < n; ++i)
            points.push_back(origin + frame.col(0) * random.uniform(-1, 1) +
                             frame.col(1) * random.uniform(-1, 1));
        SCOPED_TRACE(set);
        expect_equals_brute_force(points);
    }
}

TEST(MinimumBoundingSphere, NeverLargerThanTheApproximation)
{
    // The approximation holds every point, so it is at least the minimum; Welzl is within ~2e-10
    // of the minimum, hence 1e-9 relative slack.
    random_source random(4);
    for (int set = 0; set < 300; ++set) {
        std::size_t const n = 2 + random.below(400);
        vec3 const stretch(random.uniform(0.1, 3), random.uniform(0.1, 3), random.uniform(0.1, 3));
        Eigen::Matrix3d const turn = random.rotation();
        std::vector<vec3> points;
        for (std::size_t i = 0; i < n; ++i)
            points.push_back(turn * random.in_ball(1.0).cwiseProduct(stretch));
        sphere const approx = approximate_bounding_sphere(points);
        sphere const welzl = minimum_bounding_sphere(points);
        SCOPED_TRACE(set);
        expect_contains_all(approx, points);
        expect_contains_all(welzl, points);
        EXPECT_LE(welzl.radius, approx.radius * (1.0 + 1e-9));
    }
}

// Points given in two spans (a cloud where it is, and a few corners) are one list, the first's
// then the second's: the sphere is the same bit for bit as that of one span holding both,
// wherever the split falls (empty parts included).
TEST(MinimumBoundingSphere, TwoSpansAreOneList)
{
    random_source random(5);
    std::vector<vec3> points;
    for (int i = 0; i < 200; ++i)
        points.push_back(random.in_ball(1.0) + vec3(3.0, -2.0, 1.0));
    sphere const whole = minimum_bounding_sphere(points);
    std::span<vec3 const> const all(points);
    for (std::size_t const split : {0UL, 1UL, 117UL, 199UL, 200UL}) {
        sphere const parts = minimum_bounding_sphere(all.first(split), all.subspan(split));
        SCOPED_TRACE(split);
        EXPECT_EQ(parts.centre, whole.centre);
        EXPECT_EQ(parts.radius, whole.radius);
    }
    expect_contains_all(whole, points);
}

TEST(BoundingSpheres, EmptyInputGivesRadiusZeroAtOrigin)
{
    for (sphere const& s : {minimum_bounding_sphere({}), approximate_bounding_sphere({})}) {
        EXPECT_EQ(s.centre, vec3::Zero());
        EXPECT_EQ(s.radius, 0.0);
    }
}

TEST(BoundingSpheres, OnePointOrCopiesOfItGiveRadiusZeroAtThePoint)
{
    vec3 const p(1.25, -7.5, 3.0e5);
    for (std::size_t copies : {1u, 2u, 1000u}) {
        std::vector<vec3> const points(copies, p);
        for (sphere const& s :
             {minimum_bounding_sphere(points), approximate_bounding_sphere(points)}) {
            EXPECT_EQ(s.centre, p) << copies;
            EXPECT_EQ(s.radius, 0.0) << copies;
        }
    }
}

TEST(MinimumBoundingSphere, RepeatedPairGivesTheDiametralSphere)
{
    vec3 const a(1, 2, 3);
    vec3 const b(4, -2, 3); // |b − a| = 5
    std::vector<vec3> points;
    for (int i = 0; i < 50; ++i) {
        points.push_back(a);
        points.push_back(b);
    }
    sphere const s = minimum_bounding_sphere(points);
    // A single midpoint and half-length: a few ulps.
    EXPECT_NEAR(s.radius, 2.5, 1e-14);
    EXPECT_LE((s.centre - vec3(2.5, 0, 3)).norm(), 1e-14);
}

TEST(MinimumBoundingSphere, CollinearPointsGiveTheSegmentsMidpoint)
{
    random_source random(5);
    vec3 const start(0.3, -1.2, 2.0);
    vec3 const direction = vec3(1, 2, -2) / 3.0;
    std::vector<vec3> points{start - 2.0 * direction, start + 5.0 * direction};
    for (int i = 0; i < 2000; ++i)
        points.push_back(start + random.uniform(-2, 5) * direction);
    std::shuffle(points.begin(), points.end(), std::mt19937_64(6));
    for (sphere const& s : {minimum_bounding_sphere(points), approximate_bounding_sphere(points)}) {
        // Segment from t = −2 to t = 5: radius 3.5, centre at t = 1.5. The points themselves
        // carry rounding of a few ulps of their coordinates (~1e-15).
        expect_contains_all(s, points);
        EXPECT_NEAR(s.radius, 3.5, 1e-12);
        EXPECT_LE((s.centre - (start + 1.5 * direction)).norm(), 1e-12);
    }
}

TEST(MinimumBoundingSphere, FourCoplanarPointsOfASquare)
{
    // Four coplanar, cocircular points: no unique circumsphere of all four; the answer is their
    // circle, radius half the diagonal.
    Eigen::Matrix3d const turn = random_source(7).rotation();
    vec3 const centre(3, -1, 2);
    std::vector<vec3> points;
    for (vec3 const& corner : {vec3(1, 1, 0), vec3(-1, 1, 0), vec3(-1, -1, 0), vec3(1, -1, 0)})
        points.push_back(centre + turn * corner);
    sphere const s = minimum_bounding_sphere(points);
    expect_contains_all(s, points);
    EXPECT_NEAR(s.radius, std::sqrt(2.0), 1e-12);
    EXPECT_LE((s.centre - centre).norm(), 1e-12);
}

TEST(MinimumBoundingSphere, CocircularPolygonGivesItsCircle)
{
    Eigen::Matrix3d const turn = random_source(8).rotation();
    vec3 const centre(-2, 0.5, 1);
    std::vector<vec3> points;
    for (int k = 0; k < 36; ++k) {
        double const angle = 2.0 * std::numbers::pi * k / 36.0;
        points.push_back(centre + turn * vec3(2.0 * std::cos(angle), 2.0 * std::sin(angle), 0.0));
    }
    sphere const s = minimum_bounding_sphere(points);
    expect_contains_all(s, points);
    EXPECT_NEAR(s.radius, 2.0, 1e-12);
    EXPECT_LE((s.centre - centre).norm(), 1e-12);
}

TEST(MinimumBoundingSphere, LatticeOfACubeGivesItsCircumsphere)
{
    // 11³ lattice points: thousands of coplanar and cospherical subsets. The eight corners are
    // the farthest points, so the answer is the cube's circumsphere, radius √3 (half side 1).
    // First axis-aligned (exactly coplanar subsets), then turned and moved at random (coplanar
    // only up to rounding).
    random_source random(14);
    for (int trial = 0; trial < 6; ++trial) {
        Eigen::Matrix3d const turn = trial == 0 ? Eigen::Matrix3d::Identity() : random.rotation();
        vec3 const centre = trial == 0 ? vec3(2, -4, 6) : random.in_cube(100.0);
        std::vector<vec3> points;
        for (int x = -5; x <= 5; ++x)
            for (int y = -5; y <= 5; ++y)
                for (int z = -5; z <= 5; ++z)
                    points.push_back(centre + turn * (vec3(x, y, z) / 5.0));
        sphere const s = minimum_bounding_sphere(points);
        SCOPED_TRACE(trial);
        expect_contains_all(s, points);
        // Coordinates up to ~100 are rounded by ~1e-14; 1e-12 covers that with room.
        EXPECT_NEAR(s.radius, std::sqrt(3.0), 1e-12);
        // Opposite corners c ± p: a sphere of radius R(1 + δ) holding both has its centre
        // within R·√(2δ + δ²) of c; δ = 1e-12/√3 gives 2.5e-6 with R = √3.
        EXPECT_LE((s.centre - centre).norm(), 2.5e-6);
    }
}

TEST(MinimumBoundingSphere, CosphericalCloudGivesItsSphere)
{
    // 20000 points on one sphere of radius 2, plus its six axis points, which force the
    // minimum to be that sphere. Every four points have the same circumsphere, so nearly every
    // point lies on the current sphere to within rounding when it is tested.
    random_source random(15);
    vec3 const centre = random.in_cube(100.0);
    std::vector<vec3> points;
    for (Eigen::Index axis = 0; axis < 3; ++axis) {
        points.push_back(centre + 2.0 * vec3::Unit(axis));
        points.push_back(centre - 2.0 * vec3::Unit(axis));
    }
    for (int i = 0; i < 20000; ++i)
        points.push_back(centre + random.on_sphere(2.0));
    std::shuffle(points.begin(), points.end(), std::mt19937_64(16));
    sphere const s = minimum_bounding_sphere(points);
    expect_contains_all(s, points);
    // The points are on the sphere to the rounding of coordinates ~100 (~1e-14); Welzl adds at
    // most ~2e-10 relative: 1e-9 relative.
    EXPECT_NEAR(s.radius, 2.0, 2e-9);
    // As for the lattice: the axis pairs put the centre within R·√(2δ + δ²), 9e-5 for δ = 1e-9.
    EXPECT_LE((s.centre - centre).norm(), 9e-5);
}

TEST(MinimumBoundingSphere, IndependentOfInputOrder)
{
    random_source random(9);
    std::vector<vec3> points;
    for (int i = 0; i < 5000; ++i)
        points.push_back(random.in_cube(1.0));
    sphere const first = minimum_bounding_sphere(points);
    std::shuffle(points.begin(), points.end(), std::mt19937_64(10));
    sphere const second = minimum_bounding_sphere(points);
    // Both are within ~2e-10 of the same minimum.
    EXPECT_NEAR(first.radius, second.radius, 1e-9 * first.radius);
}

TEST(MinimumBoundingSphere, KeepsPrecisionFarFromTheOrigin)
{
    // The same cloud of size ~1 at the origin and moved by ~3e4: the moved coordinates are
    // rounded by 3e4·2⁻⁵³ ≈ 4e-12, so the radii agree to 1e-10, and not to the ~1e-7 a
    // computation at the scale of the coordinates might lose near degenerate supports.
    random_source random(11);
    vec3 const offset(1e4, -2e4, 3e4);
    std::vector<vec3> near;
    std::vector<vec3> far;
    for (int i = 0; i < 3000; ++i) {
        near.push_back(random.in_ball(1.0));
        far.push_back(near.back() + offset);
    }
    sphere const a = minimum_bounding_sphere(near);
    sphere const b = minimum_bounding_sphere(far);
    expect_contains_all(b, far);
    EXPECT_NEAR(a.radius, b.radius, 1e-10);
    // Radii within 1e-10 of one minimum R <= 1 put the centres within 2R·√(2e-10) ≈ 3e-5.
    EXPECT_LE((b.centre - offset - a.centre).norm(), 3e-5);
}

TEST(MinimumBoundingSphere, MillionPointsWithKnownAnswer)
{
    // The six axis points of the unit sphere force radius 1 at the origin (each antipodal pair
    // is a diameter); a million random points strictly inside the ball change nothing. Their
    // order is shuffled so the axis points are not found first.
    random_source random(12);
    std::vector<vec3> points;
    points.reserve(1'000'000);
    for (Eigen::Index axis = 0; axis < 3; ++axis) {
        points.push_back(vec3::Unit(axis));
        points.push_back(-vec3::Unit(axis));
    }
    while (points.size() < 1'000'000)
        points.push_back(random.in_ball(1.0));
    std::shuffle(points.begin(), points.end(), std::mt19937_64(13));

    sphere const s = minimum_bounding_sphere(points);
    expect_contains_all(s, points);
    // Radius: the exact answer is 1; Welzl is within ~2e-10 of it.
    EXPECT_NEAR(s.radius, 1.0, 1e-9);
    // Centre: holding ±e_x, ±e_y, ±e_z with radius 1 + δ puts the centre within √(2δ + δ²) of
    // the origin, 4.5e-5 for δ = 1e-9.
    EXPECT_LE(s.centre.norm(), 4.5e-5);

    sphere const approx = approximate_bounding_sphere(points);
    expect_contains_all(approx, points);
    EXPECT_GE(approx.radius, 1.0);
}

TEST(ApproximateBoundingSphere, FollowsTheLecturesSteps)
{
    // x: P_x,min = (−2, 0, 0), P_x,max = (2, 0, 0), 4 apart; y: (−2, 0, 0) and (0, 3, 0),
    // √13 apart; z: all 0. The initial sphere is on the x pair: centre 0, radius 2. (0, 3, 0)
    // lies at d = 3: radius (2 + 3)/2 = 2.5, centre moved 0.5 towards it. (0, 0.5, 0) is then
    // inside. Every step is exact in binary, so the comparison is exact.
    std::vector<vec3> const points{{-2, 0, 0}, {2, 0, 0}, {0, 0.5, 0}, {0, 3, 0}};
    sphere const approx = approximate_bounding_sphere(points);
    EXPECT_EQ(approx.centre, vec3(0, 0.5, 0));
    EXPECT_EQ(approx.radius, 2.5);

    // The minimum is the circle through (±2, 0, 0) and (0, 3, 0): centre (0, y, 0) with
    // 4 + y² = (3 − y)², y = 5/6, radius 13/6; rounding of a few ulps.
    sphere const minimum = minimum_bounding_sphere(points);
    EXPECT_NEAR(minimum.radius, 13.0 / 6.0, 1e-14);
    EXPECT_LE((minimum.centre - vec3(0, 5.0 / 6.0, 0)).norm(), 1e-14);
}

TEST(ApproximateBoundingSphere, InitialSphereIsOnTheWidestAxisPair)
{
    // The z pair, 10 apart, is the widest; every other point lies inside its sphere, so the
    // result is exactly the initial sphere (lecture: centre (P_min + P_max)/2, radius half the
    // distance).
    std::vector<vec3> const points{{1, 1, -5}, {-3, 0, 0}, {3, 0, 0}, {0, 4, 0}, {1, 1, 5}};
    sphere const s = approximate_bounding_sphere(points);
    EXPECT_EQ(s.centre, vec3(1, 1, 0));
    EXPECT_EQ(s.radius, 5.0);
}

} // namespace
} // namespace kugel::physics
