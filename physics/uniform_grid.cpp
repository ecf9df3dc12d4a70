#include "broadphase.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <limits>
#include <utility>

namespace kugel::physics {

namespace {

constexpr double unit_roundoff = 0x1p-53;
/// Largest |coordinate| / cell size the grid accepts; beyond it cells would be finer than
/// the coordinates can resolve, and the grid hands the scene to sweep and prune.
constexpr double largest_cell_coordinate = 0x1p47;
/// Up to this many cells per box the grid keeps a table of every cell (dense); beyond it
/// (a sparse scene, e.g. far-apart clusters) it sorts the keys and walks them instead.
constexpr std::uint64_t dense_cells_per_box = 8;
constexpr int radix_bits = 11;
constexpr std::uint64_t radix_mask = (std::uint64_t{1} << radix_bits) - 1;

using cell_coordinates = std::array<std::int64_t, 3>;

/// floor(q) for |q| < 2^53, without a library call.
std::int64_t floor_to_integer(double q)
{
    auto const truncated = static_cast<std::int64_t>(q);
    return q < static_cast<double>(truncated) ? truncated - 1 : truncated;
}

cell_coordinates cell_of(vec3 const& corner, double cell_size)
{
    return {floor_to_integer(corner.x() / cell_size), floor_to_integer(corner.y() / cell_size),
            floor_to_integer(corner.z() / cell_size)};
}

/// overlaps() from aabb.hpp, the lecture's max{a_i} <= min{b_i} on every axis, with the
/// three axes combined by & rather than &&, so that it compiles without branches.
bool meet(aabb const& a, aabb const& b)
{
    bool const x = std::max(a.min.x(), b.min.x()) <= std::min(a.max.x(), b.max.x());
    bool const y = std::max(a.min.y(), b.min.y()) <= std::min(a.max.y(), b.max.y());
    bool const z = std::max(a.min.z(), b.min.z()) <= std::min(a.max.z(), b.max.z());
    return x & y & z;
}

/// a · b, or nullopt when it does not fit in 64 bits.
std::optional<std::uint64_t> checked_product(std::uint64_t a, std::uint64_t b)
{
    if (a != 0 && b > std::numeric_limits<std::uint64_t>::max() / a)
        return std::nullopt;
    return a * b;
}

} // namespace

// A uniform grid, sorted rather than hashed:
//  1. The cell size h is the largest extent of any box on any axis, so a box spans at most
//     two cells per axis.
//  2. Each box is filed once, under the cell holding its lower corner. Two overlapping boxes
//     then have lower corners at most one cell apart on every axis (proof below).
//  3. The (cell key, box) entries are sorted by key (a counting sort over all cells when
//     there are few cells per box, else a radix sort), so each cell's boxes are one run.
//  4. Every cell is paired with itself and with its 13 "forward" neighbours (the half of
//     the 26 that come after it in key order), so each pair of cells, and so each pair of
//     boxes, is visited exactly once. Candidates are tested with the same interval rule as
//     the other broadphases, and the result is sorted.
//
// Why one cell apart holds in floating point: if min_a <= min_b <= max_a, then in exact
// arithmetic min_b/h - min_a/h <= (max_a - min_a)/h <= 1; the two rounded divisions and the
// rounded extent can add a few units in the last place of |coordinate|/h. h is therefore
// taken slightly larger than the largest extent (by 8u·(2 + |coordinate|_max / extent_max),
// u = 2^-53), which keeps the computed difference <= 1, so the floors differ by at most one.
// For coordinates up to 2^47 cells from the origin this enlargement stays below 1/8.
//
// Falls back to sweep_and_prune, which has no such limits, when:
//  - every box is a point (no extent gives a cell size);
//  - a coordinate is more than 2^47 cells from the origin (e.g. 1e13 m with 0.01 m boxes);
//  - the cells spanned by the scene do not fit in a 64-bit key (e.g. boxes of 0.1 m spread
//    over ±1e12 m): the key packs the three cell coordinates into one integer.
void uniform_grid_pairs(std::span<aabb const> boxes, std::vector<box_pair>& out,
                        broadphase_workspace& workspace)
{
    out.clear();
    auto const n = static_cast<std::uint32_t>(boxes.size());
    if (n < 2)
        return;

    // 1. Cell size, and the extreme lower corners (for step 2), in one pass.
    double largest_extent = 0.0; // m
    vec3 lowest_corner = boxes[0].min;
    vec3 highest_corner = boxes[0].min;
    for (aabb const& box : boxes) {
        largest_extent = std::max(largest_extent, box.extent().maxCoeff());
        lowest_corner = lowest_corner.cwiseMin(box.min);
        highest_corner = highest_corner.cwiseMax(box.min);
    }
    double const largest_coordinate = // m, of the lower corners
        std::max(lowest_corner.cwiseAbs().maxCoeff(), highest_corner.cwiseAbs().maxCoeff());
    double const reach = largest_coordinate / largest_extent;
    if (!(largest_extent > 0.0) || !(reach <= largest_cell_coordinate)) {
        sweep_and_prune_pairs(boxes, out, workspace);
        return;
    }
    double const slack = 8.0 * unit_roundoff * (2.0 + reach);
    double const cell_size = largest_extent + largest_extent * slack; // m

    // 2. The cells in use, padded by one on every side so that a neighbour's key never
    //    wraps into another row and every neighbour of an occupied cell has a key. floor(x/h)
    //    is monotone in x, so the extreme cells are those of the extreme lower corners.
    cell_coordinates const lowest = cell_of(lowest_corner, cell_size);
    cell_coordinates const highest = cell_of(highest_corner, cell_size);
    std::array<std::uint64_t, 3> padded_size;
    for (std::size_t k = 0; k < 3; ++k)
        padded_size[k] = static_cast<std::uint64_t>(highest[k] - lowest[k]) + 3;
    auto const plane_cells = checked_product(padded_size[1], padded_size[2]);
    auto const all_cells = plane_cells ? checked_product(padded_size[0], *plane_cells)
                                       : std::nullopt;
    if (!all_cells) {
        sweep_and_prune_pairs(boxes, out, workspace);
        return;
    }
    std::uint64_t const stride_y = padded_size[2];
    std::uint64_t const stride_x = *plane_cells;
    auto const key_of = [&](vec3 const& corner) {
        cell_coordinates const c = cell_of(corner, cell_size);
        auto const offset = [&](std::size_t k) {
            return static_cast<std::uint64_t>(c[k] - lowest[k]) + 1;
        };
        return offset(0) * stride_x + offset(1) * stride_y + offset(2);
    };
    // The forward rows (0, +1, *), (+1, -1, *), (+1, 0, *), (+1, +1, *): the three cells
    // z - 1, z, z + 1 of a row are adjacent in key order, so a row is one run of entries,
    // from key + offset - 1 to key + offset + 1. The (0, 0, +1) neighbour is the cell after.
    std::array<std::uint64_t, 4> const row_offsets = {stride_y, stride_x - stride_y, stride_x,
                                                      stride_x + stride_y};
    bool const dense = *all_cells <= dense_cells_per_box * n + 1024;

    // 3. File each box under its lower corner's cell; sort by key, stably, so the boxes of
    //    a cell stay in index order; copy the boxes into that order, so that the pair loops
    //    below read memory in sequence.
    auto& entries = workspace.cell_entries_;
    auto& scratch = workspace.cell_entries_scratch_;
    auto& counts = workspace.cell_counts_;
    auto& sorted_boxes = workspace.boxes_in_cell_order_;
    entries.reserve(std::size_t{n} + 1); // room for a sentinel, whichever buffer ends up here
    scratch.reserve(std::size_t{n} + 1);
    entries.resize(n);
    scratch.resize(n);
    sorted_boxes.resize(n);
    for (std::uint32_t i = 0; i < n; ++i)
        entries[i] = {key_of(boxes[i].min), i};

    if (dense) {
        // Counting sort over every cell; afterwards counts[k] is where cell k's run starts
        // (counts has one more slot than there are cells: counts[all_cells] = n).
        counts.assign(*all_cells + 1, 0);
        for (auto const& e : entries)
            ++counts[e.key];
        std::uint32_t sum = 0;
        for (auto& count : counts)
            sum = count += sum; // inclusive: the end of each run
        for (std::uint32_t i = n; i-- > 0;)
            scratch[--counts[entries[i].key]] = entries[i];
        entries.swap(scratch);
    } else {
        // LSD radix sort on the key bits in use.
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
    }
    for (std::uint32_t k = 0; k < n; ++k)
        sorted_boxes[k] = boxes[entries[k].index];

    // 4. Each box against its candidates: the rest of its own cell, the (0, 0, +1) cell and
    //    the four forward rows, five runs of entries. Each candidate is written to `out`
    //    and kept only if the boxes overlap (the count advances by the test's result), which
    //    spares a hard-to-predict branch per candidate.
    using runs = std::array<std::array<std::uint32_t, 2>, 5>;
    std::size_t found = 0;
    auto const collect = [&](std::uint32_t p, runs const& candidates) {
        std::size_t room = 0;
        for (auto const& [begin, end] : candidates)
            room += end - begin;
        if (found + room > out.size())
            out.resize(std::max(2 * out.size(), found + room));
        box_pair* const written = out.data();
        std::size_t kept = found;
        aabb const& box_p = sorted_boxes[p];
        std::uint32_t const i = entries[p].index;
        for (auto const& [begin, end] : candidates) {
            for (std::uint32_t q = begin; q < end; ++q) {
                std::uint32_t const j = entries[q].index;
                written[kept] = {std::min(i, j), std::max(i, j)};
                kept += meet(box_p, sorted_boxes[q]) ? 1 : 0;
            }
        }
        found = kept;
    };

    if (dense) {
        // Runs looked up directly: cell k holds entries [counts[k], counts[k + 1]).
        for (std::uint32_t p = 0; p < n; ++p) {
            std::uint64_t const key = entries[p].key;
            runs candidates;
            candidates[0] = {p + 1, counts[key + 2]}; // own cell, then (0, 0, +1)
            for (std::size_t r = 0; r < row_offsets.size(); ++r)
                candidates[r + 1] = {counts[key + row_offsets[r] - 1],
                                     counts[key + row_offsets[r] + 2]};
            collect(p, candidates);
        }
    } else {
        // Runs found by walking the sorted keys: a sentinel ends every walk, and each run's
        // ends only ever move forward, as the keys grow.
        entries.push_back({std::numeric_limits<std::uint64_t>::max(), n});
        runs candidates{};
        std::uint32_t begin = 0;
        while (begin < n) {
            std::uint64_t const key = entries[begin].key;
            std::uint32_t end = begin + 1;
            while (entries[end].key == key)
                ++end;
            std::uint32_t next_end = end; // end of the (0, 0, +1) neighbour
            while (entries[next_end].key == key + 1)
                ++next_end;
            for (std::size_t r = 0; r < row_offsets.size(); ++r) {
                auto& [row_begin, row_end] = candidates[r + 1];
                std::uint64_t const first = key + row_offsets[r] - 1;
                while (entries[row_begin].key < first)
                    ++row_begin;
                row_end = std::max(row_end, row_begin);
                while (entries[row_end].key <= first + 2)
                    ++row_end;
            }
            for (std::uint32_t p = begin; p < end; ++p) {
                candidates[0] = {p + 1, next_end};
                collect(p, candidates);
            }
            begin = end;
        }
    }
    out.resize(found);

    sort_box_pairs(out, n, workspace);
}

} // namespace kugel::physics
