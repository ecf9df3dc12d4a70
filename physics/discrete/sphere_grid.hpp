#pragma once

#include "physics/cells.hpp"
#include "physics/parallel_for.hpp"
#include "physics/vec.hpp"

namespace kugel::physics::discrete {
/// Which version of a kernel to run: the fast one (always, outside tests) or its plain
/// reference (discrete/kernels.hpp).
enum class kernel { fast, plain };
} // namespace kugel::physics::discrete

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <span>
#include <compare>
#include <functional>
#include <vector>

namespace kugel::physics {

/// Two spheres by their positions in a sphere_grid's cell order, a < b (which side is which
/// matters when two centres coincide: the normal is then +z, from b to a).
struct sphere_pair
{
    std::uint32_t a;
    std::uint32_t b;

    friend bool operator==(sphere_pair const&, sphere_pair const&) = default;
};

/// A sphere as the discrete step's pair passes see it: 32 bytes, two to a cache line and
/// never across two (its inverse mass, which only a push reads, is kept beside it).
struct alignas(32) packed_sphere
{
    vec3 x;        ///< m
    double radius; ///< m, > 0
};

/// What a set of bodies holds for a sphere_grid: its spheres' count, largest radius and
/// extreme centres. Min and max are exact, so extents of parts merge to the whole's, in any
/// order.
struct sphere_extent
{
    std::uint32_t spheres = 0;
    double largest_radius = 0.0; ///< m
    vec3 lowest = vec3::Constant(std::numeric_limits<double>::infinity());
    vec3 highest = vec3::Constant(-std::numeric_limits<double>::infinity());

    /// Counts a body (a sphere when r > 0) at x. Called for every body of a step by loops
    /// that do little else, where GCC would not inline it by itself.
    [[gnu::always_inline]] void add(vec3 const& x, double r)
    {
        if (!(r > 0.0))
            return;
        ++spheres;
        largest_radius = std::max(largest_radius, r);
        lowest = lowest.cwiseMin(x);
        highest = highest.cwiseMax(x);
    }
    void add(sphere_extent const& part)
    {
        spheres += part.spheres;
        largest_radius = std::max(largest_radius, part.largest_radius);
        lowest = lowest.cwiseMin(part.lowest);
        highest = highest.cwiseMax(part.highest);
    }
};

/// How a sphere_grid numbers its cells: the key of the cell a centre is in. Two builds with
/// equal frames give every centre the same key.
struct cell_frame
{
    double per_metre = 0.0;                ///< 1 / cell size, 1/m
    std::array<std::int64_t, 3> origin{};  ///< the cell, per axis, whose coordinate is 0
    std::uint64_t stride_x = 0;            ///< key step to the next x-cell
    std::uint64_t stride_y = 0;            ///< key step to the next y-cell

    /// The key of x's cell. Defined for any x, even one far outside the frame or not finite
    /// (the key is then of no use): a caller may number cells before knowing they fit.
    std::uint64_t key(vec3 const& x) const
    {
        std::uint64_t x_cell = 0;
        return key(x, x_cell);
    }
    /// The same, with the x-coordinate of the cell (in [1, cells in x] when x is in the frame).
    std::uint64_t key(vec3 const& x, std::uint64_t& x_cell) const
    {
        auto const cell = [&](Eigen::Index axis) {
            double const q = x[axis] * per_metre;
            // -2^63 for what has no 64-bit integer, where a cast would be undefined
            auto const truncated = static_cast<std::uint64_t>(cells::truncate(q));
            // floor(q), then the origin's offset, with unsigned (wrapping) arithmetic
            std::uint64_t const below = q < static_cast<double>(static_cast<std::int64_t>(truncated)) ? 1 : 0;
            return truncated - below - static_cast<std::uint64_t>(origin[static_cast<std::size_t>(axis)]);
        };
        x_cell = cell(0);
        return x_cell * stride_x + cell(1) * stride_y + cell(2);
    }
    friend bool operator==(cell_frame const&, cell_frame const&) = default;
};

/// Cell keys a caller found on a pass it makes over the bodies anyway (by body slot; any
/// value for bodies that are not spheres), and the frame it numbered them in.
struct cell_keys
{
    std::span<std::uint64_t const> keys;
    cell_frame frame;
    /// The x-coordinates of the same cells (cell_frame::key), by body slot: what a build
    /// with threads, which sorts slab by slab, needs besides.
    std::span<std::uint32_t const> x_cells = {};
};

/// The spheres of one step filed by their centres into cubic cells as wide as the largest
/// diameter, so that two spheres whose boxes overlap sit in the same cell or in neighbouring
/// ones: the discrete step's broadphase when the scene asks for the grid, and the order in
/// which the discrete step resolves contacts whichever broadphase found them.
///
/// Cell order sorts the spheres by cell (x, then y, then z) and then by body slot, so it is a
/// function of the positions and radii alone: the same state gives the same order, however
/// the world got there (a world restored from a checkpoint goes on like the original).
/// The grid keeps each sphere's position, radius and inverse mass in that order, carried
/// along while sorting, so that the pair passes read memory nearly in sequence and no
/// sphere is fetched from a scattered body slot.
///
/// Spheres are named by their position in cell order, their rank; slot() gives the body.
/// Slabs are runs of whole x-cells. A pair belongs to the slab of its first sphere in cell
/// order, and its second sphere is in that slab or the next, so the pairs of the even slabs
/// share no sphere with each other, nor do those of the odd ones: each half can be worked on
/// slab by slab at the same time, and the outcome is that of one fixed order.
class sphere_grid
{
public:
    /// Slabs a grid has at most: enough for two threads to share them evenly, few enough
    /// that a slab is much larger than its boundary with the next.
    static constexpr std::uint32_t most_slabs = 16;
    /// Called with a slab once it and the next are filed: near_pairs() of that slab may run.
    /// Calls for different slabs may come at the same time, on the threads of `loops`.
    using slab_ready = std::function<void(std::size_t)>;

