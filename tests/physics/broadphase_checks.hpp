#pragma once

// What the broadphase tests and the sphere grid's tests check every broadphase against.

#include "physics/broadphase.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <string>
#include <vector>

namespace kugel::physics {

inline constexpr broadphase_kind all_kinds[] = {broadphase_kind::brute_force,
                                         broadphase_kind::sweep_and_prune,
                                         broadphase_kind::uniform_grid};

inline std::vector<box_pair> pairs_of(broadphase_kind kind, std::vector<aabb> const& boxes)
{
    broadphase_workspace workspace;
    std::vector<box_pair> out;
    find_overlapping_pairs(kind, boxes, out, workspace);
    return out;
}

/// Runs every broadphase, expects identical vectors, sorted, with a < b, and returns them.
inline std::vector<box_pair> expect_all_kinds_agree(std::vector<aabb> const& boxes)
{
    std::vector<box_pair> const reference = pairs_of(broadphase_kind::brute_force, boxes);
    EXPECT_TRUE(std::is_sorted(reference.begin(), reference.end()));
    EXPECT_TRUE(std::adjacent_find(reference.begin(), reference.end()) == reference.end());
    for (box_pair const& p : reference) {
        EXPECT_LT(p.a, p.b);
        EXPECT_LT(p.b, boxes.size());
    }
    for (broadphase_kind kind : all_kinds) {
        SCOPED_TRACE(std::string(name(kind)));
        EXPECT_EQ(pairs_of(kind, boxes), reference);
    }
    return reference;
}

/// Spheres with centres uniform in [offset, offset + side]^3 and radii uniform in
/// [r_min, r_max], as boxes.
inline std::vector<aabb> random_spheres(std::uint64_t seed, std::size_t count, double side,
                                 double r_min, double r_max, vec3 const& offset = vec3::Zero())
{
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> coordinate(0.0, side);
    std::uniform_real_distribution<double> radius(r_min, r_max);
    std::vector<aabb> boxes;
    for (std::size_t i = 0; i < count; ++i) {
        vec3 const c(coordinate(rng), coordinate(rng), coordinate(rng));
        boxes.push_back(aabb_of_sphere(offset + c, radius(rng)));
    }
    return boxes;
}

} // namespace kugel::physics
