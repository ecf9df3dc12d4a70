#include "broadphase.hpp"

#include <algorithm>

namespace kugel::physics {

namespace {

constexpr std::uint32_t end_bit = std::uint32_t{1} << 31;

/// The axis along which the box centres spread most (largest variance): sorting on it keeps
/// the active list short. Ties go to the lower axis. Two passes (mean, then squared
/// deviations) so that a scene far from the origin does not lose its spread to cancellation.
int axis_of_largest_spread(std::span<aabb const> boxes)
{
    vec3 mean = vec3::Zero();
    for (aabb const& box : boxes)
        mean += box.centre();
    mean /= static_cast<double>(boxes.size());

    vec3 spread = vec3::Zero();
    for (aabb const& box : boxes)
        spread += (box.centre() - mean).cwiseAbs2();

    int axis = 0;
    for (int k = 1; k < 3; ++k) {
        if (spread[k] > spread[axis])
            axis = k;
    }
    return axis;
}

} // namespace

// The lecture's sweep ("Reduktion auf 1D-Probleme"):
//   sort M = {a_i} ∪ {b_i} as (m_j, index, typ); L = [];
//   for j = 1 .. 2n: if m_j is an end point, remove I_index from L;
//                    else I_index meets every interval in L on this axis; add I_index to L.
// On one axis only, the one of largest spread; each candidate from L is then checked on the
// other two axes with the same interval rule. A begin point sorts before an end point of the
// same value, so boxes that merely touch are still in L together and count as overlapping.
void sweep_and_prune_pairs(std::span<aabb const> boxes, std::vector<box_pair>& out,
                           broadphase_workspace& workspace)
{
    out.clear();
    auto const n = static_cast<std::uint32_t>(boxes.size());
    if (n < 2)
        return;

    int const axis = axis_of_largest_spread(boxes);
    int const u = (axis + 1) % 3;
    int const w = (axis + 2) % 3;

    // M, sorted by value, begin before end, then by index (only for a fixed order).
    auto& endpoints = workspace.endpoints_;
    endpoints.resize(2 * std::size_t{n});
    for (std::uint32_t i = 0; i < n; ++i) {
        endpoints[2 * std::size_t{i}] = {boxes[i].min[axis], i};
        endpoints[2 * std::size_t{i} + 1] = {boxes[i].max[axis], i | end_bit};
    }
    std::sort(endpoints.begin(), endpoints.end(), [](auto const& x, auto const& y) {
        return x.value < y.value || (x.value == y.value && x.tag < y.tag);
    });

    // L, with each box's position in it so that removal is a swap with the last entry.
    auto& active = workspace.active_;
    auto& position = workspace.position_in_active_;
    active.clear();
    position.resize(n);

    for (auto const& point : endpoints) {
        std::uint32_t const i = point.tag & ~end_bit;
        if ((point.tag & end_bit) != 0) {
            // remove I_i from L
            std::uint32_t const slot = position[i];
            active[slot] = active.back();
            position[active[slot].index] = slot;
            active.pop_back();
            continue;
        }
        // I_i meets every interval in L on the sweep axis; keep those that meet on u and w.
        aabb const& box = boxes[i];
        double const lo_u = box.min[u];
        double const hi_u = box.max[u];
        double const lo_w = box.min[w];
        double const hi_w = box.max[w];
        for (auto const& other : active) {
            if (std::max(lo_u, other.lo_u) <= std::min(hi_u, other.hi_u) &&
                std::max(lo_w, other.lo_w) <= std::min(hi_w, other.hi_w))
                out.push_back({std::min(i, other.index), std::max(i, other.index)});
        }
        // add I_i to L
        position[i] = static_cast<std::uint32_t>(active.size());
        active.push_back({lo_u, hi_u, lo_w, hi_w, i});
    }

    sort_box_pairs(out, n, workspace);
}

} // namespace kugel::physics
