#include "bounding_sphere.hpp"

#include "aabb.hpp"

#include <Eigen/LU>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <random>
#include <stdexcept>
#include <utility>
#include <vector>

namespace kugel::physics {

namespace {

/// A point counts as inside a trial sphere of radius r when its distance from the centre is at
/// most r + inside_tolerance·max(r, s), s being half the diagonal of the points' AABB.
/// Why: the centres of the trial spheres carry rounding errors, relative to the cloud, of a few
/// ε times the conditioning of the small solves. Without slack, a point that lies on the sphere
/// (a support point itself, four cocircular points, the corners of a cube) can test as outside
/// by an ulp, which drives the algorithm into support sets of coplanar or collinear points for
/// nothing. 10⁻¹⁰ is about 10⁶ ulps: well above that rounding, far below any accuracy a caller
/// needs. Since the minimum radius R is at least s/√3, a point accepted this way lies at most
/// √3·10⁻¹⁰·R outside; the final pass absorbs that, so the radius stays within about 2·10⁻¹⁰
/// of the minimum.
constexpr double inside_tolerance = 1e-10;

/// Three support points are treated as collinear, and four as coplanar, when the sine-like
/// measure |u×v|/(|u||v|) or |u·(v×w)|/(|u||v||w|) of their edge vectors falls below this.
/// Both are computed to about ε absolute, so anything smaller is rounding, not geometry.
constexpr double degenerate_tolerance = 1e-12;

/// Fixed seed of the shuffle ("Kugel" in ASCII): the same points give the same sphere.
constexpr std::uint64_t shuffle_seed = 0x4b7567656c;

bool contains(sphere const& s, vec3 const& p, double scale)
{
    double const limit = s.radius + inside_tolerance * std::max(s.radius, scale);
    return (p - s.centre).squaredNorm() <= limit * limit;
}

/// Keeps the centre and grows the radius to reach `p`. The fallback for a degenerate support
/// set, which only rounding produces (see smallest_sphere_through below).
sphere grown_to(sphere const& s, vec3 const& p)
{
    return {s.centre, std::max(s.radius, (p - s.centre).norm())};
}

/// The smallest sphere with a and b on its surface: centre a + u/2, radius |u|/2, u = b − a.
sphere smallest_sphere_through(vec3 const& a, vec3 const& b)
{
    vec3 const u = b - a;
    return {a + 0.5 * u, 0.5 * u.norm()};
}

/// The smallest sphere with a, b, c on its surface (the triangle's circumcircle). Solved relative
/// to a in the plane of the triangle: centre a + α·u + β·v with u = b − a, v = c − a, and
/// |offset − u|² = |offset|² = |offset − v|² gives the 2×2 system
///   [u·u u·v; u·v v·v]·[α; β] = ½·[u·u; v·v],
/// whose determinant is |u×v|² (taken from the cross product, which does not cancel the way
/// (u·u)(v·v) − (u·v)² does). Nothing when the points are collinear.
std::optional<sphere> smallest_sphere_through(vec3 const& a, vec3 const& b, vec3 const& c)
{
    vec3 const u = b - a;
    vec3 const v = c - a;
    double const uu = u.squaredNorm();
    double const vv = v.squaredNorm();
    double const uv = u.dot(v);
    double const det = u.cross(v).squaredNorm();
    if (!(det > degenerate_tolerance * degenerate_tolerance * uu * vv))
        return std::nullopt;
    double const alpha = 0.5 * vv * (uu - uv) / det;
    double const beta = 0.5 * uu * (vv - uv) / det;
    vec3 const offset = alpha * u + beta * v;
    return sphere{a + offset, offset.norm()};
}

/// The sphere with a, b, c, d on its surface. Solved relative to a: with u, v, w the edges from
/// a, the centre offset x satisfies 2·x·u = u·u and the same for v and w, a 3×3 system.
/// Nothing when the four points are coplanar (or fewer than four distinct).
std::optional<sphere> smallest_sphere_through(vec3 const& a, vec3 const& b, vec3 const& c,
                                              vec3 const& d)
{
    vec3 const u = b - a;
    vec3 const v = c - a;
    vec3 const w = d - a;
    double const volume = u.dot(v.cross(w));
    if (!(std::abs(volume) > degenerate_tolerance * u.norm() * v.norm() * w.norm()))
        return std::nullopt;
    Eigen::Matrix3d edges;
    edges.row(0) = u.transpose();
    edges.row(1) = v.transpose();
    edges.row(2) = w.transpose();
    vec3 const rhs = 0.5 * vec3(u.squaredNorm(), v.squaredNorm(), w.squaredNorm());
    vec3 const offset = edges.fullPivLu().solve(rhs);
    return sphere{a + offset, offset.norm()};
}

/// Uniform in [0, bound). std::uniform_int_distribution is not specified exactly and differs
/// between standard libraries; rejection of the top partial block keeps this draw unbiased.
std::uint64_t draw_below(std::mt19937_64& rng, std::uint64_t bound)
{
    constexpr std::uint64_t top = std::numeric_limits<std::uint64_t>::max();
    std::uint64_t const limit = top - top % bound; // a multiple of bound
    for (;;) {
        std::uint64_t const x = rng();
        if (x < limit)
            return x % bound;
    }
}

/// The points of two spans as one list, a's then b's, read where they are: a cloud of a
/// million spheres' centres is not copied (24 MB) to find its bounds.
struct two_spans
{
    std::span<vec3 const> a, b;

