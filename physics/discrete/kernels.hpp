#pragma once

// The discrete step's fast kernels, each beside its plain reference. The fast one runs; the
// plain one is what it must equal bit for bit, on any input, and the tests run both in the
// same binary (tests/physics/discrete/kernels_test.cpp). Without SSE2 (or with KUGEL_NO_SSE2)
// the fast names are the plain ones.

#include "physics/discrete/sphere_grid.hpp"
#include "physics/sse2.hpp"

#include <cstdint>

namespace kugel::physics::discrete {

/// Replaces each count in [first, last) by the sum of `start` and the counts up to and
/// including it: each cell's end, from the cells' counts (integer sums wrap, so any order of
/// adding gives the same).
inline void running_sums_plain(std::uint32_t* first, std::uint32_t* last, std::uint32_t start)
{
    for (; first != last; ++first)
        *first = start += *first;
}

/// The same, four at a time where the processor can: a gas has five cells per sphere, so this
/// runs over more numbers than any other loop of the grid.
inline void running_sums(std::uint32_t* first, std::uint32_t* last, std::uint32_t start)
{
#if defined(KUGEL_SSE2)
    __m128i carry = _mm_set1_epi32(static_cast<int>(start));
    for (; last - first >= 4; first += 4) {
        __m128i sums = _mm_loadu_si128(reinterpret_cast<__m128i const*>(first));
        sums = _mm_add_epi32(sums, _mm_slli_si128(sums, 4)); // each lane plus the one before
        sums = _mm_add_epi32(sums, _mm_slli_si128(sums, 8)); // and the two before those
        sums = _mm_add_epi32(sums, carry);
        _mm_storeu_si128(reinterpret_cast<__m128i*>(first), sums);
        carry = _mm_shuffle_epi32(sums, 0xff); // the last lane's sum, in every lane
    }
    start = static_cast<std::uint32_t>(_mm_cvtsi128_si32(carry));
#endif
    running_sums_plain(first, last, start);
}

/// A sphere's box [x − r, x + r], as the near-pair search tests candidates against it: the
/// box test of aabb.hpp, overlaps(aabb_of_sphere(a), aabb_of_sphere(b)), without building
/// the candidate's box (at 10^6 spheres the memory traffic, not the arithmetic, is what a
/// step waits on). max(lo) <= min(hi) is lo_a <= hi_b and lo_b <= hi_a, as lo <= hi. With a
/// margin m, a's box is [x − (r + m), x + (r + m)]: it meets every sphere less than m apart
/// (the grid's speculative contacts); with m = 0 it is the box of aabb.hpp, bit for bit.
struct sphere_box_plain
{
    double lo[3], hi[3];

    sphere_box_plain() = default;
    explicit sphere_box_plain(packed_sphere const& a, double margin = 0.0)
    {
        double const reach = a.radius + margin;
        for (Eigen::Index k = 0; k < 3; ++k) {
            lo[k] = a.x[k] - reach;
            hi[k] = a.x[k] + reach;
        }
    }
    bool meets(packed_sphere const& b) const
    {
        bool in = true;
        for (Eigen::Index k = 0; k < 3; ++k) { // &: no branch per axis
            double const centre = b.x[k];
            in &= (lo[k] <= centre + b.radius) & (centre - b.radius <= hi[k]);
        }
        return in;
    }
};

#if defined(KUGEL_SSE2)
/// The same comparisons of the same numbers, two coordinates at a time. In z, lo_a <= hi_b and
/// −hi_a <= −lo_b (exact negations, and r − z is exactly −(z − r)).
struct sphere_box_sse2
{
    __m128d lo_xy, hi_xy, z; // z: z − r, −(z + r)

    sphere_box_sse2() = default;
    explicit sphere_box_sse2(packed_sphere const& a, double margin = 0.0)
    {
        double const reach = a.radius + margin;
        __m128d const a_xy = _mm_loadu_pd(a.x.data()), a_r = _mm_set1_pd(reach);
        lo_xy = _mm_sub_pd(a_xy, a_r);
        hi_xy = _mm_add_pd(a_xy, a_r);
        z = _mm_set_pd(-(a.x.z() + reach), a.x.z() - reach);
    }
    bool meets(packed_sphere const& b) const
    {
        __m128d const xy = _mm_loadu_pd(b.x.data());
        __m128d const zr = _mm_loadu_pd(b.x.data() + 2); // z and the radius, side by side
        __m128d const rr = _mm_unpackhi_pd(zr, zr);
        __m128d const rz = _mm_shuffle_pd(zr, zr, 1);
        __m128d const zz = _mm_move_sd(_mm_sub_pd(zr, rz), _mm_add_pd(zr, rz)); // z + r, r − z
        __m128d const in_xy = _mm_and_pd(_mm_cmple_pd(lo_xy, _mm_add_pd(xy, rr)),
                                         _mm_cmple_pd(_mm_sub_pd(xy, rr), hi_xy));
        return _mm_movemask_pd(_mm_and_pd(in_xy, _mm_cmple_pd(z, zz))) == 3;
    }
};
using sphere_box = sphere_box_sse2;
#else
using sphere_box = sphere_box_plain;
#endif

} // namespace kugel::physics::discrete
