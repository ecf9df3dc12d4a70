#include "physics/obb.hpp"
#include "support/random_source.hpp"

#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <cstdint>
#include <gtest/gtest.h>
#include <limits>
#include <numbers>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

namespace kugel::physics {
namespace {

using test_support::random_source;

Eigen::Matrix3d rotation_about(vec3 const& axis, double angle)
{
    return Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
}

/// Orthonormal and right-handed. A frame built in double is orthonormal to a few ulps (~1e-16);
/// 1e-12 leaves room for that and still catches any wrong frame, which is off by O(1).
void expect_valid_frame(Eigen::Matrix3d const& axes)
{
    EXPECT_LE((axes.transpose() * axes - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_NEAR(axes.determinant(), 1.0, 1e-12);
}

/// Every point inside the box, allowing `slack` (m) for rounding.
void expect_inside(obb const& box, std::vector<vec3> const& points, double slack)
{
    for (vec3 const& p : points) {
        vec3 const local = box.axes.transpose() * (p - box.centre);
        for (Eigen::Index i = 0; i < 3; ++i)
            ASSERT_LE(std::abs(local[i]), box.half_extents[i] + slack) << "point " << p.transpose();
    }
}

bool is_inside(obb const& box, vec3 const& p)
{
    vec3 const local = box.axes.transpose() * (p - box.centre);
    return (local.cwiseAbs().array() <= box.half_extents.array()).all();
}

std::array<vec3, 8> corners(obb const& box)
{
    std::array<vec3, 8> out;
    for (std::size_t k = 0; k < 8; ++k) {
        vec3 const sign((k & 1) ? 1.0 : -1.0, (k & 2) ? 1.0 : -1.0, (k & 4) ? 1.0 : -1.0);
        out[k] = box.centre + box.axes * sign.cwiseProduct(box.half_extents);
    }
    return out;
}

/// Whether the projections of the two boxes' corners on `axis` are disjoint intervals.
bool separates(vec3 const& axis, obb const& a, obb const& b)
{
    auto range = [&](obb const& box) {
        double lo = std::numeric_limits<double>::infinity();
        double hi = -lo;
        for (vec3 const& c : corners(box)) {
            lo = std::min(lo, c.dot(axis));
            hi = std::max(hi, c.dot(axis));
        }
        return std::pair{lo, hi};
    };
    auto const [a_lo, a_hi] = range(a);
    auto const [b_lo, b_hi] = range(b);
    return a_hi < b_lo || b_hi < a_lo;
}

// --- obb_of_points -----------------------------------------------------------------------------

/// Points on the surface of the box [−3, 3] × [−2, 2] × [−1, 1] on a unit grid: the 8 corners,
/// points on every edge and on every face. The set is symmetric under each axis reflection, so
/// its covariance is diagonal in the box's frame, with distinct eigenvalues.
std::vector<vec3> box_surface_grid()
{
    std::vector<vec3> points;
    for (int x = -3; x <= 3; ++x)
        for (int y = -2; y <= 2; ++y)
            for (int z = -1; z <= 1; ++z)
                if (std::abs(x) == 3 || std::abs(y) == 2 || std::abs(z) == 1)
                    points.emplace_back(x, y, z);
    return points;
}

TEST(ObbOfPoints, RecoversTheAxesAndExtentsOfARotatedBox)
{
    random_source random(21);
    for (int trial = 0; trial < 20; ++trial) {
        Eigen::Matrix3d const turn = random.rotation();
        vec3 const centre = random.in_cube(10.0);
        std::vector<vec3> points;
        for (vec3 const& local : box_surface_grid())
            points.push_back(centre + turn * local);

        obb const box = obb_of_points(points);
        SCOPED_TRACE(trial);
        expect_valid_frame(box.axes);
        // Largest eigenvalue first: the axes come out in the order 3, 2, 1. The eigenvectors
        // are accurate to ~ε·|K|/gap ≈ 1e-15 here; 1e-9 is the required accuracy.
        for (Eigen::Index i = 0; i < 3; ++i)
            EXPECT_GT(std::abs(box.axes.col(i).dot(turn.col(i))), 1.0 - 1e-9) << i;
        EXPECT_NEAR(box.half_extents[0], 3.0, 3e-9);
        EXPECT_NEAR(box.half_extents[1], 2.0, 2e-9);
        EXPECT_NEAR(box.half_extents[2], 1.0, 1e-9);
        EXPECT_LE((box.centre - centre).norm(), 1e-9);
        // Coordinates up to ~15: rounding of a projection is ~1e-14.
        expect_inside(box, points, 1e-12);
    }
}

TEST(ObbOfPoints, LargestVarianceAxisComesFirstAndHoldsEveryPoint)
{
    random_source random(22);
    for (int trial = 0; trial < 50; ++trial) {
        Eigen::Matrix3d const turn = random.rotation();
        vec3 const stretch(random.uniform(0.1, 5), random.uniform(0.1, 5), random.uniform(0.1, 5));
        std::vector<vec3> points;
        for (int i = 0; i < 200; ++i)
            points.push_back(turn * random.in_cube(1.0).cwiseProduct(stretch) + vec3(1, 2, 3));

        obb const box = obb_of_points(points);
        SCOPED_TRACE(trial);
        expect_valid_frame(box.axes);
        expect_inside(box, points, 1e-12);
        // The variance of the points along each axis, in decreasing order (up to rounding).
        vec3 mean = vec3::Zero();
        for (vec3 const& p : points)
            mean += p / static_cast<double>(points.size());
        vec3 variance = vec3::Zero();
        for (vec3 const& p : points)
            variance += (box.axes.transpose() * (p - mean)).cwiseAbs2();
        EXPECT_GE(variance[0], variance[1] * (1.0 - 1e-12));
        EXPECT_GE(variance[1], variance[2] * (1.0 - 1e-12));
        // The fit is tight: each face touches a point (up to rounding).
        for (Eigen::Index i = 0; i < 3; ++i) {
            double lo = std::numeric_limits<double>::infinity();
            double hi = -lo;
            for (vec3 const& p : points) {
                double const q = box.axes.col(i).dot(p - box.centre);
                lo = std::min(lo, q);
                hi = std::max(hi, q);
            }
            EXPECT_NEAR(hi, box.half_extents[i], 1e-12);
            EXPECT_NEAR(lo, -box.half_extents[i], 1e-12);
        }
    }
}

TEST(ObbOfPoints, EmptyInputGivesTheEmptyBoxAtTheOrigin)
{
    obb const box = obb_of_points({});
    EXPECT_EQ(box.centre, vec3::Zero());
    EXPECT_EQ(box.axes, Eigen::Matrix3d::Identity());
    EXPECT_EQ(box.half_extents, vec3::Zero());
}

TEST(ObbOfPoints, OnePointOrCopiesOfItGiveAZeroBoxAtThePoint)
{
    vec3 const p(0.1, -2.5, 7.0);
    for (std::size_t copies : {1u, 5u}) {
        std::vector<vec3> const points(copies, p);
        obb const box = obb_of_points(points);
        expect_valid_frame(box.axes);
        // Copies of one point average to it to a few ulps.
        EXPECT_LE((box.centre - p).norm(), 1e-14) << copies;
        EXPECT_LE(box.half_extents.maxCoeff(), 1e-14) << copies;
        expect_inside(box, points, 1e-14);
    }
}

TEST(ObbOfPoints, CollinearPointsGiveASegmentAlongTheirLine)
{
    random_source random(23);
    vec3 const start(1, -1, 2);
    vec3 const direction = vec3(2, -1, 2) / 3.0;
    std::vector<vec3> points{start - 2.0 * direction, start + 5.0 * direction};
    for (int i = 0; i < 100; ++i)
        points.push_back(start + random.uniform(-2, 5) * direction);

    obb const box = obb_of_points(points);
    expect_valid_frame(box.axes);
    // Coordinates ~5: rounding of the line's points and their projections is ~1e-15; 1e-12.
    EXPECT_GT(std::abs(box.axes.col(0).dot(direction)), 1.0 - 1e-12);
    EXPECT_NEAR(box.half_extents[0], 3.5, 1e-12);
    EXPECT_LE(box.half_extents[1], 1e-12);
    EXPECT_LE(box.half_extents[2], 1e-12);
    EXPECT_LE((box.centre - (start + 1.5 * direction)).norm(), 1e-12);
    expect_inside(box, points, 1e-12);
}

TEST(ObbOfPoints, CoplanarPointsGiveAFlatBoxAcrossTheirNormal)
{
    random_source random(24);
    Eigen::Matrix3d const plane = random.rotation();
    std::vector<vec3> points;
    for (int i = 0; i < 300; ++i)
        points.push_back(vec3(4, 0, -1) + plane.col(0) * random.uniform(-3, 3) +
                         plane.col(1) * random.uniform(-1, 1));

    obb const box = obb_of_points(points);
    expect_valid_frame(box.axes);
    // The smallest eigenvalue is 0 (up to rounding): its axis is the plane's normal.
    EXPECT_GT(std::abs(box.axes.col(2).dot(plane.col(2))), 1.0 - 1e-12);
    EXPECT_LE(box.half_extents[2], 1e-12);
    expect_inside(box, points, 1e-12);
}

TEST(ObbOfPoints, CubeCornersWithRepeatedEigenvaluesStillGiveAValidBox)
{
    // A cube's corners have K = 8·I: every frame is an eigenframe. Whatever the solver picks,
    // the frame must be valid and the box must hold the corners; it cannot be wider than the
    // cube's diameter along any axis, so each half extent is at most √3 (half side 1).
    random_source random(25);
    for (int trial = 0; trial < 10; ++trial) {
        Eigen::Matrix3d const turn = trial == 0 ? Eigen::Matrix3d::Identity() : random.rotation();
        std::vector<vec3> points;
        for (vec3 const& c : corners(obb{vec3(1, 2, 3), turn, vec3::Ones()}))
            points.push_back(c);

        obb const box = obb_of_points(points);
        SCOPED_TRACE(trial);
        expect_valid_frame(box.axes);
        expect_inside(box, points, 1e-12);
        EXPECT_LE(box.half_extents.maxCoeff(), std::sqrt(3.0) + 1e-12);
        EXPECT_LE((box.centre - vec3(1, 2, 3)).norm(), std::sqrt(3.0));
    }
}

// --- obb_from_box ------------------------------------------------------------------------------

TEST(ObbFromBox, KeepsAValidBoxAsGiven)
{
    Eigen::Matrix3d const turn = random_source(26).rotation();
    obb const box = obb_from_box(vec3(1, 2, 3), vec3(0.5, 0, 2), turn);
    EXPECT_EQ(box.centre, vec3(1, 2, 3));
    EXPECT_EQ(box.half_extents, vec3(0.5, 0, 2));
    // Re-orthonormalizing an orthonormal matrix moves it by a few ulps.
    EXPECT_LE((box.axes - turn).cwiseAbs().maxCoeff(), 1e-15);
    expect_valid_frame(box.axes);
}

TEST(ObbFromBox, ReorthonormalizesARotationWithinTolerance)
{
    Eigen::Matrix3d turn = random_source(27).rotation();
    turn(0, 1) += 3e-10; // RᵀR − I is now ~3e-10, inside the 1e-9 tolerance
    obb const box = obb_from_box(vec3::Zero(), vec3::Ones(), turn);
    // The result is orthonormal to rounding, not to 3e-10.
    EXPECT_LE((box.axes.transpose() * box.axes - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff(),
              1e-15);
    EXPECT_LE((box.axes - turn).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(ObbFromBox, RejectsBadBoxesWithAClearMessage)
{
    Eigen::Matrix3d const turn = random_source(28).rotation();
    double const nan = std::numeric_limits<double>::quiet_NaN();
    double const inf = std::numeric_limits<double>::infinity();
    auto message_of = [](auto make) -> std::string {
        try {
            make();
        } catch (std::invalid_argument const& e) {
            return e.what();
        }
        return "no exception";
    };
    EXPECT_NE(message_of([&] {
                  obb_from_box(vec3::Zero(), vec3(1, -0.5, 1), turn);
              }).find("half extents"),
              std::string::npos);
    EXPECT_NE(
        message_of([&] { obb_from_box(vec3::Zero(), vec3(1, nan, 1), turn); }).find("half extents"),
        std::string::npos);
    EXPECT_NE(message_of([&] { obb_from_box(vec3(0, inf, 0), vec3::Ones(), turn); }).find("centre"),
              std::string::npos);
    EXPECT_NE(message_of([&] {
                  obb_from_box(vec3::Zero(), vec3::Ones(), 1.000001 * turn);
              }).find("orthonormal"),
              std::string::npos);
    Eigen::Matrix3d sheared = turn;
    sheared.col(1) += 1e-6 * sheared.col(0);
    EXPECT_NE(
        message_of([&] { obb_from_box(vec3::Zero(), vec3::Ones(), sheared); }).find("orthonormal"),
        std::string::npos);
    Eigen::Matrix3d nan_rotation = turn;
    nan_rotation(2, 2) = nan;
    EXPECT_NE(message_of([&] {
                  obb_from_box(vec3::Zero(), vec3::Ones(), nan_rotation);
              }).find("rotation must be finite"),
              std::string::npos);
    EXPECT_NE(
        message_of([&] { obb_from_box(vec3::Zero(), vec3::Ones(), -turn); }).find("reflection"),
        std::string::npos);
}

// --- overlaps ----------------------------------------------------------------------------------

TEST(ObbOverlap, BoxesSharingAPointOverlap)
{
    random_source random(31);
    for (int trial = 0; trial < 2000; ++trial) {
        vec3 const shared = random.in_cube(5.0);
        auto box_around = [&] {
            Eigen::Matrix3d const turn = random.rotation();
            vec3 const h(random.uniform(0.01, 3), random.uniform(0.01, 3), random.uniform(0.01, 3));
            // The shared point strictly inside: local coordinates within 99 % of the extents.
            vec3 const local(h[0] * random.uniform(-0.99, 0.99), h[1] * random.uniform(-0.99, 0.99),
                             h[2] * random.uniform(-0.99, 0.99));
            return obb_from_box(shared - turn * local, h, turn);
        };
        obb const a = box_around();
        obb const b = box_around();
        SCOPED_TRACE(trial);
        ASSERT_TRUE(is_inside(a, shared) && is_inside(b, shared));
        EXPECT_TRUE(overlaps(a, b));
        EXPECT_TRUE(overlaps(b, a));
        EXPECT_TRUE(overlaps(aabb_of(a), aabb_of(b)));
    }
}

TEST(ObbOverlap, BoxesOnEitherSideOfAPlaneDoNotOverlap)
{
    // Each box is placed so that its support along a random normal n ends gap/2 before the
    // plane n·x = n·base; a separating plane exists, so some one of the 15 axes separates too.
    random_source random(32);
    for (int trial = 0; trial < 2000; ++trial) {
        vec3 const n = random.on_sphere();
        vec3 const base = random.in_cube(5.0);
        double const gap = random.uniform(1e-3, 0.5);
        auto box_on_side = [&](double side) {
            Eigen::Matrix3d const turn = random.rotation();
            vec3 const h(random.uniform(0.01, 3), random.uniform(0.01, 3), random.uniform(0.01, 3));
            double const reach = (turn.transpose() * n).cwiseAbs().dot(h);
            vec3 tangential = random.in_cube(2.0);
            tangential -= n.dot(tangential) * n;
            return obb_from_box(base + side * (reach + 0.5 * gap) * n + tangential, h, turn);
        };
        obb const a = box_on_side(-1.0);
        obb const b = box_on_side(+1.0);
        SCOPED_TRACE(trial);
        EXPECT_FALSE(overlaps(a, b));
        EXPECT_FALSE(overlaps(b, a));
    }
}

/// A: cube of half side 1 turned 45° about z, whose edge at x = √2 runs along z. B: the same
/// cube turned 45° about y, centred at (x_b, 0, 0), whose edge at x = x_b − √2 runs along y.
/// The two edges cross at x_b = 2√2. The whole scene is then moved by a random rigid motion.
std::pair<obb, obb> crossed_edges(double x_b, Eigen::Matrix3d const& motion, vec3 const& shift)
{
    double const quarter = std::numbers::pi / 4.0;
    obb const a =
        obb_from_box(shift, vec3::Ones(), motion * rotation_about(vec3::UnitZ(), quarter));
    obb const b = obb_from_box(shift + motion * vec3(x_b, 0, 0), vec3::Ones(),
                               motion * rotation_about(vec3::UnitY(), quarter));
    return {a, b};
}

TEST(ObbOverlap, SeparatedOnlyByAnEdgeCrossEdgeAxis)
{
    random_source random(33);
    Eigen::Matrix3d const motion = random.rotation();
    vec3 const shift = random.in_cube(3.0);
    double const touching = 2.0 * std::sqrt(2.0);
    for (double gap : {1e-3, 1e-9}) {
        auto const [a, b] = crossed_edges(touching + gap, motion, shift);
        // The construction is what it claims: none of the six face normals separates, the
        // cross product of the two edges (world x before the motion) does.
        for (Eigen::Index i = 0; i < 3; ++i) {
            EXPECT_FALSE(separates(a.axes.col(i), a, b)) << "a axis " << i << " gap " << gap;
            EXPECT_FALSE(separates(b.axes.col(i), a, b)) << "b axis " << i << " gap " << gap;
        }
        EXPECT_TRUE(separates(motion.col(0), a, b)) << gap;
        EXPECT_FALSE(overlaps(a, b)) << gap;
        EXPECT_FALSE(overlaps(b, a)) << gap;
    }
    for (double depth : {1e-3, 1e-9}) {
        auto const [a, b] = crossed_edges(touching - depth, motion, shift);
        // A point on the x axis between the two crossed edges lies in both boxes.
        vec3 const shared = shift + motion * vec3(std::sqrt(2.0) - 0.5 * depth, 0, 0);
        ASSERT_TRUE(is_inside(a, shared) && is_inside(b, shared)) << depth;
        EXPECT_TRUE(overlaps(a, b)) << depth;
        EXPECT_TRUE(overlaps(b, a)) << depth;
    }
}

TEST(ObbOverlap, TouchingBoxesOverlap)
{
    // Face to face, exactly: like the AABB test, touching counts as overlapping.
    obb const a = obb_from_box(vec3::Zero(), vec3::Ones(), Eigen::Matrix3d::Identity());
    EXPECT_TRUE(
        overlaps(a, obb_from_box(vec3(2, 0, 0), vec3::Ones(), Eigen::Matrix3d::Identity())));
    EXPECT_TRUE(
        overlaps(a, obb_from_box(vec3(2, 2, 2), vec3::Ones(), Eigen::Matrix3d::Identity())));
    EXPECT_FALSE(
        overlaps(a, obb_from_box(vec3(2 + 1e-9, 0, 0), vec3::Ones(), Eigen::Matrix3d::Identity())));

    // Turned the same way: the offset along an axis is rounded (~1e-16), far below the
    // parallel epsilon's 1e-12 margin, and a real gap of 1e-9 still separates.
    random_source random(34);
    for (int trial = 0; trial < 100; ++trial) {
        Eigen::Matrix3d const turn = random.rotation();
        vec3 const h(random.uniform(0.1, 2), random.uniform(0.1, 2), random.uniform(0.1, 2));
        vec3 const centre = random.in_cube(3.0);
        obb const p = obb_from_box(centre, h, turn);
        Eigen::Index const axis = trial % 3;
        vec3 const along = turn.col(axis) * (2.0 * h[axis]);
        SCOPED_TRACE(trial);
        EXPECT_TRUE(overlaps(p, obb_from_box(centre + along, h, turn)));
        EXPECT_FALSE(overlaps(p, obb_from_box(centre + along + 1e-9 * turn.col(axis), h, turn)));
    }
}

TEST(ObbOverlap, ParallelBoxesMatchTheIntervalRule)
{
    // Boxes with the same axes are AABBs in their common frame: they overlap exactly when
    // |tᵢ| <= ha_i + hb_i on every axis. Here the nine cross products include null vectors,
    // the case the parallel epsilon is for. Offsets within 1e-9 of the boundary are skipped.
    random_source random(35);
    int overlapping = 0;
    for (int trial = 0; trial < 3000; ++trial) {
        Eigen::Matrix3d const turn = random.rotation();
        vec3 const ha(random.uniform(0.1, 2), random.uniform(0.1, 2), random.uniform(0.1, 2));
        vec3 const hb(random.uniform(0.1, 2), random.uniform(0.1, 2), random.uniform(0.1, 2));
        vec3 const t = random.in_cube(4.0);
        vec3 const margin = (ha + hb) - t.cwiseAbs();
        if (margin.cwiseAbs().minCoeff() < 1e-9)
            continue;
        bool const expected = (margin.array() >= 0.0).all();
        overlapping += expected ? 1 : 0;
        vec3 const centre = random.in_cube(3.0);
        obb const a = obb_from_box(centre, ha, turn);
        obb const b = obb_from_box(centre + turn * t, hb, turn);
        SCOPED_TRACE(trial);
        EXPECT_EQ(overlaps(a, b), expected);
        EXPECT_EQ(overlaps(b, a), expected);
    }
    EXPECT_GT(overlapping, 100); // both outcomes are exercised
    EXPECT_LT(overlapping, 2900);
}

// --- sphere_vs_obb -----------------------------------------------------------------------------

/// Box of half extents (3, 2, 1), turned and moved at random; positions given in its frame.
class SphereVsObb : public testing::Test
{
  protected:
    random_source random_{41};
    Eigen::Matrix3d turn_ = random_.rotation();
    vec3 centre_ = random_.in_cube(5.0);
    obb box_ = obb_from_box(centre_, vec3(3, 2, 1), turn_);

    vec3 world(vec3 const& local) const { return centre_ + turn_ * local; }

    /// All values are of order 1..10 and pass through one rotation: a few ulps, 1e-12 is ample.
    void expect_contact(sphere_box_contact const& c, vec3 const& local_closest,
                        vec3 const& local_normal, double distance) const
    {
        EXPECT_LE((c.closest_point - world(local_closest)).norm(), 1e-12);
        EXPECT_LE((c.normal - turn_ * local_normal).norm(), 1e-12);
        EXPECT_NEAR(c.normal.norm(), 1.0, 1e-15);
        EXPECT_NEAR(c.distance, distance, 1e-12);
        EXPECT_EQ(c.touching, c.distance <= 0.0);
    }
};

TEST_F(SphereVsObb, OutsideNearAFace)
{
    vec3 const at(3.5, 0.2, -0.3);
    expect_contact(sphere_vs_obb(world(at), 1.0, box_), {3, 0.2, -0.3}, {1, 0, 0}, -0.5);
    auto const apart = sphere_vs_obb(world(at), 0.25, box_);
    expect_contact(apart, {3, 0.2, -0.3}, {1, 0, 0}, 0.25);
    EXPECT_FALSE(apart.touching);
    expect_contact(sphere_vs_obb(world({0.5, 0.5, -1.75}), 0.5, box_), {0.5, 0.5, -1}, {0, 0, -1},
                   0.25);
}

TEST_F(SphereVsObb, OutsideNearAnEdge)
{
    // 0.3 past the x face and 0.4 past the y face: the closest point is on the edge, 0.5 away.
    vec3 const at(3.3, 2.4, 0.5);
    expect_contact(sphere_vs_obb(world(at), 0.2, box_), {3, 2, 0.5}, {0.6, 0.8, 0}, 0.3);
    // Touching at radius 0.5, up to the rounding of the rotation (~1e-16): 1e-12 either side.
    EXPECT_TRUE(sphere_vs_obb(world(at), 0.5 + 1e-12, box_).touching);
    EXPECT_FALSE(sphere_vs_obb(world(at), 0.5 - 1e-12, box_).touching);
}

TEST_F(SphereVsObb, OutsideNearACorner)
{
    // Offset (−1, 2, −2) from the corner (−3, 2, −1): distance 3.
    vec3 const at(-4, 4, -3);
    expect_contact(sphere_vs_obb(world(at), 1.0, box_), {-3, 2, -1}, vec3(-1, 2, -2) / 3.0, 2.0);
    expect_contact(sphere_vs_obb(world(at), 4.0, box_), {-3, 2, -1}, vec3(-1, 2, -2) / 3.0, -1.0);
}

TEST_F(SphereVsObb, CentreInsideLeavesThroughTheNearestFace)
{
    // Depths (0.1, 1.5, 0.8): the +x face.
    expect_contact(sphere_vs_obb(world({2.9, 0.5, 0.2}), 0.5, box_), {3, 0.5, 0.2}, {1, 0, 0},
                   -0.6);
    // Depths (2.5, 0.3, 0.8): the −y face.
    expect_contact(sphere_vs_obb(world({0.5, -1.7, 0.2}), 0.5, box_), {0.5, -2, 0.2}, {0, -1, 0},
                   -0.8);
    // Depths (2.9, 1.8, 0.05): the −z face.
    expect_contact(sphere_vs_obb(world({0.1, 0.2, -0.95}), 0.0, box_), {0.1, 0.2, -1}, {0, 0, -1},
                   -0.05);
    // At the centre the least depth is 1, along z; ties go to the + face.
    expect_contact(sphere_vs_obb(world(vec3::Zero()), 0.5, box_), {0, 0, 1}, {0, 0, 1}, -1.5);
}

TEST_F(SphereVsObb, ContinuousAcrossTheSurface)
{
    // Just outside, on, and just inside the +x face: same normal and closest point, and the
    // distance goes through −radius.
    for (double offset : {1e-6, 0.0, -1e-6}) {
        vec3 const at(3.0 + offset, -0.4, 0.6);
        expect_contact(sphere_vs_obb(world(at), 0.5, box_), {3, -0.4, 0.6}, {1, 0, 0},
                       offset - 0.5);
    }
}

// --- aabb_of -----------------------------------------------------------------------------------

TEST(AabbOfObb, IsTheSmallestAxisAlignedBoxOfTheCorners)
{
    random_source random(51);
    for (int trial = 0; trial < 100; ++trial) {
        obb const box =
            obb_from_box(random.in_cube(5.0),
                         vec3(random.uniform(0, 2), random.uniform(0, 2), random.uniform(0, 2)),
                         random.rotation());
        aabb const bounds = aabb_of(box);
        vec3 lo = vec3::Constant(std::numeric_limits<double>::infinity());
        vec3 hi = -lo;
        for (vec3 const& c : corners(box)) {
            lo = lo.cwiseMin(c);
            hi = hi.cwiseMax(c);
        }
        // Corners and bounds are both sums of three rotated extents: they agree to a few ulps.
        SCOPED_TRACE(trial);
        EXPECT_LE((bounds.min - lo).cwiseAbs().maxCoeff(), 1e-12);
        EXPECT_LE((bounds.max - hi).cwiseAbs().maxCoeff(), 1e-12);
    }
    // Axis-aligned: exactly the box.
    aabb const plain =
        aabb_of(obb_from_box(vec3(1, 2, 3), vec3(0.5, 1, 1.5), Eigen::Matrix3d::Identity()));
    EXPECT_EQ(plain.min, vec3(0.5, 1, 1.5));
    EXPECT_EQ(plain.max, vec3(1.5, 3, 4.5));
}

} // namespace
} // namespace kugel::physics
