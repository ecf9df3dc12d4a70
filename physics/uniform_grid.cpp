#include "broadphase.hpp"
#include "cells.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <limits>
#include <optional>
#include <utility>

namespace kugel::physics {

namespace {

/// Up to this many cells per box the grid keeps a table of every cell (dense); beyond it
/// (a sparse scene, e.g. far-apart clusters) it sorts the keys and walks them instead.
constexpr std::uint64_t dense_cells_per_box = 8;
constexpr int radix_bits = 11;
constexpr std::uint64_t radix_mask = (std::uint64_t{1} << radix_bits) - 1;

using cell_coordinates = std::array<std::int64_t, 3>;
/// A box's candidates: five runs of entries, [begin, end) each.
using runs = std::array<std::array<std::uint32_t, 2>, 5>;

cell_coordinates cell_of(vec3 const& corner, double cell_size)
{
    return {cells::floor_to_integer(corner.x() / cell_size), cells::floor_to_integer(corner.y() / cell_size),
            cells::floor_to_integer(corner.z() / cell_size)};
}

/// The cells of one call: their size, the padded extent, and how keys number them.
struct grid_layout
{
    double cell_size = 0.0; ///< m
    cell_coordinates lowest{};
    std::uint64_t stride_x = 0, stride_y = 0, all_cells = 0;
    bool dense = false;

