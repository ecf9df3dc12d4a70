#include "sphere_grid.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace kugel::physics {

namespace {

constexpr double unit_roundoff = 0x1p-53;
/// As in uniform_grid.cpp: beyond this |coordinate| / cell size, cells get finer than the
/// coordinates can resolve.
constexpr double largest_cell_coordinate = 0x1p47;
/// Slabs per grid at most: enough for two threads to share them evenly, few enough that a
/// slab is much larger than its boundary with the next.
constexpr std::size_t most_slabs = 16;

/// floor(q) for |q| < 2^53, without a library call.
std::int64_t floor_to_integer(double q)
{
    auto const truncated = static_cast<std::int64_t>(q);
    return q < static_cast<double>(truncated) ? truncated - 1 : truncated;
}

/// What one chunk of bodies holds: its spheres' count, largest radius and extreme centres.
struct chunk_extremes
{
    std::uint32_t spheres = 0;
    double largest_radius = 0.0; // m
    vec3 lowest = vec3::Constant(std::numeric_limits<double>::infinity());
    vec3 highest = vec3::Constant(-std::numeric_limits<double>::infinity());
};

} // namespace

// Why neighbouring cells suffice, in floating point: boxes [x − r, x + r] that overlap on an
// axis have centres at most r₁ + r₂ <= 2·r_max apart plus the rounding of x ± r, and their
// cells are computed from rounded quotients x/h. With h = 2·r_max·(1 + 8u·(2 + reach)),
// reach = max|x| / (2·r_max) and u = 2^-53, the computed quotients of two such centres differ
// by at most 1 (the rounding adds at most u·(4·reach + 1) relative to h), so their cells are
// the same or adjacent on every axis. The same argument as uniform_grid.cpp's, for centres.
bool sphere_grid::build(std::span<vec3 const> x, std::span<double const> radius, parallel_for* loops)
{
    slab_begin_.assign(1, 0);
    slab_column_.assign(1, 0);
    std::size_t const n = x.size();
    if (n >= (std::size_t{1} << 30))
        return false; // the tables below count in 32 bits

    // 1. Spheres, largest radius and extreme centres, per chunk of bodies (min and max are
    //    exact, so any split gives the same result).
    std::vector<chunk_extremes> chunks(chunk_count(n));
    run_chunks(loops, n, [&](std::size_t c, std::size_t begin, std::size_t end) {
        chunk_extremes found;
        for (std::size_t i = begin; i < end; ++i) {
            if (!(radius[i] > 0.0))
                continue;
            ++found.spheres;
            found.largest_radius = std::max(found.largest_radius, radius[i]);
            found.lowest = found.lowest.cwiseMin(x[i]);
            found.highest = found.highest.cwiseMax(x[i]);
        }
        chunks[c] = found;
    });
    chunk_extremes all;
    std::vector<std::uint32_t> first_entry(chunks.size()); // of each chunk's spheres
    for (std::size_t c = 0; c < chunks.size(); ++c) {
        first_entry[c] = all.spheres;
        all.spheres += chunks[c].spheres;
        all.largest_radius = std::max(all.largest_radius, chunks[c].largest_radius);
        all.lowest = all.lowest.cwiseMin(chunks[c].lowest);
        all.highest = all.highest.cwiseMax(chunks[c].highest);
    }
    if (all.spheres == 0)
        return false;

    // 2. Cell size and the grid's extent, padded by one cell on every side so that every
    //    neighbour of an occupied cell has a column and a z-cell.
    double const diameter = 2.0 * all.largest_radius;
    double const reach =
        std::max(all.lowest.cwiseAbs().maxCoeff(), all.highest.cwiseAbs().maxCoeff()) / diameter;
    if (!(reach <= largest_cell_coordinate))
        return false;
    double const cell_size = diameter + diameter * (8.0 * unit_roundoff * (2.0 + reach)); // m
    std::array<std::int64_t, 3> lowest_cell, size;
    for (int k = 0; k < 3; ++k) {
        lowest_cell[static_cast<std::size_t>(k)] = floor_to_integer(all.lowest[k] / cell_size);
        size[static_cast<std::size_t>(k)] =
            floor_to_integer(all.highest[k] / cell_size) - lowest_cell[static_cast<std::size_t>(k)] + 3;
    }
    // Tables of columns and z-cells no larger than a few entries per sphere.
    auto const limit = static_cast<std::int64_t>(4 * std::size_t{all.spheres} + 1024);
    if (size[0] > limit || size[1] > limit || size[2] > limit || size[0] * size[1] > limit)
        return false;
    cells_y_ = static_cast<std::size_t>(size[1]);
    auto const columns = static_cast<std::size_t>(size[0] * size[1]);
    auto const cells_z = static_cast<std::size_t>(size[2]);

    // 3. Each sphere's column and z-cell, in slot order.
    entries_.resize(all.spheres);
    run_chunks(loops, n, [&](std::size_t c, std::size_t begin, std::size_t end) {
        std::uint32_t k = first_entry[c];
        for (std::size_t i = begin; i < end; ++i) {
            if (!(radius[i] > 0.0))
                continue;
            auto const cell = [&](int axis) {
                return static_cast<std::uint32_t>(floor_to_integer(x[i][axis] / cell_size) -
                                                  lowest_cell[static_cast<std::size_t>(axis)] + 1);
            };
            entries_[k++] = {static_cast<std::uint32_t>(cell(0) * cells_y_ + cell(1)), cell(2),
                             static_cast<std::uint32_t>(i)};
        }
    });

    // 4. Sort by (column, z-cell, slot): two stable counting sorts, on the z-cell and then on
    //    the column, of entries that start in slot order.
    scratch_.resize(all.spheres);
    auto const counting_sort = [&](std::vector<cell_entry> const& from, std::vector<cell_entry>& to,
                                   std::size_t buckets, auto key) {
        counts_.assign(buckets + 1, 0);
        for (cell_entry const& e : from)
            ++counts_[key(e) + 1];
        for (std::size_t b = 1; b <= buckets; ++b)
            counts_[b] += counts_[b - 1];
        for (cell_entry const& e : from)
            to[counts_[key(e)]++] = e;
    };
    counting_sort(entries_, scratch_, cells_z, [](cell_entry const& e) { return e.z; });
    counting_sort(scratch_, entries_, columns, [](cell_entry const& e) { return e.column; });
    // After the scatter counts_[b] is the end of column b's run: shift it into the starts.
    column_begin_.resize(columns + 1);
    column_begin_[0] = 0;
    std::copy(counts_.begin(), counts_.begin() + static_cast<std::ptrdiff_t>(columns),
              column_begin_.begin() + 1);

    // 5. The spheres in cell order, and each slot's position in it.
    spheres_.resize(all.spheres);
    cell_z_.resize(all.spheres);
    slot_.resize(all.spheres);
    rank_.resize(n);
    run_chunks(loops, all.spheres, [&](std::size_t, std::size_t begin, std::size_t end) {
        for (std::size_t k = begin; k < end; ++k) {
            std::uint32_t const i = entries_[k].slot;
            spheres_[k] = {x[i].x(), x[i].y(), x[i].z(), radius[i]};
            cell_z_[k] = entries_[k].z;
            slot_[k] = i;
            rank_[i] = static_cast<std::uint32_t>(k);
        }
    });

    // 6. Slabs of equal numbers of x-cells (the padding cells hold no sphere).
    auto const cells_x = static_cast<std::size_t>(size[0]) - 2;
    std::size_t const width = (cells_x + most_slabs - 1) / most_slabs;
    std::size_t const slabs = (cells_x + width - 1) / width;
    slab_column_.resize(slabs + 1);
    slab_begin_.resize(slabs + 1);
    for (std::size_t s = 0; s <= slabs; ++s) {
        std::size_t const first_x = s == 0 ? 0 : std::min(1 + s * width, cells_x + 1);
        slab_column_[s] = static_cast<std::uint32_t>(s == slabs ? columns : first_x * cells_y_);
        slab_begin_[s] = column_begin_[slab_column_[s]];
    }
    return true;
}