    /// Files the spheres (radius > 0) at x. False, with nothing filed, when the grid cannot
    /// hold them: no sphere, coordinates more than 2^47 cells from the origin (e.g. 10^13 m
    /// with 0.1 m spheres), or a scene spanning more cells than a 64-bit key can number.
    /// Positions and radii must be finite. When given, ready() is called for every slab of
    /// the grid, each as soon as it can be (not at all when the grid declines).
    bool build(std::span<vec3 const> x, std::span<double const> radius,
               std::span<double const> inverse_mass, parallel_for* loops, slab_ready const& ready = {});
    /// The same, given the bodies' extent (found on a pass the caller makes anyway).
    /// With `keyed`, keys numbered in the frame the build turns out to use spare it finding
    /// them (with threads, only when their x-cells come too); keys in another frame are not
    /// read.
    bool build(std::span<vec3 const> x, std::span<double const> radius,
               std::span<double const> inverse_mass, sphere_extent const& all, parallel_for* loops,
               slab_ready const& ready, cell_keys const* keyed = nullptr);

    /// The frame of the last build when it kept a table of every cell (the case in which it
    /// reads keys given to it): a scene with a few cells per sphere, such as a gas. A gas in
    /// a box keeps its frame from step to step (the extreme centres stay in their cells), so
    /// keys numbered in the last build's frame usually fit the next.
    std::optional<cell_frame> const& keying_frame() const { return keying_frame_; }

    /// When build() declines: files every sphere in one slab, in slot order, for a caller that
    /// finds the pairs elsewhere (near_pairs() is not available then).
    void file_in_slot_order(std::span<vec3 const> x, std::span<double const> radius,
                            std::span<double const> inverse_mass);

    std::size_t slab_count() const { return slab_begin_.size() - 1; }
    /// True when the last build() filed the spheres in cell order (it did not decline).
    bool in_cell_order() const { return in_cell_order_; }
    /// How many spheres are filed.
    std::uint32_t sphere_count() const { return slab_begin_.back(); }
    /// The first position in cell order of slab s; slab_begin(slab_count()) is the end.
    std::uint32_t slab_begin(std::size_t s) const { return slab_begin_[s]; }
    /// Which slab the sphere at this position of cell order is in.
    std::size_t slab_of(std::uint32_t rank) const;
    /// The body slot of the sphere at this position of cell order.
    std::uint32_t slot(std::uint32_t rank) const { return slots_[rank]; }
    /// The sphere at this position of cell order, as given to build(); the caller may move it.
    packed_sphere& sphere(std::uint32_t rank) { return spheres_[rank]; }
    packed_sphere const& sphere(std::uint32_t rank) const { return spheres_[rank]; }
    /// The inverse mass of that sphere, 1/kg (0 for a static one).
    double inverse_mass(std::uint32_t rank) const { return inverse_masses_[rank]; }
    /// Fills `out` with the position in cell order of the sphere in each body slot (of n; the
    /// entries of bodies that are not spheres are left as they were).
    void ranks(std::size_t n, std::vector<std::uint32_t>& out) const;

    /// The contact margin m (m >= 0) of the builds that follow: near pairs and contacts are
    /// found as if one sphere of each pair were m larger (speculative contacts, which a step
    /// under forces needs: two spheres a rounding error apart that fall together are still a
    /// contact). 0, the default, finds the pairs that touch.
    void set_contact_margin(double m) { margin_ = m; }
    double contact_margin() const { return margin_; }

