#include "sphere_grid.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <optional>
#include <utility>

namespace kugel::physics {

namespace {

constexpr double unit_roundoff = 0x1p-53;
/// As in uniform_grid.cpp: beyond this |coordinate| / cell size, cells get finer than the
/// coordinates can resolve.
constexpr double largest_cell_coordinate = 0x1p47;
/// Slabs per grid at most: enough for two threads to share them evenly, few enough that a
/// slab is much larger than its boundary with the next.
constexpr std::uint32_t most_slabs = 16;
/// Up to this many cells per sphere the grid keeps a table of every cell's start (a gas at
/// 10% fill has about 5); beyond it, a sparse scene, it searches the sorted keys instead.
constexpr std::uint64_t dense_cells_per_sphere = 16;

/// floor(q) for |q| < 2^53, without a library call.
std::int64_t floor_to_integer(double q)
{
    auto const truncated = static_cast<std::int64_t>(q);
    return q < static_cast<double>(truncated) ? truncated - 1 : truncated;
}

/// a · b, or nullopt when it does not fit in 64 bits.
std::optional<std::uint64_t> checked_product(std::uint64_t a, std::uint64_t b)
{
    if (a != 0 && b > std::numeric_limits<std::uint64_t>::max() / a)
        return std::nullopt;
    return a * b;
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
bool sphere_grid::build(std::span<vec3 const> x, std::span<double const> radius,
                        std::span<double const> inverse_mass, parallel_for* loops)
{
    slab_begin_.assign(1, 0);
    slab_cell_.assign(1, 0);
    std::size_t const n = x.size();
    if (n >= (std::size_t{1} << 28))
        return false; // the tables below count in 32 bits

    // 1. Spheres, largest radius and extreme centres, per chunk of bodies (min and max are
    //    exact, so any split gives the same result).
    std::size_t const chunks = chunk_count(n);
    std::vector<chunk_extremes> found(chunks);
    run_chunks(loops, n, [&](std::size_t c, std::size_t begin, std::size_t end) {
        chunk_extremes e;
        for (std::size_t i = begin; i < end; ++i) {
            if (!(radius[i] > 0.0))
                continue;
            ++e.spheres;
            e.largest_radius = std::max(e.largest_radius, radius[i]);
            e.lowest = e.lowest.cwiseMin(x[i]);
            e.highest = e.highest.cwiseMax(x[i]);
        }
        found[c] = e;
    });
    chunk_extremes all;
    for (std::size_t c = 0; c < chunks; ++c) {
        all.spheres += found[c].spheres;
        all.largest_radius = std::max(all.largest_radius, found[c].largest_radius);
        all.lowest = all.lowest.cwiseMin(found[c].lowest);
        all.highest = all.highest.cwiseMax(found[c].highest);
    }
    if (all.spheres == 0)
        return false;

    // 2. Cell size and the grid's extent, padded by one cell on every side so that every
    //    neighbour of an occupied cell has a key and no neighbour's key wraps into another row.
    double const diameter = 2.0 * all.largest_radius;
    double const reach =
        std::max(all.lowest.cwiseAbs().maxCoeff(), all.highest.cwiseAbs().maxCoeff()) / diameter;
    if (!(reach <= largest_cell_coordinate))
        return false;
    double const cell_size = diameter + diameter * (8.0 * unit_roundoff * (2.0 + reach)); // m
    std::array<std::int64_t, 3> lowest_cell, size;
    for (std::size_t k = 0; k < 3; ++k) {
        auto const axis = static_cast<Eigen::Index>(k);
        lowest_cell[k] = floor_to_integer(all.lowest[axis] / cell_size);
        size[k] = floor_to_integer(all.highest[axis] / cell_size) - lowest_cell[k] + 3;
    }
    // Keys number every cell of the padded grid; a table of them all is kept when it has no
    // more than a few entries per sphere.
    auto const plane_cells = checked_product(static_cast<std::uint64_t>(size[1]), static_cast<std::uint64_t>(size[2]));
    auto const cells = plane_cells ? checked_product(static_cast<std::uint64_t>(size[0]), *plane_cells) : std::nullopt;
    if (!cells || *cells >= std::numeric_limits<std::uint64_t>::max() / 2)
        return false;
    stride_y_ = static_cast<std::uint64_t>(size[2]);
    stride_x_ = *plane_cells;
    dense_ = *cells <= dense_cells_per_sphere * std::uint64_t{all.spheres} + 1024;

    // 3. Slabs of equal numbers of x-cells; the first and last also hold the padding cells,
    //    and the last the end of the table.
    auto const cells_x = static_cast<std::uint64_t>(size[0]) - 2;
    std::uint64_t const width = (cells_x + most_slabs - 1) / most_slabs;
    auto const slabs = static_cast<std::uint32_t>((cells_x + width - 1) / width);
    slab_cell_.resize(slabs + 1);
    for (std::uint32_t s = 1; s < slabs; ++s)
        slab_cell_[s] = (1 + s * width) * stride_x_;
    slab_cell_[slabs] = *cells + 1;

    // 4. Each sphere's cell key and slab, and how many spheres each chunk of bodies has in
    //    each slab; then where each chunk's share of a slab goes, after the earlier chunks'
    //    shares, so that every slab holds its spheres in slot order.
    auto const cell_of = [&](std::size_t i, Eigen::Index axis) {
        return static_cast<std::uint64_t>(floor_to_integer(x[i][axis] / cell_size) -
                                          lowest_cell[static_cast<std::size_t>(axis)] + 1);
    };
    // A table of each x-cell's slab spares a 64-bit division per sphere (the padding cells
    // belong to the first and last slab).
    std::size_t const table_x = dense_ ? static_cast<std::size_t>(size[0]) : 0;
    slab_of_x_.resize(table_x);
    for (std::size_t cx = 0; cx < table_x; ++cx)
        slab_of_x_[cx] = static_cast<std::uint32_t>(std::min<std::uint64_t>((std::max<std::uint64_t>(cx, 1) - 1) / width, slabs - 1));
    auto const slab_of_x_cell = [&](std::uint64_t cx) {
        return dense_ ? slab_of_x_[cx] : static_cast<std::uint32_t>((cx - 1) / width);
    };
    chunk_slab_start_.assign(chunks * slabs, 0);
    keys_.resize(n);
    slabs_.resize(n);
    run_chunks(loops, n, [&](std::size_t c, std::size_t begin, std::size_t end) {
        std::uint32_t* const count = chunk_slab_start_.data() + c * slabs;
        for (std::size_t i = begin; i < end; ++i) {
            if (!(radius[i] > 0.0))
                continue;
            std::uint64_t const cx = cell_of(i, 0);
            keys_[i] = cx * stride_x_ + cell_of(i, 1) * stride_y_ + cell_of(i, 2);
            slabs_[i] = slab_of_x_cell(cx);
            ++count[slabs_[i]];
        }
    });
    slab_begin_.resize(slabs + 1);
    std::uint32_t next = 0;
    for (std::uint32_t s = 0; s < slabs; ++s) {
        slab_begin_[s] = next;
        for (std::size_t c = 0; c < chunks; ++c)
            next += std::exchange(chunk_slab_start_[c * slabs + s], next);
    }
    slab_begin_[slabs] = next;

    // 5. Each sphere with its cell key, to its slab.
    by_slab_.resize(all.spheres);
    run_chunks(loops, n, [&](std::size_t c, std::size_t begin, std::size_t end) {
        std::uint32_t* const start = chunk_slab_start_.data() + c * slabs;
        for (std::size_t i = begin; i < end; ++i) {
            if (!(radius[i] > 0.0))
                continue;
            by_slab_[start[slabs_[i]]++] = {keys_[i], static_cast<std::uint32_t>(i),
                                            {x[i], radius[i], inverse_mass[i]}};
        }
    });

    // 6. Within each slab, the spheres sorted by cell, then slot: a counting sort over the
    //    slab's cells, stable, which leaves the table of where each cell starts (dense), or a
    //    comparison sort (sparse). The slabs' cells and entries are disjoint, so slabs sort
    //    at the same time.
    if (dense_)
        cell_begin_.resize(*cells + 1);
    filed_.resize(all.spheres);
    run_loop(loops, slabs, [&](std::size_t s) {
        std::uint32_t const begin = slab_begin_[s], end = slab_begin_[s + 1];
        if (dense_) {
            auto const first_cell = cell_begin_.begin() + static_cast<std::ptrdiff_t>(slab_cell_[s]);
            auto const last_cell = cell_begin_.begin() + static_cast<std::ptrdiff_t>(slab_cell_[s + 1]);
            std::fill(first_cell, last_cell, 0U);
            for (std::uint32_t k = begin; k < end; ++k)
                ++cell_begin_[by_slab_[k].cell];
            std::uint32_t sum = begin;
            for (auto cell = first_cell; cell != last_cell; ++cell)
                *cell = sum += *cell; // each cell's end, for now
            for (std::uint32_t k = end; k-- > begin;)
                filed_[--cell_begin_[by_slab_[k].cell]] = by_slab_[k]; // now each cell's start
        } else {
            auto const first = filed_.begin() + begin, last = filed_.begin() + end;
            std::copy(by_slab_.begin() + begin, by_slab_.begin() + end, first);
            std::sort(first, last, [](filed_sphere const& a, filed_sphere const& b) {
                return a.cell != b.cell ? a.cell < b.cell : a.slot < b.slot;
            });
        }
    });
    return true;
}

void sphere_grid::file_in_slot_order(std::span<vec3 const> x, std::span<double const> radius,
                                     std::span<double const> inverse_mass)
{
    filed_.clear();
    for (std::size_t i = 0; i < x.size(); ++i)
        if (radius[i] > 0.0)
            filed_.push_back({0, static_cast<std::uint32_t>(i), {x[i], radius[i], inverse_mass[i]}});
    slab_begin_ = {0, static_cast<std::uint32_t>(filed_.size())};
}

void sphere_grid::ranks(std::size_t n, std::vector<std::uint32_t>& out) const
{
    out.resize(n);
    for (std::uint32_t k = 0; k < filed_.size(); ++k)
        out[filed_[k].slot] = k;
}

std::size_t sphere_grid::slab_of(std::uint32_t rank) const
{
    auto const after = std::upper_bound(slab_begin_.begin(), slab_begin_.end() - 1, rank);
    return static_cast<std::size_t>(after - slab_begin_.begin()) - 1;
}

// Each sphere against the rest of its own cell and the 13 neighbouring cells that come after
// its cell in cell order, so that each pair of cells is visited once: the cell above it
// (z + 1, which follows its own in the table, so the two are one run) and four rows of three
// cells (z − 1 to z + 1, one run each) at (y + 1), (x + 1, y − 1), (x + 1, y), (x + 1, y + 1).
// The runs come in cell order, so the output is sorted without a sort.
void sphere_grid::near_pairs(std::size_t s, std::vector<sphere_pair>& near,
                             std::vector<sphere_pair>& touching) const
{
    if (dense_) {
        near_pairs(s, near, touching, [&](std::uint64_t key) { return cell_begin_[key]; });
    } else {
        near_pairs(s, near, touching, [&](std::uint64_t key) {
            auto const found = std::partition_point(filed_.begin(), filed_.end(),
                                                    [&](filed_sphere const& e) { return e.cell < key; });
            return static_cast<std::uint32_t>(found - filed_.begin());
        });
    }
}

template <class First>
void sphere_grid::near_pairs(std::size_t s, std::vector<sphere_pair>& near,
                             std::vector<sphere_pair>& touching, First const& first_at_or_after) const
{
    near.clear();
    touching.clear();
    std::array<std::uint64_t, 4> const row_offsets = {stride_y_, stride_x_ - stride_y_, stride_x_,
                                                      stride_x_ + stride_y_};
    for (std::uint32_t p = slab_begin_[s]; p < slab_begin_[s + 1]; ++p) {
        std::uint64_t const key = filed_[p].cell;
        std::array<std::array<std::uint32_t, 2>, 5> runs;
        runs[0] = {p + 1, first_at_or_after(key + 2)};
        for (std::size_t k = 0; k < 4; ++k)
            runs[k + 1] = {first_at_or_after(key + row_offsets[k] - 1),
                           first_at_or_after(key + row_offsets[k] + 2)};
        packed_sphere const& a = filed_[p].sphere;
        vec3 const a_lo = (a.x.array() - a.radius).matrix(), a_hi = (a.x.array() + a.radius).matrix();
        for (auto const& [begin, end] : runs) {
            for (std::uint32_t q = begin; q < end; ++q) {
                packed_sphere const& b = filed_[q].sphere;
                // overlaps() from aabb.hpp on [x − r, x + r]: max(lo) <= min(hi) is lo_a <= hi_b
                // and lo_b <= hi_a (as lo <= hi), tested without a branch per axis
                bool meet = a_lo.x() <= b.x.x() + b.radius;
                meet &= b.x.x() - b.radius <= a_hi.x();
                meet &= a_lo.y() <= b.x.y() + b.radius;
                meet &= b.x.y() - b.radius <= a_hi.y();
                meet &= a_lo.z() <= b.x.z() + b.radius;
                meet &= b.x.z() - b.radius <= a_hi.z();
                if (!meet)
                    continue;
                sphere_pair const pair = filed_[p].slot < filed_[q].slot ? sphere_pair{p, q} : sphere_pair{q, p};
                near.push_back(pair);
                // the discrete step's contact test: |x_i − x_j|² against (r_i + r_j)²
                double const reach = a.radius + b.radius;
                if (!((a.x - b.x).squaredNorm() > reach * reach))
                    touching.push_back(pair);
            }
        }
    }
}

} // namespace kugel::physics
