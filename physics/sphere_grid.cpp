#include "sphere_grid.hpp"

#include "aabb.hpp"
#include "sse2.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>
#include <utility>


namespace kugel::physics {

namespace {

constexpr double unit_roundoff = 0x1p-53;
/// As in uniform_grid.cpp: beyond this |coordinate| / cell size, cells get finer than the
/// coordinates can resolve.
constexpr double largest_cell_coordinate = 0x1p47;
/// Up to this many cells per sphere the grid keeps a table of every cell's start (a gas at
/// 10% fill has about 5); beyond it, a sparse scene, it searches the sorted keys instead.
constexpr std::uint64_t dense_cells_per_sphere = 16;
/// Up to this many cells (a 4 MiB table) one thread sorts all spheres at once; a larger
/// table is sorted slab by slab even on one thread, so that each slab's part of the table
/// stays in cache while its spheres are counted and placed (the gas_step benchmark at 10^6
/// spheres: 150 ms per step sorting all at once, 140 ms slab by slab).
constexpr std::uint64_t direct_sort_cells = std::uint64_t{1} << 20;

/// How many spheres ahead the counting sorts fetch the table entries (and the destinations,
/// half as far) they will need: the table is larger than the nearest caches and the cells come
/// in no order. 16 and 32 measured the same; without, a step of 10^5 spheres was 8 % slower.
constexpr std::size_t prefetch_distance = 16;

/// Replaces each count in [first, last) by the sum of `start` and the counts up to and
/// including it: each cell's end, from the cells' counts. A gas has five cells per sphere, so
/// this runs over more numbers than any other loop of the grid; four at a time where the
/// processor can (the same sums: integer addition is exact).
void running_sums(std::uint32_t* first, std::uint32_t* last, std::uint32_t start)
{
#if defined(KUGEL_SSE2)
    __m128i carry = _mm_set1_epi32(static_cast<int>(start));
    for (; last - first >= 4; first += 4) {
        __m128i sums = _mm_loadu_si128(reinterpret_cast<__m128i const*>(first));
        sums = _mm_add_epi32(sums, _mm_slli_si128(sums, 4)); // each lane plus the one before
        sums = _mm_add_epi32(sums, _mm_slli_si128(sums, 8)); // and the two before those
        sums = _mm_add_epi32(sums, carry);
        _mm_storeu_si128(reinterpret_cast<__m128i*>(first), sums);
        carry = _mm_shuffle_epi32(sums, 0xff); // the last lane's sum, in every lane
    }
    start = static_cast<std::uint32_t>(_mm_cvtsi128_si32(carry));
#endif
    for (; first != last; ++first)
        *first = start += *first;
}

/// a · b, or nullopt when it does not fit in 64 bits.
std::optional<std::uint64_t> checked_product(std::uint64_t a, std::uint64_t b)
{
    if (a != 0 && b > std::numeric_limits<std::uint64_t>::max() / a)
        return std::nullopt;
    return a * b;
}

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

// Why neighbouring cells suffice, in floating point: boxes [x − r, x + r] that overlap on an
// axis have centres at most r₁ + r₂ <= 2·r_max apart plus the rounding of x ± r, and their
// cells are computed from rounded products x·(1/h), 1/h itself rounded. With
// h = 2·r_max·(1 + 8u·(2 + reach)), reach >= max|x| / (2·r_max) and u = 2^-53, the computed
// products of two such centres differ by at most 1: the rounding of 1/h scales both alike
// (a factor 1 + u on their difference), and rounding each product and x ± r adds at most
// u·(4·reach + 1) relative to h, so all of it stays below the 8u·(2 + reach) that h was
// widened by. So their cells are the same or adjacent on every axis. The same argument as
// uniform_grid.cpp's (which divides), for centres. The grid takes for reach the power of two
// at or above max|x| / (2·r_max), so that its cells stay the same while the scene's extent
// changes a little: a gas numbers its cells in the same frame step after step.
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
    std::size_t const chunks = chunk_count(n);

