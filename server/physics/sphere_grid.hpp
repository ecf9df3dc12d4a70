#pragma once

#include "broadphase.hpp"
#include "parallel_for.hpp"
#include "vec.hpp"

#include <cstddef>
#include <cstdint>
#include <span>
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
    /// hold them: no sphere, coordinates more than 2^47 cells from the origin, or spheres so
    /// spread out that the grid's tables would dwarf their number (e.g. one sphere flung far
    /// off). Positions and radii must be finite.
    bool build(std::span<vec3 const> x, std::span<double const> radius, parallel_for* loops);

    std::size_t slab_count() const { return slab_begin_.size() - 1; }
    /// Which slab the sphere at this position of cell order is in.
    std::size_t slab_of(std::uint32_t rank) const;
    /// Position in cell order of the sphere in each body slot (filed spheres only).
    std::span<std::uint32_t const> rank() const { return rank_; }

    /// Clears `out` and fills it with every pair of slab s whose boxes [x − r, x + r] overlap
    /// (the broadphases' rule, at the positions given to build()), as body slots a < b,
    /// ordered by the cell order of their first, then their second sphere.
    void near_pairs(std::size_t s, std::vector<box_pair>& out) const;

private:
    /// A sphere as filed: its centre (m) and radius (m).
    struct filed_sphere
    {
        double x, y, z, r;
    };
    /// A sphere's cells while sorting.
    struct cell_entry
    {
        std::uint32_t column; ///< x-cell · (y-cells) + y-cell
        std::uint32_t z;      ///< z-cell
        std::uint32_t slot;   ///< body slot
    };

    std::size_t cells_y_ = 0;                  ///< y-cells in a row of columns, padding included
    std::vector<cell_entry> entries_, scratch_;
    std::vector<std::uint32_t> counts_;
    std::vector<std::uint32_t> column_begin_;  ///< cell-order start of each column, and the end
    std::vector<std::uint32_t> slab_column_;   ///< first column of each slab, and the end
    std::vector<std::uint32_t> slab_begin_;    ///< cell-order start of each slab, and the end
    std::vector<filed_sphere> spheres_;        ///< in cell order
    std::vector<std::uint32_t> cell_z_;        ///< z-cell of each, in cell order
    std::vector<std::uint32_t> slot_;          ///< body slot of each, in cell order
    std::vector<std::uint32_t> rank_;          ///< by body slot
};

} // namespace kugel::physics
