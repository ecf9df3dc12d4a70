#include "physics/broadphase.hpp"
#include "physics/broadphase_checks.hpp"
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