    // 2. Cell size and the grid's extent, padded by one cell on every side so that every
    //    neighbour of an occupied cell has a key and no neighbour's key wraps into another row,
    //    and by a second above in z, so that the end of a run of three cells (the start of the
    //    cell after it) is in the same row too: the pairs of a slab then read the table and
    //    the spheres of that slab and the next alone, which lets them be found before the
    //    slab after that is sorted.
    double const diameter = 2.0 * all.largest_radius;
    double const reach =
        std::max(all.lowest.cwiseAbs().maxCoeff(), all.highest.cwiseAbs().maxCoeff()) / diameter;
    if (!(reach <= largest_cell_coordinate))
        return false;
    double const reach_bound = std::exp2(std::ceil(std::log2(std::max(reach, 1.0)))); // exact
    double const cell_size = diameter + diameter * (8.0 * unit_roundoff * (2.0 + reach_bound)); // m
    double const per_metre = 1.0 / cell_size; // a product is cheaper than a quotient, three per sphere
    std::array<std::int64_t, 3> lowest_cell, size;
    for (std::size_t k = 0; k < 3; ++k) {
        auto const axis = static_cast<Eigen::Index>(k);
        lowest_cell[k] = floor_to_integer(all.lowest[axis] * per_metre);
        size[k] = floor_to_integer(all.highest[axis] * per_metre) - lowest_cell[k] + (k == 2 ? 4 : 3);
    }
    // Keys number every cell of the padded grid; a table of them all is kept when it has no
    // more than a few entries per sphere.
    auto const plane_cells = checked_product(static_cast<std::uint64_t>(size[1]), static_cast<std::uint64_t>(size[2]));
    auto const cells = plane_cells ? checked_product(static_cast<std::uint64_t>(size[0]), *plane_cells) : std::nullopt;
    if (!cells || *cells >= std::numeric_limits<std::uint64_t>::max() / 2)
        return false;
    in_cell_order_ = true; // from here on, the spheres are filed in cell order
    stride_y_ = static_cast<std::uint64_t>(size[2]);
    stride_x_ = *plane_cells;
    // Coordinate 0 is the padding cell below the lowest occupied one.
    cell_frame const frame{per_metre, {lowest_cell[0] - 1, lowest_cell[1] - 1, lowest_cell[2] - 1}, stride_x_, stride_y_};
    dense_ = *cells <= dense_cells_per_sphere * std::uint64_t{all.spheres} + 1024;
    if (dense_)
        keying_frame_ = frame;
    // Keys given in this very frame are the ones the build would find (threads need their
    // x-cells too).
    bool const keys_fit = dense_ && keyed && keyed->frame == frame && keyed->keys.size() == n;

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
    if (dense_ && !loops && *cells <= direct_sort_cells) {
        // On one thread, a single counting sort over every cell, straight from the bodies:
        // the same order (cell, then slot) without the buckets per slab that let threads sort
        // slabs at the same time. A slab then starts where its first cell does.
        // The table (a few cells per sphere) is larger than the nearest caches, and the cells
        // come in no order: so the keys are found first, and each pass fetches the table's
        // entry (and, placing, the entry's destination) some spheres ahead of using it.
        std::uint64_t const* key = nullptr;
        if (keys_fit) {
            key = keyed->keys.data();
        } else {
            keys_.resize(n);
            for (std::size_t i = 0; i < n; ++i) // bodies that are not spheres get a key, unused
                keys_[i] = radius[i] > 0.0 ? frame.key(x[i]) : 0;
            key = keys_.data();
        }
        std::uint32_t* const table = (cell_begin_.assign(*cells + 1, 0U), cell_begin_.data());
        for (std::size_t i = 0; i < n; ++i) {
            if (i + prefetch_distance < n)
                __builtin_prefetch(table + key[i + prefetch_distance], 1);
            table[key[i]] += radius[i] > 0.0 ? 1U : 0U;
        }
        running_sums(table, table + cell_begin_.size(), 0); // each cell's end, for now
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
        slab_begin_.resize(slabs + 1);
        for (std::uint32_t s = 0; s <= slabs; ++s)
            slab_begin_[s] = s < slabs ? cell_begin_[slab_cell_[s]] : all.spheres;
        if (ready)
            for (std::size_t s = 0; s < slabs; ++s)
                ready(s);
        return true;
    }

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
    slabs_.resize(n);
    // Keys given in this frame, with their x-cells, leave only the slabs to find.
    bool const given = keys_fit && keyed->x_cells.size() == n;
    if (!given)
        keys_.resize(n);
    std::uint64_t const* const key = given ? keyed->keys.data() : keys_.data();
    run_chunks(loops, n, [&](std::size_t c, std::size_t begin, std::size_t end) {
        std::uint32_t* const count = chunk_slab_start_.data() + c * slabs;
        if (given) {
            std::uint32_t const* const x_cell = keyed->x_cells.data();
            for (std::size_t i = begin; i < end; ++i)
                if (radius[i] > 0.0)
                    ++count[slabs_[i] = slab_of_x_[x_cell[i]]];
            return;
        }
        for (std::size_t i = begin; i < end; ++i) {
            if (!(radius[i] > 0.0))
                continue;
            std::uint64_t cx = 0;
            keys_[i] = frame.key(x[i], cx);
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

    // 5. Each sphere's cell key and slot, to its slab. Its position, radius and inverse mass
    //    are read again from its body when it is placed: a slab's entries come in slot order,
    //    and a large world keeps its bodies in cell order (world::bodies_worth_sorting), so
    //    those reads go nearly in sequence, where carrying them through here wrote and read
    //    40 bytes more per sphere (at 10^6 spheres, 40 MB each way).
    by_slab_.resize(all.spheres);
    run_chunks(loops, n, [&](std::size_t c, std::size_t begin, std::size_t end) {
        std::uint32_t* const start = chunk_slab_start_.data() + c * slabs;
        for (std::size_t i = begin; i < end; ++i)
            if (radius[i] > 0.0)
                by_slab_[start[slabs_[i]]++] = {key[i], static_cast<std::uint32_t>(i)};
    });
    auto const filed = [&](slab_entry const& e) -> filed_sphere {
        return {e.cell, e.slot, x[e.slot], radius[e.slot], inverse_mass[e.slot]};
    };

    // 6. Within each slab, the spheres sorted by cell, then slot: a counting sort over the
    //    slab's cells, stable, which leaves the table of where each cell starts (dense), or a
    //    comparison sort (sparse). The slabs' cells and entries are disjoint, so slabs sort
    //    at the same time.
    if (dense_)
        cell_begin_.resize(*cells + 1);
    resize_filed(all.spheres);
    auto const file = filer();
    auto const sort_slab = [&](std::size_t s) {
        std::uint32_t const begin = slab_begin_[s], end = slab_begin_[s + 1];
        if (dense_) {
            std::uint32_t* const first_cell = cell_begin_.data() + slab_cell_[s];
            std::uint32_t* const last_cell = cell_begin_.data() + slab_cell_[s + 1];
            std::fill(first_cell, last_cell, 0U);
            std::uint32_t* const table = cell_begin_.data();
            slab_entry const* const entry = by_slab_.data();
            for (std::uint32_t k = begin; k < end; ++k) {
                if (k + prefetch_distance < end) // as in the sort on one thread above
                    __builtin_prefetch(table + entry[k + prefetch_distance].cell, 1);
                ++table[entry[k].cell];
            }
            running_sums(first_cell, last_cell, begin); // each cell's end, for now
            for (std::uint32_t k = end; k-- > begin;) {
                if (k >= begin + prefetch_distance)
                    __builtin_prefetch(table + entry[k - prefetch_distance].cell, 1);
                if (k >= begin + prefetch_distance / 2)
                    fetch_destination(table[entry[k - prefetch_distance / 2].cell]);
                file(--table[entry[k].cell], filed(entry[k])); // now each cell's start
            }
        } else {
            auto const first = by_slab_.begin() + begin, last = by_slab_.begin() + end;
            std::sort(first, last, [](slab_entry const& a, slab_entry const& b) {
                return a.cell != b.cell ? a.cell < b.cell : a.slot < b.slot;
            });
            for (std::uint32_t k = begin; k < end; ++k)
                file(k, filed(by_slab_[k]));
        }
    };
    if (!ready || !dense_) { // a sparse grid's search reads every slab's keys
        run_loop(loops, slabs, sort_slab);
        if (ready)
            run_loop(loops, slabs, ready);
        return true;
    }
    // 7. Each slab is ready as soon as it and the next are sorted: then, while both are still
    //    in cache, ready() reads them (at 10^6 spheres the grid is larger than the last-level
    //    cache, and reading it afterwards waited on memory). Runs of whole slabs are sorted at
    //    the same time, each in order; the last slab of each run waits for the next run.
    std::size_t const runs = loops ? std::min<std::size_t>(4, slabs) : 1;
    auto const run_begin = [&](std::size_t r) { return slabs * r / runs; };
    run_loop(loops, runs, [&](std::size_t r) {
        for (std::size_t s = run_begin(r); s < run_begin(r + 1); ++s) {
            sort_slab(s);
            if (s > run_begin(r))
                ready(s - 1);
        }
    });
    run_loop(loops, runs, [&](std::size_t r) { ready(run_begin(r + 1) - 1); });
    return true;
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

// Each sphere against the rest of its own cell and the 13 neighbouring cells that come after
// its cell in cell order, so that each pair of cells is visited once: the cell above it
// (z + 1, which follows its own in the table, so the two are one run) and four rows of three
// cells (z − 1 to z + 1, one run each) at (y + 1), (x + 1, y − 1), (x + 1, y), (x + 1, y + 1).
// The runs come in cell order, so the output is sorted without a sort.
void sphere_grid::near_pairs(std::size_t s, std::vector<sphere_pair>& near,
                             std::vector<sphere_pair>& touching) const
{
    if (dense_)
        return near_pairs_dense(s, near, touching);
    // A sparse scene: each run's ends searched for in the sorted keys, one run after another.
    auto const first_at_or_after = [&](std::uint64_t key) {
        auto const found = std::partition_point(cells_.begin(), cells_.end(), [&](std::uint64_t c) { return c < key; });
        return static_cast<std::uint32_t>(found - cells_.begin());
    };
    near.clear();
    touching.clear();
    std::array<std::uint64_t, 4> const row_offsets = {stride_y_, stride_x_ - stride_y_, stride_x_,
                                                      stride_x_ + stride_y_};
    for (std::uint32_t p = slab_begin_[s]; p < slab_begin_[s + 1]; ++p) {
        std::uint64_t const key = cells_[p];
        std::array<std::array<std::uint32_t, 2>, 5> runs;
        runs[0] = {p + 1, first_at_or_after(key + 2)};
        for (std::size_t k = 0; k < 4; ++k)
            runs[k + 1] = {first_at_or_after(key + row_offsets[k] - 1),
                           first_at_or_after(key + row_offsets[k] + 2)};
        packed_sphere const& a = spheres_[p];
        aabb const a_box = aabb_of_sphere(a.x, a.radius);
        for (auto const& [begin, end] : runs) {
            for (std::uint32_t q = begin; q < end; ++q) {
                packed_sphere const& b = spheres_[q];
                if (!overlaps(a_box, aabb_of_sphere(b.x, b.radius)))
                    continue;
                sphere_pair const pair{p, q};
                near.push_back(pair);
                // the discrete step's contact test: |x_i − x_j|² against (r_i + r_j)²
                double const reach = a.radius + b.radius;
                if (!((a.x - b.x).squaredNorm() > reach * reach))
                    touching.push_back(pair);
            }
        }
    }
}

// The same runs and tests as the sparse search above, with the runs' ends read from the table
// of cells and written for speed: this is the hottest loop of a discrete step (bench/README.md).
// A gas has about 0.6 spheres per run, so runs of 0, 1 or 2 spheres come in no pattern the
// processor can predict, and neither does the test's outcome. So a sphere's candidates are
// gathered from its five runs into one short list, four ranks per run in one write (the count
// keeps only the run's own), and each candidate's pair is written whatever the test says and
// kept by advancing the count by the result: no branch on the outcome. The lists of four
// spheres in a row go into one, tested in one loop (each candidate against its own sphere's
// box), so that a loop of unpredictable length ends once per four spheres (a list per sphere
// was 4-6 % slower at 10^5, one per eight 2-3 %). The box test computes each candidate's box
// from its filed sphere, two coordinates at a time: the same comparisons of the same numbers
// as a table of boxes would give, without writing and reading one (at 10^6 spheres the
// memory traffic, not the arithmetic, is what a step waits on).
void sphere_grid::near_pairs_dense(std::size_t s, std::vector<sphere_pair>& near,
                                   std::vector<sphere_pair>& touching) const
{
    using ranks4 = std::uint32_t __attribute__((vector_size(16)));
    constexpr std::uint32_t gather_width = 4; // runs shorter than this are gathered in one write
    constexpr std::uint32_t most_gathered = 5 * (gather_width - 1); // where the writes start at most
    ranks4 const ascending = {0, 1, 2, 3};
    std::vector<std::uint32_t> spilled;
    // Everything the loop reads or writes, in locals: read through the members, each was
    // loaded again for every sphere (the writes through the output could alias them).
    std::uint32_t const* const table = cell_begin_.data();
    std::uint64_t const* const keys = cells_.data();
    packed_sphere const* const filed = spheres_.data();
    // Each row's first cell, from the sphere's own; its three cells end three further on.
    auto const row = [](std::uint64_t offset) { return static_cast<std::ptrdiff_t>(offset) - 1; };
    std::ptrdiff_t const row_y = row(stride_y_), row_xy = row(stride_x_ - stride_y_), row_x = row(stride_x_),
                         row_xyy = row(stride_x_ + stride_y_);
    std::size_t found = 0, checked = 0, touched = 0; // near pairs written, of them tested, touching
    // The contact test, the discrete step's |x_a − x_b|² against (r_a + r_b)², on the near
    // pairs found since it last ran: every contact_block spheres, while their entries are
    // still in the nearest cache.
    constexpr std::uint32_t contact_block = 256;
    touching.resize(near.size()); // touching stays as long as near
    sphere_pair* near_out = near.data();
    sphere_pair* touching_out = touching.data();
    std::size_t room = near.size();
    auto const find_contacts = [&] {
        for (; checked < found; ++checked) {
            sphere_pair const pair = near_out[checked];
            packed_sphere const& a = filed[pair.a];
            packed_sphere const& b = filed[pair.b];
            double const reach = a.radius + b.radius;
            touching_out[touched] = pair;
            touched += !((a.x - b.x).squaredNorm() > reach * reach);
        }
    };
    std::uint32_t const last = slab_begin_[s + 1];
    constexpr std::uint32_t group = 4; // spheres whose candidates share a list and a loop
    std::array<std::uint32_t, group * (most_gathered + gather_width)> gathered;
    struct box_bounds
    {
#if defined(KUGEL_SSE2)
        __m128d lo_xy, hi_xy, z; // z: z − r, −(z + r)
#else
        double lo[3], hi[3];
#endif
    };
    std::array<box_bounds, group> bounds;
    auto const bounds_of = [&](packed_sphere const& a) {
        box_bounds out;
#if defined(KUGEL_SSE2)
        __m128d const a_xy = _mm_loadu_pd(a.x.data()), a_r = _mm_set1_pd(a.radius);
        out.lo_xy = _mm_sub_pd(a_xy, a_r);
        out.hi_xy = _mm_add_pd(a_xy, a_r);
        out.z = _mm_set_pd(-(a.x.z() + a.radius), a.x.z() - a.radius);
#else
        for (Eigen::Index k = 0; k < 3; ++k) {
            out.lo[k] = a.x[k] - a.radius;
            out.hi[k] = a.x[k] + a.radius;
        }
#endif
        return out;
    };
    // overlaps() from aabb.hpp: max(lo) <= min(hi) is lo_a <= hi_b and lo_b <= hi_a (as
    // lo <= hi), with aabb_of_sphere's bounds x − r and x + r; in z, lo_a <= hi_b and
    // −hi_a <= −lo_b (exact negations, and r − z is exactly −(z − r)).
    auto const meets = [&](box_bounds const& a, packed_sphere const& b) {
#if defined(KUGEL_SSE2)
        __m128d const xy = _mm_loadu_pd(b.x.data());
        __m128d const zr = _mm_loadu_pd(b.x.data() + 2); // z and the radius, side by side
        __m128d const rr = _mm_unpackhi_pd(zr, zr);
        __m128d const rz = _mm_shuffle_pd(zr, zr, 1);
        __m128d const z = _mm_move_sd(_mm_sub_pd(zr, rz), _mm_add_pd(zr, rz)); // z + r, r − z
        __m128d const in_xy = _mm_and_pd(_mm_cmple_pd(a.lo_xy, _mm_add_pd(xy, rr)),
                                         _mm_cmple_pd(_mm_sub_pd(xy, rr), a.hi_xy));
        return _mm_movemask_pd(_mm_and_pd(in_xy, _mm_cmple_pd(a.z, z))) == 3;
#else
        bool in = true;
        for (Eigen::Index k = 0; k < 3; ++k) { // &: no branch per axis
            double const centre = b.x[k];
            in &= (a.lo[k] <= centre + b.radius) & (centre - b.radius <= a.hi[k]);
        }
        return in;
#endif
    };
    for (std::uint32_t p = slab_begin_[s]; p < last; p += group) {
        std::uint32_t const spheres = std::min<std::uint32_t>(group, last - p);
        // The five runs of each sphere, each written whole (four ranks from its start) where the
        // last one ended: one write per run, whatever its length, and only the run's own count
        // kept. A run of gather_width or more spheres spoils the list; then it is gathered
        // again. ends[j]: where sphere p + j's candidates end.
        std::uint32_t filled = 0, any_length = 0;
        auto const gather = [&](std::uint32_t begin, std::uint32_t end) {
            ranks4 const run = begin + ascending;
            std::memcpy(gathered.data() + filled, &run, sizeof run);
            std::uint32_t const length = end - begin;
            any_length |= length; // below gather_width (a power of 2) only if all are
            // A longer run spoils the list anyway: only the low bits count, which keeps the
            // writes inside it (five runs of at most three) without a comparison per run.
            filled += length & (gather_width - 1);
        };
        std::array<std::uint32_t, group> ends;
        ends.fill(~0U);
        for (std::uint32_t j = 0; j < spheres; ++j) {
            std::uint32_t const* const cell = table + keys[p + j];
            gather(p + j + 1, cell[2]);
            gather(cell[row_y], cell[row_y + 3]);
            gather(cell[row_xy], cell[row_xy + 3]);
            gather(cell[row_x], cell[row_x + 3]);
            gather(cell[row_xyy], cell[row_xyy + 3]);
            ends[j] = filled;
            bounds[j] = bounds_of(filed[p + j]);
        }
        std::uint32_t const* candidate = gathered.data();
        std::uint32_t count = filled;
        if (any_length >= gather_width) [[unlikely]] {
            // Out of line, so that the common path keeps its values in registers.
            [&]() __attribute__((noinline)) {
                spilled.clear();
                for (std::uint32_t j = 0; j < spheres; ++j) {
                    std::uint32_t const* const cell = table + keys[p + j];
                    for (std::uint32_t q = p + j + 1; q < cell[2]; ++q) // its own cell and the next, after it
                        spilled.push_back(q);
                    for (std::ptrdiff_t const first : {row_y, row_xy, row_x, row_xyy})
                        for (std::uint32_t q = cell[first]; q < cell[first + 3]; ++q)
                            spilled.push_back(q);
                    ends[j] = static_cast<std::uint32_t>(spilled.size());
                }
            }();
            candidate = spilled.data();
            count = static_cast<std::uint32_t>(spilled.size());
        }
        if (room < found + count) {
            near.resize(found + count + room / 2);
            touching.resize(near.size());
            near_out = near.data();
            touching_out = touching.data();
            room = near.size();
        }
        for (std::uint32_t k = 0; k < count; ++k) {
            std::uint32_t const q = candidate[k];
            std::uint32_t owner = 0; // which of the spheres this candidate is for
            for (std::uint32_t j = 0; j + 1 < group; ++j)
                owner += k >= ends[j] ? 1U : 0U;
            near_out[found] = {p + owner, q};
            found += meets(bounds[owner], filed[q]);
        }
        if (((p + group - 1) & (contact_block - 1)) < group) // once per contact_block spheres
            find_contacts();
    }
    find_contacts();
    near.resize(found);
    touching.resize(touched);
}

} // namespace kugel::physics
