#include "physics/aabb.hpp"

#include <gtest/gtest.h>

#include <vector>

namespace kugel::physics {
namespace {

TEST(Aabb, OfPointsIsTheSmallestBoxHoldingThem)
{
    std::vector<vec3> const points{{1, -2, 3}, {-4, 5, 0}, {2, 2, -6}};
    aabb const box = aabb_of_points(points);
    EXPECT_EQ(box.min, vec3(-4, -2, -6));
    EXPECT_EQ(box.max, vec3(2, 5, 3));
    EXPECT_EQ(aabb_of_points({}).min, vec3::Zero());
}

TEST(Aabb, OfASphereIsCentrePlusMinusRadius)
{
    aabb const box = aabb_of_sphere(vec3(1, 2, 3), 0.5); // lecture: [xᵢ − rᵢ, xᵢ + rᵢ] per axis
    EXPECT_EQ(box.min, vec3(0.5, 1.5, 2.5));
    EXPECT_EQ(box.max, vec3(1.5, 2.5, 3.5));
    EXPECT_EQ(box.centre(), vec3(1, 2, 3));
    EXPECT_EQ(box.extent(), vec3(1, 1, 1));
}

TEST(Aabb, OverlapNeedsEveryAxisAndTouchingCounts)
{
    aabb const a{vec3(0, 0, 0), vec3(1, 1, 1)};
    EXPECT_TRUE(overlaps(a, aabb{vec3(0.5, 0.5, 0.5), vec3(2, 2, 2)}));
    EXPECT_TRUE(overlaps(a, aabb{vec3(1, 1, 1), vec3(2, 2, 2)})); // max{aᵢ} = min{bᵢ}
    // separated on one axis only: no overlap (the lecture's 1D rule on every axis)
    EXPECT_FALSE(overlaps(a, aabb{vec3(0.5, 0.5, 1.001), vec3(2, 2, 2)}));
    EXPECT_FALSE(overlaps(a, aabb{vec3(-3, 0.2, 0.2), vec3(-0.001, 0.8, 0.8)}));
    EXPECT_TRUE(overlaps(a, a));
}

TEST(Aabb, MergeHoldsBoth)
{
    aabb const m = merge(aabb{vec3(0, 0, 0), vec3(1, 1, 1)}, aabb{vec3(-1, 2, 0.5), vec3(0, 3, 0.7)});
    EXPECT_EQ(m.min, vec3(-1, 0, 0));
    EXPECT_EQ(m.max, vec3(1, 3, 1));
}

} // namespace
} // namespace kugel::physics