std::size_t sphere_grid::slab_of(std::uint32_t rank) const
{
    auto const after = std::upper_bound(slab_begin_.begin(), slab_begin_.end() - 1, rank);
    return static_cast<std::size_t>(after - slab_begin_.begin()) - 1;
}

// Each sphere against the rest of its own cell, the cell above it, and the cells of four
// neighbouring columns from one z-cell below to one above: the 13 neighbours that come
// after a cell in cell order, so each pair of cells is visited once. Within a column the
// spheres are sorted by z-cell, so each neighbour column's window only moves forward.
// The candidates come in cell order, which makes the output sorted without a sort.
void sphere_grid::near_pairs(std::size_t s, std::vector<box_pair>& out) const
{
    out.clear();
    auto const meet = [](filed_sphere const& a, filed_sphere const& b) {
        bool const x = std::max(a.x - a.r, b.x - b.r) <= std::min(a.x + a.r, b.x + b.r);
        bool const y = std::max(a.y - a.r, b.y - b.r) <= std::min(a.y + a.r, b.y + b.r);
        bool const z = std::max(a.z - a.r, b.z - b.r) <= std::min(a.z + a.r, b.z + b.r);
        return x & y & z;
    };
    for (std::size_t column = slab_column_[s]; column < slab_column_[s + 1]; ++column) {
        std::uint32_t const begin = column_begin_[column], end = column_begin_[column + 1];
        if (begin == end)
            continue;
        std::array<std::size_t, 4> const neighbours = {column + 1, column + cells_y_ - 1,
                                                       column + cells_y_, column + cells_y_ + 1};
        std::array<std::uint32_t, 4> window, window_end;
        for (std::size_t k = 0; k < 4; ++k) {
            window[k] = column_begin_[neighbours[k]];
            window_end[k] = column_begin_[neighbours[k] + 1];
        }
        for (std::uint32_t p = begin; p < end; ++p) {
            std::uint32_t const z = cell_z_[p];
            filed_sphere const& a = spheres_[p];
            auto const test = [&](std::uint32_t q) {
                if (meet(a, spheres_[q]))
                    out.push_back({std::min(slot_[p], slot_[q]), std::max(slot_[p], slot_[q])});
            };
            for (std::uint32_t q = p + 1; q < end && cell_z_[q] <= z + 1; ++q)
                test(q);
            for (std::size_t k = 0; k < 4; ++k) {
                while (window[k] < window_end[k] && cell_z_[window[k]] + 1 < z)
                    ++window[k];
                for (std::uint32_t q = window[k]; q < window_end[k] && cell_z_[q] <= z + 1; ++q)
                    test(q);
            }
        }
    }
}

} // namespace kugel::physics
