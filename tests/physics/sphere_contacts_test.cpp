#include "physics/sphere_contacts.hpp"

#include <cmath>
#include <gtest/gtest.h>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

namespace kugel::physics {
namespace {

/// Bodies as the caller holds them: centres and radii in two arrays.
struct scene
{
    std::vector<vec3> x;        ///< m
    std::vector<double> radius; ///< m

    void add(vec3 const& centre, double r)
    {
        x.push_back(centre);
        radius.push_back(r);
    }
};

/// The contract, pair by pair: i < j, both radii > 0, and the test evaluated as written,
/// per axis d = x_i − x_j, then (d_x² + d_y²) + d_z² <= (r_i + r_j)².
std::vector<box_pair> brute_force_touching(scene const& s)
{
    std::vector<box_pair> pairs;
    auto const n = static_cast<std::uint32_t>(s.x.size());
    for (std::uint32_t i = 0; i < n; ++i) {
        for (std::uint32_t j = i + 1; j < n; ++j) {
            if (!(s.radius[i] > 0.0) || !(s.radius[j] > 0.0))
                continue;
            double const dx = s.x[i].x() - s.x[j].x();
            double const dy = s.x[i].y() - s.x[j].y();
            double const dz = s.x[i].z() - s.x[j].z();
            double const reach = s.radius[i] + s.radius[j];
            if (dx * dx + dy * dy + dz * dz <= reach * reach)
                pairs.push_back({i, j});
        }
    }
    return pairs;
}

std::vector<box_pair> touching(scene const& s)
{
    sphere_contacts_workspace workspace;
    std::vector<box_pair> out;
    find_touching_spheres(s.x, s.radius, out, workspace);
    return out;
}

/// Expects find_touching_spheres to return exactly the brute-force vector (same pairs, same
/// order), with a fresh workspace and with one reused across all calls; returns it.
std::vector<box_pair> expect_agrees_with_brute_force(scene const& s)
{
    static sphere_contacts_workspace shared_workspace;
    std::vector<box_pair> const reference = brute_force_touching(s);
    EXPECT_EQ(touching(s), reference);
    std::vector<box_pair> reused = {{7, 9}}; // stale contents must be cleared
    find_touching_spheres(s.x, s.radius, reused, shared_workspace);
    EXPECT_EQ(reused, reference);
    return reference;
}

/// `count` spheres with centres uniform in [offset, offset + side]^3 and radii uniform in
/// [r_min, r_max].
scene random_scene(std::uint64_t seed, std::size_t count, double side, double r_min, double r_max,
                   vec3 const& offset = vec3::Zero())
{
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> coordinate(0.0, side);
    std::uniform_real_distribution<double> radius(r_min, r_max);
    scene s;
    for (std::size_t i = 0; i < count; ++i) {
        vec3 const c(coordinate(rng), coordinate(rng), coordinate(rng));
        s.add(offset + c, radius(rng));
    }
    return s;
}

/// The side of a cube in which `count` spheres of radius r fill the fraction `fill`.
double side_for_fill(std::size_t count, double r, double fill)
{
    double const volume = 4.0 / 3.0 * 3.141592653589793 * r * r * r;
    return std::cbrt(static_cast<double>(count) * volume / fill);
}

TEST(FindTouchingSpheres, FindsHandComputedPairsOnTinyScene)
{
    scene s;
    s.add({0, 0, 0}, 1.0);      // 0
    s.add({2, 0, 0}, 1.0);      // 1: touches 0 exactly (d = 2 = 1 + 1)
    s.add({1, 1, 0}, 0.5);      // 2: d to 0 and to 1 is √2 <= 1.5
    s.add({5, 5, 5}, 0.0);      // 3: radius 0, skipped even though 4 holds it
    s.add({5, 5, 5.5}, 1.0);    // 4
    s.add({0, 0, 2.0001}, 1.0); // 5: just apart from 0
    s.add({5, 5, 7.5}, 1.0);    // 6: touches 4 exactly
    std::vector<box_pair> const expected = {{0, 1}, {0, 2}, {1, 2}, {4, 6}};
    EXPECT_EQ(brute_force_touching(s), expected);
    EXPECT_EQ(expect_agrees_with_brute_force(s), expected);
}

TEST(FindTouchingSpheres, EmptyOneAndTwoBodies)
{
    EXPECT_TRUE(expect_agrees_with_brute_force({}).empty());
    scene one;
    one.add({1, 2, 3}, 0.5);
    EXPECT_TRUE(expect_agrees_with_brute_force(one).empty());
    scene two = one;
    two.add({1, 2, 4}, 0.5);
    EXPECT_EQ(expect_agrees_with_brute_force(two), (std::vector<box_pair>{{0, 1}}));
    two.x[1].z() = 4.0000001;
    EXPECT_TRUE(expect_agrees_with_brute_force(two).empty());
}

TEST(FindTouchingSpheres, AgreesWithBruteForceOnRandomScenes)
{
    // Sizes from the trivial to 5000; densities from sparse (1 % of the volume filled) to
    // packed (60 %, heavily overlapping); radii equal, spanning a factor of 20, and with a
    // fifth of the bodies at radius 0.
    struct radius_mix
    {
        double r_min;
        double r_max;
        double zero_fraction;
    };
    for (std::size_t count : {0, 1, 2, 3, 10, 100, 1000, 5000}) {
        for (double fill : {0.01, 0.1, 0.6}) {
            for (radius_mix mix : {radius_mix{0.05, 0.05, 0.0}, radius_mix{0.01, 0.2, 0.0},
                                   radius_mix{0.01, 0.2, 0.2}}) {
                std::uint64_t const seeds = count >= 5000 ? 1 : 3;
                for (std::uint64_t seed = 1; seed <= seeds; ++seed) {
                    SCOPED_TRACE("count " + std::to_string(count) + " fill " +
                                 std::to_string(fill) + " radii " + std::to_string(mix.r_min) +
                                 ".." + std::to_string(mix.r_max) + " zero " +
                                 std::to_string(mix.zero_fraction) + " seed " +
                                 std::to_string(seed));
                    double const mean_r = 0.5 * (mix.r_min + mix.r_max);
                    scene s = random_scene(seed, count, side_for_fill(count, mean_r, fill),
                                           mix.r_min, mix.r_max);
                    std::mt19937_64 rng(seed + 1000);
                    std::bernoulli_distribution zero(mix.zero_fraction);
                    for (double& r : s.radius)
                        r = zero(rng) ? 0.0 : r;
                    auto const pairs = expect_agrees_with_brute_force(s);
                    if (count >= 1000 && fill >= 0.1) {
                        EXPECT_GT(pairs.size(), count / 10); // not a vacuous comparison
                    }
                }
            }
        }
    }
}

TEST(FindTouchingSpheres, AgreesWithBruteForceWithOneHugeSphere)
{
    // 2000 spheres of 0.05 m and one whose radius is 2 m (inside the scene), 1e3 m (holding
    // the scene) or 1e100 m (holding everything, its squares still finite), placed first,
    // in the middle or last.
    for (double huge : {2.0, 1e3, 1e100}) {
        for (std::size_t where : {std::size_t{0}, std::size_t{1000}, std::size_t{2000}}) {
            SCOPED_TRACE("huge " + std::to_string(huge) + " at " + std::to_string(where));
            scene s = random_scene(21, 2000, 5.0, 0.05, 0.05);
            s.x.insert(s.x.begin() + static_cast<std::ptrdiff_t>(where), vec3(2.5, 2.5, 2.5));
            s.radius.insert(s.radius.begin() + static_cast<std::ptrdiff_t>(where), huge);
            auto const pairs = expect_agrees_with_brute_force(s);
            auto const with_huge = std::count_if(pairs.begin(), pairs.end(), [&](box_pair p) {
                return p.a == where || p.b == where;
            });
            EXPECT_GT(with_huge, huge > 100.0 ? 1999 : 100);
        }
    }
}

TEST(FindTouchingSpheres, AgreesWithBruteForceOnWidelyMixedRadii)
{
    // Radii log-uniform over 1e-3 … 10 m: several levels of cells, and pairs across them.
    for (std::uint64_t seed = 1; seed <= 4; ++seed) {
        SCOPED_TRACE("seed " + std::to_string(seed));
        std::mt19937_64 rng(seed);
        std::uniform_real_distribution<double> coordinate(0.0, 20.0);
        std::uniform_real_distribution<double> exponent(-3.0, 1.0);
        scene s;
        for (int i = 0; i < 3000; ++i)
            s.add({coordinate(rng), coordinate(rng), coordinate(rng)},
                  std::pow(10.0, exponent(rng)));
        EXPECT_GT(expect_agrees_with_brute_force(s).size(), 1000u);
    }
}

TEST(FindTouchingSpheres, CountsExactlyTouchingSpheresOnIntegerLattice)
{
    // Radius 0.5 at integer spacing: axis neighbours are exactly 1 = 0.5 + 0.5 apart (all
    // exactly representable, also at 1e9 and 1e12, where the spacing of doubles is 2^-23 and
    // 2^-13), diagonal ones √2 apart. A 10 × 10 × 10 lattice has 3 · 9 · 100 such pairs.
    for (double offset : {0.0, -7.0, 1e9, 1e12, -1e12}) {
        SCOPED_TRACE("offset " + std::to_string(offset));
        scene s;
        for (int i = 0; i < 10; ++i)
            for (int j = 0; j < 10; ++j)
                for (int k = 0; k < 10; ++k)
                    s.add(vec3(i, j, k) + vec3::Constant(offset), 0.5);
        EXPECT_EQ(expect_agrees_with_brute_force(s).size(), 2700u);
    }
}

TEST(FindTouchingSpheres, AgreesWithBruteForceFarFromTheOrigin)
{
    // Coordinates near 1e9 and 1e12 m: 1 m spheres stay on the grid; at 1e12 m, 1 mm spheres
    // would need more than 2^47 cells per coordinate and go to the sweep-and-prune fallback.
    struct case_t
    {
        double offset;
        double r;
    };
    for (case_t c : {case_t{1e9, 0.05}, case_t{-1e9, 0.05}, case_t{1e12, 1.0}, case_t{-1e12, 1.0},
                     case_t{1e12, 0.001}}) {
        SCOPED_TRACE("offset " + std::to_string(c.offset) + " r " + std::to_string(c.r));
        double const side = side_for_fill(2000, c.r, 0.2);
        auto const s = random_scene(31, 2000, side, c.r, c.r, vec3::Constant(c.offset));
        EXPECT_GT(expect_agrees_with_brute_force(s).size(), 100u);
    }
}

TEST(FindTouchingSpheres, AgreesWithBruteForceOnClusteredPoints)
{
    // 40 clusters of 50 spheres, each cluster 1 m across, the clusters spread over 1e4 m
    // (sparse cells: keys sorted, not tabled) and over ±1e12 m (cells beyond a 64-bit key:
    // the sweep-and-prune fallback).
    for (double spread : {1e4, 2e12}) {
        SCOPED_TRACE("spread " + std::to_string(spread));
        std::mt19937_64 rng(42);
        std::uniform_real_distribution<double> centre(-0.5 * spread, 0.5 * spread);
        std::normal_distribution<double> around(0.0, 0.25);
        std::uniform_real_distribution<double> radius(0.02, 0.1);
        scene s;
        for (int cluster = 0; cluster < 40; ++cluster) {
            vec3 const c(centre(rng), centre(rng), centre(rng));
            for (int k = 0; k < 50; ++k)
                s.add(c + vec3(around(rng), around(rng), around(rng)), radius(rng));
        }
        EXPECT_GT(expect_agrees_with_brute_force(s).size(), 500u);
    }
}

TEST(FindTouchingSpheres, AgreesWithBruteForceOnDuplicatePositions)
{
    // Groups of bodies at identical centres (distance 0 touches for any radii > 0), some of
    // them with radius 0, and pairs of groups exactly touching.
    scene s;
    for (int group = 0; group < 30; ++group) {
        for (int k = 0; k < 12; ++k)
            s.add(vec3(group % 5, group / 5, 0.0), k % 4 == 0 ? 0.0 : 0.25 * (1 + k % 3));
    }
    auto const pairs = expect_agrees_with_brute_force(s);
    EXPECT_GE(pairs.size(), 30u * 36u); // the 9 bodies > 0 of each group touch each other
}

TEST(FindTouchingSpheres, SkipsBodiesWithoutPositiveRadius)
{
    scene s;
    s.add({0, 0, 0}, 0.0);
    s.add({0, 0, 0}, -1.0);
    s.add({0, 0, 0}, std::numeric_limits<double>::quiet_NaN());
    s.add({0, 0, 0}, 0.0);
    EXPECT_TRUE(expect_agrees_with_brute_force(s).empty());
    s.add({0, 0, 0.1}, 0.1);
    s.add({0, 0, 0.2}, 0.1);
    EXPECT_EQ(expect_agrees_with_brute_force(s), (std::vector<box_pair>{{4, 5}}));
}

TEST(FindTouchingSpheres, AgreesWithBruteForceOnNonFiniteAndExtremeValues)
{
    // Beyond the grid's range the contract still holds, one pair at a time: an infinite
    // radius touches every finite centre, a NaN or infinite centre touches nothing but an
    // infinite radius (∞ <= ∞), 1e300 m radii square to infinity, and squares of 1e-300 m
    // underflow to zero, so such spheres 1e-170 m apart count as touching.
    double const inf = std::numeric_limits<double>::infinity();
    double const nan = std::numeric_limits<double>::quiet_NaN();
    scene s = random_scene(51, 300, 3.0, 0.05, 0.2);
    s.add({1, 1, 1}, inf);
    s.add({nan, 0, 0}, 1.0);
    s.add({inf, 0, 0}, 1.0);
    s.add({1, 1, 1}, 1e300);
    s.add({-1e305, 0, 0}, 1.0);
    s.add({1e305, 0, 0}, 1.0);
    s.add({2, 2, 2}, 1e-300);
    s.add({2, 2, 2 + 1e-170}, 1e-300);
    s.add({inf, inf, inf}, inf);
    auto const pairs = expect_agrees_with_brute_force(s);
    EXPECT_TRUE(std::find(pairs.begin(), pairs.end(), box_pair{306, 307}) != pairs.end());
}

TEST(FindTouchingSpheres, RejectsSpansOfDifferentSizes)
{
    std::vector<vec3> const x(3, vec3::Zero());
    std::vector<double> const radius(2, 1.0);
    sphere_contacts_workspace workspace;
    std::vector<box_pair> out;
    EXPECT_THROW(find_touching_spheres(x, radius, out, workspace), std::invalid_argument);
}

TEST(FindTouchingSpheres, WorkspaceIsReusableAcrossScenes)
{
    auto const large = random_scene(61, 3000, 6.0, 0.05, 0.2);
    auto const small = random_scene(62, 50, 1.0, 0.05, 0.2);
    auto const far = random_scene(63, 300, 5.0, 0.05, 0.2, vec3::Constant(1e9));
    auto const clustered = random_scene(64, 300, 1e5, 0.05, 0.2);
    sphere_contacts_workspace workspace;
    std::vector<box_pair> out;
    for (auto const* s : {&large, &small, &far, &clustered, &large, &small}) {
        find_touching_spheres(s->x, s->radius, out, workspace);
        EXPECT_EQ(out, brute_force_touching(*s));
    }
}

TEST(FindTouchingSpheres, SteadyStateCallsDoNotGrowTheWorkspace)
{
    // Every scratch buffer is a vector that only reallocates to grow, so unchanged capacities
    // mean no allocation: a packed scene (cells tabled), a spread one (keys sorted) and one
    // with a huge sphere (two levels).
    auto const packed = random_scene(71, 3000, 3.0, 0.05, 0.1);
    auto const spread = [] {
        auto s = random_scene(72, 1500, 3.0, 0.05, 0.1);
        auto const far = random_scene(74, 1500, 3.0, 0.05, 0.1, vec3::Constant(1e4));
        s.x.insert(s.x.end(), far.x.begin(), far.x.end());
        s.radius.insert(s.radius.end(), far.radius.begin(), far.radius.end());
        return s;
    }();
    auto const with_huge = [] {
        auto s = random_scene(73, 3000, 4.0, 0.05, 0.1);
        s.add({2, 2, 2}, 1.5);
        return s;
    }();
    for (auto const* s : {&packed, &spread, &with_huge}) {
        sphere_contacts_workspace workspace;
        std::vector<box_pair> out;
        find_touching_spheres(s->x, s->radius, out, workspace); // warms the buffers up
        ASSERT_FALSE(out.empty());
        std::size_t const bytes = workspace.capacity_bytes();
        std::size_t const out_capacity = out.capacity();
        EXPECT_GT(bytes, 0u);
        find_touching_spheres(s->x, s->radius, out, workspace);
        find_touching_spheres(s->x, s->radius, out, workspace);
        EXPECT_EQ(workspace.capacity_bytes(), bytes);
        EXPECT_EQ(out.capacity(), out_capacity);
    }
}

} // namespace
} // namespace kugel::physics
