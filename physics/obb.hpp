#pragma once

#include "aabb.hpp"
#include "vec.hpp"

#include <Eigen/Core>
#include <span>

namespace kugel::physics {

/// Oriented bounding box (lecture: "(object) oriented bounding box (OBB oder OOBB)").
/// A point x is inside when |axes.col(i)·(x − centre)| <= half_extents[i] for i = 0, 1, 2.
struct obb
{
    vec3 centre = vec3::Zero();                         ///< m
    Eigen::Matrix3d axes = Eigen::Matrix3d::Identity(); ///< columns: orthonormal unit axes,
                                                        ///< right-handed (det = +1)
    vec3 half_extents = vec3::Zero();                   ///< m, >= 0, along each column of axes
};

/// The lecture's OBB ("Bestimmung OBBs"): the centroid of the points, the covariance
/// K = Σ wᵢwᵢᵀ of the centred points wᵢ, its eigenvectors a, b, c (K is symmetric, so they are
/// orthogonal) with the largest eigenvalue's ("Hauptrichtung") first, and then the box fitted
/// so that every point is inside: the points are projected on each axis, and the centre moves
/// to the middle of each range ("neuer Mittelpunkt, Kantenlängen α, β, γ").
/// The axes are always an orthonormal right-handed frame, also when eigenvalues repeat (a
/// cube's corners: any frame of the eigenspace) or vanish (one point, collinear or coplanar
/// points: zero extents). Every point lies inside up to rounding (a few ε of the coordinates).
/// An empty span gives the empty box at the origin with identity axes. Points must be finite.
obb obb_of_points(std::span<vec3 const> points);

/// A box given directly. `rotation`'s columns are the box's axes in world space; it must be
/// orthonormal to within 1e-9 (every entry of RᵀR − I) and right-handed (det R > 0). It is
/// re-orthonormalized, a change of at most about 1e-9, so the box's axes are orthonormal to
/// rounding. Throws std::invalid_argument naming the problem when a half extent is negative or
/// not finite, the centre is not finite, or `rotation` is not a rotation.
obb obb_from_box(vec3 centre, vec3 half_extents, Eigen::Matrix3d rotation);

/// Separating axis test with the 15 candidate axes: the 3 axes of each box and the 9 cross
/// products of one box's axes with the other's. Touching boxes overlap. Conservative by about
/// 10⁻¹² of the boxes' size (see the source), so boxes that touch to rounding overlap too.
bool overlaps(obb const& a, obb const& b);

/// Where a sphere meets a box.
struct sphere_box_contact
{
    bool touching;      ///< distance <= 0
    vec3 closest_point; ///< m, the point of the box's surface nearest the sphere's centre
    vec3 normal;        ///< unit, from the box towards the sphere's centre
    double distance;    ///< m, signed: gap between sphere and box surface, < 0 when they overlap
};

/// Sphere against box. Outside the box: the closest point is the centre clamped to the box in
/// the box's frame, normal = (centre − closest)/|centre − closest|, distance =
/// |centre − closest| − radius. Inside (or on the surface): the face of least penetration
/// depth (ties go to the lower axis, then to the + face) gives the normal (its outward normal)
/// and the closest point (the centre projected on that face), distance = −(depth + radius).
/// `centre` in m; `radius` in m, >= 0.
sphere_box_contact sphere_vs_obb(vec3 centre, double radius, obb const& box);

/// The smallest axis-aligned box holding the oriented one: half extent Σⱼ |axes(i, j)|·hⱼ on
/// world axis i.
aabb aabb_of(obb const& box);

} // namespace kugel::physics
