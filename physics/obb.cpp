#include "obb.hpp"

#include <Eigen/Eigenvalues>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace kugel::physics {

namespace {

/// How far from orthonormal a rotation given to obb_from_box may be, in every entry of RᵀR − I.
constexpr double rotation_tolerance = 1e-9;

/// Added to every |R(i, j)| in the separating axis test (Gottschalk's RAPID; Ericson,
/// Real-Time Collision Detection, 4.4.1). When an edge of one box is parallel to an edge of
/// the other, their cross product is the zero vector up to rounding, and the test on that
/// axis compares two rounding noises of order ε·|t| (t the centres' offset): it could call two
/// overlapping parallel boxes separated. The epsilon raises the projected radii by 10⁻¹² of
/// the half extents, well above that noise for boxes close enough to overlap, and is a
/// negligible inflation otherwise (a false overlap is harmless for a bounding volume, a false
/// separation loses a contact). A box with two zero extents (a segment) gets no such margin on
/// the cross axes: give segments a small thickness.
constexpr double parallel_epsilon = 1e-12;

/// An orthonormal right-handed frame: column 0 along `first`, column 1 along the part of
/// `second` orthogonal to it, column 2 their cross product. Nearly zero or nearly parallel
/// inputs fall back to any orthonormal completion.
Eigen::Matrix3d orthonormal_frame(vec3 const& first, vec3 const& second)
{
    double const first_norm = first.norm();
    if (!(first_norm > 0.0))
        return Eigen::Matrix3d::Identity();
    vec3 const a = first / first_norm;
    vec3 b = second - a.dot(second) * a;
    if (!(b.norm() > 1e-6 * second.norm()) || !(b.norm() > 0.0)) {
        // Any unit vector orthogonal to a: start from the world axis least aligned with it.
        Eigen::Index least = 0;
        a.cwiseAbs().minCoeff(&least);
        vec3 const e = vec3::Unit(least);
        b = e - a.dot(e) * a;
    }
    b.normalize();
    Eigen::Matrix3d frame;
    frame.col(0) = a;
    frame.col(1) = b;
    frame.col(2) = a.cross(b);
    return frame;
}

[[noreturn]] void reject_box(std::string const& what)
{
    throw std::invalid_argument("obb_from_box: " + what);
}

} // namespace

obb obb_of_points(std::span<vec3 const> points)
{
    if (points.empty())
        return {};
    auto const n = static_cast<double>(points.size());

    // Centroid ("Schwerpunkt (Mittelpunkt) aller Punkte").
    vec3 mean = vec3::Zero();
    for (vec3 const& p : points)
        mean += p;
    mean /= n;

    // Covariance of the centred ("balancierten") points, K = Σ wᵢwᵢᵀ; dividing by n leaves the
    // eigenvectors as they are and keeps the numbers of the order of the squared extents.
    Eigen::Matrix3d k = Eigen::Matrix3d::Zero();
    for (vec3 const& p : points) {
        vec3 const w = p - mean;
        k.noalias() += w * w.transpose();
    }
    k /= n;

    // Eigenvectors of the symmetric K, ascending eigenvalues: the last is the "Hauptrichtung".
    // Repeated eigenvalues leave the vectors free inside their eigenspace; the frame is built
    // from the two largest and completed by a cross product, so it is orthonormal and
    // right-handed whatever the solver returns.
    Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> const solver(k);
    if (solver.info() == Eigen::Success)
        axes = orthonormal_frame(solver.eigenvectors().col(2), solver.eigenvectors().col(1));

    // Fit the box: the range of the projections on each axis, and the centre in its middle.
    vec3 lowest = vec3::Constant(std::numeric_limits<double>::infinity());
    vec3 highest = -lowest;
    for (vec3 const& p : points) {
        vec3 const q = axes.transpose() * (p - mean);
        lowest = lowest.cwiseMin(q);
        highest = highest.cwiseMax(q);
    }
    return {mean + axes * (0.5 * (lowest + highest)), axes, 0.5 * (highest - lowest)};
}

