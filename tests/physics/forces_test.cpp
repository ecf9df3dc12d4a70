#include "physics/forces.hpp"
#include "physics/diagnostics.hpp"
#include "physics/world.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <vector>

namespace kugel::physics {
namespace {

/// The two pairwise laws, for tests that hold for both.
std::vector<std::unique_ptr<force_model>> pairwise_models(double softening)
{
    std::vector<std::unique_ptr<force_model>> models;
    models.push_back(std::make_unique<newtonian_gravity>(1.0, softening));
    models.push_back(std::make_unique<coulomb>(1.0, softening));
    return models;
}

std::vector<vec3> forces_of(force_model const& model, body_storage const& bodies)
{
    std::vector<vec3> f(bodies.size(), vec3::Zero());
    model.add_forces(bodies, bodies.positions(), f);
    return f;
}

body_desc charge_at(vec3 x, double q, double m = 1.0) { return {x, vec3::Zero(), m, 0.0, q, false}; }

// Rounding in one pair force is a few ulps: 1e-15 relative is ~5 ulps.
constexpr double pair_tolerance = 1e-15;

TEST(Coulomb, LikeChargesRepelWithTheLecturesMagnitude)
{
    body_storage bodies;
    bodies.add(charge_at({0, 0, 0}, 2.0));
    bodies.add(charge_at({2, 0, 0}, 3.0));
    auto const f = forces_of(coulomb(1.0, 0.0), bodies);
    // |F| = k·q₁q₂/r² = 6/4; body 1 is pushed away from body 2 (−x).
    EXPECT_NEAR(f[0].x(), -1.5, 1.5 * pair_tolerance);
    EXPECT_NEAR(f[1].x(), 1.5, 1.5 * pair_tolerance);
    EXPECT_EQ(f[0].y(), 0.0);
    EXPECT_EQ(f[0].z(), 0.0);
}

TEST(Coulomb, OppositeChargesAttract)
{
    body_storage bodies;
    bodies.add(charge_at({0, 0, 0}, 2.0));
    bodies.add(charge_at({0, 0, 4}, -1.0));
    auto const f = forces_of(coulomb(3.0, 0.0), bodies);
    EXPECT_NEAR(f[0].z(), 3.0 * 2.0 / 16.0, 0.375 * pair_tolerance); // toward body 2 (+z)
    EXPECT_NEAR(f[1].z(), -0.375, 0.375 * pair_tolerance);
}

TEST(Coulomb, MatchesTheLecturesFormulaForRandomPairs)
{
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> u(-3.0, 3.0);
    for (int trial = 0; trial < 100; ++trial) {
        body_storage bodies;
        vec3 const x1(u(rng), u(rng), u(rng));
        vec3 const x2(u(rng), u(rng), u(rng));
        double const q1 = u(rng), q2 = u(rng), k = 0.5 + std::abs(u(rng));
        bodies.add(charge_at(x1, q1));
        bodies.add(charge_at(x2, q2));
        auto const f = forces_of(coulomb(k, 0.0), bodies);
        // F₁ = −k·q₁q₂/|x₂−x₁|² · (x₂−x₁)/|x₂−x₁|
        vec3 const d = x2 - x1;
        vec3 const expected = -k * q1 * q2 / d.squaredNorm() * d / d.norm();
        EXPECT_LE((f[0] - expected).norm(), 1e-14 * expected.norm()) << trial;
        EXPECT_LE((f[1] + expected).norm(), 1e-14 * expected.norm()) << trial;
    }
}

TEST(Coulomb, UnchargedBodiesFeelNothing)
{
    body_storage bodies;
    bodies.add(charge_at({0, 0, 0}, 0.0));
    bodies.add(charge_at({1, 0, 0}, 5.0));
    auto const f = forces_of(coulomb(1.0, 0.0), bodies);
    EXPECT_EQ(f[0], vec3::Zero());
    EXPECT_EQ(f[1], vec3::Zero());
}

TEST(NewtonianGravity, AttractsWithTheLecturesMagnitude)
{
    body_storage bodies;
    bodies.add(charge_at({0, 0, 0}, 0.0, 3.0));
    bodies.add(charge_at({0, 5, 0}, 0.0, 10.0));
    auto const f = forces_of(newtonian_gravity(2.0, 0.0), bodies);
    // F₁ = G·m₁m₂/r² toward body 2: 2·3·10/25 = 2.4 along +y.
    EXPECT_NEAR(f[0].y(), 2.4, 2.4 * pair_tolerance);
    EXPECT_NEAR(f[1].y(), -2.4, 2.4 * pair_tolerance);
}

TEST(NewtonianGravity, SofteningReplacesRSquaredByRSquaredPlusEpsilonSquared)
{
    body_storage bodies;
    bodies.add(charge_at({0, 0, 0}, 0.0, 1.0));
    bodies.add(charge_at({3, 0, 0}, 0.0, 1.0));
    newtonian_gravity const g(1.0, 4.0);
    auto const f = forces_of(g, bodies);
    // Plummer: F = G·m₁m₂·r / (r² + ε²)^{3/2} = 3/125; U = −G·m₁m₂ / √(r² + ε²) = −1/5.
    EXPECT_NEAR(f[0].x(), 3.0 / 125.0, 1e-17);
    EXPECT_NEAR(g.potential_energy(bodies, bodies.positions()), -0.2, 1e-16);
}

TEST(NewtonianGravity, PotentialIsMinusGmmOverR)
{
    body_storage bodies;
    bodies.add(charge_at({1, 1, 1}, 0.0, 2.0));
    bodies.add(charge_at({1, 1, 5}, 0.0, 6.0));
    bodies.add(charge_at({1, 4, 5}, 0.0, 1.0));
    // pairs: (2·6)/4 + (2·1)/5 + (6·1)/3, times −G
    double const expected = -0.5 * (3.0 + 0.4 + 2.0);
    EXPECT_NEAR(newtonian_gravity(0.5, 0.0).potential_energy(bodies, bodies.positions()), expected,
                1e-15);
}

// The force must be minus the gradient of the model's potential energy. Central differences
// with step h have error O(h²)·U''' ≈ 1e-12 here and rounding ≈ 1e-16·U/h ≈ 1e-10, so 1e-7
// relative separates a correct pair from a sign or factor error by many orders of magnitude.
TEST(ForceModels, ForceIsMinusGradientOfPotential)
{
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> u(-2.0, 2.0);
    body_storage bodies;
    for (int i = 0; i < 6; ++i)
        bodies.add(charge_at({u(rng), u(rng), u(rng)}, u(rng), 1.0 + std::abs(u(rng))));
    newtonian_gravity const gravity(1.3, 0.1);
    coulomb const electric(0.7, 0.1);
    uniform_field const field(vec3(0.3, -0.2, -9.81));
    for (force_model const* model : {static_cast<force_model const*>(&gravity),
                                     static_cast<force_model const*>(&electric),
                                     static_cast<force_model const*>(&field)}) {
        auto const f = forces_of(*model, bodies);
        std::vector<vec3> x(bodies.positions().begin(), bodies.positions().end());
        double const h = 1e-6;
        for (std::size_t i = 0; i < x.size(); ++i) {
            for (int axis = 0; axis < 3; ++axis) {
                auto shifted = x;
                shifted[i][axis] += h;
                double const up = model->potential_energy(bodies, shifted);
                shifted[i][axis] -= 2 * h;
                double const down = model->potential_energy(bodies, shifted);
                double const gradient = (up - down) / (2 * h);
                EXPECT_NEAR(-gradient, f[i][axis], 1e-7 * (1.0 + f[i].norm()))
                    << model->name() << " body " << i << " axis " << axis;
            }
        }
    }
}

TEST(UniformField, IsMassTimesGAndPotentialIsMgh)
{
    body_storage bodies;
    bodies.add(charge_at({0, 0, 2}, 0.0, 3.0));
    uniform_field const field(vec3(0, 0, -9.81));
    auto const f = forces_of(field, bodies);
    EXPECT_EQ(f[0], vec3(0, 0, -3.0 * 9.81)); // lecture: [0, 0, −m·g]
    EXPECT_NEAR(field.potential_energy(bodies, bodies.positions()), 3.0 * 9.81 * 2.0, 1e-14);
    EXPECT_TRUE(field.is_constant());
    EXPECT_FALSE(newtonian_gravity(1, 0).is_constant());
}

// Pairs are applied symmetrically, so Σ F vanishes up to rounding in the sum: with ~n terms
// of size F the rounding is about n·ε·F, far below 1e-12 of Σ|F| for n = 200.
TEST(ForceModels, PairwiseForcesSumToZero)
{
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> u(-10.0, 10.0);
    body_storage bodies;
    for (int i = 0; i < 200; ++i)
        bodies.add(charge_at({u(rng), u(rng), u(rng)}, u(rng), 1.0 + std::abs(u(rng))));
    for (auto const& model : pairwise_models(0.0)) {
        auto const f = forces_of(*model, bodies);
        vec3 sum = vec3::Zero();
        double magnitude = 0.0;
        for (auto const& fi : f) {
            sum += fi;
            magnitude += fi.norm();
        }
        EXPECT_LE(sum.norm(), 1e-12 * magnitude) << model->name();
    }
}

// Over a run, momentum changes only by the rounding of Σ m·(F/m)·h per step; 1e-12 of the
// momentum scale Σ m|v| holds with a wide margin for 2,000 steps of 50 bodies.
TEST(ForceModels, WorldWithGravityAndCoulombConservesMomentum)
{
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    world w({.integrator = integrator_kind::velocity_verlet, .substeps = 1});
    w.add_force(std::make_unique<newtonian_gravity>(1.0, 0.05));
    w.add_force(std::make_unique<coulomb>(0.5, 0.05));
    for (int i = 0; i < 50; ++i)
        w.add_body({vec3(u(rng), u(rng), u(rng)) * 5.0, vec3(u(rng), u(rng), u(rng)),
                    1.0 + std::abs(u(rng)), 0.0, u(rng), false});
    auto const before = measure(w);
    double scale = 0.0;
    for (std::size_t i = 0; i < w.bodies().size(); ++i)
        scale += w.bodies().masses()[i] * w.bodies().velocities()[i].norm();
    for (int i = 0; i < 2000; ++i)
        w.step(1e-3);
    auto const after = measure(w);
    EXPECT_LE((after.momentum - before.momentum).norm(), 1e-12 * scale);
}

TEST(ForceModels, CoincidentBodiesWithoutSofteningAreAClearError)
{
    body_storage bodies;
    bodies.add(charge_at({1, 2, 3}, 1.0));
    bodies.add(charge_at({1, 2, 3}, 1.0));
    for (auto const& model : pairwise_models(0.0)) {
        std::vector<vec3> f(2, vec3::Zero());
        try {
            model->add_forces(bodies, bodies.positions(), f);
            ADD_FAILURE() << model->name() << " accepted coincident bodies";
        } catch (singular_force_error const& e) {
            EXPECT_NE(std::string(e.what()).find("softening"), std::string::npos) << e.what();
            EXPECT_NE(std::string(e.what()).find(model->name()), std::string::npos) << e.what();
        }
        EXPECT_THROW(model->potential_energy(bodies, bodies.positions()), singular_force_error);
    }
}

TEST(ForceModels, SofteningMakesCoincidentBodiesHarmless)
{
    body_storage bodies;
    bodies.add(charge_at({1, 2, 3}, 1.0));
    bodies.add(charge_at({1, 2, 3}, 1.0));
    auto const f = forces_of(newtonian_gravity(1.0, 0.1), bodies);
    EXPECT_EQ(f[0], vec3::Zero()); // no direction, no force
    EXPECT_TRUE(std::isfinite(newtonian_gravity(1.0, 0.1).potential_energy(bodies, bodies.positions())));
}

// check_addition against the analytic pair: G = k = 1, strengths 1 and 2 (masses for
// gravity, charges for Coulomb, each body of 1 kg so the acceleration is the force), 2 m
// apart: |F| = 1·2/2² = 0.5 N. The check takes the force loop's arithmetic, so the figures
// agree with the law to a few ulps (pair_tolerance).
TEST(ForceModels, AdditionIsRefusedExactlyWhereThePairForcePassesTheLimits)
{
    for (auto const& model : pairwise_models(0.0)) {
        SCOPED_TRACE(std::string(model->name()));
        bool const gravity = model->name() == "gravity";
        body_storage bodies;
        bodies.add(gravity ? charge_at({0, 0, 0}, 0.0, 2.0) : charge_at({0, 0, 0}, 2.0));
        body_desc const candidate = charge_at({2, 0, 0}, gravity ? 0.0 : 1.0, 1.0);

        auto const refusal = model->check_addition(bodies, candidate, {.max_acceleration = 0.49});
        ASSERT_TRUE(refusal);
        EXPECT_EQ(refusal->model, model->name());
        EXPECT_EQ(refusal->other, 0U);
        EXPECT_EQ(refusal->distance, 2.0);
        EXPECT_NEAR(refusal->force, 0.5, 0.5 * pair_tolerance);
        EXPECT_NEAR(refusal->acceleration, 0.5, 0.5 * pair_tolerance); // the 1 kg body's
        EXPECT_FALSE(model->check_addition(bodies, candidate, {.max_acceleration = 0.51}));

        // On the other body's point: singular without softening, nothing with it.
        body_desc on_top = candidate;
        on_top.position = vec3::Zero();
        auto const singular = model->check_addition(bodies, on_top, {});
        ASSERT_TRUE(singular);
        EXPECT_EQ(singular->force, std::numeric_limits<double>::infinity());
        EXPECT_FALSE((gravity ? static_cast<force_model const&>(newtonian_gravity(1.0, 0.1))
                              : static_cast<force_model const&>(coulomb(1.0, 0.1)))
                         .check_addition(bodies, on_top, {}));

        // A coupling beyond a double, far apart.
        body_desc huge = candidate;
        huge.position = {1e10, 0, 0};
        (gravity ? huge.mass : huge.charge) = 1e308;
        EXPECT_TRUE(model->check_addition(bodies, huge, {}));
    }
}

TEST(ForceModels, RefuseBadParameters)
{
    EXPECT_THROW(newtonian_gravity(-1.0, 0.0), std::invalid_argument);
    EXPECT_THROW(newtonian_gravity(1.0, -0.1), std::invalid_argument);
    EXPECT_THROW(coulomb(NAN, 0.0), std::invalid_argument);
    EXPECT_THROW(coulomb(1.0, INFINITY), std::invalid_argument);
}

} // namespace
} // namespace kugel::physics
