#pragma once

// Where the continuous mode's paths are during one slice of a step, for finding who a path
// may meet: a dense grid of cells over the spheres, rebuilt by a counting sort at the start of
// each slice, into which every path that changes during the slice is filed again.

#include "physics/aabb.hpp"

#include <algorithm>
#include <array>
#include <cstdint>
#include <span>
#include <vector>

namespace kugel::physics::continuous {

/// The swept boxes of one slice's paths. At the slice's start each box is filed under the
/// cell of its centre (cells at least as large as the box, so that two boxes that overlap lie
/// in the same or neighbouring cells), sorted by cell so that each row of cells is one run of
/// entries. The few boxes larger than a cell go to a list instead. A path that changes
/// during the slice is filed in each cell its new box overlaps (a few), as event-driven codes
/// file each change where it happens, so that a query looks only at the changes near it; a
/// body filed again leaves its older filings stale, and queries pass over them. Queries see a
/// superset of the current paths, which the caller checks exactly; the order in which they
/// see them does not matter, since events are ordered by time and indices alone.
///
/// Cells are clamped to the grid: a box beyond its edge is filed in the edge's cell, and a
/// query beyond it looks there, which keeps every overlap between neighbouring cells.
class path_grid
{
public:
    /// Files boxes[i] of each body i in `members` (boxes is indexed by body). Bodies are
    /// numbered below boxes.size().
    void reset(std::span<aabb const> boxes, std::span<std::uint32_t const> members);

    /// Layers of cells (along z) the grid has.
    std::size_t layers() const { return dims_[2]; }
    /// Every two bodies filed by reset() whose boxes overlap, neither of them listed, once
    /// each (in no particular order), of those where the first lies in layers [first, last):
    /// parts of the layers may be searched side by side.
    void overlapping_pairs(std::size_t first, std::size_t last, std::vector<std::array<std::uint32_t, 2>>& out) const;

    /// The bodies reset() found too large for a cell, with their boxes.
    std::span<std::uint32_t const> listed_at_reset() const { return listed_at_reset_; }

    /// Calls f(j) for every body filed by reset() and not listed whose centre cell lies within
    /// half a cell of `box` (a superset of those whose reset() box overlaps it).
    template <class F>
    void for_each_filed_near(aabb const& box, F f) const;

    /// Files `box` as body's current box: in the cells it overlaps, or in the list of large
    /// boxes, leaving its earlier filings stale.
    void insert(std::uint32_t body, aabb const& box);

    /// Calls f(j) once for every body that may have had a box overlapping `box` since
    /// reset(): its box at reset() or any box filed since.
    template <class F>
    void for_each_near(aabb const& box, F f);

private:
    using cell = std::array<std::uint32_t, 3>;

    struct filed_change
    {
        std::uint32_t body;
        std::uint32_t filing; ///< which of the body's filings: stale once it is filed again
        std::uint32_t next;   ///< the cell's change before it, or none
    };

    static constexpr std::uint32_t none = 0xffffffffU;
    /// Cells a changed box is filed in at most; beyond, it is listed.
    static constexpr std::uint64_t most_cells = 27;

    std::uint32_t coordinate(double p, int axis) const
    {
        double const u = (p - origin_[axis]) * inverse_cell_;
        // Clamped to the grid; truncation is floor for u >= 1; NaN and below the grid land in 0.
        return u >= 1.0 ? static_cast<std::uint32_t>(std::min(u, top_[static_cast<std::size_t>(axis)])) : 0U;
    }
    cell cell_of(vec3 const& p) const { return {coordinate(p.x(), 0), coordinate(p.y(), 1), coordinate(p.z(), 2)}; }
    std::uint32_t index(std::uint32_t x, std::uint32_t y, std::uint32_t z) const
    {
        return x + dims_[0] * (y + dims_[1] * z);
    }
    static std::uint64_t cell_count(cell const& lo, cell const& hi)
    {
        return std::uint64_t{hi[0] - lo[0] + 1} * (hi[1] - lo[1] + 1) * (hi[2] - lo[2] + 1);
    }
    /// Files body's box in the list of large boxes, replacing its entry there.
    void list(std::uint32_t body, aabb const& box);
    void choose_cells(std::span<aabb const> boxes, std::span<std::uint32_t const> members);

