#include "sphere_grid.hpp"

#include "kernels.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <optional>
#include <utility>

namespace kugel::physics {

namespace {

/// Up to this many cells per sphere the grid keeps a table of every cell's start (a gas at
/// 10% fill has about 5); beyond it, a sparse scene, it searches the sorted keys instead.
constexpr std::uint64_t dense_cells_per_sphere = 16;
/// Up to this many cells (a 4 MiB table) one thread sorts all spheres at once; a larger
/// table is sorted slab by slab even on one thread, so that each slab's part of the table
/// stays in cache while its spheres are counted and placed (bench/README.md, decisions).
constexpr std::uint64_t direct_sort_cells = std::uint64_t{1} << 20;
/// How many spheres ahead the counting sorts fetch the table entries (and the destinations,
/// half as far) they will need: the table is larger than the nearest caches and the cells come
/// in no order (bench/README.md, decisions).
constexpr std::size_t prefetch_distance = 16;

} // namespace

void sphere_grid::resize_filed(std::uint32_t spheres)
{
    spheres_.resize(spheres);
    inverse_masses_.resize(spheres);
    slots_.resize(spheres);
    cells_.resize(spheres);
}

void sphere_grid::fetch_destination(std::uint32_t start) const
{
    // one before the cell's present start; a cell with no sphere left to place may start at 0
    __builtin_prefetch(spheres_.data() + (start - (start > 0 ? 1 : 0)), 1);
}

auto sphere_grid::filer()
{
    return [spheres = spheres_.data(), inverse_masses = inverse_masses_.data(), slots = slots_.data(),
            cells = cells_.data()](std::uint32_t rank, filed_sphere const& e) {
        spheres[rank] = {e.x, e.radius};
        inverse_masses[rank] = e.inverse_mass;
        slots[rank] = e.slot;
        cells[rank] = e.cell;
    };
}

bool sphere_grid::build(std::span<vec3 const> x, std::span<double const> radius,
                        std::span<double const> inverse_mass, parallel_for* loops, slab_ready const& ready)
{
    // 1. Spheres, largest radius and extreme centres, per chunk of bodies.
    std::vector<sphere_extent> found(chunk_count(x.size()));
    run_chunks(loops, x.size(), [&](std::size_t c, std::size_t begin, std::size_t end) {
        for (std::size_t i = begin; i < end; ++i)
            found[c].add(x[i], radius[i]);
    });
    sphere_extent all;
    for (sphere_extent const& part : found)
        all.add(part);
    return build(x, radius, inverse_mass, all, loops, ready);
}

// Cells are as wide as the largest diameter, widened for rounding (physics/cells.hpp); for
// the reach that widening depends on, the grid takes the power of two at or above
// max|x| / (2·r_max), so that its cells stay the same while the scene's extent changes a
// little: a gas numbers its cells in the same frame step after step.
bool sphere_grid::build(std::span<vec3 const> x, std::span<double const> radius,
                        std::span<double const> inverse_mass, sphere_extent const& all, parallel_for* loops,
                        slab_ready const& ready, cell_keys const* keyed)
{
    slab_begin_.assign(1, 0);
    slab_cell_.assign(1, 0);
    in_cell_order_ = false;
    keying_frame_.reset();
    std::size_t const n = x.size();
    if (n >= (std::size_t{1} << 28))
        return false; // the tables below count in 32 bits
    if (all.spheres == 0)
        return false;
    std::optional<layout> const grid = lay_out(all); // 2, 3
    if (!grid)
        return false;
    in_cell_order_ = true; // from here on, the spheres are filed in cell order
    // Keys given in this very frame are the ones the build would find (threads need their
    // x-cells too).
    bool const keys_fit = dense_ && keyed && keyed->frame == grid->frame && keyed->keys.size() == n;
    if (dense_ && !loops && grid->cells <= direct_sort_cells)
        sort_all_at_once(x, radius, inverse_mass, all, *grid, keys_fit ? keyed->keys.data() : nullptr, ready);
    else
        sort_slab_by_slab(x, radius, inverse_mass, all, *grid, keys_fit ? keyed : nullptr, loops, ready);
    return true;
}

std::optional<sphere_grid::layout> sphere_grid::lay_out(sphere_extent const& all)
{
    // 2. Cell size and the grid's extent, padded by one cell on every side so that every
    //    neighbour of an occupied cell has a key and no neighbour's key wraps into another row,
    //    and by a second above in z, so that the end of a run of three cells (the start of the
    //    cell after it) is in the same row too: the pairs of a slab then read the table and
    //    the spheres of that slab and the next alone, which lets them be found before the
    //    slab after that is sorted.
    double const diameter = 2.0 * all.largest_radius + margin_; // what a near pair spans on an axis
    double const reach =
        std::max(all.lowest.cwiseAbs().maxCoeff(), all.highest.cwiseAbs().maxCoeff()) / diameter;
    if (!(reach <= cells::largest_cell_coordinate))
        return std::nullopt;
    double const reach_bound = std::exp2(std::ceil(std::log2(std::max(reach, 1.0)))); // exact
    double const cell_size = cells::widened_cell_size(diameter, reach_bound); // m
    double const per_metre = 1.0 / cell_size; // a product is cheaper than a quotient, three per sphere
    layout out;
    std::array<std::int64_t, 3> lowest_cell;
    for (std::size_t k = 0; k < 3; ++k) {
        auto const axis = static_cast<Eigen::Index>(k);
        lowest_cell[k] = cells::floor_to_integer(all.lowest[axis] * per_metre);
        out.size[k] = cells::floor_to_integer(all.highest[axis] * per_metre) - lowest_cell[k] + (k == 2 ? 4 : 3);
    }
    // Keys number every cell of the padded grid; a table of them all is kept when it has no
    // more than a few entries per sphere.
    auto const plane_cells =
        cells::checked_product(static_cast<std::uint64_t>(out.size[1]), static_cast<std::uint64_t>(out.size[2]));
    auto const all_cells =
        plane_cells ? cells::checked_product(static_cast<std::uint64_t>(out.size[0]), *plane_cells) : std::nullopt;
    if (!all_cells || *all_cells >= std::numeric_limits<std::uint64_t>::max() / 2)
        return std::nullopt;
    out.cells = *all_cells;
    stride_y_ = static_cast<std::uint64_t>(out.size[2]);
    stride_x_ = *plane_cells;
    // Coordinate 0 is the padding cell below the lowest occupied one.
    out.frame = {per_metre, {lowest_cell[0] - 1, lowest_cell[1] - 1, lowest_cell[2] - 1}, stride_x_, stride_y_};
    dense_ = out.cells <= dense_cells_per_sphere * std::uint64_t{all.spheres} + 1024;
    if (dense_)
        keying_frame_ = out.frame;

    // 3. Slabs of equal numbers of x-cells; the first and last also hold the padding cells,
    //    and the last the end of the table.
    auto const cells_x = static_cast<std::uint64_t>(out.size[0]) - 2;
    out.slab_width = (cells_x + most_slabs - 1) / most_slabs;
    out.slabs = static_cast<std::uint32_t>((cells_x + out.slab_width - 1) / out.slab_width);
    slab_cell_.resize(out.slabs + 1);
    for (std::uint32_t s = 1; s < out.slabs; ++s)
        slab_cell_[s] = (1 + s * out.slab_width) * stride_x_;
    slab_cell_[out.slabs] = out.cells + 1;
    return out;
}

// 4. On one thread, a single counting sort over every cell, straight from the bodies: the same
//    order (cell, then slot) without the buckets per slab that let threads sort slabs at the
//    same time. A slab then starts where its first cell does. The table (a few cells per
//    sphere) is larger than the nearest caches, and the cells come in no order: so the keys are
//    found first, and each pass fetches the table's entry (and, placing, the entry's
//    destination) some spheres ahead of using it.
void sphere_grid::sort_all_at_once(std::span<vec3 const> x, std::span<double const> radius,
                                   std::span<double const> inverse_mass, sphere_extent const& all,
                                   layout const& grid, std::uint64_t const* given_keys, slab_ready const& ready)
{
    std::size_t const n = x.size();
    std::uint64_t const* key = given_keys;
    if (!key) {
        keys_.resize(n);
        for (std::size_t i = 0; i < n; ++i) // bodies that are not spheres get a key, unused
            keys_[i] = radius[i] > 0.0 ? grid.frame.key(x[i]) : 0;
        key = keys_.data();
    }
    std::uint32_t* const table = (cell_begin_.assign(grid.cells + 1, 0U), cell_begin_.data());
    for (std::size_t i = 0; i < n; ++i) {
        if (i + prefetch_distance < n)
            __builtin_prefetch(table + key[i + prefetch_distance], 1);
        table[key[i]] += radius[i] > 0.0 ? 1U : 0U;
    }
    discrete::running_sums(table, table + cell_begin_.size(), 0); // each cell's end, for now
    resize_filed(all.spheres);
    auto const file = filer();
    for (std::size_t i = n; i-- > 0;) {
        if (i >= prefetch_distance)
            __builtin_prefetch(table + key[i - prefetch_distance], 1);
        if (i >= prefetch_distance / 2)
            fetch_destination(table[key[i - prefetch_distance / 2]]);
        if (radius[i] > 0.0) // now each cell's start:
            file(--table[key[i]], {key[i], static_cast<std::uint32_t>(i), x[i], radius[i], inverse_mass[i]});
    }
    slab_begin_.resize(grid.slabs + 1);
    for (std::uint32_t s = 0; s <= grid.slabs; ++s)
        slab_begin_[s] = s < grid.slabs ? cell_begin_[slab_cell_[s]] : all.spheres;
    if (ready)
        for (std::size_t s = 0; s < grid.slabs; ++s)
            ready(s);
}

// 5. Each sphere's cell key and slab, and how many spheres each chunk of bodies has in each
//    slab; then where each chunk's share of a slab goes, after the earlier chunks' shares, so
//    that every slab holds its spheres in slot order. Returns the keys by body slot.
std::uint64_t const* sphere_grid::count_by_slab(std::span<vec3 const> x, std::span<double const> radius,
                                                layout const& grid, cell_keys const* given, parallel_for* loops)
{
    std::size_t const n = x.size(), chunks = chunk_count(n);
    std::uint32_t const slabs = grid.slabs;
    // A table of each x-cell's slab spares a 64-bit division per sphere (the padding cells
    // belong to the first and last slab).
    std::size_t const table_x = dense_ ? static_cast<std::size_t>(grid.size[0]) : 0;
    slab_of_x_.resize(table_x);
    for (std::size_t cx = 0; cx < table_x; ++cx)
        slab_of_x_[cx] = static_cast<std::uint32_t>(
            std::min<std::uint64_t>((std::max<std::uint64_t>(cx, 1) - 1) / grid.slab_width, slabs - 1));
    auto const slab_of_x_cell = [&](std::uint64_t cx) {
        return dense_ ? slab_of_x_[cx] : static_cast<std::uint32_t>((cx - 1) / grid.slab_width);
    };
    chunk_slab_start_.assign(chunks * slabs, 0);
    slabs_.resize(n);
    // Keys given in this frame, with their x-cells, leave only the slabs to find.
    bool const keys_given = given && given->x_cells.size() == n;
    if (!keys_given)
        keys_.resize(n);
    run_chunks(loops, n, [&](std::size_t c, std::size_t begin, std::size_t end) {
        std::uint32_t* const count = chunk_slab_start_.data() + c * slabs;
        if (keys_given) {
            std::uint32_t const* const x_cell = given->x_cells.data();
            for (std::size_t i = begin; i < end; ++i)
                if (radius[i] > 0.0)
                    ++count[slabs_[i] = slab_of_x_[x_cell[i]]];
            return;
        }
        for (std::size_t i = begin; i < end; ++i) {
            if (!(radius[i] > 0.0))
                continue;
            std::uint64_t cx = 0;
            keys_[i] = grid.frame.key(x[i], cx);
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
    return keys_given ? given->keys.data() : keys_.data();
}

// 6. Within slab s, the spheres sorted by cell, then slot: a counting sort over the slab's
//    cells, stable, which leaves the table of where each cell starts (dense), or a comparison
//    sort (sparse). The slabs' cells and entries are disjoint, so slabs sort at the same time.
//    Each sphere's position, radius and inverse mass are read from its body as it is placed:
//    a slab's entries come in slot order, and a large world keeps its bodies in cell order
//    (world::bodies_worth_sorting), so those reads go nearly in sequence.
void sphere_grid::sort_slab(std::size_t s, std::span<vec3 const> x, std::span<double const> radius,
                            std::span<double const> inverse_mass)
{
    auto const file = filer();
    auto const filed = [&](slab_entry const& e) -> filed_sphere {
        return {e.cell, e.slot, x[e.slot], radius[e.slot], inverse_mass[e.slot]};
    };
    std::uint32_t const begin = slab_begin_[s], end = slab_begin_[s + 1];
    if (!dense_) {
        auto const first = by_slab_.begin() + begin, last = by_slab_.begin() + end;
        std::sort(first, last, [](slab_entry const& a, slab_entry const& b) {
            return a.cell != b.cell ? a.cell < b.cell : a.slot < b.slot;
        });
        for (std::uint32_t k = begin; k < end; ++k)
            file(k, filed(by_slab_[k]));
        return;
    }
    std::uint32_t* const first_cell = cell_begin_.data() + slab_cell_[s];
    std::uint32_t* const last_cell = cell_begin_.data() + slab_cell_[s + 1];
    std::fill(first_cell, last_cell, 0U);
    std::uint32_t* const table = cell_begin_.data();
    slab_entry const* const entry = by_slab_.data();
    for (std::uint32_t k = begin; k < end; ++k) {
        if (k + prefetch_distance < end) // as in sort_all_at_once()
            __builtin_prefetch(table + entry[k + prefetch_distance].cell, 1);
        ++table[entry[k].cell];
    }
    discrete::running_sums(first_cell, last_cell, begin); // each cell's end, for now
    for (std::uint32_t k = end; k-- > begin;) {
        if (k >= begin + prefetch_distance)
            __builtin_prefetch(table + entry[k - prefetch_distance].cell, 1);
        if (k >= begin + prefetch_distance / 2)
            fetch_destination(table[entry[k - prefetch_distance / 2].cell]);
        file(--table[entry[k].cell], filed(entry[k])); // now each cell's start
    }
}

void sphere_grid::sort_slab_by_slab(std::span<vec3 const> x, std::span<double const> radius,
                                    std::span<double const> inverse_mass, sphere_extent const& all,
                                    layout const& grid, cell_keys const* given, parallel_for* loops,
                                    slab_ready const& ready)
{
    std::size_t const n = x.size();
    std::uint32_t const slabs = grid.slabs;
    std::uint64_t const* const key = count_by_slab(x, radius, grid, given, loops); // 5
    // Each sphere's cell key and slot, to its slab (its position, radius and inverse mass
    // come when it is placed: carrying them here would write and read 40 bytes more each).
    by_slab_.resize(all.spheres);
    run_chunks(loops, n, [&](std::size_t c, std::size_t begin, std::size_t end) {
        std::uint32_t* const start = chunk_slab_start_.data() + c * slabs;
        for (std::size_t i = begin; i < end; ++i)
            if (radius[i] > 0.0)
                by_slab_[start[slabs_[i]]++] = {key[i], static_cast<std::uint32_t>(i)};
    });
    if (dense_)
        cell_begin_.resize(grid.cells + 1);
    resize_filed(all.spheres);
    auto const sort = [&](std::size_t s) { sort_slab(s, x, radius, inverse_mass); }; // 6
    if (!ready || !dense_) { // a sparse grid's search reads every slab's keys
        run_loop(loops, slabs, sort);
        if (ready)
            run_loop(loops, slabs, ready);
        return;
    }
    // 7. Each slab is ready as soon as it and the next are sorted: then, while both are still
    //    in cache, ready() reads them (at 10^6 spheres the grid is larger than the last-level
    //    cache, and reading it afterwards waited on memory). Runs of whole slabs are sorted at
    //    the same time, each in order; the last slab of each run waits for the next run.
    std::size_t const runs = loops ? std::min<std::size_t>(4, slabs) : 1;
    auto const run_begin = [&](std::size_t r) { return slabs * r / runs; };
    run_loop(loops, runs, [&](std::size_t r) {
        for (std::size_t s = run_begin(r); s < run_begin(r + 1); ++s) {
            sort(s);
            if (s > run_begin(r))
                ready(s - 1);
        }
    });
    run_loop(loops, runs, [&](std::size_t r) { ready(run_begin(r + 1) - 1); });
}

void sphere_grid::file_in_slot_order(std::span<vec3 const> x, std::span<double const> radius,
                                     std::span<double const> inverse_mass)
{
    auto const spheres = static_cast<std::uint32_t>(std::count_if(radius.begin(), radius.end(), [](double r) { return r > 0.0; }));
    resize_filed(spheres);
    auto const file = filer();
    std::uint32_t k = 0;
    for (std::size_t i = 0; i < x.size(); ++i)
        if (radius[i] > 0.0)
            file(k++, {0, static_cast<std::uint32_t>(i), x[i], radius[i], inverse_mass[i]});
    slab_begin_ = {0, spheres};
    in_cell_order_ = false;
}

void sphere_grid::ranks(std::size_t n, std::vector<std::uint32_t>& out) const
{
    out.resize(n);
    for (std::uint32_t k = 0; k < slots_.size(); ++k)
        out[slots_[k]] = k;
}

std::size_t sphere_grid::slab_of(std::uint32_t rank) const
{
    auto const after = std::upper_bound(slab_begin_.begin(), slab_begin_.end() - 1, rank);
    return static_cast<std::size_t>(after - slab_begin_.begin()) - 1;
}

} // namespace kugel::physics
