#include "physics/collision_response.hpp"
#include "physics/collision_rules.hpp"

#include <gtest/gtest.h>

#include <random>

namespace kugel::physics {
namespace {

TEST(ReflectOffPlane, ElasticWithoutFrictionMirrorsTheVelocity)
{
    vec3 const n(0, 0, 1);
    vec3 const v(3, -1, -4);
    // lecture: w = v − 2(v·n)·n
    EXPECT_EQ(reflect_off_plane(v, n, 0.0, 0.0), v - 2.0 * v.dot(n) * n);
}

TEST(ReflectOffPlane, DampingAndFrictionScaleTheirParts)
{
    vec3 const n = vec3(1, 1, 0).normalized();
    vec3 const v(-2, -1, 5);
    double const alpha = 0.3, mu = 0.2;
    vec3 const w = reflect_off_plane(v, n, alpha, mu);
    vec3 const vn = v.dot(n) * n;
    vec3 const vt = v - vn;
    EXPECT_LE((w - ((1 - mu) * vt - (1 - alpha) * vn)).norm(), 1e-15 * v.norm());
    EXPECT_NEAR(w.dot(n), -(1 - alpha) * v.dot(n), 1e-15 * v.norm());
}

TEST(ReflectOffPlane, LeavesBodiesMovingAwayOrAlongTheWallAlone)
{
    vec3 const n(0, 1, 0);
    EXPECT_EQ(reflect_off_plane(vec3(1, 2, 3), n, 0.5, 0.5), vec3(1, 2, 3));
    EXPECT_EQ(reflect_off_plane(vec3(1, 0, 3), n, 0.5, 0.5), vec3(1, 0, 3));
}

TEST(ReflectOffPlane, FullDampingStopsTheNormalMotion)
{
    vec3 const w = reflect_off_plane(vec3(1, -5, 0), vec3(0, 1, 0), 1.0, 0.0);
    EXPECT_EQ(w, vec3(1, 0, 0));
}

TEST(CollideSpheres, EqualMassesHeadOnSwapVelocities)
{
    auto const [w1, w2] = collide_spheres(vec3(2, 0, 0), 1.0, vec3(-1, 0, 0), 1.0, vec3(-1, 0, 0), 1.0);
    EXPECT_EQ(w1, vec3(-1, 0, 0)); // lecture: m₁ = m₂ ⇒ w₁ = v₂, w₂ = v₁
    EXPECT_EQ(w2, vec3(2, 0, 0));
}

TEST(CollideSpheres, MatchesTheLecturesOneDimensionalFormula)
{
    std::mt19937_64 rng(1);
    std::uniform_real_distribution<double> u(-5.0, 5.0), mass(0.1, 10.0);
    for (int trial = 0; trial < 100; ++trial) {
        double const m1 = mass(rng), m2 = mass(rng);
        double v1 = u(rng), v2 = u(rng);
        if (v1 < v2)
            std::swap(v1, v2); // approaching along +x: body 1 is behind body 2
        vec3 const n(-1, 0, 0); // from body 2 to body 1
        auto const [w1, w2] = collide_spheres(vec3(v1, 0, 0), 1 / m1, vec3(v2, 0, 0), 1 / m2, n, 1.0);
        double const e1 = (m1 - m2) / (m1 + m2) * v1 + 2 * m2 / (m1 + m2) * v2;
        double const e2 = 2 * m1 / (m1 + m2) * v1 + (m2 - m1) / (m1 + m2) * v2;
        // Two algebraically equal forms; they differ by rounding of a few operations.
        EXPECT_NEAR(w1.x(), e1, 1e-13 * (std::abs(v1) + std::abs(v2))) << trial;
        EXPECT_NEAR(w2.x(), e2, 1e-13 * (std::abs(v1) + std::abs(v2))) << trial;
    }
}

TEST(CollideSpheres, ElasticGlancingCollisionOfEqualMassesLeavesPerpendicularVelocities)
{
    vec3 const n = vec3(-1, -0.6, 0.2).normalized(); // any contact normal
    auto const [w1, w2] = collide_spheres(vec3(3, 0, 0), 1.0, vec3::Zero(), 1.0, n, 1.0);
    EXPECT_NEAR(w1.dot(w2), 0.0, 1e-14 * 9);
    EXPECT_GT(w1.norm(), 0.1);
    EXPECT_GT(w2.norm(), 0.1);
}

// Every response conserves momentum to 1e-12 of the momentum scale (products m·(1/m) round
// to an ulp) and, for e = 1, kinetic energy to 1e-12; tangential parts are untouched.
TEST(CollideSpheres, ConservesMomentumAndElasticEnergyOnRandomCollisions)
{
    std::mt19937_64 rng(2);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    std::uniform_real_distribution<double> log_mass(-6.0, 6.0);
    for (int trial = 0; trial < 1000; ++trial) {
        double const m1 = std::pow(10.0, log_mass(rng)), m2 = std::pow(10.0, log_mass(rng));
        vec3 const v1(u(rng), u(rng), u(rng)), v2(u(rng), u(rng), u(rng));
        vec3 const n = vec3(u(rng), u(rng), u(rng)).normalized();
        double const e = trial % 2 == 0 ? 1.0 : std::abs(u(rng));
        auto const [w1, w2] = collide_spheres(v1, 1 / m1, v2, 1 / m2, n, e);
        vec3 const p0 = m1 * v1 + m2 * v2;
        double const scale = m1 * v1.norm() + m2 * v2.norm();
        EXPECT_LE((m1 * w1 + m2 * w2 - p0).norm(), 1e-12 * scale) << trial;
        if (e == 1.0) {
            double const k0 = m1 * v1.squaredNorm() + m2 * v2.squaredNorm();
            EXPECT_NEAR(m1 * w1.squaredNorm() + m2 * w2.squaredNorm(), k0, 1e-12 * k0) << trial;
        }
        vec3 const t1 = v1 - v1.dot(n) * n;
        EXPECT_LE(((w1 - w1.dot(n) * n) - t1).norm(), 1e-14 * (1 + v1.norm())) << trial;
    }
}

TEST(CollideSpheres, AStaticBodyActsAsAWall)
{
    // A sphere hitting a static one along n bounces like off a plane with α = 1 − e.
    vec3 const n(0, 0, 1);
    auto const [w1, w2] = collide_spheres(vec3(1, 0, -2), 1.0, vec3::Zero(), 0.0, n, 0.5);
    EXPECT_EQ(w1, vec3(1, 0, 1));
    EXPECT_EQ(w2, vec3::Zero());
    auto const both_static = collide_spheres(vec3::Zero(), 0.0, vec3::Zero(), 0.0, n, 1.0);
    EXPECT_EQ(both_static.first, vec3::Zero());
}

TEST(CollideSpheres, MassRatioOfTenToTheTwelveStaysFiniteAndConservesMomentum)
{
    double const heavy = 1e12, light = 1.0;
    vec3 const n(1, 0, 0);
    auto const [w1, w2] = collide_spheres(vec3(-1, 0, 0), 1 / light, vec3(1e-3, 0, 0), 1 / heavy, n, 1.0);
    EXPECT_TRUE(w1.allFinite());
    EXPECT_TRUE(w2.allFinite());
    EXPECT_NEAR(w1.x(), 1.0 + 2e-3, 1e-9); // bounces off a wall that moves at 1e-3
    vec3 const p0 = light * vec3(-1, 0, 0) + heavy * vec3(1e-3, 0, 0);
    EXPECT_LE((light * w1 + heavy * w2 - p0).norm(), 1e-12 * (light + heavy * 1e-3));
}

TEST(CollideSpheres, SeparatingPairsAreLeftAlone)
{
    auto const r = collide_spheres(vec3(1, 0, 0), 1.0, vec3(-1, 0, 0), 1.0, vec3(1, 0, 0), 1.0);
    EXPECT_EQ(r.first, vec3(1, 0, 0));
    EXPECT_EQ(r.second, vec3(-1, 0, 0));
}

// ---- the two-sphere response both collision modes use -----------------------------------

// Friction between spheres is Coulomb's: the relative tangential speed loses at most μ times
// the change the contact made to the relative normal speed (the impulses' cone |J_t| <= μ·J_n,
// on speeds, as spheres here do not spin), and like every impulse between the two it keeps
// their momentum. Two spheres (masses 1 and 3) meet head-on along x, closing at 2 m/s, while
// sliding past each other along y at 2 m/s. An elastic contact turns the closing 2 m/s into
// 2 m/s apart, a change of 4 m/s: with μ = 0.25 the sliding loses 1 m/s and goes on at 1 m/s;
// with μ = 1 it would lose up to 4 m/s and so stops (the contact sticks, and friction never
// reverses it). The normal exchange is the plain elastic one, and momentum is the same to
// rounding (1e-15 of it: each speed is a few ulps of 1).
TEST(SphereContact, FrictionIsCoulombsBoundedByTheNormalChangeAndKeepsMomentum)
{
    collision_settings settings;
    settings.restitution = 1.0;
    vec3 const n(1, 0, 0); // from b to a
    double const m_a = 1.0, m_b = 3.0;
    vec3 const still = vec3::Zero();
    for (auto const& [friction, sliding_after] : {std::pair{0.25, 1.0}, std::pair{1.0, 0.0}}) {
        settings.friction = friction;
        vec3 v_a(-1, 1, 0), v_b(1, -1, 0);
        vec3 const p0 = m_a * v_a + m_b * v_b;
        ASSERT_TRUE(detail::respond_to_sphere_contact(v_a, 1 / m_a, still, v_b, 1 / m_b, still, n, settings, 1.0 / 60));
        EXPECT_NEAR((v_a - v_b).y(), sliding_after, 1e-15) << friction;
        EXPECT_NEAR((v_a - v_b).x(), 2.0, 1e-15) << friction; // elastic: the closing 2 m/s comes back
        EXPECT_LE((m_a * v_a + m_b * v_b - p0).norm(), 1e-15 * 4.0) << friction;
    }
    settings.friction = 0.0; // none: the tangential motion is untouched
    vec3 w_a(-1, 1, 0), w_b(1, -1, 0);
    detail::respond_to_sphere_contact(w_a, 1 / m_a, still, w_b, 1 / m_b, still, n, settings, 1.0 / 60);
    EXPECT_EQ((w_a - w_b).y(), 2.0);
}

// A speculative contact: spheres 1 mm apart at the end of free motion, in a step of 0.1 s, may
// close at 1 cm/s and still end touching. Closing at 3 cm/s, they lose the excess 2 cm/s along
// the normal, shared by inverse mass (masses 1 and 3: 1.5 and 0.5 cm/s), with no bounce and
// momentum kept; closing at 1 cm/s or slower they are left alone. Tolerance: a few ulps of the
// speeds.
TEST(SphereContact, ASpeculativeContactTakesOnlyTheApproachThatWouldOverlap)
{
    collision_settings settings;
    settings.restitution = 1.0; // not used: apart spheres do not bounce
    vec3 const n(0, 0, 1);
    double const allowed = 0.001 / 0.1;
    vec3 v_a(0, 0, -0.02), v_b(0, 0, 0.01);
    ASSERT_TRUE(detail::respond_to_speculative_contact(v_a, 1.0, v_b, 1.0 / 3, n, allowed, settings));
    EXPECT_NEAR((v_a - v_b).z(), -allowed, 1e-17);
    EXPECT_NEAR(v_a.z(), -0.02 + 0.015, 1e-17);
    EXPECT_NEAR(v_b.z(), 0.01 - 0.005, 1e-17);
    EXPECT_NEAR(v_a.z() + 3 * v_b.z(), -0.02 + 0.03, 1e-17);
    vec3 slow_a(0, 0, -0.005), slow_b(0, 0, 0.005);
    EXPECT_FALSE(detail::respond_to_speculative_contact(slow_a, 1.0, slow_b, 1.0, n, allowed, settings));
    EXPECT_EQ(slow_a.z(), -0.005);
}

} // namespace
} // namespace kugel::physics
