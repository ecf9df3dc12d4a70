// The discrete step's near pairs: each slab's pairs of spheres whose boxes overlap, found in
// the sphere grid, and of them the contacts, the pairs that touch.

#include "sphere_grid.hpp"

#include "kernels.hpp"
#include "physics/aabb.hpp"
#include "physics/time_of_impact.hpp"

#include <algorithm>
#include <array>
#include <cstring>

namespace kugel::physics {

namespace {

using ranks4 = std::uint32_t __attribute__((vector_size(16)));
constexpr std::uint32_t gather_width = 4; // runs shorter than this are gathered in one write
constexpr std::uint32_t most_gathered = 5 * (gather_width - 1); // where the writes start at most
constexpr std::uint32_t group = 4; // spheres whose candidates share a list and a loop

/// The candidates of a group of spheres, gathered run by run: each run written whole (four
/// ranks from its start) where the last one ended, one write per run whatever its length, and
/// only the run's own count kept. A run of gather_width or more spheres spoils the list
/// (spoiled()); the group's candidates are then listed one by one instead.
struct gathered_runs
{
    std::array<std::uint32_t, group * (most_gathered + gather_width)> ranks;
    std::uint32_t filled = 0;
    std::uint32_t any_length = 0;

    void add(std::uint32_t begin, std::uint32_t end)
    {
        static constexpr ranks4 ascending = {0, 1, 2, 3};
        ranks4 const run = begin + ascending;
        std::memcpy(ranks.data() + filled, &run, sizeof run);
        std::uint32_t const length = end - begin;
        any_length |= length; // below gather_width (a power of 2) only if all are
        // A longer run spoils the list anyway: only the low bits count, which keeps the
        // writes inside it (five runs of at most three) without a comparison per run.
        filled += length & (gather_width - 1);
    }
    bool spoiled() const { return any_length >= gather_width; }
};

} // namespace

void sphere_grid::near_pairs(std::size_t s, std::vector<sphere_pair>& near, std::vector<sphere_pair>& touching,
                             discrete::kernel with) const
{
    if (!dense_)
        return near_pairs_sparse(s, near, touching);
#if defined(KUGEL_SSE2)
    if (with == discrete::kernel::fast)
        return near_pairs_dense<discrete::sphere_box_sse2>(s, near, touching);
#endif
    (void)with;
    near_pairs_dense<discrete::sphere_box_plain>(s, near, touching);
}

// Each sphere against the rest of its own cell and the 13 neighbouring cells that come after
// its cell in cell order, so that each pair of cells is visited once: the cell above it
// (z + 1, which follows its own in the table, so the two are one run) and four rows of three
// cells (z − 1 to z + 1, one run each) at (y + 1), (x + 1, y − 1), (x + 1, y), (x + 1, y + 1).
// The runs come in cell order, so the output is sorted without a sort. A sparse scene: each
// run's ends are searched for in the sorted keys, one run after another.
void sphere_grid::near_pairs_sparse(std::size_t s, std::vector<sphere_pair>& near,
                                    std::vector<sphere_pair>& touching) const
{
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
        aabb const a_box = aabb_of_sphere(a.x, a.radius + margin_);
        for (auto const& [begin, end] : runs) {
            for (std::uint32_t q = begin; q < end; ++q) {
                packed_sphere const& b = spheres_[q];
                if (!overlaps(a_box, aabb_of_sphere(b.x, b.radius)))
                    continue;
                near.push_back({p, q});
                if (spheres_overlap(a.x, a.radius + margin_, b.x, b.radius))
                    touching.push_back({p, q});
            }
        }
    }
}

// The same runs and tests as the sparse search, with the runs' ends read from the table of
// cells, written for speed: this is the hottest loop of a discrete step. A gas has about 0.6
// spheres per run, so runs of 0, 1 or 2 spheres come in no pattern the processor can predict,
// and neither does the test's outcome. So a sphere's candidates are gathered from its five
// runs into one short list (gathered_runs), and each candidate's pair is written whatever the
// test says and kept by advancing the count by the result: no branch on the outcome. The
// lists of `group` spheres in a row go into one, tested in one loop (each candidate against
// its own sphere's box), so that a loop of unpredictable length ends once per group
// (bench/README.md, decisions). Everything the loop reads or writes is in locals: read
// through the members, each was loaded again for every sphere (the writes through the output
// could alias them).
template <class box>
void sphere_grid::near_pairs_dense(std::size_t s, std::vector<sphere_pair>& near,
                                   std::vector<sphere_pair>& touching) const
{
    std::vector<std::uint32_t> spilled;
    std::uint32_t const* const table = cell_begin_.data();
    std::uint64_t const* const keys = cells_.data();
    packed_sphere const* const filed = spheres_.data();
    double const margin = margin_;
    // Each row's first cell, from the sphere's own; its three cells end three further on.
    auto const row = [](std::uint64_t offset) { return static_cast<std::ptrdiff_t>(offset) - 1; };
    std::array<std::ptrdiff_t, 4> const rows = {row(stride_y_), row(stride_x_ - stride_y_), row(stride_x_),
                                                row(stride_x_ + stride_y_)};
    std::size_t found = 0, checked = 0, touched = 0; // near pairs written, of them tested, touching
    // The contact test on the near pairs found since it last ran: every contact_block spheres,
    // while their entries are still in the nearest cache.
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
            touching_out[touched] = pair;
            touched += spheres_overlap(a.x, a.radius + margin, b.x, b.radius);
        }
    };
    std::uint32_t const last = slab_begin_[s + 1];
    for (std::uint32_t p = slab_begin_[s]; p < last; p += group) {
        std::uint32_t const spheres = std::min<std::uint32_t>(group, last - p);
        gathered_runs runs;
        std::array<std::uint32_t, group> ends; // where sphere p + j's candidates end
        ends.fill(~0U);
        std::array<box, group> boxes;
        for (std::uint32_t j = 0; j < spheres; ++j) {
            std::uint32_t const* const cell = table + keys[p + j];
            runs.add(p + j + 1, cell[2]); // its own cell and the next, after it
            for (std::ptrdiff_t const first : rows)
                runs.add(cell[first], cell[first + 3]);
            ends[j] = runs.filled;
            boxes[j] = box(filed[p + j], margin);
        }
        std::uint32_t const* candidate = runs.ranks.data();
        std::uint32_t count = runs.filled;
        if (runs.spoiled()) [[unlikely]] {
            // Out of line, so that the common path keeps its values in registers.
            [&]() __attribute__((noinline)) {
                spilled.clear();
                for (std::uint32_t j = 0; j < spheres; ++j) {
                    std::uint32_t const* const cell = table + keys[p + j];
                    for (std::uint32_t q = p + j + 1; q < cell[2]; ++q)
                        spilled.push_back(q);
                    for (std::ptrdiff_t const first : rows)
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
            found += boxes[owner].meets(filed[q]);
        }
        if (((p + group - 1) & (contact_block - 1)) < group) // once per contact_block spheres
            find_contacts();
    }
    find_contacts();
    near.resize(found);
    touching.resize(touched);
}

} // namespace kugel::physics
