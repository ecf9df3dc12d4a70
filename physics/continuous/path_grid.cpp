#include "path_grid.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace kugel::physics::continuous {

void path_grid::choose_cells(std::span<aabb const> boxes, std::span<std::uint32_t const> members)
{
    // Cells as large as the largest box when boxes are alike (a gas): a query then looks at
    // two or three cells an axis, each holding few boxes. Where sizes spread widely, cells
    // twice the mean box, and the few larger boxes listed; should that list many (more than
    // one in 64), the cells grow to the size that lists no more.
    double extent = 0.0, largest = 0.0;
    for (std::uint32_t i : members) {
        double const e = boxes[i].extent().maxCoeff();
        extent += e;
        largest = std::max(largest, e);
    }
    double const n = static_cast<double>(members.size());
    double const mean = extent / n;
    cell_ = std::max(largest <= 2.0 * mean ? largest : 2.0 * mean, 1e-300);
    std::size_t too_large = 0;
    for (std::uint32_t i : members)
        too_large += boxes[i].extent().maxCoeff() > cell_ ? 1U : 0U;
    std::size_t const allowed = members.size() / 64 + 16;
    if (too_large > allowed) {
        std::vector<double> extents;
        extents.reserve(members.size());
        for (std::uint32_t i : members)
            extents.push_back(boxes[i].extent().maxCoeff());
        auto const at = extents.end() - static_cast<std::ptrdiff_t>(allowed);
        std::nth_element(extents.begin(), at, extents.end());
        cell_ = std::max(cell_, *at);
    }
    // The grid spans the centres of the boxes that fit; at most a few cells per box, else
    // the cells grow (a few bodies far apart).
    vec3 lo = vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
    for (std::uint32_t i : members) {
        if (boxes[i].extent().maxCoeff() > cell_)
            continue;
        vec3 const c = boxes[i].centre();
        lo = lo.cwiseMin(c);
        hi = hi.cwiseMax(c);
    }
    if (!(lo.array() <= hi.array()).all() || !lo.allFinite() || !hi.allFinite()) {
        lo = hi = vec3::Zero();
    }
    if (!(cell_ > 0.0) || !std::isfinite(cell_)) // boxes not finite: one cell holds them all
        cell_ = std::max((hi - lo).maxCoeff(), 1.0);
    double const most = 4.0 * n + 64.0;
    for (;;) {
        double total = 1.0;
        for (int axis = 0; axis < 3; ++axis)
            total *= std::floor((hi[axis] - lo[axis]) / cell_) + 1.0;
        if (total <= most)
            break;
        cell_ *= std::max(std::cbrt(total / most), 1.0 + 1e-6);
    }
    origin_ = lo;
    inverse_cell_ = 1.0 / cell_;
    cells_ = 1;
    for (int axis = 0; axis < 3; ++axis) {
        auto const a = static_cast<std::size_t>(axis);
        dims_[a] = static_cast<std::uint32_t>(std::floor((hi[axis] - lo[axis]) / cell_)) + 1U;
        top_[a] = static_cast<double>(dims_[a] - 1U);
        cells_ *= dims_[a];
    }
}

void path_grid::reset(std::span<aabb const> boxes, std::span<std::uint32_t const> members)
{
    std::size_t const bodies = boxes.size();
    listed_.clear();
    listed_slot_.assign(bodies, none);
    listed_at_reset_.clear();
    changed_.clear();
    filing_.resize(bodies);
    seen_.resize(bodies);
    if (members.empty()) {
        cells_ = 1;
        dims_ = {1, 1, 1};
        top_ = {0.0, 0.0, 0.0};
        start_.assign(2, 0U);
        changed_head_.assign(1, none);
        entry_body_.clear();
        entry_box_.clear();
        entry_x_.clear();
        return;
    }
    choose_cells(boxes, members);
    changed_head_.assign(cells_, none);

    // A counting sort of the boxes that fit by the cell of their centre.
    start_.assign(cells_ + 1U, 0U);
    entry_cell_.resize(members.size());
    for (std::size_t k = 0; k < members.size(); ++k) {
        aabb const& box = boxes[members[k]];
        if (box.extent().maxCoeff() > cell_) {
            entry_cell_[k] = none;
            listed_at_reset_.push_back(members[k]);
            list(members[k], box);
            continue;
        }
        cell const c = cell_of(box.centre());
        entry_cell_[k] = index(c[0], c[1], c[2]);
        ++start_[entry_cell_[k] + 1U];
    }
    for (std::uint32_t c = 0; c < cells_; ++c)
        start_[c + 1U] += start_[c];
    std::size_t const filed = members.size() - listed_at_reset_.size();
    entry_body_.resize(filed);
    entry_box_.resize(filed);
    entry_x_.resize(filed);
    // start_[c] is advanced past each entry placed, then moved back by one cell.
    for (std::size_t k = 0; k < members.size(); ++k) {
        if (entry_cell_[k] == none)
            continue;
        std::uint32_t const at = start_[entry_cell_[k]]++;
        entry_body_[at] = members[k];
        entry_box_[at] = boxes[members[k]];
        entry_x_[at] = entry_cell_[k] % dims_[0];
    }
    for (std::uint32_t c = cells_; c > 0; --c)
        start_[c] = start_[c - 1U];
    start_[0] = 0;
}

