#pragma once

// Internal to the collision code: the walls as both modes test spheres against them.

#include "collisions.hpp"
#include "sse2.hpp"

#include <limits>
#include <span>
#include <vector>

namespace kugel::physics::detail {

/// The walls, with the axis-aligned ones (normal ±e_k, as make_plane stores them) also kept
/// as bounds per coordinate: for those, n·x is ±x_k exactly, so "n·x >= offset + r for every
/// wall" becomes two comparisons per axis, bit for bit the same test. Built once per step.
class wall_set
{
public:
    explicit wall_set(std::span<wall const> walls) : all(walls)
    {
        for (wall const& w : walls) {
            vec3 const& n = w.surface.normal;
            Eigen::Index axis = 0;
            if (n.cwiseAbs().maxCoeff(&axis) == 1.0 && (n.array() == 0.0).count() == 2) {
                double& bound = (n[axis] > 0.0 ? below_ : above_)[axis];
                bound = std::max(bound, w.surface.offset);
            } else {
                oblique_.push_back(w);
            }
        }
    }

    /// True when a sphere of radius r at x is clear of every wall (n·x >= offset + r for all):
    /// the common case, tested without a branch per wall (every wall pass asks it of every
    /// sphere).
    bool clear(vec3 const& x, double r) const
    {
#if defined(KUGEL_SSE2)
        return clear_of_axis_walls_sse2(x, r) && clear_of_oblique_walls(x, r);
#else
        return clear_plain(x, r);
#endif
    }

    /// The plain reference of clear().
    bool clear_plain(vec3 const& x, double r) const
    {
        bool clear = x.x() >= below_.x() + r; // &=, not &&: no branch per wall
        clear &= x.y() >= below_.y() + r;
        clear &= x.z() >= below_.z() + r;
        clear &= -x.x() >= above_.x() + r;
        clear &= -x.y() >= above_.y() + r;
        clear &= -x.z() >= above_.z() + r;
        return clear && clear_of_oblique_walls(x, r);
    }

#if defined(KUGEL_SSE2)
    /// The six comparisons of clear_plain() with the axis-aligned walls, two at a time.
    bool clear_of_axis_walls_sse2(vec3 const& x, double r) const
    {
        __m128d const reach = _mm_set1_pd(r);
        __m128d const xy = _mm_loadu_pd(x.data());
        __m128d const minus_xy = _mm_sub_pd(_mm_setzero_pd(), xy); // 0 − x: −x, also for x = 0
        __m128d const lanes =
            _mm_and_pd(_mm_and_pd(_mm_cmpge_pd(xy, _mm_add_pd(_mm_loadu_pd(below_.data()), reach)),
                                  _mm_cmpge_pd(minus_xy, _mm_add_pd(_mm_loadu_pd(above_.data()), reach))),
                       _mm_cmpge_pd(_mm_set_pd(-x.z(), x.z()), _mm_add_pd(_mm_set_pd(above_.z(), below_.z()), reach)));
        return _mm_movemask_pd(lanes) == 3;
    }
#endif

    /// True when a sphere at x is farther than `reach` from every wall (n·x > offset + reach
    /// for all).
    bool beyond(vec3 const& x, double reach) const
    {
        bool beyond = x.x() > below_.x() + reach;
        beyond &= x.y() > below_.y() + reach;
        beyond &= x.z() > below_.z() + reach;
        beyond &= -x.x() > above_.x() + reach;
        beyond &= -x.y() > above_.y() + reach;
        beyond &= -x.z() > above_.z() + reach;
        for (wall const& w : oblique_)
            beyond &= w.surface.normal.dot(x) > w.surface.offset + reach;
        return beyond;
    }

    std::span<wall const> all;

private:
    bool clear_of_oblique_walls(vec3 const& x, double r) const
    {
        bool clear = true;
        for (wall const& w : oblique_)
            clear &= w.surface.normal.dot(x) >= w.surface.offset + r;
        return clear;
    }

    static constexpr double none = -std::numeric_limits<double>::infinity();
    vec3 below_ = vec3::Constant(none); ///< largest offset of the walls with normal +e_k
    vec3 above_ = vec3::Constant(none); ///< largest offset of the walls with normal −e_k
    std::vector<wall> oblique_;         ///< every other wall
};

} // namespace kugel::physics::detail
