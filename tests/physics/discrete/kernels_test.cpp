// Each fast kernel of the discrete step against its plain reference, bit for bit, in the same
// binary: on random inputs across the whole range of doubles and on the edges (signed zeros,
// exact ties, infinities, NaN), since a kernel the engine runs must agree on every input it can
// be given, not only on a gas. Without SSE2 the fast kernels are the plain ones, and the
// comparisons hold trivially.

#include "physics/cells.hpp"
#include "physics/discrete/kernels.hpp"
#include "physics/discrete/sphere_grid.hpp"
#include "physics/wall_set.hpp"

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>
#include <vector>

using namespace kugel::physics;

namespace {

constexpr double inf = std::numeric_limits<double>::infinity();
constexpr double not_a_number = std::numeric_limits<double>::quiet_NaN();

/// Doubles of every magnitude and sign, with the edges mixed in.
std::vector<double> awkward_doubles(std::mt19937_64& rng, std::size_t count)
{
    std::vector<double> out = {0.0, -0.0, 1.0, -1.0, 0.5, -0.5, inf, -inf, not_a_number, -not_a_number,
                               0x1p62, -0x1p62, 0x1p63, -0x1p63, std::nextafter(0x1p63, 0.0),
                               std::nextafter(-0x1p63, 0.0), std::nextafter(-0x1p63, -inf), 0x1p64,
                               std::numeric_limits<double>::denorm_min(), -std::numeric_limits<double>::denorm_min(),
                               std::numeric_limits<double>::max(), -std::numeric_limits<double>::max(),
                               0x1p53, 0x1p53 + 2, -0x1p53 - 2, 4503599627370495.5};
    std::uniform_real_distribution<double> mantissa(-2.0, 2.0);
    std::uniform_int_distribution<int> exponent(-60, 70);
    while (out.size() < count)
        out.push_back(std::ldexp(mantissa(rng), exponent(rng)));
    return out;
}

} // namespace