    /// Clears `near` and fills it with every pair of slab s whose boxes [x − r, x + r] overlap
    /// (the broadphases' rule, at the positions given to build()), as positions in cell order,
    /// a < b, sorted by a, then b; `touching` gets those of them whose spheres touch
    /// (|x_a − x_b| <= r_a + r_b), in the same order. With a contact margin m, the first box
    /// is [x − (r + m), x + (r + m)] and touching is |x_a − x_b| <= r_a + r_b + m.
    /// `with` chooses the box test: the fast kernel, or its plain reference (for the tests
    /// that compare the two, discrete/kernels.hpp).
    void near_pairs(std::size_t s, std::vector<sphere_pair>& near, std::vector<sphere_pair>& touching,
                    discrete::kernel with = discrete::kernel::fast) const;

private:
    /// What a build decided before filing a sphere: the frame, the slabs, the table.
    struct layout
    {
        cell_frame frame;
        std::array<std::int64_t, 3> size{}; ///< cells per axis, padding included
        std::uint64_t cells = 0;            ///< keys in use: the table's length
        std::uint64_t slab_width = 0;       ///< x-cells per slab
        std::uint32_t slabs = 0;
    };
    /// Steps 2 and 3 of build(): the cell size, the frame and the slabs, or nothing when the
    /// grid cannot hold the scene.
    std::optional<layout> lay_out(sphere_extent const& all);
    /// Sorts every sphere at once, on one thread, by a counting sort over every cell.
    void sort_all_at_once(std::span<vec3 const> x, std::span<double const> radius,
                          std::span<double const> inverse_mass, sphere_extent const& all,
                          layout const& grid, std::uint64_t const* given_keys, slab_ready const& ready);
    /// Sorts the spheres into their slabs (in slot order within each), then each slab by cell.
    void sort_slab_by_slab(std::span<vec3 const> x, std::span<double const> radius,
                           std::span<double const> inverse_mass, sphere_extent const& all, layout const& grid,
                           cell_keys const* given, parallel_for* loops, slab_ready const& ready);
    /// Counts each chunk's spheres per slab and notes each sphere's key and slab.
    std::uint64_t const* count_by_slab(std::span<vec3 const> x, std::span<double const> radius,
                                       layout const& grid, cell_keys const* given, parallel_for* loops);
    /// Sorts slab s (its entries in by_slab_) by cell, then slot, into cell order.
    void sort_slab(std::size_t s, std::span<vec3 const> x, std::span<double const> radius,
                   std::span<double const> inverse_mass);

    void near_pairs_sparse(std::size_t s, std::vector<sphere_pair>& near, std::vector<sphere_pair>& touching) const;
    template <class box>
    void near_pairs_dense(std::size_t s, std::vector<sphere_pair>& near, std::vector<sphere_pair>& touching) const;

    /// A sphere and its cell, on its way into cell order.
    struct filed_sphere
    {
        std::uint64_t cell; ///< key of its cell: (x · cells_y + y) · cells_z + z
        std::uint32_t slot; ///< body slot
        vec3 x;             ///< m
        double radius;      ///< m
        double inverse_mass; ///< 1/kg
    };

    void resize_filed(std::uint32_t spheres);
    /// While placing: fetches where the next sphere of a cell whose present start is `start`
    /// will go (its spheres go in from the back).
    void fetch_destination(std::uint32_t start) const;
    /// A function (rank, filed_sphere) that puts the sphere at that position of cell order,
    /// into the tables as resize_filed() left them.
    auto filer();

    bool in_cell_order_ = false;
    double margin_ = 0.0; ///< m, the contact margin
    std::optional<cell_frame> keying_frame_;
    std::uint64_t stride_y_ = 0; ///< key step to the next y-cell (= cells in z, padded)
    std::uint64_t stride_x_ = 0; ///< key step to the next x-cell
    /// A table of every cell's start, when there are few cells per sphere; else the starts
    /// are searched for in the sorted keys (a sparse scene).
    bool dense_ = false;
    // The filed spheres in cell order, in four tables: the pair passes read the spheres
    // alone, 32 bytes each, two to a cache line (at 10^6 spheres the step waits on memory,
    // and reads the spheres several times).
    std::vector<packed_sphere> spheres_;       ///< in cell order
    std::vector<double> inverse_masses_;       ///< in cell order
    std::vector<std::uint32_t> slots_;         ///< body slot, in cell order
    std::vector<std::uint64_t> cells_;         ///< cell key, in cell order
    /// A sphere on its way into its slab: its cell and body slot.
    struct slab_entry
    {
        std::uint64_t cell;
        std::uint32_t slot;
    };
    std::vector<slab_entry> by_slab_;          ///< by slab, in slot order within each
    std::vector<std::uint64_t> keys_;          ///< cell key by body slot (spheres only)
    std::vector<std::uint32_t> slabs_;         ///< slab by body slot (spheres only)
    std::vector<std::uint32_t> slab_of_x_;     ///< dense: slab of each x-cell
    std::vector<std::uint32_t> chunk_slab_start_; ///< per chunk of bodies and slab: first entry
    std::vector<std::uint32_t> cell_begin_;    ///< dense: cell-order start of each cell, and the end
    std::vector<std::uint64_t> slab_cell_;     ///< first cell key of each slab, and the end
    std::vector<std::uint32_t> slab_begin_;    ///< cell-order start of each slab, and the end
};

} // namespace kugel::physics
