// Bounding volumes on degenerate input at extreme coordinates: one point, duplicates,
// collinear and coplanar clouds, general clouds, tiny clouds far from the origin, and huge
// coordinates. Every result is finite and holds every point.

#include "physics/bounding_sphere.hpp"
#include "physics/obb.hpp"
#include "support/random_source.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace kugel::physics {
namespace {

using test_support::random_source;

constexpr double epsilon = std::numeric_limits<double>::epsilon();

struct cloud
{
    std::string name;
    std::vector<vec3> points;
};

/// Degenerate and ordinary clouds of size ~`size` around `offset`.
std::vector<cloud> clouds(vec3 const& offset, double size, std::uint64_t seed)
{
    random_source random(seed);
    std::vector<cloud> out;
    out.push_back({"one point", {offset}});
    out.push_back({"duplicates", std::vector<vec3>(50, offset + vec3(size, 0, 0))});
    vec3 const direction = random.on_sphere();
    cloud line{"collinear", {}};
    for (int i = 0; i < 100; ++i)
        line.points.push_back(offset + random.uniform(-size, size) * direction);
    out.push_back(line);
    vec3 const u = random.on_sphere();
    vec3 const w = u.cross(random.on_sphere()).normalized();
    cloud flat{"coplanar", {}};
    for (int i = 0; i < 100; ++i)
        flat.points.push_back(offset + random.uniform(-size, size) * u +
                              random.uniform(-size, size) * w);
    out.push_back(flat);
    cloud pair{"repeated pair", {}};
    for (int i = 0; i < 20; ++i) {
        pair.points.push_back(offset);
        pair.points.push_back(offset + size * direction);
    }
    out.push_back(pair);
    cloud ball{"ball", {}};
    for (int i = 0; i < 200; ++i)
        ball.points.push_back(offset + random.in_ball(size));
    out.push_back(ball);
    return out;
}

/// How far a point may lie outside a volume through rounding: a few ε of the larger of the
/// coordinates' magnitude and the cloud's size (the points' own coordinates carry ε·|x|).
double rounding_slack(vec3 const& offset, double size)
{
    return 64 * epsilon * (offset.cwiseAbs().maxCoeff() + size);
}

TEST(BoundingVolumes, DegenerateCloudsAtExtremeCoordinatesGiveFiniteVolumesHoldingEveryPoint)
{
    // Offsets from 0 to 1e150 m and cloud sizes from 1e-9 m to 1e6 m, so that a cloud can be
    // 1e-159 of its distance from the origin (all its points then round to a few values).
    // Spheres: finite centre and radius; both bounding spheres promise every point inside as
    // evaluated in double, and the minimum one is never larger than the approximation (bound:
    // the rounding slack). OBB: finite, orthonormal right-handed axes (1e-12), every point
    // inside up to the slack.
    std::uint64_t seed = 1;
    for (double const offset_size : {0.0, 1.0, 1e6, 1e12, 1e100, 1e150}) {
        for (double const size : {1e-9, 1.0, 1e6}) {
            vec3 const offset = offset_size * vec3(1, -0.75, 0.5);
            double const slack = rounding_slack(offset, size);
            for (cloud const& c : clouds(offset, size, seed++)) {
                SCOPED_TRACE(testing::Message() << c.name << ", offset " << offset_size
                                                << ", size " << size);
                sphere const exact = minimum_bounding_sphere(c.points);
                sphere const approximate = approximate_bounding_sphere(c.points);
                for (sphere const& s : {exact, approximate}) {
                    ASSERT_TRUE(s.centre.allFinite());
                    ASSERT_TRUE(std::isfinite(s.radius));
                    ASSERT_GE(s.radius, 0.0);
                    for (vec3 const& p : c.points)
                        ASSERT_LE((p - s.centre).norm(), s.radius);
                }
                EXPECT_LE(exact.radius, approximate.radius + slack);

                obb const box = obb_of_points(c.points);
                ASSERT_TRUE(box.centre.allFinite());
                ASSERT_TRUE(box.axes.allFinite());
                ASSERT_TRUE(box.half_extents.allFinite());
                EXPECT_LE((box.axes.transpose() * box.axes - Eigen::Matrix3d::Identity())
                              .cwiseAbs()
                              .maxCoeff(),
                          1e-12);
                EXPECT_GT(box.axes.determinant(), 0.0);
                for (vec3 const& p : c.points) {
                    vec3 const local = box.axes.transpose() * (p - box.centre);
                    for (int k = 0; k < 3; ++k)
                        ASSERT_LE(std::abs(local[k]), box.half_extents[k] + slack);
                }
            }
        }
    }
}

TEST(BoundingVolumes, OnePointAndDuplicatesGiveAZeroVolumeAtThePointAtAnyCoordinate)
{
    // Exact: no arithmetic on a single distinct point needs rounding.
    for (double const x : {1e-300, 1.0, 1e12, 1e150}) {
        vec3 const p(x, -x, 0.5 * x);
        for (std::size_t copies : {1U, 7U}) {
            std::vector<vec3> const points(copies, p);
            for (sphere const& s :
                 {minimum_bounding_sphere(points), approximate_bounding_sphere(points)}) {
                EXPECT_EQ(s.centre, p);
                EXPECT_EQ(s.radius, 0.0);
            }
            obb const box = obb_of_points(points);
            EXPECT_LE((box.centre - p).norm(), 4 * epsilon * p.norm());
            EXPECT_LE(box.half_extents.maxCoeff(), 4 * epsilon * p.norm());
        }
    }
}

} // namespace
} // namespace kugel::physics
