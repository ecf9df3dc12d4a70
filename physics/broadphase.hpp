#pragma once

#include "aabb.hpp"

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

namespace kugel::physics {

/// Two boxes whose AABBs overlap: indices into the span given to the broadphase, a < b.
struct box_pair
{
    std::uint32_t a; ///< index of the first box, < b
    std::uint32_t b; ///< index of the second box

    friend bool operator==(box_pair const&, box_pair const&) = default;
    friend auto operator<=>(box_pair const&, box_pair const&) = default;
};

/// How candidate pairs are found. All kinds return the same pairs; they differ in speed only.
enum class broadphase_kind {
    brute_force,     ///< all n(n-1)/2 pairs tested (lecture: "Brute force: n^2 Tests")
    sweep_and_prune, ///< the lecture's sorted endpoint list with an active list L
    uniform_grid,    ///< boxes filed into cells as large as the largest box
};

/// "brute_force", "sweep_and_prune" or "grid"; anything else is nullopt.
std::optional<broadphase_kind> broadphase_from_name(std::string_view name);
/// The inverse of broadphase_from_name.
std::string_view name(broadphase_kind kind);

/// Scratch memory reused from call to call, so that a steady-state broadphase (same scene
/// size, or smaller) does not allocate. Not shared between threads; one per caller.
class broadphase_workspace
{
public:
    broadphase_workspace() = default;

private:
    /// A begin or end point of a box's interval on the sweep axis.
    struct endpoint
    {
        double value;      ///< m, the interval's lower or upper bound
        std::uint32_t tag; ///< box index, with end_bit set for an end point
    };
    /// An entry of the active list L, with the box's intervals on the two other axes.
    struct active_box
    {
        double lo_u; ///< m, interval on the first other axis
        double hi_u;
        double lo_w; ///< m, interval on the second other axis
        double hi_w;
        std::uint32_t index; ///< box index
    };
    /// A box filed under the cell that holds its lower corner.
    struct cell_entry
    {
        std::uint64_t key;   ///< packed cell coordinates
        std::uint32_t index; ///< box index
    };

    // sweep and prune
    std::vector<endpoint> endpoints_;
    std::vector<active_box> active_;
    std::vector<std::uint32_t> position_in_active_; ///< where each active box sits in active_

    // uniform grid
    std::vector<cell_entry> cell_entries_;
    std::vector<cell_entry> cell_entries_scratch_;
    std::vector<std::uint32_t> cell_counts_; ///< radix buckets, or the run start of every cell
    std::vector<aabb> boxes_in_cell_order_;

    // output sorting
    std::vector<box_pair> pairs_scratch_;
    std::vector<std::size_t> pair_counts_;

    friend void sweep_and_prune_pairs(std::span<aabb const> boxes, std::vector<box_pair>& out,
                                      broadphase_workspace& workspace);
    friend void uniform_grid_pairs(std::span<aabb const> boxes, std::vector<box_pair>& out,
                                   broadphase_workspace& workspace);
    friend void sort_box_pairs(std::vector<box_pair>& pairs, std::size_t box_count,
                               broadphase_workspace& workspace);
};

/// Clears `out` and fills it with every pair of boxes that overlap (touching counts, the
/// lecture's max{a_i} <= min{b_i} on every axis), sorted ascending by (a, b). Every kind
/// returns the identical vector.
/// Preconditions: every box has finite coordinates and min <= max on every axis.
/// Throws std::length_error for 2^31 boxes or more.
void find_overlapping_pairs(broadphase_kind kind, std::span<aabb const> boxes,
                            std::vector<box_pair>& out, broadphase_workspace& workspace);

/// The individual broadphases behind find_overlapping_pairs (same contract, fewer than
/// 2^31 boxes; not checked here).
void brute_force_pairs(std::span<aabb const> boxes, std::vector<box_pair>& out);
void sweep_and_prune_pairs(std::span<aabb const> boxes, std::vector<box_pair>& out,
                           broadphase_workspace& workspace);
void uniform_grid_pairs(std::span<aabb const> boxes, std::vector<box_pair>& out,
                        broadphase_workspace& workspace);

/// Sorts pairs with a < b < box_count ascending by (a, b) in O(box_count + pairs):
/// a counting sort on a, then each run sorted on b.
void sort_box_pairs(std::vector<box_pair>& pairs, std::size_t box_count,
                    broadphase_workspace& workspace);

} // namespace kugel::physics
