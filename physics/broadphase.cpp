#include "broadphase.hpp"

#include <algorithm>
#include <stdexcept>

namespace kugel::physics {

std::optional<broadphase_kind> broadphase_from_name(std::string_view name)
{
    if (name == "brute_force")
        return broadphase_kind::brute_force;
    if (name == "sweep_and_prune")
        return broadphase_kind::sweep_and_prune;
    if (name == "grid")
        return broadphase_kind::uniform_grid;
    return std::nullopt;
}

std::string_view name(broadphase_kind kind)
{
    switch (kind) {
    case broadphase_kind::brute_force:
        return "brute_force";
    case broadphase_kind::sweep_and_prune:
        return "sweep_and_prune";
    case broadphase_kind::uniform_grid:
        return "grid";
    }
    return "unknown";
}

void find_overlapping_pairs(broadphase_kind kind, std::span<aabb const> boxes,
                            std::vector<box_pair>& out, broadphase_workspace& workspace)
{
    // Sweep and prune keeps the end flag in the top bit of a 32-bit index.
    if (boxes.size() >= (std::size_t{1} << 31))
        throw std::length_error("broadphase: at most 2^31 - 1 boxes");

    switch (kind) {
    case broadphase_kind::brute_force:
        brute_force_pairs(boxes, out);
        return;
    case broadphase_kind::sweep_and_prune:
        sweep_and_prune_pairs(boxes, out, workspace);
        return;
    case broadphase_kind::uniform_grid:
        uniform_grid_pairs(boxes, out, workspace);
        return;
    }
    throw std::invalid_argument("broadphase: unknown kind");
}

void sort_box_pairs(std::vector<box_pair>& pairs, std::size_t box_count,
                    broadphase_workspace& workspace)
{
    auto const by_b = [](box_pair const& x, box_pair const& y) { return x.b < y.b; };

    // Few pairs against many boxes: a comparison sort is cheaper than the histogram.
    if (pairs.size() < 64 || pairs.size() * 8 < box_count) {
        std::sort(pairs.begin(), pairs.end());
        return;
    }

    // Counting sort on a: counts_[k] becomes the first slot of the pairs with a == k.
    auto& counts = workspace.pair_counts_;
    counts.assign(box_count + 1, 0);
    for (box_pair const& p : pairs)
        ++counts[p.a + 1];
    for (std::size_t k = 1; k <= box_count; ++k)
        counts[k] += counts[k - 1];

    auto& sorted = workspace.pairs_scratch_;
    sorted.resize(pairs.size());
    for (box_pair const& p : pairs)
        sorted[counts[p.a]++] = p;

    // Now counts[k] is the end of run k; sort each run on b (runs are short in practice).
    std::size_t begin = 0;
    for (std::size_t k = 0; k < box_count; ++k) {
        std::size_t const end = counts[k];
        if (end - begin > 1)
            std::sort(sorted.begin() + static_cast<std::ptrdiff_t>(begin),
                      sorted.begin() + static_cast<std::ptrdiff_t>(end), by_b);
        begin = end;
    }
    std::copy(sorted.begin(), sorted.end(), pairs.begin());
}

} // namespace kugel::physics
