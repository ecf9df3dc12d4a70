#pragma once

#include "vec.hpp"

#include <span>

namespace kugel::physics {

/// A sphere used as a bounding volume (lecture: "bounding spheres").
struct sphere
{
    vec3 centre = vec3::Zero(); ///< m
    double radius = 0.0;        ///< m, >= 0
};

/// The lecture's (non-optimal) bounding sphere, "Kollisionserkennung - Allgemeines: Bestimmung
/// einer (nicht optimalen) bounding sphere":
///   1. find x_min, P_x,min, x_max, P_x,max and the same for y and z;
///   2. initial sphere on the pair (P_o,min, P_o,max) with the widest separation:
///      centre (P_o,min + P_o,max)/2, radius ‖P_o,min − P_o,max‖/2;
///   3. one pass in input order, enlarging the sphere for each point outside it (Ritter):
///      radius (r + d)/2, centre moved toward the point so that the old sphere stays inside.
/// A last pass sets the radius to at least the largest centre distance; it changes nothing in
/// exact arithmetic and absorbs the rounding of step 3, so every point p satisfies
/// (p − centre).norm() <= radius as evaluated in double. The result is in general larger than
/// the minimum (see minimum_bounding_sphere); an empty span gives radius 0 at the origin.
/// Points must be finite. O(n).
sphere approximate_bounding_sphere(std::span<vec3 const> points);

/// The smallest sphere holding every point (Welzl's algorithm; the lecture's remark
/// "der Algorithmus von Welzl liefert die optimale").
///
/// The points are those of `points` followed by those of `more` (a cloud and a few corners,
/// without copying the cloud).
///
/// Iterative: four nested loops over the points in a deterministically shuffled order, the
/// support set being at most 4 points, so there is no recursion on the number of points;
/// expected O(n) time, and 4 bytes a point of extra memory (the order). The shuffle uses a
/// fixed seed and its own index draw, so the order, and with it the result, is the same with
/// every standard library.
///
/// Accuracy: every point p satisfies (p − centre).norm() <= radius as evaluated in double
/// (a last pass makes sure of it). The radius exceeds the exact minimum by at most about
/// 2·10⁻¹⁰ relative (the inside tolerance, see the source), plus rounding. Points closer
/// together than about 10⁻¹⁰ of the cloud's size are treated as one.
///
/// Degenerate input is handled: an empty span gives radius 0 at the origin; one point, or
/// copies of one point, give radius 0 at that point; collinear and coplanar points give the
/// smallest sphere whose centre lies on their line or plane. Points must be finite.
sphere minimum_bounding_sphere(std::span<vec3 const> points, std::span<vec3 const> more = {});

} // namespace kugel::physics