obb obb_from_box(vec3 centre, vec3 half_extents, Eigen::Matrix3d rotation)
{
    if (!centre.allFinite()) {
        std::ostringstream out;
        out << "centre must be finite, got (" << centre.transpose() << ")";
        reject_box(out.str());
    }
    if (!half_extents.allFinite() || (half_extents.array() < 0.0).any()) {
        std::ostringstream out;
        out << "half extents must be finite and >= 0, got (" << half_extents.transpose() << ")";
        reject_box(out.str());
    }
    if (!rotation.allFinite())
        reject_box("rotation must be finite");
    double const error =
        (rotation.transpose() * rotation - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
    if (!(error <= rotation_tolerance)) {
        std::ostringstream out;
        out << "rotation must be orthonormal to within " << rotation_tolerance
            << ", but an entry of R^T R - I is " << error;
        reject_box(out.str());
    }
    if (!(rotation.determinant() > 0.0))
        reject_box("rotation must be right-handed, but its determinant is -1 (a reflection)");
    return {centre, orthonormal_frame(rotation.col(0), rotation.col(1)), half_extents};
}

bool overlaps(obb const& a, obb const& b)
{
    // b's axes in a's frame, R(i, j) = aᵢ·bⱼ, and the offset of the centres in a's frame.
    Eigen::Matrix3d const r = a.axes.transpose() * b.axes;
    Eigen::Matrix3d const abs_r = r.cwiseAbs().array() + parallel_epsilon;
    vec3 const t = a.axes.transpose() * (b.centre - a.centre);
    vec3 const& ea = a.half_extents;
    vec3 const& eb = b.half_extents;

    // An axis L separates when |t·L| exceeds the sum of the boxes' projected radii on it.
    // a's axes.
    for (Eigen::Index i = 0; i < 3; ++i) {
        if (std::abs(t[i]) > ea[i] + eb.dot(abs_r.row(i).transpose()))
            return false;
    }
    // b's axes.
    for (Eigen::Index j = 0; j < 3; ++j) {
        if (std::abs(t.dot(r.col(j))) > ea.dot(abs_r.col(j)) + eb[j])
            return false;
    }
    // aᵢ × bⱼ, written in a's frame; i1, i2 (j1, j2) are the other two axes of a (b).
    for (Eigen::Index i = 0; i < 3; ++i) {
        Eigen::Index const i1 = (i + 1) % 3;
        Eigen::Index const i2 = (i + 2) % 3;
        for (Eigen::Index j = 0; j < 3; ++j) {
            Eigen::Index const j1 = (j + 1) % 3;
            Eigen::Index const j2 = (j + 2) % 3;
            double const ra = ea[i1] * abs_r(i2, j) + ea[i2] * abs_r(i1, j);
            double const rb = eb[j1] * abs_r(i, j2) + eb[j2] * abs_r(i, j1);
            if (std::abs(t[i2] * r(i1, j) - t[i1] * r(i2, j)) > ra + rb)
                return false;
        }
    }
    return true;
}

sphere_box_contact sphere_vs_obb(vec3 centre, double radius, obb const& box)
{
    vec3 const& h = box.half_extents;
    vec3 const local = box.axes.transpose() * (centre - box.centre);

    // Outside: clamp to the box in its own frame.
    vec3 const clamped = local.cwiseMax(-h).cwiseMin(h);
    vec3 const gap = local - clamped;
    double const gap_length = gap.norm();
    if (gap_length > 0.0) {
        double const distance = gap_length - radius;
        return {distance <= 0.0, box.centre + box.axes * clamped, box.axes * (gap / gap_length),
                distance};
    }

    // Inside or on the surface: leave through the face of least penetration depth.
    vec3 const depth = h - local.cwiseAbs();
    Eigen::Index axis = 0;
    for (Eigen::Index i = 1; i < 3; ++i) {
        if (depth[i] < depth[axis])
            axis = i;
    }
    double const side = local[axis] < 0.0 ? -1.0 : 1.0;
    vec3 on_face = local;
    on_face[axis] = side * h[axis];
    double const distance = -(depth[axis] + radius);
    return {distance <= 0.0, box.centre + box.axes * on_face, side * box.axes.col(axis), distance};
}

aabb aabb_of(obb const& box)
{
    vec3 const reach = box.axes.cwiseAbs() * box.half_extents;
    return {box.centre - reach, box.centre + reach};
}

} // namespace kugel::physics