TEST(Kernels, TruncationAgreesWithItsReferenceOnEveryKindOfDouble)
{
    std::mt19937_64 rng(1);
    for (double q : awkward_doubles(rng, 200'000))
        ASSERT_EQ(cells::truncate(q), cells::truncate_plain(q)) << q;
    // What the reference promises: toward zero, and -2^63 for what has no 64-bit integer.
    EXPECT_EQ(cells::truncate_plain(-2.5), -2);
    EXPECT_EQ(cells::truncate_plain(2.5), 2);
    EXPECT_EQ(cells::truncate_plain(not_a_number), std::numeric_limits<std::int64_t>::min());
    EXPECT_EQ(cells::truncate_plain(0x1p63), std::numeric_limits<std::int64_t>::min());
    EXPECT_EQ(cells::truncate_plain(-0x1p63), std::numeric_limits<std::int64_t>::min());
    EXPECT_EQ(cells::truncate_plain(std::nextafter(0x1p63, 0.0)), std::int64_t{0x7ffffffffffffc00});
}

TEST(Kernels, RunningSumsAgreeWithTheReferenceForEveryLengthAndWrap)
{
    std::mt19937_64 rng(2);
    std::uniform_int_distribution<std::uint32_t> count(0, 40), huge;
    for (std::size_t length = 0; length < 70; ++length) {
        for (int round = 0; round < 20; ++round) {
            std::vector<std::uint32_t> counts(length);
            for (auto& c : counts)
                c = round % 4 == 3 ? huge(rng) : count(rng); // every fourth round wraps
            std::uint32_t const start = round % 2 ? huge(rng) : 0;
            auto fast = counts, plain = counts;
            discrete::running_sums(fast.data(), fast.data() + length, start);
            discrete::running_sums_plain(plain.data(), plain.data() + length, start);
            ASSERT_EQ(fast, plain) << "length " << length << ", round " << round;
            if (length > 0 && round % 4 != 3) { // no wrap: the last sum is start plus every count
                EXPECT_EQ(plain.back(), start + std::accumulate(counts.begin(), counts.end(), 0U));
            }
        }
    }
}

TEST(Kernels, WallTestAgreesWithTheReferenceAtEveryWallAndPosition)
{
    std::vector<wall> walls;
    for (int axis = 0; axis < 3; ++axis) { // a box [-1, 1]^3 ...
        vec3 n = vec3::Zero();
        n[axis] = 1.0;
        walls.push_back({make_plane(n, -1.0), 0.0, 0.0});
        walls.push_back({make_plane(-n, -1.0), 0.0, 0.0});
    }
    walls.push_back({make_plane(vec3(1, 1, 0), -1.2), 0.0, 0.0}); // ... with a corner cut off
    detail::wall_set const set(walls);
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> inside(-1.2, 1.2), radius(0.0, 0.3);
    std::vector<double> const edges = {-1.0, 1.0, 0.0, -0.0, 0.9, -0.9, inf, -inf, not_a_number};
    std::size_t clear = 0, checked = 0;
    for (int k = 0; k < 200'000; ++k) {
        vec3 x(inside(rng), inside(rng), inside(rng));
        double r = radius(rng);
        if (k % 3 == 0) // coordinates exactly on a bound, or where r reaches it exactly
            x[k % 9 / 3] = edges[static_cast<std::size_t>(k / 3) % edges.size()];
        if (k % 5 == 0)
            r = 0.1, x[0] = -0.9; // touches x = -1 exactly
        bool const plain = set.clear_plain(x, r);
        ASSERT_EQ(set.clear(x, r), plain) << x.transpose() << " r " << r;
        clear += plain ? 1U : 0U;
        ++checked;
    }
    EXPECT_GT(clear, checked / 10); // both outcomes were compared
    EXPECT_LT(clear, checked - checked / 10);
    EXPECT_TRUE(set.clear_plain(vec3(-0.9, 0, 0), 0.1)) << "touching counts as clear";
    EXPECT_FALSE(set.clear_plain(vec3(not_a_number, 0, 0), 0.1)) << "NaN is never clear";
}

TEST(Kernels, SphereBoxTestAgreesWithTheReferenceAndWithOverlaps)
{
    std::mt19937_64 rng(4);
    std::uniform_real_distribution<double> near(-1.0, 1.0), radius(0.01, 0.5);
    std::uniform_int_distribution<int> grid(-4, 4);
    std::size_t met = 0;
    for (int k = 0; k < 200'000; ++k) {
        packed_sphere a{{near(rng), near(rng), near(rng)}, radius(rng)};
        packed_sphere b{{near(rng), near(rng), near(rng)}, radius(rng)};
        if (k % 2 == 0) { // on a lattice of 0.25: boxes that touch exactly, on any axis
            a = {{0.25 * grid(rng), 0.25 * grid(rng), 0.25 * grid(rng)}, 0.25};
            b = {{0.25 * grid(rng), 0.25 * grid(rng), 0.25 * grid(rng)}, 0.25 * (1 + k % 3)};
        }
        if (k % 7 == 0)
            b.x[k % 3] = k % 14 == 0 ? not_a_number : inf;
        double const margin = k % 5 == 0 ? 0.125 : 0.0; // a contact margin grows a's box
        bool const plain = discrete::sphere_box_plain(a, margin).meets(b);
        ASSERT_EQ(discrete::sphere_box(a, margin).meets(b), plain) << k;
        if (b.x.allFinite()) { // the box test of aabb.hpp, by another route
            ASSERT_EQ(plain, overlaps(aabb_of_sphere(a.x, a.radius + margin), aabb_of_sphere(b.x, b.radius))) << k;
        }
        met += plain ? 1U : 0U;
    }
    EXPECT_GT(met, 20'000U);
    EXPECT_LT(met, 180'000U);
}

TEST(Kernels, NearPairSearchGivesTheSamePairsWithEitherBoxTest)
{
    // A gas dense enough for every slab to have pairs, with some spheres on a lattice so that
    // boxes touch exactly.
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> in(-2.0, 2.0), radius(0.02, 0.06);
    std::vector<vec3> x;
    std::vector<double> r, inverse_mass;
    for (int k = 0; k < 20'000; ++k) {
        x.push_back(k % 4 == 0 ? vec3(0.1 * std::round(10 * in(rng)), 0.1 * std::round(10 * in(rng)), 0.1 * std::round(10 * in(rng)))
                               : vec3(in(rng), in(rng), in(rng)));
        r.push_back(k % 4 == 0 ? 0.05 : radius(rng));
        inverse_mass.push_back(1.0);
    }
    std::size_t pairs = 0;
    for (double const margin : {0.0, 0.01}) { // without and with a contact margin
        sphere_grid grid;
        grid.set_contact_margin(margin);
        ASSERT_TRUE(grid.build(x, r, inverse_mass, nullptr));
        ASSERT_TRUE(grid.keying_frame()) << "the search with a table of cells is the one with a fast kernel";
        for (std::size_t s = 0; s < grid.slab_count(); ++s) {
            std::vector<sphere_pair> near_fast, touching_fast, near_plain, touching_plain;
            grid.near_pairs(s, near_fast, touching_fast, discrete::kernel::fast);
            grid.near_pairs(s, near_plain, touching_plain, discrete::kernel::plain);
            ASSERT_EQ(near_fast, near_plain) << "slab " << s;
            ASSERT_EQ(touching_fast, touching_plain) << "slab " << s;
            pairs += near_plain.size();
        }
    }
    EXPECT_GT(pairs, 2000U);
}
