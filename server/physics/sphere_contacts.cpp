#include "sphere_contacts.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <optional>
#include <stdexcept>
#include <utility>

namespace kugel::physics {

namespace {

using detail::cell_entry;
using detail::sphere_grid;
using detail::sphere_record;
using cell_coordinates = std::array<std::int64_t, 3>;

/// [begin, end) of a grid's spheres.
struct run
{
    std::uint32_t begin;
    std::uint32_t end;
};

constexpr double unit_roundoff = 0x1p-53;
/// Largest |coordinate| / cell size a level accepts; beyond it cells would be finer than the
/// coordinates can resolve, and the whole scene goes to the sweep-and-prune fallback.
constexpr double largest_cell_coordinate = 0x1p47;
/// Bodies with a coordinate or radius beyond these (or NaN, or infinite) are "irregular":
/// tested one by one against every body. Within them no sum, difference or square below
/// overflows except |x_i − x_j|², and that only for pairs that do not touch.
constexpr double largest_regular_coordinate = 0x1p1000; // m
constexpr double largest_regular_radius = 0x1p500;      // m
/// Added to every cell size and inflated radius: covers the absolute error of squares that
/// underflow, for which the relative error bounds below do not hold.
constexpr double underflow_margin = 0x1p-500; // m
/// A level takes the spheres up to this many times the median radius of those left.
constexpr double level_radius_ratio = 4.0;
/// Up to this many cells per sphere a level tables every cell (dense); beyond it (a sparse
/// scene, e.g. far-apart clusters) it radix-sorts the keys and searches them instead.
constexpr std::uint64_t dense_cells_per_sphere = 8;
constexpr int radix_bits = 11;
constexpr std::uint64_t radix_mask = (std::uint64_t{1} << radix_bits) - 1;

/// floor(q) for |q| < 2^53, without a library call.
std::int64_t floor_to_integer(double q)
{
    auto const truncated = static_cast<std::int64_t>(q);
    return q < static_cast<double>(truncated) ? truncated - 1 : truncated;
}

/// The contact test of the contract, evaluated exactly as written there.
bool touch(sphere_record const& a, sphere_record const& b)
{
    double const dx = a.x - b.x;
    double const dy = a.y - b.y;
    double const dz = a.z - b.z;
    double const reach = a.r + b.r;
    return dx * dx + dy * dy + dz * dz <= reach * reach;
}

sphere_record record_of(vec3 const& centre, double radius)
{
    return {centre.x(), centre.y(), centre.z(), radius};
}

bool is_regular(vec3 const& centre, double radius)
{
    return radius > 0.0 && radius <= largest_regular_radius &&
           centre.cwiseAbs().maxCoeff() <= largest_regular_coordinate;
}

/// a · b, or nullopt when it does not fit in 64 bits.
std::optional<std::uint64_t> checked_product(std::uint64_t a, std::uint64_t b)
{
    if (a != 0 && b > std::numeric_limits<std::uint64_t>::max() / a)
        return std::nullopt;
    return a * b;
}

cell_coordinates cell_of(sphere_record const& s, double inverse_cell_size)
{
    return {floor_to_integer(s.x * inverse_cell_size), floor_to_integer(s.y * inverse_cell_size),
            floor_to_integer(s.z * inverse_cell_size)};
}

/// The key of a cell within lowest - 1 … highest + 1 on every axis.
std::uint64_t key_of(sphere_grid const& grid, cell_coordinates const& c)
{
    auto const offset = [&](std::size_t k) {
        return static_cast<std::uint64_t>(c[k] - grid.lowest[k]) + 1;
    };
    return offset(0) * grid.stride_x + offset(1) * grid.stride_y + offset(2);
}

/// The spheres of the cells with keys first … last, which must be one row (same x and y).
run run_of(sphere_grid const& grid, std::uint64_t first, std::uint64_t last)
{
    if (grid.dense)
        return {grid.run_starts[first], grid.run_starts[last + 1]};
    auto const keys_begin = grid.keys.begin();
    auto const keys_end = keys_begin + static_cast<std::ptrdiff_t>(grid.spheres.size());
    auto const begin = std::lower_bound(keys_begin, keys_end, first);
    auto const end = std::lower_bound(begin, keys_end, last + 1);
    return {static_cast<std::uint32_t>(begin - keys_begin),
            static_cast<std::uint32_t>(end - keys_begin)};
}

/// Pairs as they are found, in no particular order.
struct pair_collector
{
    std::vector<box_pair>& pairs; ///< the first `found` are the pairs; the rest is room
    std::size_t found = 0;