    std::uint64_t key_of(vec3 const& corner) const
    {
        cell_coordinates const c = cell_of(corner, cell_size);
        auto const offset = [&](std::size_t k) { return static_cast<std::uint64_t>(c[k] - lowest[k]) + 1; };
        return offset(0) * stride_x + offset(1) * stride_y + offset(2);
    }
    /// The forward rows (0, +1, *), (+1, -1, *), (+1, 0, *), (+1, +1, *): the three cells
    /// z - 1, z, z + 1 of a row are adjacent in key order, so a row is one run of entries,
    /// from key + offset - 1 to key + offset + 1. The (0, 0, +1) neighbour is the cell after.
    std::array<std::uint64_t, 4> row_offsets() const
    {
        return {stride_y, stride_x - stride_y, stride_x, stride_x + stride_y};
    }
};

/// 1, 2. The cell size, from the largest extent and the extreme lower corners, and the cells
/// in use, padded by one on every side so that a neighbour's key never wraps into another
/// row and every neighbour of an occupied cell has a key. floor(x/h) is monotone in x, so the
/// extreme cells are those of the extreme lower corners. Nothing when the grid cannot hold
/// the scene.
std::optional<grid_layout> lay_out(std::span<aabb const> boxes)
{
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
    if (!(largest_extent > 0.0) || !(reach <= cells::largest_cell_coordinate))
        return std::nullopt;
    grid_layout grid;
    grid.cell_size = cells::widened_cell_size(largest_extent, reach); // m
    grid.lowest = cell_of(lowest_corner, grid.cell_size);
    cell_coordinates const highest = cell_of(highest_corner, grid.cell_size);
    std::array<std::uint64_t, 3> padded_size;
    for (std::size_t k = 0; k < 3; ++k)
        padded_size[k] = static_cast<std::uint64_t>(highest[k] - grid.lowest[k]) + 3;
    auto const plane_cells = cells::checked_product(padded_size[1], padded_size[2]);
    auto const all_cells = plane_cells ? cells::checked_product(padded_size[0], *plane_cells) : std::nullopt;
    if (!all_cells)
        return std::nullopt;
    grid.stride_y = padded_size[2];
    grid.stride_x = *plane_cells;
    grid.all_cells = *all_cells;
    grid.dense = *all_cells <= dense_cells_per_box * boxes.size() + 1024;
    return grid;
}

/// 3. The entries sorted by key, stably, so the boxes of a cell stay in index order: a
///    counting sort over every cell (after which counts[k] is where cell k's run starts, and
///    counts[all_cells] = n), or an LSD radix sort on the key bits in use.
template <class Entries>
void sort_by_cell(grid_layout const& grid, Entries& entries, Entries& scratch, std::vector<std::uint32_t>& counts)
{
    if (grid.dense) {
        counts.assign(grid.all_cells + 1, 0);
        for (auto const& e : entries)
            ++counts[e.key];
        std::uint32_t sum = 0;
        for (auto& count : counts)
            sum = count += sum; // inclusive: the end of each run
        for (auto i = entries.size(); i-- > 0;)
            scratch[--counts[entries[i].key]] = entries[i];
        entries.swap(scratch);
        return;
    }
    auto const key_bits = static_cast<int>(std::bit_width(grid.all_cells - 1));
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

/// 4, dense: runs looked up directly, cell k holding entries [counts[k], counts[k + 1]).
template <class Entries, class Collect>
void each_box_dense(grid_layout const& grid, Entries const& entries, std::vector<std::uint32_t> const& counts,
                    Collect const& collect)
{
    auto const rows = grid.row_offsets();
    for (std::uint32_t p = 0; p < entries.size(); ++p) {
        std::uint64_t const key = entries[p].key;
        runs candidates;
        candidates[0] = {p + 1, counts[key + 2]}; // own cell, then (0, 0, +1)
        for (std::size_t r = 0; r < rows.size(); ++r)
            candidates[r + 1] = {counts[key + rows[r] - 1], counts[key + rows[r] + 2]};
        collect(p, candidates);
    }
}

/// 4, sparse: runs found by walking the sorted keys. A sentinel (pushed here) ends every walk,
/// and each run's ends only ever move forward, as the keys grow.
template <class Entries, class Collect>
void each_box_sparse(grid_layout const& grid, Entries& entries, Collect const& collect)
{
    auto const n = static_cast<std::uint32_t>(entries.size());
    auto const rows = grid.row_offsets();
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
        for (std::size_t r = 0; r < rows.size(); ++r) {
            auto& [row_begin, row_end] = candidates[r + 1];
            std::uint64_t const first = key + rows[r] - 1;
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
// Why one cell apart holds in floating point: cells.hpp, with the extent of the largest box
// for E and the lower corners for the things filed.
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
    std::optional<grid_layout> const grid = lay_out(boxes); // 1, 2
    if (!grid) {
        sweep_and_prune_pairs(boxes, out, workspace);
        return;
    }
    // 3. File each box under its lower corner's cell, sort, and copy the boxes into that
    //    order, so that the pair loops below read memory in sequence.
    auto& entries = workspace.cell_entries_;
    auto& scratch = workspace.cell_entries_scratch_;
    auto& sorted_boxes = workspace.boxes_in_cell_order_;
    entries.reserve(std::size_t{n} + 1); // room for a sentinel, whichever buffer ends up here
    scratch.reserve(std::size_t{n} + 1);
    entries.resize(n);
    scratch.resize(n);
    sorted_boxes.resize(n);
    for (std::uint32_t i = 0; i < n; ++i)
        entries[i] = {grid->key_of(boxes[i].min), i};
    sort_by_cell(*grid, entries, scratch, workspace.cell_counts_);
    for (std::uint32_t k = 0; k < n; ++k)
        sorted_boxes[k] = boxes[entries[k].index];

    // 4. Each box against its candidates: the rest of its own cell, the (0, 0, +1) cell and
    //    the four forward rows, five runs of entries. Each candidate is written to `out`
    //    and kept only if the boxes overlap (the count advances by the test's result), which
    //    spares a hard-to-predict branch per candidate.
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
                kept += overlaps(box_p, sorted_boxes[q]) ? 1 : 0;
            }
        }
        found = kept;
    };
    if (grid->dense)
        each_box_dense(*grid, entries, workspace.cell_counts_, collect);
    else
        each_box_sparse(*grid, entries, collect);
    out.resize(found);

    sort_box_pairs(out, n, workspace);
}

} // namespace kugel::physics
