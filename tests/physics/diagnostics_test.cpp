#include "physics/diagnostics.hpp"
#include "physics/world.hpp"

#include <gtest/gtest.h>

namespace kugel::physics {
namespace {

TEST(Diagnostics, MeasuresAHandMadeWorld)
{
    world w;
    w.add_force(std::make_unique<uniform_field>(vec3(0, 0, -10)));
    w.add_force(std::make_unique<newtonian_gravity>(1.0, 0.0));
    w.add_body({vec3(0, 0, 1), vec3(1, 0, 0), 2.0, 0.0, 0.0, false});
    w.add_body({vec3(0, 2, 1), vec3(0, 0, 3), 1.0, 0.0, 0.0, false});
    w.add_body({vec3(4, 0, 0), vec3::Zero(), 5.0, 0.0, 0.0, true});
    auto const d = measure(w);
    EXPECT_DOUBLE_EQ(d.kinetic, 0.5 * 2 * 1 + 0.5 * 1 * 9);
    // field: m·g·z = 2·10·1 + 1·10·1 + 0; gravity pairs: 2·1/2 + 2·5/√17 + 1·5/√21
    double const u = 30.0 - (1.0 + 10.0 / std::sqrt(17.0) + 5.0 / std::sqrt(21.0));
    EXPECT_NEAR(d.potential, u, 1e-14);
    EXPECT_NEAR(d.total, d.kinetic + u, 1e-14);
    EXPECT_EQ(d.momentum, vec3(2, 0, 3));
    // L = Σ m·x × v: 2·(0,0,1)×(1,0,0) + (0,2,1)×(0,0,3) = (0,2,0) + (6,0,0)
    EXPECT_EQ(d.angular_momentum, vec3(6, 2, 0));
    EXPECT_DOUBLE_EQ(d.mass, 8.0);
    EXPECT_LE((d.centre_of_mass - vec3(20.0, 2.0, 3.0) / 8.0).norm(), 1e-15);
    EXPECT_EQ(d.bodies, 3U);
    EXPECT_EQ(d.largest_speed, 3.0); // the second body's; the static one has none
}

TEST(Diagnostics, EmptyWorldIsAllZero)
{
    auto const d = measure(world{});
    EXPECT_EQ(d.total, 0.0);
    EXPECT_EQ(d.centre_of_mass, vec3::Zero());
}

// Gravity is central, so the angular momentum of an isolated system is conserved; Verlet
// conserves it exactly in exact arithmetic, leaving ~1e-13 of rounding over 10⁴ steps.
TEST(Diagnostics, TwoBodyOrbitKeepsAngularMomentum)
{
    world w;
    w.add_force(std::make_unique<newtonian_gravity>(1.0, 0.0));
    w.add_body({vec3(-0.1, 0, 0), vec3(0, -0.1, 0), 1.0, 0.0, 0.0, false});
    w.add_body({vec3(1, 0, 0), vec3(0, 1, 0), 0.1, 0.0, 0.0, false});
    vec3 const l0 = measure(w).angular_momentum;
    for (int i = 0; i < 10000; ++i)
        w.step(1e-3);
    EXPECT_LE((measure(w).angular_momentum - l0).norm(), 1e-12 * l0.norm());
}

} // namespace
} // namespace kugel::physics