    /// Sphere s (body `body`) against the spheres of `grid` in `runs`. Each candidate is
    /// written and kept only if the spheres touch (the count advances by the test's result),
    /// which spares a hard-to-predict branch per candidate.
    void test(sphere_record const& s, std::uint32_t body, sphere_grid const& grid,
              std::span<run const> runs)
    {
        std::size_t room = 0;
        for (run const& r : runs)
            room += r.end - r.begin;
        if (found + room > pairs.size())
            pairs.resize(std::max(2 * pairs.size(), found + room));
        box_pair* const written = pairs.data();
        sphere_record const* const spheres = grid.spheres.data();
        std::uint32_t const* const bodies = grid.bodies.data();
        std::size_t kept = found;
        for (run const& r : runs) {
            for (std::uint32_t q = r.begin; q < r.end; ++q) {
                std::uint32_t const other = bodies[q];
                written[kept] = {std::min(body, other), std::max(body, other)};
                kept += touch(s, spheres[q]) ? 1 : 0;
            }
        }
        found = kept;
    }

    void add(std::uint32_t i, std::uint32_t j)
    {
        if (found == pairs.size())
            pairs.resize(std::max<std::size_t>(2 * pairs.size(), 16));
        pairs[found++] = {std::min(i, j), std::max(i, j)};
    }
};

/// Files `members` (body indices, ascending) into `grid` under the cells of their centres,
/// cells of `cell_size` m. False when the cells spanned do not fit a 64-bit key.
bool build_level(std::span<vec3 const> x, std::span<double const> radius,
                 std::span<std::uint32_t const> members, double cell_size, sphere_grid& grid,
                 detail::cell_sort_buffers& buffers)
{
    auto const m = static_cast<std::uint32_t>(members.size());
    grid.inverse_cell_size = 1.0 / cell_size;

    // The cells in use, padded by one on every side so that a neighbour's key never wraps
    // into another row. floor(x/h) is monotone in x: the extreme cells hold the extreme
    // centres.
    vec3 low = x[members[0]];
    vec3 high = low;
    for (std::uint32_t body : members) {
        low = low.cwiseMin(x[body]);
        high = high.cwiseMax(x[body]);
    }
    grid.lowest = cell_of(record_of(low, 0.0), grid.inverse_cell_size);
    grid.highest = cell_of(record_of(high, 0.0), grid.inverse_cell_size);
    std::array<std::uint64_t, 3> padded_size;
    for (std::size_t k = 0; k < 3; ++k)
        padded_size[k] = static_cast<std::uint64_t>(grid.highest[k] - grid.lowest[k]) + 3;
    auto const plane_cells = checked_product(padded_size[1], padded_size[2]);
    auto const all_cells =
        plane_cells ? checked_product(padded_size[0], *plane_cells) : std::nullopt;
    if (!all_cells || *all_cells == std::numeric_limits<std::uint64_t>::max())
        return false;
    grid.stride_y = padded_size[2];
    grid.stride_x = *plane_cells;
    grid.dense = *all_cells <= dense_cells_per_sphere * m + 1024;

    grid.spheres.resize(m);
    grid.bodies.resize(m);
    grid.keys.reserve(std::size_t{m} + 1); // room for the sparse walk's sentinel
    grid.keys.resize(m);
    auto& member_keys = buffers.member_keys;
    auto& member_slabs = buffers.member_slabs;
    auto& counts = buffers.counts;
    member_keys.resize(m);
    member_slabs.resize(m);
    for (std::uint32_t p = 0; p < m; ++p) {
        std::uint32_t const body = members[p];
        cell_coordinates const c = cell_of(record_of(x[body], 0.0), grid.inverse_cell_size);
        member_keys[p] = key_of(grid, c);
        member_slabs[p] = static_cast<std::uint32_t>(c[0] - grid.lowest[0]) + 1;
    }

    if (grid.dense) {
        // Counting sort over every cell, in two passes that each work in cache: the spheres
        // are first dealt into slabs of one x cell (one write position per slab), then each
        // slab, whose cell counters and records fit in the L2 cache, is sorted by cell. A
        // single pass would scatter into the whole table and the whole output at random.
        // Afterwards run_starts[k] is where cell k's run starts, and run_starts[all_cells]
        // is m.
        std::size_t const slabs = padded_size[0];
        counts.assign(slabs + 1, 0);
        for (std::uint32_t slab : member_slabs)
            ++counts[slab + 1];
        for (std::size_t s = 1; s <= slabs; ++s)
            counts[s] += counts[s - 1];
        buffers.staged_spheres.resize(m);
        buffers.staged_bodies.resize(m);
        buffers.staged_keys.resize(m);
        for (std::uint32_t p = 0; p < m; ++p) {
            std::uint32_t const body = members[p];
            std::uint32_t const slot = counts[member_slabs[p]]++;
            buffers.staged_spheres[slot] = record_of(x[body], radius[body]);
            buffers.staged_bodies[slot] = body;
            buffers.staged_keys[slot] = member_keys[p];
        }
        // Now counts[s] is the end of slab s, and the start of slab s + 1.
        auto& starts = grid.run_starts;
        starts.resize(*all_cells + 1);
        for (std::size_t s = 0; s < slabs; ++s) {
            std::uint32_t const begin = s == 0 ? 0 : counts[s - 1];
            std::uint32_t const end = counts[s];
            std::uint64_t const first_key = s * grid.stride_x;
            std::uint32_t* const slab_starts = starts.data() + first_key;
            std::fill(slab_starts, slab_starts + grid.stride_x, 0);
            for (std::uint32_t q = begin; q < end; ++q)
                ++slab_starts[buffers.staged_keys[q] - first_key];
            std::uint32_t sum = begin;
            for (std::uint64_t k = 0; k < grid.stride_x; ++k)
                sum = slab_starts[k] += sum; // inclusive: the end of each run
            for (std::uint32_t q = end; q-- > begin;) {
                std::uint64_t const key = buffers.staged_keys[q];
                std::uint32_t const slot = --slab_starts[key - first_key];
                grid.spheres[slot] = buffers.staged_spheres[q];
                grid.bodies[slot] = buffers.staged_bodies[q];
                grid.keys[slot] = key;
            }
        }
        starts[*all_cells] = m;
        return true;
    }

    // Sparse: LSD radix sort of (key, member) on the key bits in use, then a gather.
    auto& entries = buffers.entries;
    auto& scratch = buffers.entries_scratch;
    entries.resize(m);
    scratch.resize(m);
    for (std::uint32_t p = 0; p < m; ++p)
        entries[p] = {member_keys[p], p};
    auto const key_bits = static_cast<int>(std::bit_width(*all_cells - 1));
    for (int shift = 0; shift < key_bits; shift += radix_bits) {
        counts.assign(radix_mask + 1, 0);
        for (auto const& e : entries)
            ++counts[(e.key >> shift) & radix_mask];
        std::uint32_t sum = 0;
        for (auto& count : counts)
            sum += std::exchange(count, sum);
        for (auto const& e : entries)
            scratch[counts[(e.key >> shift) & radix_mask]++] = e;
        entries.swap(scratch);
    }
    for (std::uint32_t k = 0; k < m; ++k) {
        std::uint32_t const body = members[entries[k].position];
        grid.spheres[k] = record_of(x[body], radius[body]);
        grid.bodies[k] = body;
        grid.keys[k] = entries[k].key;
    }
    grid.keys.push_back(std::numeric_limits<std::uint64_t>::max()); // ends every walk
    return true;
}

/// Every pair of spheres within one level: each sphere against the rest of its own cell,
/// the (0, 0, +1) cell and the four forward rows (0, +1, *), (+1, -1, *), (+1, 0, *),
/// (+1, +1, *); the three cells z - 1, z, z + 1 of a row are adjacent in key order, so a
/// row is one run. Those are 14 of the 27 cells around it, and every pair of neighbouring
/// cells is visited from exactly one side.
void collect_level_pairs(sphere_grid const& grid, pair_collector& out)
{
    auto const m = static_cast<std::uint32_t>(grid.spheres.size());
    std::array<std::uint64_t, 4> const row_offsets = {grid.stride_y, grid.stride_x - grid.stride_y,
                                                      grid.stride_x, grid.stride_x + grid.stride_y};
    std::array<run, 5> candidates{};

    if (grid.dense) {
        // Runs looked up directly: cell k holds [run_starts[k], run_starts[k + 1]).
        auto const& starts = grid.run_starts;
        for (std::uint32_t p = 0; p < m; ++p) {
            std::uint64_t const key = grid.keys[p];
            candidates[0] = {p + 1, starts[key + 2]}; // own cell, then (0, 0, +1)
            for (std::size_t r = 0; r < row_offsets.size(); ++r)
                candidates[r + 1] = {starts[key + row_offsets[r] - 1],
                                     starts[key + row_offsets[r] + 2]};
            out.test(grid.spheres[p], grid.bodies[p], grid, candidates);
        }
        return;
    }

    // Runs found by walking the sorted keys: the sentinel ends every walk, and each run's
    // ends only ever move forward, as the keys grow.
    auto const& keys = grid.keys;
    std::uint32_t begin = 0;
    while (begin < m) {
        std::uint64_t const key = keys[begin];
        std::uint32_t end = begin + 1;
        while (keys[end] == key)
            ++end;
        std::uint32_t next_end = end; // end of the (0, 0, +1) neighbour
        while (keys[next_end] == key + 1)
            ++next_end;
        for (std::size_t r = 0; r < row_offsets.size(); ++r) {
            auto& [row_begin, row_end] = candidates[r + 1];
            std::uint64_t const first = key + row_offsets[r] - 1;
            while (keys[row_begin] < first)
                ++row_begin;
            row_end = std::max(row_end, row_begin);
            while (keys[row_end] <= first + 2)
                ++row_end;
        }
        for (std::uint32_t p = begin; p < end; ++p) {
            candidates[0] = {p + 1, next_end};
            out.test(grid.spheres[p], grid.bodies[p], grid, candidates);
        }
        begin = end;
    }
}

/// Every pair of a sphere of `finer` with a sphere of `coarser` (a level of radii at least
/// as large): each sphere of `finer` against the spheres of `coarser` in the 27 cells of
/// `coarser` around its centre, clipped to the occupied cells.
void collect_cross_pairs(sphere_grid const& finer, sphere_grid const& coarser, pair_collector& out)
{
    std::array<run, 9> candidates{};
    for (std::size_t p = 0; p < finer.spheres.size(); ++p) {
        sphere_record const& s = finer.spheres[p];
        cell_coordinates const c = cell_of(s, coarser.inverse_cell_size);
        cell_coordinates low;
        cell_coordinates high;
        bool empty = false;
        for (std::size_t k = 0; k < 3; ++k) {
            low[k] = std::max(c[k] - 1, coarser.lowest[k]);
            high[k] = std::min(c[k] + 1, coarser.highest[k]);
            empty |= low[k] > high[k];
        }
        if (empty)
            continue;
        std::size_t rows = 0;
        auto const row_length = static_cast<std::uint64_t>(high[2] - low[2]);
        for (std::int64_t cx = low[0]; cx <= high[0]; ++cx) {
            for (std::int64_t cy = low[1]; cy <= high[1]; ++cy) {
                std::uint64_t const first = key_of(coarser, {cx, cy, low[2]});
                candidates[rows++] = run_of(coarser, first, first + row_length);
            }
        }
        out.test(s, finer.bodies[p], coarser, std::span(candidates).first(rows));
    }
}

/// Sweep and prune on boxes grown enough that every touching pair's boxes overlap (see
/// find_touching_spheres), then the exact test. For scenes the grid cannot key.
void collect_pairs_by_sweep(std::span<vec3 const> x, std::span<double const> radius,
                            std::vector<aabb>& boxes, std::vector<std::uint32_t>& members,
                            std::vector<box_pair>& candidates, broadphase_workspace& workspace,
                            pair_collector& out)
{
    boxes.clear();
    members.clear();
    for (std::size_t i = 0; i < x.size(); ++i) {
        if (is_regular(x[i], radius[i])) {
            double const grown = radius[i] * (1.0 + 8.0 * unit_roundoff) + underflow_margin;
            boxes.push_back(aabb_of_sphere(x[i], grown));
            members.push_back(static_cast<std::uint32_t>(i));
        }
    }
    find_overlapping_pairs(broadphase_kind::sweep_and_prune, boxes, candidates, workspace);
    for (box_pair const& c : candidates) {
        std::uint32_t const i = members[c.a];
        std::uint32_t const j = members[c.b];
        if (touch(record_of(x[i], radius[i]), record_of(x[j], radius[j])))
            out.add(i, j);
    }
}

/// Sorts `pairs` (i < j < body_count) into `out` ascending by (i, j) in
/// O(body_count + pairs): a counting sort on i, then each run sorted on j.
void sort_pairs(std::span<box_pair const> pairs, std::size_t body_count,
                std::vector<std::uint32_t>& counts, std::vector<box_pair>& out)
{
    out.resize(pairs.size());
    // Few pairs against many bodies: a comparison sort is cheaper than the histogram.
    if (pairs.size() < 64 || pairs.size() * 8 < body_count) {
        std::copy(pairs.begin(), pairs.end(), out.begin());
        std::sort(out.begin(), out.end());
        return;
    }
    counts.assign(body_count + 1, 0);
    for (box_pair const& p : pairs)
        ++counts[p.a + 1];
    for (std::size_t k = 1; k <= body_count; ++k)
        counts[k] += counts[k - 1];
    for (box_pair const& p : pairs)
        out[counts[p.a]++] = p;
    // Now counts[k] is the end of run k; runs are short in practice.
    auto const by_j = [](box_pair const& a, box_pair const& b) { return a.b < b.b; };
    std::size_t begin = 0;
    for (std::size_t k = 0; k < body_count; ++k) {
        std::size_t const end = counts[k];
        if (end - begin > 1)
            std::sort(out.begin() + static_cast<std::ptrdiff_t>(begin),
                      out.begin() + static_cast<std::ptrdiff_t>(end), by_j);
        begin = end;
    }
}

std::size_t bytes_of(auto const& v)
{
    return v.capacity() * sizeof(v[0]);
}

} // namespace

std::size_t sphere_contacts_workspace::capacity_bytes() const noexcept
{
    auto const& b = sort_buffers_;
    std::size_t bytes = bytes_of(remaining_) + bytes_of(members_) + bytes_of(irregular_) +
                        bytes_of(radii_) + bytes_of(levels_) + bytes_of(pairs_) +
                        bytes_of(pair_counts_) + bytes_of(b.member_keys) +
                        bytes_of(b.member_slabs) + bytes_of(b.counts) + bytes_of(b.staged_spheres) +
                        bytes_of(b.staged_bodies) + bytes_of(b.staged_keys) + bytes_of(b.entries) +
                        bytes_of(b.entries_scratch);
    for (detail::sphere_grid const& level : levels_)
        bytes += bytes_of(level.keys) + bytes_of(level.run_starts) + bytes_of(level.spheres) +
                 bytes_of(level.bodies);
    return bytes;
}

// A grid of levels, sorted rather than hashed:
//  1. Spheres are split into levels by radius: a level takes the spheres up to 4 times the
//     median radius of those left (all of them when the largest is within 4 times the
//     smallest), so one large sphere does not make every cell large. Each level has at
//     most half the spheres of the one before, so there are at most log2(n) + 1 levels;
//     a typical scene has one.
//  2. A level's cell size h is its largest diameter D (slightly enlarged, below), and each
//     sphere is filed under the cell of its centre. Two touching spheres of a level, or a
//     sphere touching one of a coarser level, are then at most one cell apart on every axis
//     (proof below) in the coarser level's grid.
//  3. The (cell key, sphere) entries are sorted by key: a counting sort over all cells when
//     there are few cells per sphere, else a radix sort. The centres and radii are stored in
//     that order as 32-byte records, so the scans below read memory in sequence.
//  4. Within a level, each cell is paired with itself and its 13 forward neighbours; across
//     levels, each sphere looks up the 27 cells around it in every coarser level. Every
//     candidate gets the exact test, and the pairs are sorted.
//
// Why one cell apart holds in floating point. If the computed test passes, then on every
// axis |x_i − x_j| <= (r_i + r_j)(1 + 5u) + 2^-535 (u = 2^-53: each rounded operation of
// the test moves it by a factor of at most 1 + u, and underflowing squares by at most
// 2^-1074); with r_i + r_j <= D this is below D(1 + 5u) + 2^-535. The cell coordinates
// q = x · fl(1/h) carry a relative error of about 2u, i.e. an absolute error of 2u·X/h for
// coordinates up to X. Taking h = D + 8u·(2D + X) + 2^-500 keeps the computed difference
// of two q below 1, so their floors differ by at most one. X/D is limited to 2^47, which
// keeps the enlargement below D/8.
//
// Falls back to sweep and prune, with each radius grown by 8u plus 2^-500 (which makes
// every touching pair's boxes overlap, by the same bound), when X/D exceeds 2^47 in some
// level (e.g. 1e12 m with 1 mm spheres) or a level's cells do not fit a 64-bit key (e.g.
// 0.1 m spheres spread over ±1e12 m).
void find_touching_spheres(std::span<vec3 const> x, std::span<double const> radius,
                           std::vector<box_pair>& out, sphere_contacts_workspace& ws)
{
    if (x.size() != radius.size())
        throw std::invalid_argument("find_touching_spheres: x and radius differ in size");
    if (x.size() >= (std::size_t{1} << 31))
        throw std::length_error("find_touching_spheres: at most 2^31 - 1 bodies");
    out.clear();
    auto const n = static_cast<std::uint32_t>(x.size());

    // 1. Split the bodies: regular spheres go to the grid, irregular ones are tested one
    //    by one, bodies of radius <= 0 (or NaN) are skipped. X is the largest coordinate.
    ws.remaining_.clear();
    ws.irregular_.clear();
    double largest_coordinate = 0.0; // m
    for (std::uint32_t i = 0; i < n; ++i) {
        if (is_regular(x[i], radius[i])) {
            ws.remaining_.push_back(i);
            largest_coordinate = std::max(largest_coordinate, x[i].cwiseAbs().maxCoeff());
        } else if (radius[i] > 0.0) {
            ws.irregular_.push_back(i);
        }
    }

    // 2. Levels, from the smallest radii up; each is filed into its grid.
    pair_collector collector{ws.pairs_};
    bool gridded = true;
    ws.level_count_ = 0;
    while (!ws.remaining_.empty()) {
        double smallest = radius[ws.remaining_[0]];
        double largest = smallest;
        for (std::uint32_t body : ws.remaining_) {
            smallest = std::min(smallest, radius[body]);
            largest = std::max(largest, radius[body]);
        }
        double threshold = largest; // m, the level takes radii up to this
        if (largest > level_radius_ratio * smallest) {
            ws.radii_.clear();
            for (std::uint32_t body : ws.remaining_)
                ws.radii_.push_back(radius[body]);
            auto const middle =
                ws.radii_.begin() + static_cast<std::ptrdiff_t>(ws.radii_.size() / 2);
            std::nth_element(ws.radii_.begin(), middle, ws.radii_.end());
            threshold = level_radius_ratio * *middle;
        }
        // Members in body order; the rest stays in remaining_, in order.
        ws.members_.clear();
        std::size_t rest = 0;
        double level_largest = 0.0; // m
        for (std::uint32_t body : ws.remaining_) {
            if (radius[body] <= threshold) {
                ws.members_.push_back(body);
                level_largest = std::max(level_largest, radius[body]);
            } else {
                ws.remaining_[rest++] = body;
            }
        }
        ws.remaining_.resize(rest);

        double const diameter = 2.0 * level_largest; // m
        if (!(largest_coordinate / diameter <= largest_cell_coordinate)) {
            gridded = false;
            break;
        }
        double const cell_size = diameter +
                                 8.0 * unit_roundoff * (2.0 * diameter + largest_coordinate) +
                                 underflow_margin;
        if (ws.levels_.size() == ws.level_count_)
            ws.levels_.emplace_back();
        if (!build_level(x, radius, ws.members_, cell_size, ws.levels_[ws.level_count_],
                         ws.sort_buffers_)) {
            gridded = false;
            break;
        }
        ++ws.level_count_;
    }

    // 3. Pairs within each level and between each level and every coarser one.
    if (gridded) {
        for (std::size_t b = 0; b < ws.level_count_; ++b) {
            collect_level_pairs(ws.levels_[b], collector);
            for (std::size_t a = 0; a < b; ++a)
                collect_cross_pairs(ws.levels_[a], ws.levels_[b], collector);
        }
    } else {
        collect_pairs_by_sweep(x, radius, ws.fallback_boxes_, ws.members_, ws.fallback_pairs_,
                               ws.fallback_workspace_, collector);
    }

    // 4. Irregular spheres against every sphere, each pair of them once.
    for (std::uint32_t i : ws.irregular_) {
        sphere_record const s = record_of(x[i], radius[i]);
        for (std::uint32_t j = 0; j < n; ++j) {
            if (j == i || !(radius[j] > 0.0) || (j < i && !is_regular(x[j], radius[j])))
                continue;
            if (touch(s, record_of(x[j], radius[j])))
                collector.add(i, j);
        }
    }

    // 5. Ascending by (i, j).
    sort_pairs(std::span(ws.pairs_).first(collector.found), n, ws.pair_counts_, out);
}

} // namespace kugel::physics
