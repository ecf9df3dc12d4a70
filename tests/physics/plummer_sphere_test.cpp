#include "physics/plummer_sphere.hpp"

#include "physics/diagnostics.hpp"
#include "physics/forces.hpp"
#include "physics/world.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <numbers>
#include <vector>

namespace kugel::physics {
namespace {

plummer_settings const sphere{.count = 4000, .total_mass = 2.0, .scale_radius = 1.5, .G = 1.0,
                              .seed = 3};

TEST(PlummerSphere, IsSeededCentredAndAtRest)
{
    auto const a = plummer_sphere(sphere);
    auto const b = plummer_sphere(sphere);
    ASSERT_EQ(a.size(), sphere.count);
    vec3 centre = vec3::Zero();
    vec3 momentum = vec3::Zero();
    for (std::size_t i = 0; i < a.size(); ++i) {
        EXPECT_EQ(a[i].position, b[i].position);
        EXPECT_EQ(a[i].velocity, b[i].velocity);
        EXPECT_EQ(a[i].mass, 2.0 / 4000.0);
        centre += a[i].mass * a[i].position;
        momentum += a[i].mass * a[i].velocity;
    }
    EXPECT_LE(centre.norm(), 1e-14);
    EXPECT_LE(momentum.norm(), 1e-14);
    EXPECT_NE(plummer_sphere({.count = 10, .seed = 4})[0].position,
              plummer_sphere({.count = 10, .seed = 5})[0].position);
}

// Half the mass of a Plummer sphere lies within r = a/√(2^{2/3} − 1) = 1.305·a (less the
// 1.5% cut off beyond 10·a). The sample median of 4000 radii is within ~2% of it (its
// standard error is about 1/(2·f(median)·√N) ≈ 1.3% here), so 5% tolerates sampling only.
TEST(PlummerSphere, HalfTheMassIsWithinTheHalfMassRadius)
{
    auto const bodies = plummer_sphere(sphere);
    std::vector<double> radii;
    for (auto const& b : bodies)
        radii.push_back(b.position.norm());
    std::nth_element(radii.begin(), radii.begin() + 2000, radii.end());
    double const half_mass_radius = 1.5 / std::sqrt(std::pow(2.0, 2.0 / 3.0) - 1.0);
    EXPECT_NEAR(radii[2000], half_mass_radius, 0.05 * half_mass_radius);
    EXPECT_LE(*std::max_element(radii.begin(), radii.end()), 10.0 * 1.5 * 1.01);
}

// In equilibrium 2K = −U (virial theorem), with U = −(3π/32)·G·M²/a for the whole sphere.
// A sample of 4000 meets both to a few percent (sampling noise and the cut at 10·a).
TEST(PlummerSphere, IsInVirialEquilibrium)
{
    world w;
    w.add_force(std::make_unique<newtonian_gravity>(1.0, 0.0));
    for (auto const& b : plummer_sphere(sphere))
        w.add_body(b);
    auto const d = measure(w);
    double const expected_u = -3.0 * std::numbers::pi / 32.0 * 1.0 * 2.0 * 2.0 / 1.5;
    std::cout << "2K/|U| = " << 2.0 * d.kinetic / -d.potential << ", U/U_plummer = "
              << d.potential / expected_u << '\n';
    EXPECT_NEAR(2.0 * d.kinetic / -d.potential, 1.0, 0.05);
    EXPECT_NEAR(d.potential / expected_u, 1.0, 0.05);
}

} // namespace
} // namespace kugel::physics
