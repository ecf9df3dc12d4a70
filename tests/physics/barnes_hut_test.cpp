#include "physics/barnes_hut.hpp"
#include "physics/diagnostics.hpp"
#include "physics/forces.hpp"
#include "physics/plummer_sphere.hpp"
#include "physics/world.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>
#include <vector>

namespace kugel::physics {
namespace {

/// N equal masses (total 1) in a Plummer sphere of scale radius 1, G = 1: the standard
/// test of tree codes, dense core and sparse halo.
body_storage plummer_bodies(std::size_t count, std::uint64_t seed)
{
    body_storage bodies;
    for (auto const& b : plummer_sphere({.count = count, .total_mass = 1.0, .scale_radius = 1.0,
                                         .G = 1.0, .seed = seed}))
        bodies.add(b);
    return bodies;
}

std::vector<vec3> forces_of(force_model const& model, body_storage const& bodies)
{
    std::vector<vec3> f(bodies.size(), vec3::Zero());
    model.add_forces(bodies, bodies.positions(), f);
    return f;
}

/// √(Σ|F_tree − F_direct|² / Σ|F_direct|²): the usual measure of a tree code's force error.
double relative_rms_error(std::vector<vec3> const& approximate, std::vector<vec3> const& exact)
{
    double error2 = 0.0;
    double norm2 = 0.0;
    for (std::size_t i = 0; i < exact.size(); ++i) {
        error2 += (approximate[i] - exact[i]).squaredNorm();
        norm2 += exact[i].squaredNorm();
    }
    return std::sqrt(error2 / norm2);
}

bool all_finite(std::vector<vec3> const& f)
{
    for (auto const& v : f)
        if (!v.allFinite())
            return false;
    return true;
}

// θ = 0 opens every cell, so every pair is summed exactly as in the direct sum, only in
// another order: each force has ~N terms, so the difference is rounding, a few ulps of the
// larger terms. 1e-12 relative per body is far above that and far below any real error.
TEST(TreeGravity, ThetaZeroIsDirectSummation)
{
    body_storage const bodies = plummer_bodies(1000, 3);
    for (double softening : {0.0, 0.01}) {
        SCOPED_TRACE(softening);
        newtonian_gravity const direct(1.0, softening);
        tree_gravity const tree(1.0, softening, 0.0);
        auto const exact = forces_of(direct, bodies);
        auto const approximate = forces_of(tree, bodies);
        for (std::size_t i = 0; i < exact.size(); ++i)
            ASSERT_LE((approximate[i] - exact[i]).norm(), 1e-12 * exact[i].norm()) << i;
        double const u = direct.potential_energy(bodies, bodies.positions());
        EXPECT_NEAR(tree.potential_energy(bodies, bodies.positions()), u, 1e-13 * std::abs(u));
    }
}

// The monopole of a cell about its centre of mass has no dipole term: the first error is
// the quadrupole, relative size ~(s/d)² < θ² per cell. Summed over a Plummer sphere the
// relative RMS error falls faster than θ² (most cells are accepted well inside the
// criterion): measured on this sphere (N = 4000, seed 5, ε = 0.01) 3.4e-4, 2.5e-3, 7.7e-3
// and 1.76e-2 at θ = 0.25, 0.5, 0.75 and 1, about 0.02·θ³. The tolerance is twice that
// fit at every θ; a missing body, a wrong centre of mass or a criterion that lets a body
// take its own cell's monopole is off by orders of magnitude.
double error_bound(double theta) { return 0.04 * theta * theta * theta; }

TEST(TreeGravity, ForceErrorIsBoundedAndGrowsWithTheta)
{
    body_storage const bodies = plummer_bodies(4000, 5);
    auto const exact = forces_of(newtonian_gravity(1.0, 0.01), bodies);
    double previous = 0.0;
    for (double theta : {0.25, 0.5, 0.75, 1.0}) {
        double const error = relative_rms_error(forces_of(tree_gravity(1.0, 0.01, theta), bodies), exact);
        std::cout << "theta " << theta << ": relative RMS force error " << error << '\n';
        EXPECT_LE(error, error_bound(theta)) << "theta " << theta;
        EXPECT_GE(error, previous) << "theta " << theta;
        previous = error;
    }
}

// The potential goes through the same tree (U = −½·G·Σ m_i·φ_i); its monopole error
// partly cancels over the sum, so the total is far better than each force.
TEST(TreeGravity, PotentialEnergyIsCloseToDirect)
{
    body_storage const bodies = plummer_bodies(4000, 5);
    double const exact = newtonian_gravity(1.0, 0.01).potential_energy(bodies, bodies.positions());
    for (double theta : {0.5, 1.0}) {
        double const u = tree_gravity(1.0, 0.01, theta).potential_energy(bodies, bodies.positions());
        std::cout << "theta " << theta << ": relative potential error " << (u - exact) / exact << '\n';
        EXPECT_NEAR(u, exact, 1e-3 * theta * theta * std::abs(exact)) << "theta " << theta;
    }
}

// Tree forces are not pairwise symmetric: body i may feel body j through a cell's monopole
// while j feels i exactly. So Σ F is not zero to rounding as in the direct sum; it is a sum
// of force errors, which partly cancel: measured 1.5e-4 and 8.7e-4 of Σ|F| at θ = 0.5 and 1,
// a tenth to a twentieth of the RMS error. Bounded by the force error bound.
TEST(TreeGravity, NetForceIsZeroOnlyToTheApproximation)
{
    body_storage const bodies = plummer_bodies(4000, 5);
    for (double theta : {0.5, 1.0}) {
        auto const f = forces_of(tree_gravity(1.0, 0.01, theta), bodies);
        vec3 sum = vec3::Zero();
        double magnitude = 0.0;
        for (auto const& fi : f) {
            sum += fi;
            magnitude += fi.norm();
        }
        std::cout << "theta " << theta << ": |sum F| / sum |F| = " << sum.norm() / magnitude << '\n';
        EXPECT_LE(sum.norm(), error_bound(theta) * magnitude) << "theta " << theta;
        EXPECT_GT(sum.norm(), 1e-12 * magnitude) << "expected a real, if small, asymmetry";
    }
}

// Over a run the momentum changes by h·Σ F each step. With the net force above, the change
// over t = 1 (about one crossing time of the sphere) measured 6.5e-5 of the momentum scale
// Σ m|v| at θ = 0.5; bounded at 3e-4. (The direct sum keeps it to rounding:
// ForceModels.WorldWithGravityAndCoulombConservesMomentum.) A scene that needs momentum
// kept exactly uses the direct method.
TEST(TreeGravity, MomentumDriftOverARunIsSmallAndMeasured)
{
    world w({.integrator = integrator_kind::velocity_verlet, .substeps = 1});
    w.add_force(std::make_unique<tree_gravity>(1.0, 0.01, 0.5));
    for (auto const& b : plummer_sphere({.count = 2000, .seed = 9}))
        w.add_body(b);
    double scale = 0.0;
    for (std::size_t i = 0; i < w.bodies().size(); ++i)
        scale += w.bodies().masses()[i] * w.bodies().velocities()[i].norm();
    vec3 const before = measure_motion(w).momentum;
    for (int step = 0; step < 100; ++step)
        w.step(0.01);
    vec3 const after = measure_motion(w).momentum;
    std::cout << "momentum drift / sum m|v| over t = 1: " << (after - before).norm() / scale << '\n';
    EXPECT_LE((after - before).norm(), 3e-4 * scale);
}

TEST(TreeGravity, OneBodyFeelsNothing)
{
    body_storage bodies;
    bodies.add({.position = {1, 2, 3}, .mass = 5.0});
    tree_gravity const tree(1.0, 0.0, 0.5);
    auto const f = forces_of(tree, bodies);
    EXPECT_EQ(f[0], vec3::Zero());
    EXPECT_EQ(tree.potential_energy(bodies, bodies.positions()), 0.0);
}

TEST(TreeGravity, NoBodiesAndMasslessBodiesAreFine)
{
    body_storage bodies;
    tree_gravity const tree(1.0, 0.0, 0.5);
    EXPECT_EQ(tree.potential_energy(bodies, bodies.positions()), 0.0);
    bodies.add({.position = {0, 0, 0}, .mass = 0.0, .is_static = true});
    bodies.add({.position = {1, 0, 0}, .mass = 2.0});
    auto const f = forces_of(tree, bodies);
    EXPECT_EQ(f[0], vec3::Zero());
    EXPECT_EQ(f[1], vec3::Zero());
}

// With softening the force between coincident bodies is 0 (d = 0) and the potential
// −G·m₁m₂/ε, as in the direct sum.
TEST(TreeGravity, CoincidentBodiesWithSofteningGiveZeroForce)
{
    body_storage bodies;
    bodies.add({.position = {1, 1, 1}, .mass = 2.0});
    bodies.add({.position = {1, 1, 1}, .mass = 3.0});
    tree_gravity const tree(1.0, 0.5, 0.5);
    auto const f = forces_of(tree, bodies);
    EXPECT_EQ(f[0], vec3::Zero());
    EXPECT_EQ(f[1], vec3::Zero());
    EXPECT_DOUBLE_EQ(tree.potential_energy(bodies, bodies.positions()), -6.0 / 0.5);
}

// Coincident bodies can never be split: the tree stops at its depth cap with them all in
// one leaf (and that leaf is summed directly), so building terminates.
TEST(TreeGravity, AllBodiesCoincidentTerminatesAtTheDepthCap)
{
    body_storage bodies;
    for (int i = 0; i < 500; ++i)
        bodies.add({.position = {-3, 7, 1e6}, .mass = 1.0});
    bodies.add({.position = {-3, 7, 1e6 + 1}, .mass = 1.0}); // one more, a metre away
    std::vector<double> masses(bodies.masses().begin(), bodies.masses().end());
    source_tree tree;
    tree.build(bodies.positions(), masses, 0.5);
    EXPECT_EQ(tree.depth(), source_tree::max_depth);

    tree_gravity const model(1.0, 0.1, 0.5);
    auto const f = forces_of(model, bodies);
    ASSERT_TRUE(all_finite(f));
    auto const exact = forces_of(newtonian_gravity(1.0, 0.1), bodies);
    EXPECT_LE(relative_rms_error(f, exact), 1e-12);
    EXPECT_TRUE(std::isfinite(model.potential_energy(bodies, bodies.positions())));
}

TEST(TreeGravity, CoincidentBodiesWithoutSofteningAreSingularAsInTheDirectSum)
{
    body_storage bodies;
    bodies.add({.position = {0, 0, 0}, .mass = 1.0});
    bodies.add({.position = {5, 0, 0}, .mass = 1.0});
    bodies.add({.position = {0, 0, 0}, .mass = 1.0});
    tree_gravity const tree(1.0, 0.0, 0.5);
    EXPECT_THROW(forces_of(tree, bodies), singular_force_error);
    EXPECT_THROW(tree.potential_energy(bodies, bodies.positions()), singular_force_error);
}

// Bodies 1e12 apart next to a cluster of size 1: the root cell is 1e12 wide and the cluster
// sits 40 levels down, beyond the depth cap; nothing overflows and the forces match.
TEST(TreeGravity, BodiesFarApartGiveFiniteForces)
{
    body_storage bodies = plummer_bodies(300, 4);
    bodies.add({.position = {1e12, 0, 0}, .mass = 1.0});
    bodies.add({.position = {-1e12, 1e12, 0}, .mass = 1.0});
    for (double softening : {0.0, 0.01}) {
        auto const f = forces_of(tree_gravity(1.0, softening, 0.7), bodies);
        ASSERT_TRUE(all_finite(f));
        auto const exact = forces_of(newtonian_gravity(1.0, softening), bodies);
        EXPECT_LE(relative_rms_error(f, exact), 0.01);
        for (std::size_t i = bodies.size() - 2; i < bodies.size(); ++i) // the far two: exact
            EXPECT_LE((f[i] - exact[i]).norm(), 1e-9 * exact[i].norm());
    }
}

TEST(TreeGravity, RefusesBadParameters)
{
    EXPECT_THROW(tree_gravity(1.0, 0.0, -0.1), std::invalid_argument);
    EXPECT_THROW(tree_gravity(1.0, 0.0, 1.5), std::invalid_argument);
    EXPECT_THROW(tree_gravity(1.0, 0.0, std::nan("")), std::invalid_argument);
    EXPECT_THROW(tree_gravity(-1.0, 0.0, 0.5), std::invalid_argument);
    EXPECT_THROW(tree_gravity(1.0, -1.0, 0.5), std::invalid_argument);
    EXPECT_NO_THROW(tree_gravity(1.0, 0.0, 1.0));
}

/// A Plummer sphere's bodies with charges: `positive_fraction` of them +1, the rest −1.
body_storage charged_bodies(std::size_t count, double positive_fraction)
{
    body_storage bodies;
    std::mt19937_64 rng(17);
    std::bernoulli_distribution positive(positive_fraction);
    for (auto b : plummer_sphere({.count = count, .seed = 6})) {
        b.charge = positive(rng) ? 1.0 : -1.0;
        bodies.add(b);
    }
    return bodies;
}

TEST(TreeCoulomb, ThetaZeroIsDirectSummationForMixedCharges)
{
    body_storage const bodies = charged_bodies(800, 0.5);
    ASSERT_TRUE(has_mixed_charges(bodies));
    coulomb const direct(1.0, 0.01);
    tree_coulomb const tree(1.0, 0.01, 0.0);
    auto const exact = forces_of(direct, bodies);
    auto const approximate = forces_of(tree, bodies);
    for (std::size_t i = 0; i < exact.size(); ++i)
        ASSERT_LE((approximate[i] - exact[i]).norm(), 1e-11 * exact[i].norm()) << i;
    double const u = direct.potential_energy(bodies, bodies.positions());
    EXPECT_NEAR(tree.potential_energy(bodies, bodies.positions()), u, 1e-11 * std::abs(u));
}

// Charges of one sign: one tree, the same bound as gravity (measured 2.8e-3 and 1.7e-2).
TEST(TreeCoulomb, OneSignChargesHaveGravitysErrorBound)
{
    body_storage const bodies = charged_bodies(4000, 1.0);
    EXPECT_FALSE(has_mixed_charges(bodies));
    auto const exact = forces_of(coulomb(1.0, 0.01), bodies);
    for (double theta : {0.5, 1.0}) {
        double const error = relative_rms_error(forces_of(tree_coulomb(1.0, 0.01, theta), bodies), exact);
        EXPECT_LE(error, error_bound(theta)) << "theta " << theta;
    }
}

// Mixed signs, nearly neutral: the net forces are differences of the two signs' fields,
// which largely cancel. Each tree's error is bounded relative to its own field, so the
// error is bounded by the per-sign scale √Σ q_i²(|E₊|² + |E₋|²) (k = 1), not by the net
// force. Measured (N = 3000, half of each sign): 2.9e-3 and 1.95e-2 of the per-sign scale
// at θ = 0.5 and 1, but 6.1e-3 and 4.2e-2 of the net force, about twice: what the docs warn
// about, and worse the more neutral the cloud.
TEST(TreeCoulomb, MixedChargesAreBoundedPerSignNotByTheNetForce)
{
    body_storage const bodies = charged_bodies(3000, 0.5);
    auto const q = bodies.charges();
    auto const x = bodies.positions();
    double const eps2 = 0.01 * 0.01;
    double per_sign2 = 0.0; // the per-sign fields, by a direct double loop
    for (std::size_t i = 0; i < x.size(); ++i) {
        vec3 field[2] = {vec3::Zero(), vec3::Zero()};
        for (std::size_t j = 0; j < x.size(); ++j) {
            if (j == i)
                continue;
            vec3 const d = x[j] - x[i];
            double const r2 = d.squaredNorm() + eps2;
            field[q[j] > 0 ? 0 : 1] += d / (r2 * std::sqrt(r2));
        }
        per_sign2 += q[i] * q[i] * (field[0].squaredNorm() + field[1].squaredNorm());
    }
    auto const exact = forces_of(coulomb(1.0, 0.01), bodies);
    for (double theta : {0.5, 1.0}) {
        auto const f = forces_of(tree_coulomb(1.0, 0.01, theta), bodies);
        double error2 = 0.0;
        double net2 = 0.0;
        for (std::size_t i = 0; i < exact.size(); ++i) {
            error2 += (f[i] - exact[i]).squaredNorm();
            net2 += exact[i].squaredNorm();
        }
        double const per_sign_error = std::sqrt(error2 / per_sign2);
        double const net_error = std::sqrt(error2 / net2);
        std::cout << "mixed charges, theta " << theta << ": error / per-sign scale "
                  << per_sign_error << ", error / net force " << net_error << '\n';
        EXPECT_LE(per_sign_error, error_bound(theta)) << "theta " << theta;
        EXPECT_GT(net_error, per_sign_error); // the cancellation the bound does not cover
    }
}

} // namespace
} // namespace kugel::physics
