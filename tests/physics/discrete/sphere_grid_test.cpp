// The discrete step's sphere grid: the broadphases' pairs, in an order that neither threads
// nor keys found beforehand change.

#include "physics/broadphase_checks.hpp"
#include "physics/discrete/sphere_grid.hpp"
#include "physics/thread_pool.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

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

// With a contact margin m (the discrete step's speculative contacts, under forces) the grid's
// contacts are exactly the pairs less than m apart, |x_a − x_b| <= r_a + r_b + m, as a search
// of every pair finds them: random spheres, radii spanning a factor of 5, a margin of a
// quarter of the largest radius (the step uses at most half), which widens the cells.
TEST(SphereGrid, WithAContactMarginFindsEveryPairWithinIt)
{
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> in(-1.0, 1.0), radius(0.01, 0.05);
    std::vector<vec3> x;
    std::vector<double> r;
    for (int k = 0; k < 3000; ++k) {
        x.emplace_back(in(rng), in(rng), in(rng));
        r.push_back(radius(rng));
    }
    double const margin = 0.25 * 0.05;
    sphere_grid grid;
    grid.set_contact_margin(margin);
    std::vector<double> const inverse_mass(x.size(), 1.0);
    ASSERT_TRUE(grid.build(x, r, inverse_mass, nullptr));
    std::vector<box_pair> found;
    std::vector<sphere_pair> near, touching;
    for (std::size_t s = 0; s < grid.slab_count(); ++s) {
        grid.near_pairs(s, near, touching);
        for (sphere_pair const& p : touching)
            found.push_back({std::min(grid.slot(p.a), grid.slot(p.b)), std::max(grid.slot(p.a), grid.slot(p.b))});
    }
    std::sort(found.begin(), found.end());
    std::vector<box_pair> expected;
    std::size_t touching_without_margin = 0;
    for (std::uint32_t i = 0; i < x.size(); ++i) {
        for (std::uint32_t j = i + 1; j < x.size(); ++j) {
            double const distance = (x[i] - x[j]).norm();
            if (distance <= r[i] + r[j] + margin)
                expected.push_back({i, j});
            touching_without_margin += distance <= r[i] + r[j] ? 1U : 0U;
        }
    }
    EXPECT_EQ(found, expected);
    EXPECT_GT(expected.size(), touching_without_margin + 100); // the margin found more
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

} // namespace
} // namespace kugel::physics