    vec3 origin_ = vec3::Zero();
    double cell_ = 1.0;
    double inverse_cell_ = 1.0;
    std::array<std::uint32_t, 3> dims_{1, 1, 1};
    std::array<double, 3> top_{0.0, 0.0, 0.0}; ///< dims − 1, as doubles
    std::uint32_t cells_ = 1;

    std::vector<std::uint32_t> start_;      ///< per cell: its first entry; one more at the end
    std::vector<std::uint32_t> entry_body_; ///< the filed bodies, in cell order
    std::vector<aabb> entry_box_;           ///< their boxes at reset(), in the same order
    std::vector<std::uint32_t> entry_x_;    ///< their cells' x, in the same order
    std::vector<std::uint32_t> entry_cell_; ///< scratch: each member's cell, in member order
    std::vector<std::uint32_t> listed_at_reset_;

    std::vector<std::uint32_t> changed_head_; ///< per cell: its newest change, or none
    std::vector<filed_change> changed_;
    std::vector<std::pair<std::uint32_t, aabb>> listed_;
    std::vector<std::uint32_t> listed_slot_; ///< per body: its place in listed_, or none
    std::vector<std::uint32_t> filing_;      ///< per body: its latest filing in the cells
    std::vector<std::uint32_t> seen_;        ///< per body: the stamp of the query that saw it
    std::uint32_t stamp_ = 0;
};

template <class F>
void path_grid::for_each_filed_near(aabb const& box, F f) const
{
    vec3 const half = vec3::Constant(0.5 * cell_);
    cell const lo = cell_of(box.min - half), hi = cell_of(box.max + half);
    for (std::uint32_t z = lo[2]; z <= hi[2]; ++z)
        for (std::uint32_t y = lo[1]; y <= hi[1]; ++y)
            for (std::uint32_t k = start_[index(lo[0], y, z)], end = start_[index(hi[0], y, z) + 1]; k < end; ++k)
                f(entry_body_[k]);
}

template <class F>
void path_grid::for_each_near(aabb const& box, F f)
{
    if (++stamp_ == 0) { // the stamps wrapped: none may look seen
        std::fill(seen_.begin(), seen_.end(), 0U);
        stamp_ = 1;
    }
    auto visit = [&](std::uint32_t j) {
        if (seen_[j] != stamp_) {
            seen_[j] = stamp_;
            f(j);
        }
    };
    for (auto const& [j, listed_box] : listed_)
        if (overlaps(box, listed_box))
            visit(j);
    for_each_filed_near(box, visit);
    // The changes: a box that overlaps this one shares a cell with it.
    cell const lo = cell_of(box.min), hi = cell_of(box.max);
    if (cell_count(lo, hi) > changed_.size()) {
        for (filed_change const& filed : changed_)
            if (filed.filing == filing_[filed.body])
                visit(filed.body);
        return;
    }
    for (std::uint32_t z = lo[2]; z <= hi[2]; ++z)
        for (std::uint32_t y = lo[1]; y <= hi[1]; ++y)
            for (std::uint32_t x = lo[0]; x <= hi[0]; ++x) {
                // Stale filings are unlinked on the way, so that a cell's chain holds about
                // one filing per body there, however often they change.
                for (std::uint32_t* link = &changed_head_[index(x, y, z)]; *link != none;) {
                    filed_change const& filed = changed_[*link];
                    if (filed.filing != filing_[filed.body]) {
                        *link = filed.next;
                        continue;
                    }
                    visit(filed.body);
                    link = &changed_[*link].next;
                }
            }
}

} // namespace kugel::physics::continuous
