#pragma once

#include "broadphase.hpp"
#include "parallel_for.hpp"
#include "vec.hpp"

#include <cstddef>
#include <cstdint>
#include <span>
#include <compare>
#include <vector>

namespace kugel::physics {

/// The spheres of one step filed by their centres into cubic cells as wide as the largest
/// diameter, so that two spheres whose boxes overlap sit in the same cell or in neighbouring
/// ones: the discrete step's broadphase when the scene asks for the grid, and the order in
/// which the discrete step resolves contacts whichever broadphase found them.
///
/// Cell order sorts the spheres by cell (x, then y, then z) and then by body slot, so it is a
/// function of the positions and radii alone: the same state gives the same order, however
/// the world got there (a world restored from a checkpoint goes on like the original).
///
/// Slabs are runs of whole x-cells. A pair belongs to the slab of its first sphere in cell
/// order, and its second sphere is in that slab or the next, so the pairs of the even slabs
/// share no sphere with each other, nor do those of the odd ones: each half can be worked on
/// slab by slab at the same time, and the outcome is that of one fixed order.
class sphere_grid
{
public:
    /// Files the spheres (radius > 0) at x. False, with nothing filed, when the grid cannot
    /// hold them: no sphere, coordinates more than 2^47 cells from the origin (e.g. 10^13 m
    /// with 0.1 m spheres), or a scene spanning more cells than a 64-bit key can number.
    /// Positions and radii must be finite.
    bool build(std::span<vec3 const> x, std::span<double const> radius, parallel_for* loops);

    std::size_t slab_count() const { return slab_begin_.size() - 1; }
    /// Which slab the sphere at this position of cell order is in.
    std::size_t slab_of(std::uint32_t rank) const;
    /// Position in cell order of the sphere in each body slot (filed spheres only).
    std::span<std::uint32_t const> rank() const { return rank_; }

    /// Clears `near` and fills it with every pair of slab s whose boxes [x − r, x + r] overlap
    /// (the broadphases' rule, at the positions given to build()), as body slots a < b,
    /// ordered by the cell order of their first, then their second sphere; `touching` gets
    /// those of them whose spheres touch (|x_a − x_b| <= r_a + r_b), in the same order.
    void near_pairs(std::size_t s, std::vector<box_pair>& near, std::vector<box_pair>& touching) const;

private:
    /// A sphere as filed: its centre (m) and radius (m).
    struct filed_sphere
    {
        double x, y, z, r;
    };
    /// A sphere while sorting.
    struct cell_entry
    {
        std::uint64_t cell; ///< key of its cell: (x · cells_y + y) · cells_z + z
        std::uint32_t slot; ///< body slot

        friend auto operator<=>(cell_entry const&, cell_entry const&) = default;
    };

    /// near_pairs() with `first_at_or_after(key)`, the position in cell order of the first
    /// sphere whose cell key is `key` or larger.
    template <class First>
    void near_pairs(std::size_t s, std::vector<box_pair>& near, std::vector<box_pair>& touching,
                    First const& first_at_or_after) const;

    std::uint64_t stride_y_ = 0; ///< key step to the next y-cell (= cells in z, padded)
    std::uint64_t stride_x_ = 0; ///< key step to the next x-cell
    /// A table of every cell's start, when there are few cells per sphere; else the starts
    /// are searched for in the sorted keys (a sparse scene).
    bool dense_ = false;
    std::vector<cell_entry> entries_;          ///< in cell order
    std::vector<cell_entry> by_slab_;          ///< by slab, in slot order within each
    std::vector<std::uint32_t> slab_of_entry_; ///< slab of each sphere, in slot order
    std::vector<std::uint32_t> chunk_slab_start_; ///< per chunk of bodies and slab: first entry
    std::vector<std::uint32_t> cell_begin_;    ///< dense: cell-order start of each cell, and the end
    std::vector<std::uint64_t> slab_cell_;     ///< first cell key of each slab, and the end
    std::vector<std::uint32_t> slab_begin_;    ///< cell-order start of each slab, and the end
    std::vector<filed_sphere> spheres_;        ///< in cell order
    std::vector<std::uint32_t> rank_;          ///< by body slot
};

} // namespace kugel::physics