    std::size_t size() const { return a.size() + b.size(); }
    vec3 const& operator[](std::size_t i) const { return i < a.size() ? a[i] : b[i - a.size()]; }
};

/// The numbers below n in a fixed pseudo-random order (Fisher–Yates).
std::vector<std::uint32_t> shuffled_indices(std::size_t n)
{
    std::vector<std::uint32_t> order(n);
    for (std::size_t i = 0; i < n; ++i)
        order[i] = static_cast<std::uint32_t>(i);
    std::mt19937_64 rng(shuffle_seed);
    for (std::size_t i = n; i > 1; --i)
        std::swap(order[i - 1], order[draw_below(rng, i)]);
    return order;
}

/// The radius grown, if need be, to the largest distance from `centre` to any point, so that
/// (p − centre).norm() <= radius holds for every point as evaluated in double.
template <class Points>
double enclosing_radius(Points const& points, vec3 const& centre, double radius)
{
    double max_squared = 0.0;
    for (std::size_t i = 0; i < points.size(); ++i)
        max_squared = std::max(max_squared, (points[i] - centre).squaredNorm());
    return std::max(radius, std::sqrt(max_squared));
}

} // namespace

sphere approximate_bounding_sphere(std::span<vec3 const> points)
{
    if (points.empty())
        return {};

    // 1. The lecture's extreme points P_o,min and P_o,max for o = x, y, z.
    std::array<std::size_t, 3> lowest{};
    std::array<std::size_t, 3> highest{};
    for (std::size_t i = 1; i < points.size(); ++i) {
        for (Eigen::Index o = 0; o < 3; ++o) {
            auto const axis = static_cast<std::size_t>(o);
            if (points[i][o] < points[lowest[axis]][o])
                lowest[axis] = i;
            if (points[i][o] > points[highest[axis]][o])
                highest[axis] = i;
        }
    }

    // 2. Initial sphere on the widest pair: centre (P_o,min + P_o,max)/2,
    //    radius ‖P_o,min − P_o,max‖/2.
    std::size_t widest = 0;
    double widest_squared = -1.0;
    for (std::size_t o = 0; o < 3; ++o) {
        double const d2 = (points[highest[o]] - points[lowest[o]]).squaredNorm();
        if (d2 > widest_squared) {
            widest_squared = d2;
            widest = o;
        }
    }
    vec3 const& p_min = points[lowest[widest]];
    vec3 const& p_max = points[highest[widest]];
    sphere s{0.5 * (p_min + p_max), 0.5 * (p_max - p_min).norm()};

    // 3. "Sukzessives Anpassen der initialen Kugel (für jeden äußeren Punkt)": a point at
    //    distance d > r gives the sphere of radius (r + d)/2 through the point and through the
    //    old sphere's far side, which therefore stays inside.
    for (vec3 const& p : points) {
        vec3 const to_p = p - s.centre;
        double const d2 = to_p.squaredNorm();
        if (d2 <= s.radius * s.radius)
            continue;
        double const d = std::sqrt(d2);
        double const grown = 0.5 * (s.radius + d);
        s.centre += ((grown - s.radius) / d) * to_p;
        s.radius = grown;
    }

    s.radius = enclosing_radius(points, s.centre, s.radius);
    return s;
}

sphere minimum_bounding_sphere(std::span<vec3 const> points, std::span<vec3 const> more)
{
    two_spans const all{points, more};
    std::size_t const n = all.size();
    if (n == 0)
        return {};
    if (n > std::numeric_limits<std::uint32_t>::max())
        throw std::length_error("minimum_bounding_sphere: more than 2^32 - 1 points");

    // Work relative to the middle of the cloud, so that rounding is relative to its size and
    // not to its distance from the origin.
    aabb box{all[0], all[0]};
    for (std::size_t i = 1; i < n; ++i) {
        box.min = box.min.cwiseMin(all[i]);
        box.max = box.max.cwiseMax(all[i]);
    }
    vec3 const origin = box.centre();
    double const scale = 0.5 * box.extent().norm();
    // The points in a fixed pseudo-random order, relative to the origin: an index a point
    // (4 bytes) rather than a shifted copy (24).
    std::vector<std::uint32_t> const order = shuffled_indices(n);
    auto p = [&](std::size_t k) -> vec3 { return all[order[k]] - origin; };

    // Welzl without recursion on the points: the loop at depth k finds the smallest sphere
    // holding the points so far with the k chosen points on its surface. A point outside the
    // current sphere lies on the surface of the next one (Welzl's lemma), so it joins the
    // support set and the points before it are scanned again one level deeper. Depth 4 fixes
    // the sphere completely. In exact arithmetic the support sets are never degenerate; in
    // floating point a collinear or coplanar set can only come from rounding, and then the
    // current sphere is grown to reach the new point instead.
    sphere s{p(0), 0.0};
    for (std::size_t i = 1; i < n; ++i) {
        vec3 const pi = p(i);
        if (contains(s, pi, scale))
            continue;
        s = {pi, 0.0};
        for (std::size_t j = 0; j < i; ++j) {
            vec3 const pj = p(j);
            if (contains(s, pj, scale))
                continue;
            s = smallest_sphere_through(pi, pj);
            for (std::size_t k = 0; k < j; ++k) {
                vec3 const pk = p(k);
                if (contains(s, pk, scale))
                    continue;
                auto const through_k = smallest_sphere_through(pi, pj, pk);
                s = through_k ? *through_k : grown_to(s, pk);
                for (std::size_t l = 0; l < k; ++l) {
                    vec3 const pl = p(l);
                    if (contains(s, pl, scale))
                        continue;
                    auto const through_l = smallest_sphere_through(pi, pj, pk, pl);
                    s = through_l ? *through_l : grown_to(s, pl);
                }
            }
        }
    }

    vec3 const centre = origin + s.centre;
    return {centre, enclosing_radius(all, centre, s.radius)};
}

} // namespace kugel::physics
