#pragma once

// The cell arithmetic both grids share: the broadphase's uniform grid (uniform_grid.cpp) and
// the discrete step's sphere grid (discrete/sphere_grid.hpp).
//
// Why neighbouring cells suffice, in floating point. A grid files each thing (a box by its
// lower corner, a sphere by its centre) into the cell floor(x / h) on every axis, with h the
// largest extent E of anything filed (a box's edge, a sphere's diameter). Two things that
// overlap on an axis are then at most E apart there in exact arithmetic, so their cells are
// the same or adjacent. In floating point the computed quotients (or products x · (1/h), 1/h
// itself rounded) and the bounds x ± r are each off by a few units in the last place of
// |x| / h. With u = 2^-53 and reach >= max|x| / E, all of it stays below u · (4 · reach + 1)
// relative to h, and widened_cell_size() makes h larger than E by 8u · (2 + reach), which
// covers it: the computed difference of two such cells' coordinates is still at most 1.
// For coordinates up to largest_cell_coordinate cells from the origin the widening stays
// below 1/8 of a cell.

#include "sse2.hpp"

#include <cstdint>
#include <limits>
#include <optional>

namespace kugel::physics::cells {

constexpr double unit_roundoff = 0x1p-53;
/// Largest |coordinate| / cell size a grid accepts; beyond it cells would be finer than the
/// coordinates can resolve (and a grid hands the scene to another method).
constexpr double largest_cell_coordinate = 0x1p47;

/// The cell size for things of largest extent `extent` whose coordinates reach at most
/// `reach` extents from the origin (see the top of this file).
inline double widened_cell_size(double extent, double reach)
{
    return extent + extent * (8.0 * unit_roundoff * (2.0 + reach));
}

/// floor(q) for |q| < 2^53, without a library call.
inline std::int64_t floor_to_integer(double q)
{
    auto const truncated = static_cast<std::int64_t>(q);
    return q < static_cast<double>(truncated) ? truncated - 1 : truncated;
}

/// a · b, or nullopt when it does not fit in 64 bits.
inline std::optional<std::uint64_t> checked_product(std::uint64_t a, std::uint64_t b)
{
    if (a != 0 && b > std::numeric_limits<std::uint64_t>::max() / a)
        return std::nullopt;
    return a * b;
}

/// q rounded toward zero to a 64-bit integer, defined for every double: what has no 64-bit
/// integer (NaN, |q| >= 2^63) gives -2^63, as the x86-64 conversion does. The plain reference
/// of truncate(); the two agree on every input (tests/physics/discrete/kernels_test.cpp).
inline std::int64_t truncate_plain(double q)
{
    if (!(q >= -0x1p63 && q < 0x1p63))
        return std::numeric_limits<std::int64_t>::min();
    return static_cast<std::int64_t>(q);
}

/// The same, in one instruction where the processor has it.
inline std::int64_t truncate(double q)
{
#if defined(KUGEL_SSE2) && defined(__x86_64__)
    return _mm_cvttsd_si64(_mm_set_sd(q));
#else
    return truncate_plain(q);
#endif
}

} // namespace kugel::physics::cells