void path_grid::overlapping_pairs(std::size_t first, std::size_t last,
                                  std::vector<std::array<std::uint32_t, 2>>& out) const
{
    // Each box against the rest of its own cell and the next cell of its row (one run), and
    // against the rows of its cell's half of the neighbours that come later in cell order,
    // (y + 1, z) and (y − 1 … y + 1, z + 1), each from x − 1 to x + 1 (one run each): each
    // pair of neighbouring cells once. A gas has about one box in a cell, so runs of 0, 1 or 2
    // come in no pattern a processor predicts: every candidate pair is written and kept by
    // the box test's result, not by a branch on it (as the discrete step's near-pair search
    // does). Rows without boxes are passed over whole.
    std::uint32_t const* const start = start_.data();
    std::uint32_t const* const body = entry_body_.data();
    std::uint32_t const* const column = entry_x_.data();
    aabb const* const box = entry_box_.data();
    std::size_t found = 0;
    std::size_t const entries = entry_body_.size();
    std::uint32_t const dx = dims_[0], dy = dims_[1], dz = dims_[2];
    for (auto z = static_cast<std::uint32_t>(first); z < std::min<std::size_t>(last, dz); ++z)
        for (std::uint32_t y = 0; y < dy; ++y) {
            std::uint32_t const row = index(0, y, z);
            std::uint32_t const row_begin = start[row], row_end = start[row + dx];
            if (row_begin == row_end)
                continue;
            // the later rows beside this one, by the index of their first cell
            std::array<std::uint32_t, 4> later{};
            std::size_t rows = 0;
            if (y + 1 < dy)
                later[rows++] = index(0, y + 1, z);
            if (z + 1 < dz)
                for (std::uint32_t ry = y > 0 ? y - 1 : 0; ry <= std::min(y + 1, dy - 1); ++ry)
                    later[rows++] = index(0, ry, z + 1);
            for (std::uint32_t k = row_begin; k < row_end; ++k) {
                std::uint32_t const x = column[k];
                std::uint32_t const x0 = x > 0 ? x - 1 : 0, x1 = std::min(x + 1, dx - 1);
                std::uint32_t const own_end = start[row + x1 + 1];
                // room for every other entry: no box has more candidates
                if (out.size() < found + entries)
                    out.resize(2 * (found + entries) + 64);
                std::array<std::uint32_t, 2>* written = out.data() + found;
                aabb const own = box[k];
                std::uint32_t const own_body = body[k];
                auto const run = [&](std::uint32_t l, std::uint32_t end) __attribute__((always_inline)) {
                    for (; l < end; ++l) {
                        *written = {own_body, body[l]};
                        written += overlaps(own, box[l]) ? 1 : 0;
                    }
                };
                run(k + 1, own_end);
                for (std::size_t r = 0; r < rows; ++r)
                    run(start[later[r] + x0], start[later[r] + x1 + 1]);
                found = static_cast<std::size_t>(written - out.data());
            }
        }
    out.resize(found);
}

void path_grid::list(std::uint32_t body, aabb const& box)
{
    if (listed_slot_[body] == none) {
        listed_slot_[body] = static_cast<std::uint32_t>(listed_.size());
        listed_.push_back({body, box});
    } else {
        listed_[listed_slot_[body]].second = box;
    }
}

void path_grid::insert(std::uint32_t body, aabb const& box)
{
    std::uint32_t const filing = ++filing_[body]; // its earlier filings are stale now
    cell const lo = cell_of(box.min), hi = cell_of(box.max);
    if (cell_count(lo, hi) > most_cells)
        return list(body, box);
    for (std::uint32_t z = lo[2]; z <= hi[2]; ++z)
        for (std::uint32_t y = lo[1]; y <= hi[1]; ++y)
            for (std::uint32_t x = lo[0]; x <= hi[0]; ++x) {
                std::uint32_t& head = changed_head_[index(x, y, z)];
                changed_.push_back({body, filing, head});
                head = static_cast<std::uint32_t>(changed_.size() - 1);
            }
}

} // namespace kugel::physics::continuous
