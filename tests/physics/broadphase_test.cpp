#include "physics/broadphase.hpp"
#include "physics/sphere_grid.hpp"
#include "physics/thread_pool.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <iterator>
#include <limits>
#include <new>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

// ThreadSanitizer's runtime defines operator new itself, so a build with it cannot replace
// it: there, the allocation test below is skipped (the tsan preset runs only this file's
// thread tests).
#if defined(__SANITIZE_THREAD__)
#define KUGEL_TEST_THREAD_SANITIZER 1
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define KUGEL_TEST_THREAD_SANITIZER 1
#endif
#endif

// Counts heap allocations while a test asks for it (SteadyStateCallsDoNotAllocate). The
// replacement pairs malloc with free; GCC cannot see that and warns about the pairing.
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
namespace {
long allocation_count = 0;
bool counting_allocations = false;
} // namespace

#if !defined(KUGEL_TEST_THREAD_SANITIZER)
void* operator new(std::size_t size)
{
    if (counting_allocations)
        ++allocation_count;
    if (void* p = std::malloc(size == 0 ? 1 : size))
        return p;
    throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
#endif

namespace kugel::physics {
namespace {

constexpr broadphase_kind all_kinds[] = {broadphase_kind::brute_force,
                                         broadphase_kind::sweep_and_prune,
                                         broadphase_kind::uniform_grid};

std::vector<box_pair> pairs_of(broadphase_kind kind, std::vector<aabb> const& boxes)
{
    broadphase_workspace workspace;
    std::vector<box_pair> out;
    find_overlapping_pairs(kind, boxes, out, workspace);
    return out;
}

/// Runs every broadphase, expects identical vectors, sorted, with a < b, and returns them.
std::vector<box_pair> expect_all_kinds_agree(std::vector<aabb> const& boxes)
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
std::vector<aabb> random_spheres(std::uint64_t seed, std::size_t count, double side,
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

TEST(BruteForce, FindsHandComputedPairsOnTinyScene)
{
    std::vector<aabb> const boxes = {
        {{0, 0, 0}, {1, 1, 1}},                   // 0
        {{1, 0, 0}, {2, 1, 1}},                   // 1: shares the face x = 1 with 0
        {{0.5, 0.5, 0.5}, {1.5, 1.5, 1.5}},       // 2: overlaps 0 and 1
        {{3, 3, 3}, {4, 4, 4}},                   // 3
        {{2, 2, 2}, {3, 3, 3}},                   // 4: shares only the corner (3,3,3) with 3
        {{0, 0, 1.0000001}, {1, 1, 2}},           // 5: just above 0 and 1, inside 2
    };
    std::vector<box_pair> const expected = {{0, 1}, {0, 2}, {1, 2}, {2, 5}, {3, 4}};
    EXPECT_EQ(pairs_of(broadphase_kind::brute_force, boxes), expected);
    EXPECT_EQ(expect_all_kinds_agree(boxes), expected);
}

TEST(Broadphase, NamesRoundTrip)
{
    for (broadphase_kind kind : all_kinds)
        EXPECT_EQ(broadphase_from_name(name(kind)), kind);
    EXPECT_EQ(name(broadphase_kind::uniform_grid), "grid");
    EXPECT_EQ(broadphase_from_name("brute_force"), broadphase_kind::brute_force);
    EXPECT_EQ(broadphase_from_name("sweep_and_prune"), broadphase_kind::sweep_and_prune);
    EXPECT_EQ(broadphase_from_name("grid"), broadphase_kind::uniform_grid);
    EXPECT_EQ(broadphase_from_name("uniform_grid"), std::nullopt);
    EXPECT_EQ(broadphase_from_name(""), std::nullopt);
    EXPECT_EQ(broadphase_from_name("Grid"), std::nullopt);
}

TEST(Broadphase, EmptyAndSingleBoxGiveNoPairs)
{
    EXPECT_TRUE(expect_all_kinds_agree({}).empty());
    EXPECT_TRUE(expect_all_kinds_agree({{{0, 0, 0}, {1, 1, 1}}}).empty());
}

TEST(Broadphase, AgreesOnTwoBoxesOverlappingOrNot)
{
    EXPECT_EQ(expect_all_kinds_agree({{{0, 0, 0}, {1, 1, 1}}, {{0.5, 0.5, 0.5}, {2, 2, 2}}}),
              (std::vector<box_pair>{{0, 1}}));
    EXPECT_TRUE(expect_all_kinds_agree({{{0, 0, 0}, {1, 1, 1}}, {{0.5, 1.5, 0.5}, {2, 2, 2}}})
                    .empty());
}

TEST(Broadphase, AllKindsAgreeWithBruteForceOnRandomScenes)
{
    // Sizes from the trivial to a few thousand; the side is chosen so that the scenes hold
    // a few pairs per box, with radii spanning a factor of 20.
    for (std::size_t const count : std::initializer_list<std::size_t>{0, 1, 2, 3, 10, 100, 2000}) {
        for (std::uint64_t seed = 1; seed <= 5; ++seed) {
            SCOPED_TRACE("count " + std::to_string(count) + " seed " + std::to_string(seed));
            double const side = 0.5 * std::cbrt(static_cast<double>(count) + 1.0);
            auto const pairs = expect_all_kinds_agree(random_spheres(seed, count, side, 0.01, 0.2));
            if (count >= 100) {
                EXPECT_GT(pairs.size(), count / 10); // not a vacuous comparison
            }
        }
    }
}

TEST(UniformGrid, AgreesWithBruteForceOnClusteredPoints)
{
    std::mt19937_64 rng(42);
    std::normal_distribution<double> spread(0.0, 0.3);
    std::uniform_real_distribution<double> where(-20.0, 20.0);
    std::uniform_real_distribution<double> radius(0.01, 0.1);
    std::vector<aabb> boxes;
    for (int cluster = 0; cluster < 8; ++cluster) {
        vec3 const centre(where(rng), where(rng), where(rng));
        for (int i = 0; i < 200; ++i) {
            vec3 const offset(spread(rng), spread(rng), spread(rng));
            boxes.push_back(aabb_of_sphere(centre + offset, radius(rng)));
        }
    }
    EXPECT_GT(expect_all_kinds_agree(boxes).size(), 1000u);
}

TEST(UniformGrid, AgreesWhenAllBoxesAreIdentical)
{
    std::vector<aabb> const boxes(40, aabb{{-0.3, 1.7, 2.9}, {0.1, 2.2, 3.0}});
    EXPECT_EQ(expect_all_kinds_agree(boxes).size(), 40u * 39u / 2u);
}

TEST(UniformGrid, CountsExactlyTouchingBoxesOnALattice)
{
    // Unit boxes on a k^3 lattice of spacing 1: neighbours share a face, an edge or a corner,
    // and every such contact counts. Per axis 3k - 2 ordered index pairs differ by at most 1,
    // so there are ((3k - 2)^3 - k^3) / 2 unordered pairs of distinct boxes.
    int const k = 4;
    std::vector<aabb> boxes;
    for (int x = 0; x < k; ++x)
        for (int y = 0; y < k; ++y)
            for (int z = 0; z < k; ++z)
                boxes.push_back(aabb_of_sphere(vec3(x, y, z), 0.5));
    std::size_t const expected = ((3 * k - 2) * (3 * k - 2) * (3 * k - 2) - k * k * k) / 2;
    EXPECT_EQ(expect_all_kinds_agree(boxes).size(), expected);
}

TEST(SweepAndPrune, LineOfBoxesSharingEndpointsTouchOnlyNeighbours)
{
    // Boxes [x_k, x_{k+1}] along x with x_k = 0.1·k (not exact in binary): neighbours share
    // the very same double, so they touch; nothing else overlaps.
    std::size_t const count = 300;
    std::vector<double> x(count + 1);
    for (std::size_t k = 0; k <= count; ++k)
        x[k] = 0.1 * static_cast<double>(k);
    std::vector<aabb> touching;
    std::vector<aabb> apart;
    for (std::size_t k = 0; k < count; ++k) {
        touching.push_back({{x[k], 0.0, 0.0}, {x[k + 1], 0.05, 0.05}});
        apart.push_back({{x[k], 0.0, 0.0}, {std::nextafter(x[k + 1], 0.0), 0.05, 0.05}});
    }
    std::vector<box_pair> expected;
    for (std::uint32_t k = 0; k + 1 < count; ++k)
        expected.push_back({k, k + 1});
    EXPECT_EQ(expect_all_kinds_agree(touching), expected);
    EXPECT_TRUE(expect_all_kinds_agree(apart).empty()); // one ulp apart is apart
}

TEST(UniformGrid, AgreesOnTouchingChainsAcrossCellBoundaries)
{
    // Each box starts exactly where the previous one ends on all three axes, with random
    // extents and at random offsets, so lower corners fall on or next to cell boundaries
    // of the grid in every way rounding allows.
    for (double base : {0.0, -1234.5678, 1.0e6, 3.0e9}) {
        SCOPED_TRACE("base " + std::to_string(base));
        std::mt19937_64 rng(7);
        std::uniform_real_distribution<double> extent(0.01, 0.1);
        std::vector<aabb> boxes;
        vec3 corner = vec3::Constant(base);
        for (int i = 0; i < 500; ++i) {
            vec3 const upper = corner + vec3(extent(rng), extent(rng), extent(rng));
            boxes.push_back({corner, upper});
            corner = upper;
        }
        EXPECT_GE(expect_all_kinds_agree(boxes).size(), boxes.size() - 1);
    }
}

TEST(UniformGrid, FindsTouchingBoxesWhoseExtentRoundsDown)
{
    // Box 0 spans [-1e-20, 0.1] on x; its computed extent 0.1 + 1e-20 rounds to 0.1, a little
    // less than the true one. Box 1 starts at x = 0.1, touching it. With the cell size taken
    // as exactly 0.1 their lower corners would fall two cells apart (floor(-1e-20 / 0.1) = -1,
    // floor(0.1 / 0.1) = 1) and the pair would be lost.
    std::vector<aabb> const boxes = {{{-1e-20, 0.0, 0.0}, {0.1, 0.05, 0.05}},
                                     {{0.1, 0.0, 0.0}, {0.15, 0.05, 0.05}}};
    EXPECT_EQ(expect_all_kinds_agree(boxes), (std::vector<box_pair>{{0, 1}}));
}

TEST(UniformGrid, AgreesAroundTheOrigin)
{
    // Negative and positive coordinates: cells come from floor(), not truncation.
    EXPECT_GT(expect_all_kinds_agree(random_spheres(11, 1500, 5.0, 0.05, 0.15, vec3::Constant(-2.5)))
                  .size(),
              100u);
}

TEST(UniformGrid, AgreesFarFromTheOrigin)
{
    // ~1e9 m: 0.05 m boxes still resolve to ~1e-7 m.
    auto const far = random_spheres(3, 2000, 4.0, 0.05, 0.05, vec3(1e9, -2e9, 1e9));
    EXPECT_GT(expect_all_kinds_agree(far).size(), 100u);

    // ~1e12 m with 0.05 m boxes: a cluster is still gridded (cell coordinates ~2e13).
    auto const very_far = random_spheres(4, 2000, 4.0, 0.05, 0.05, vec3(1e12, 1e12, -1e12));
    EXPECT_GT(expect_all_kinds_agree(very_far).size(), 100u);

    // Spread over ±1e12 m, the cells no longer fit in a 64-bit key and the grid hands the
    // scene to sweep and prune; a few boxes placed together still pair up.
    auto scattered = random_spheres(5, 1000, 2e12, 0.05, 0.05, vec3::Constant(-1e12));
    for (int i = 0; i < 5; ++i)
        scattered.push_back(aabb_of_sphere(vec3(4e11 + 0.02 * i, -7e11, 1e11), 0.05));
    EXPECT_EQ(expect_all_kinds_agree(scattered).size(), 10u);

    // ~1e15 m: 1 m boxes are 1e15 cells from the origin, finer than the grid resolves
    // (ulp 0.125 m); the grid hands the scene to sweep and prune.
    auto const beyond = random_spheres(6, 1000, 20.0, 0.5, 0.5, vec3(1e15, 0.0, 0.0));
    EXPECT_GT(expect_all_kinds_agree(beyond).size(), 100u);
}

TEST(UniformGrid, AgreesOnPointsAndDuplicates)
{
    // Zero-extent boxes overlap only when equal; there is no extent to size the cells with.
    std::vector<aabb> boxes;
    std::mt19937_64 rng(9);
    std::uniform_int_distribution<int> lattice(0, 5);
    for (int i = 0; i < 400; ++i) {
        vec3 const p(lattice(rng), lattice(rng), lattice(rng));
        boxes.push_back({p, p});
    }
    EXPECT_GT(expect_all_kinds_agree(boxes).size(), 100u);
}

TEST(UniformGrid, AgreesWithOneHugeBoxAmongSmallOnes)
{
    // The huge box sets the cell size, so the grid degenerates to few cells; still right.
    auto boxes = random_spheres(12, 500, 20.0, 0.02, 0.05);
    boxes.push_back({{5, 5, 5}, {12, 12, 12}});
    EXPECT_GT(expect_all_kinds_agree(boxes).size(), 20u);
}

TEST(SweepAndPrune, AgreesWhenAllCentresLieOnOneAxis)
{
    // A line of overlapping boxes along z: the sweep axis must be z (largest spread).
    std::vector<aabb> boxes;
    for (int i = 0; i < 1000; ++i)
        boxes.push_back(aabb_of_sphere(vec3(0.0, 0.0, 0.07 * i), 0.05));
    EXPECT_EQ(expect_all_kinds_agree(boxes).size(), 999u);
}

TEST(Broadphase, ClearsTheOutputFirst)
{
    auto const boxes = random_spheres(13, 100, 3.0, 0.05, 0.2);
    auto const reference = pairs_of(broadphase_kind::brute_force, boxes);
    for (broadphase_kind kind : all_kinds) {
        SCOPED_TRACE(std::string(name(kind)));
        broadphase_workspace workspace;
        std::vector<box_pair> out(17, box_pair{5, 3});
        find_overlapping_pairs(kind, boxes, out, workspace);
        EXPECT_EQ(out, reference);
    }
}

TEST(Broadphase, WorkspaceIsReusableAcrossScenes)
{
    auto const large = random_spheres(14, 2000, 12.0, 0.05, 0.2);
    auto const small = random_spheres(15, 50, 2.0, 0.05, 0.2);
    auto const far = random_spheres(16, 300, 5.0, 0.05, 0.2, vec3::Constant(1e9));
    for (broadphase_kind kind : all_kinds) {
        SCOPED_TRACE(std::string(name(kind)));
        broadphase_workspace workspace;
        std::vector<box_pair> out;
        for (auto const* scene : {&large, &small, &far, &large, &small}) {
            find_overlapping_pairs(kind, *scene, out, workspace);
            EXPECT_EQ(out, pairs_of(broadphase_kind::brute_force, *scene));
        }
    }
}

TEST(Broadphase, SteadyStateCallsDoNotAllocate)
{
#if defined(KUGEL_TEST_THREAD_SANITIZER)
    GTEST_SKIP() << "ThreadSanitizer's own operator new cannot be replaced to count allocations";
#endif
    // A spread-out scene (the grid sorts its keys) and a packed one (it tables every cell).
    auto const spread = random_spheres(17, 3000, 13.0, 0.05, 0.1);
    auto const packed = random_spheres(18, 3000, 3.0, 0.05, 0.1);
    for (broadphase_kind kind : all_kinds) {
        for (auto const* boxes : {&spread, &packed}) {
            SCOPED_TRACE(std::string(name(kind)) + (boxes == &spread ? " spread" : " packed"));
            broadphase_workspace workspace;
            std::vector<box_pair> out;
            find_overlapping_pairs(kind, *boxes, out, workspace); // warms the buffers up
            ASSERT_FALSE(out.empty());

            allocation_count = 0;
            counting_allocations = true;
            find_overlapping_pairs(kind, *boxes, out, workspace);
            find_overlapping_pairs(kind, *boxes, out, workspace);
            counting_allocations = false;
            EXPECT_EQ(allocation_count, 0);
        }
    }
}

} // namespace
} // namespace kugel::physics

namespace kugel::physics {
namespace {

/// The sphere grid's near pairs of every slab, checking on the way what the discrete step's
/// threads rely on (each slab's pairs come in cell order, start in that slab and end in it or
/// the next) and that the touching ones are exactly the near pairs within r_a + r_b.
/// Returned sorted by body slot, to compare with the broadphases.
std::vector<box_pair> sphere_grid_pairs(std::vector<vec3> const& x, std::vector<double> const& r,
                                        parallel_for* loops = nullptr)
{
    sphere_grid grid;
    std::vector<double> const inverse_mass(x.size(), 1.0);
    EXPECT_TRUE(grid.build(x, r, inverse_mass, loops));
    std::vector<box_pair> all;
    std::vector<sphere_pair> near, touching, expected_touching;
    for (std::size_t s = 0; s < grid.slab_count(); ++s) {
        grid.near_pairs(s, near, touching);
        expected_touching.clear();
        std::copy_if(near.begin(), near.end(), std::back_inserter(expected_touching), [&](sphere_pair const& p) {
            std::uint32_t const i = grid.slot(p.a), j = grid.slot(p.b);
            double const reach = r[i] + r[j];
            return !((x[i] - x[j]).squaredNorm() > reach * reach);
        });
        EXPECT_TRUE(touching == expected_touching);
        box_pair previous{0, 0};
        for (sphere_pair const& p : near) {
            EXPECT_LT(p.a, p.b);
            box_pair const ranks{p.a, p.b};
            EXPECT_TRUE(&p == near.data() || previous < ranks);
            previous = ranks;
            EXPECT_EQ(grid.slab_of(ranks.a), s);
            std::size_t const second = grid.slab_of(ranks.b);
            EXPECT_TRUE(second == s || second == s + 1) << "slab " << s << " reaches " << second;
            all.push_back({std::min(grid.slot(p.a), grid.slot(p.b)), std::max(grid.slot(p.a), grid.slot(p.b))});
        }
    }
    std::sort(all.begin(), all.end());
    return all;
}

/// What the broadphases find among the same spheres (radius > 0), by body slot.
std::vector<box_pair> broadphase_pairs(std::vector<vec3> const& x, std::vector<double> const& r)
{
    std::vector<aabb> boxes;
    std::vector<std::uint32_t> slot;
    for (std::size_t i = 0; i < x.size(); ++i) {
        if (r[i] > 0.0) {
            boxes.push_back(aabb_of_sphere(x[i], r[i]));
            slot.push_back(static_cast<std::uint32_t>(i));
        }
    }
    std::vector<box_pair> pairs = expect_all_kinds_agree(boxes);
    for (box_pair& p : pairs)
        p = {slot[p.a], slot[p.b]};
    return pairs;
}

// The discrete step's own grid must find exactly the broadphases' pairs: random scenes with
// radii spanning a factor of 20, point masses (radius 0, never filed), duplicates, centres
// on both sides of the origin and far from it, and exactly touching spheres on a lattice.
TEST(SphereGrid, FindsTheBroadphasesPairs)
{
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    for (std::size_t const count : std::initializer_list<std::size_t>{1, 2, 10, 300, 3000}) {
        for (vec3 const& offset : {vec3(0, 0, 0), vec3(-3, -1, -2), vec3(1e6, -1e6, 5e5)}) {
            SCOPED_TRACE("count " + std::to_string(count));
            double const side = 0.5 * std::cbrt(static_cast<double>(count) + 1.0);
            std::vector<vec3> x;
            std::vector<double> r;
            for (std::size_t i = 0; i < count; ++i) {
                x.push_back(offset + side * vec3(unit(rng), unit(rng), unit(rng)));
                r.push_back(i % 17 == 3 ? 0.0 : 0.01 + 0.19 * unit(rng));
                if (i % 29 == 5) { // a duplicate of the previous sphere
                    x.push_back(x.back());
                    r.push_back(r.back());
                }
            }
            auto const pairs = sphere_grid_pairs(x, r);
            EXPECT_EQ(pairs, broadphase_pairs(x, r));
            if (count >= 300) {
                EXPECT_GT(pairs.size(), count / 10); // not a vacuous comparison
            }
        }
    }
    std::vector<vec3> lattice;
    std::vector<double> radii;
    for (int i = 0; i < 12; ++i)
        for (int j = 0; j < 12; ++j)
            for (int k = 0; k < 12; ++k) {
                lattice.push_back(0.1 * vec3(i, j, k) - vec3(0.55, 0.55, 0.55));
                radii.push_back(0.05);
            }
    auto const touching = sphere_grid_pairs(lattice, radii);
    EXPECT_GT(touching.size(), 3U * 11U * 12U * 12U / 2U); // not a vacuous comparison
    EXPECT_EQ(touching, broadphase_pairs(lattice, radii));
}

/// Appends `count` spheres with centres uniform in the cube [corner, corner + side]³ and radii
/// uniform in [r_min, r_max]. One draw per statement, so every compiler draws the same scene.
void add_random_spheres(std::mt19937_64& rng, std::size_t count, vec3 const& corner, double side,
                        double r_min, double r_max, std::vector<vec3>& x, std::vector<double>& r)
{
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    for (std::size_t i = 0; i < count; ++i) {
        double const cx = unit(rng);
        double const cy = unit(rng);
        double const cz = unit(rng);
        x.push_back(corner + side * vec3(cx, cy, cz));
        r.push_back(r_min + (r_max - r_min) * unit(rng));
    }
}

/// Two grids of the same spheres hold them in the same order, in the same slabs, with the
/// same near pairs and contacts in each.
void expect_same_grid(sphere_grid const& grid, sphere_grid const& expected)
{
    ASSERT_EQ(grid.slab_count(), expected.slab_count());
    ASSERT_EQ(grid.sphere_count(), expected.sphere_count());
    for (std::uint32_t k = 0; k < grid.sphere_count(); ++k)
        ASSERT_EQ(grid.slot(k), expected.slot(k));
    std::vector<sphere_pair> a, b, a_touching, b_touching;
    for (std::size_t s = 0; s < grid.slab_count(); ++s) {
        grid.near_pairs(s, a, a_touching);
        expected.near_pairs(s, b, b_touching);
        EXPECT_TRUE(a == b) << "slab " << s;
        EXPECT_TRUE(a_touching == b_touching) << "slab " << s;
    }
}

TEST(SphereGrid, SameOrderWithAPoolOfThreads)
{
    std::mt19937_64 rng(5);
    std::vector<vec3> x;
    std::vector<double> r;
    add_random_spheres(rng, 20000, vec3::Zero(), 7.0, 0.05, 0.1, x, r);
    thread_pool pool(2);
    sphere_grid alone, shared;
    std::vector<double> const inverse_mass(x.size(), 1.0);
    ASSERT_TRUE(alone.build(x, r, inverse_mass, nullptr));
    ASSERT_TRUE(shared.build(x, r, inverse_mass, &pool));
    ASSERT_GT(alone.slab_count(), 2U);
    ASSERT_EQ(alone.sphere_count(), x.size());
    expect_same_grid(shared, alone);
}

// The discrete wall pass numbers the spheres' cells in the grid's last frame, to spare the
// grid that pass. Keys in the frame the grid turns out to use must give exactly the grid it
// builds by itself, on one thread or two; keys in any other frame must not be read at all
// (here they are nonsense).
TEST(SphereGrid, TakesKeysFoundBeforehandOnlyInItsOwnFrame)
{
    std::mt19937_64 rng(11);
    std::vector<vec3> x;
    std::vector<double> r;
    add_random_spheres(rng, 5000, vec3::Zero(), 4.1, 0.05, 0.1, x, r); // 20.5 cells wide
    r[17] = 0.0; // a point mass among them: never filed, whatever its key
    std::vector<double> const inverse_mass(x.size(), 1.0);
    sphere_extent all;
    for (std::size_t i = 0; i < x.size(); ++i)
        all.add(x[i], r[i]);
    sphere_grid fresh;
    ASSERT_TRUE(fresh.build(x, r, inverse_mass, all, nullptr, {}));
    ASSERT_TRUE(fresh.keying_frame().has_value());
    cell_frame const frame = *fresh.keying_frame();

    std::vector<std::uint64_t> keys(x.size(), 0);
    for (std::size_t i = 0; i < x.size(); ++i)
        keys[i] = r[i] > 0.0 ? frame.key(x[i]) : 12345;
    // The wall pass keys every sphere before anyone knows whether the frame still holds: a
    // key is defined anywhere, far outside the frame or not a number (the sanitized build
    // checks that no conversion there is undefined).
    for (double const far : {1e300, -1e300, std::numeric_limits<double>::infinity(),
                             -std::numeric_limits<double>::infinity(), std::numeric_limits<double>::quiet_NaN()}) {
        vec3 const nowhere(far, 0.5, -far);
        EXPECT_EQ(frame.key(nowhere), frame.key(nowhere));
    }
    cell_frame shifted = frame;
    shifted.origin[1] -= 1;
    std::vector<std::uint64_t> const nonsense(x.size(), std::numeric_limits<std::uint64_t>::max());
    cell_keys const own{keys, frame}, other{nonsense, shifted};
    for (cell_keys const* keyed : {&own, &other}) {
        sphere_grid grid;
        ASSERT_TRUE(grid.build(x, r, inverse_mass, all, nullptr, {}, keyed));
        EXPECT_TRUE(grid.keying_frame() == fresh.keying_frame());
        expect_same_grid(grid, fresh);
    }

    // The sphere farthest from the origin (all coordinates are positive), moved outwards to
    // the end of its cell on that axis, widens the scene's reach by a good part of a cell but
    // changes no extreme cell: the frame stays, as the cell size depends on the reach only
    // through the power of two above it (taken as it is, the reach widens the cells by a few
    // units in the last place here).
    std::size_t farthest = 0;
    Eigen::Index axis = 0;
    for (std::size_t i = 0; i < x.size(); ++i) {
        Eigen::Index k = 0;
        if (r[i] > 0.0 && x[i].cwiseAbs().maxCoeff(&k) > std::abs(x[farthest][axis])) {
            farthest = i;
            axis = k;
        }
    }
    std::vector<vec3> moved = x;
    double const cell = std::floor(x[farthest][axis] * frame.per_metre);
    moved[farthest][axis] = (cell + 0.999) / frame.per_metre;
    ASSERT_EQ(std::floor(moved[farthest][axis] * frame.per_metre), cell);
    ASSERT_GT((moved[farthest][axis] - x[farthest][axis]) * frame.per_metre, 0.25);
    sphere_grid next;
    ASSERT_TRUE(next.build(moved, r, inverse_mass, nullptr));
    EXPECT_TRUE(next.keying_frame() == fresh.keying_frame());

    // Threads sort slab by slab: they take the keys when their x-cells come with them, and
    // otherwise find both themselves. Either way, the grid built alone.
    thread_pool pool(2);
    std::vector<std::uint32_t> x_cells(x.size(), 0);
    for (std::size_t i = 0; i < x.size(); ++i) {
        std::uint64_t x_cell = 0;
        if (r[i] > 0.0) {
            EXPECT_EQ(frame.key(x[i], x_cell), keys[i]);
            x_cells[i] = static_cast<std::uint32_t>(x_cell);
        }
    }
    std::vector<std::uint32_t> const nonsense_cells(x.size(), 7);
    cell_keys const with_cells{keys, frame, x_cells}, other_cells{nonsense, shifted, nonsense_cells};
    for (cell_keys const* keyed : {&with_cells, &own, &other_cells}) {
        sphere_grid shared;
        ASSERT_TRUE(shared.build(x, r, inverse_mass, all, &pool, {}, keyed));
        ASSERT_GT(shared.slab_count(), 2U);
        EXPECT_TRUE(shared.keying_frame() == fresh.keying_frame());
        expect_same_grid(shared, fresh);
    }
}

// The discrete step finds each slab's pairs while the grid is still being built, as soon as
// that slab and the next are sorted (while other threads sort the rest). They must be the
// pairs found once it is built: scenes of 16 x-cells or fewer have slabs one cell wide, where
// a slab's pairs reach the next slab's cells, with spheres in the corners of the grid too.
TEST(SphereGrid, PairsFoundWhileBuildingAreThoseFoundAfter)
{
    thread_pool two(2), three(3);
    for (std::uint64_t const seed : {21U, 22U, 23U}) {
        std::mt19937_64 rng(seed);
        std::vector<vec3> x;
        std::vector<double> r;
        double const side = seed == 23U ? 3.0 : 1.5; // cells of 0.1 m
        add_random_spheres(rng, seed == 23U ? 16000 : 2000, vec3::Zero(), side, 0.03, 0.05, x, r); // as dense
        for (double const cx : {0.0, side})
            for (double const cy : {0.0, side})
                for (double const cz : {0.0, side}) {
                    x.push_back(vec3(cx, cy, cz));
                    r.push_back(0.05);
                    x.push_back(vec3(cx, cy, cz) + vec3(0.04, 0.0, 0.0));
                    r.push_back(0.05);
                }
        std::vector<double> const inverse_mass(x.size(), 1.0);
        for (parallel_for* loops : {static_cast<parallel_for*>(nullptr), static_cast<parallel_for*>(&two),
                                    static_cast<parallel_for*>(&three)}) {
            SCOPED_TRACE("seed " + std::to_string(seed) + (loops == nullptr ? ", no pool" : ", a pool"));
            sphere_grid grid;
            std::vector<std::vector<sphere_pair>> near(sphere_grid::most_slabs), touching(sphere_grid::most_slabs);
            std::vector<int> calls(sphere_grid::most_slabs, 0);
            ASSERT_TRUE(grid.build(x, r, inverse_mass, loops, [&](std::size_t s) {
                ++calls[s];
                grid.near_pairs(s, near[s], touching[s]);
            }));
            ASSERT_EQ(grid.slab_count(), 16U); // 16 and 31 x-cells: slabs one and two cells wide
            std::vector<sphere_pair> after, after_touching;
            std::size_t pairs = 0;
            for (std::size_t s = 0; s < grid.slab_count(); ++s) {
                EXPECT_EQ(calls[s], 1) << "slab " << s;
                grid.near_pairs(s, after, after_touching);
                EXPECT_TRUE(near[s] == after) << "slab " << s;
                EXPECT_TRUE(touching[s] == after_touching) << "slab " << s;
                pairs += after.size();
            }
            EXPECT_GT(pairs, 1000U); // not a vacuous comparison
        }
    }
}

// The grid declines what it cannot hold, and the discrete step then falls back to the
// broadphases in slot order: no sphere, or coordinates so far out that cells finer than the
// coordinates resolve would be needed. A sparse scene (one sphere flung far off) it holds,
// searching its sorted keys instead of keeping a table of every cell.
TEST(SphereGrid, DeclinesOnlyScenesItCannotHold)
{
    sphere_grid grid;
    std::vector<vec3> x = {vec3::Zero(), vec3(0.1, 0, 0), vec3(1, 0, 0)};
    std::vector<double> r = {0.0, 0.0, 0.0};
    std::vector<double> const inverse_mass = {1.0, 1.0, 1.0};
    EXPECT_FALSE(grid.build(x, r, inverse_mass, nullptr));
    r = {0.1, 0.1, 0.1};
    EXPECT_TRUE(grid.build(x, r, inverse_mass, nullptr));
    x[2] = vec3(1e5, -1e5, 3e4);
    EXPECT_EQ(sphere_grid_pairs(x, r), broadphase_pairs(x, r));
    x[2] = vec3(1e300, 0, 0);
    EXPECT_FALSE(grid.build(x, r, inverse_mass, nullptr));
}

TEST(SphereGrid, SparseScenesFindTheBroadphasesPairs)
{
    std::mt19937_64 rng(23);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    std::vector<vec3> x;
    std::vector<double> r;
    for (int cluster = 0; cluster < 6; ++cluster) {
        double const cx = unit(rng);
        double const cy = unit(rng);
        double const cz = unit(rng);
        add_random_spheres(rng, 300, 1000.0 * vec3(cx, cy, cz), 1.0, 0.02, 0.1, x, r);
    }
    auto const pairs = sphere_grid_pairs(x, r);
    EXPECT_EQ(pairs, broadphase_pairs(x, r));
    EXPECT_GT(pairs.size(), 300U);
}

TEST(ThreadPool, RunsEachIterationOnceAndRethrows)
{
    for (std::size_t const threads : std::initializer_list<std::size_t>{1, 2, 3}) {
        thread_pool pool(threads);
        std::vector<int> runs(1000, 0);
        for (int round = 0; round < 20; ++round)
            pool.run(runs.size(), [&](std::size_t k) { ++runs[k]; });
        EXPECT_TRUE(std::ranges::all_of(runs, [](int n) { return n == 20; }));
        EXPECT_THROW(pool.run(100, [](std::size_t k) { if (k == 42) throw std::runtime_error("42"); }),
                     std::runtime_error);
        pool.run(3, [&](std::size_t k) { runs[k] = 0; }); // still usable after a throw
        EXPECT_EQ(runs[0] + runs[1] + runs[2], 0);
    }
    EXPECT_THROW(thread_pool(0), std::invalid_argument);
}

} // namespace
} // namespace kugel::physics
