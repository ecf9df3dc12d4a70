#pragma once

#include "broadphase.hpp"
#include "vec.hpp"

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace kugel::physics {

namespace detail {

/// A sphere as the grid stores it: centre and radius side by side, so that one candidate
/// test reads 32 contiguous bytes.
struct sphere_record
{
    double x; ///< m, centre
    double y;
    double z;
    double r; ///< m, radius, > 0
};

/// A sphere's cell key and its position in its level's member list (for the radix sort).
struct cell_entry
{
    std::uint64_t key;
    std::uint32_t position;
};

/// Scratch of the sorts that file a level's spheres into cell order.
struct cell_sort_buffers
{
    std::vector<std::uint64_t> member_keys;    ///< cell key of every member, member order
    std::vector<std::uint32_t> member_slabs;   ///< x slab of every member (dense sort)
    std::vector<std::uint32_t> counts;         ///< slab starts (dense) or radix buckets
    std::vector<sphere_record> staged_spheres; ///< dense: the spheres dealt into slabs
    std::vector<std::uint32_t> staged_bodies;
    std::vector<std::uint64_t> staged_keys;
    std::vector<cell_entry> entries; ///< sparse: radix sort buffers
    std::vector<cell_entry> entries_scratch;
};

/// One level of the grid: spheres of similar size, each filed under the cell of its centre.
struct sphere_grid
{
    double inverse_cell_size = 0.0;        ///< 1/m
    std::array<std::int64_t, 3> lowest{};  ///< cell coordinates of the lowest occupied cell
    std::array<std::int64_t, 3> highest{}; ///< ... and of the highest, per axis
    std::uint64_t stride_x = 0;            ///< key step of one cell along x
    std::uint64_t stride_y = 0;            ///< key step of one cell along y (z steps by 1)
    bool dense = true;                     ///< run_starts tables every cell
    std::vector<std::uint64_t> keys;       ///< cell key of every sphere, ascending
    std::vector<std::uint32_t> run_starts; ///< dense: first sphere of every cell, then size
    std::vector<sphere_record> spheres;    ///< in key order
    std::vector<std::uint32_t> bodies;     ///< body index of every sphere, in key order
};

} // namespace detail

/// Scratch memory reused from call to call, so that a steady-state search (same scene size,
/// or smaller) does not allocate. Not shared between threads; one per caller.
class sphere_contacts_workspace
{
  public:
    sphere_contacts_workspace() = default;

    /// Bytes reserved by the scratch buffers. A call that did not need to grow any buffer
    /// leaves it unchanged (the sweep-and-prune fallback's own buffers are not counted).
    std::size_t capacity_bytes() const noexcept;

  private:
    std::vector<std::uint32_t> remaining_; ///< bodies not yet given a level, ascending
    std::vector<std::uint32_t> members_;   ///< bodies of the level being built, ascending
    std::vector<std::uint32_t> irregular_; ///< bodies outside the grid's numeric range
    std::vector<double> radii_;            ///< m, scratch for the median radius
    detail::cell_sort_buffers sort_buffers_;
    std::vector<detail::sphere_grid> levels_; ///< grown only; level_count_ in use
    std::size_t level_count_ = 0;
    std::vector<box_pair> pairs_;            ///< pairs as found, before sorting
    std::vector<std::uint32_t> pair_counts_; ///< counting sort of pairs by first body
    std::vector<aabb> fallback_boxes_;       ///< sweep-and-prune fallback
    std::vector<box_pair> fallback_pairs_;
    broadphase_workspace fallback_workspace_;

    friend void find_touching_spheres(std::span<vec3 const> x, std::span<double const> radius,
                                      std::vector<box_pair>& out, sphere_contacts_workspace& ws);
};

/// Clears `out` and fills it with every pair (i < j) of bodies with radius[i] > 0 and
/// radius[j] > 0 whose spheres touch or overlap, |x_i − x_j|² <= (r_i + r_j)², as body
/// indices sorted ascending by (i, j). The test is evaluated exactly as written, per axis
/// d = x_i − x_j and then (d_x² + d_y²) + d_z² <= (r_i + r_j)², so the result is the one
/// of that test applied to all n(n−1)/2 pairs, for any input (bodies with a NaN or infinite
/// centre or radius are tested against every other body one by one).
/// Throws std::invalid_argument when the spans differ in size, std::length_error for 2^31
/// bodies or more.
void find_touching_spheres(std::span<vec3 const> x, std::span<double const> radius,
                           std::vector<box_pair>& out, sphere_contacts_workspace& ws);

} // namespace kugel::physics
