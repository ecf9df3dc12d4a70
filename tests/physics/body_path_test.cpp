#include "physics/body_path.hpp"

#include <gtest/gtest.h>

#include <random>

namespace kugel::physics {
namespace {

TEST(BodyPath, FollowsTheLecturesParabola)
{
    body_path p{vec3(1, 2, 3), vec3(4, 0, -1), vec3(0, 0, -10), 0.5};
    // x(t) = x₀ + v₀·s + a·s²/2 with s = t − t₀
    EXPECT_EQ(p.position_at(1.5), vec3(5, 2, 3 - 1 - 5));
    EXPECT_EQ(p.velocity_at(1.5), vec3(4, 0, -11));
    p.advance_to(1.5);
    EXPECT_EQ(p.t, 1.5);
    EXPECT_EQ(p.x, vec3(5, 2, -3));
}

// The swept box must hold the sphere at every moment of the path, including the vertex of
// the parabola between the ends: continuous mode finds no contact outside it. Sampled at
// 1,000 times per path over random paths; the box is built from exact extremes, so any
// sample outside (beyond rounding, 1e-12) is a bug.
TEST(BodyPath, SweptBoxHoldsTheSphereAllAlongThePath)
{
    std::mt19937_64 rng(8);
    std::uniform_real_distribution<double> u(-5.0, 5.0);
    for (int trial = 0; trial < 200; ++trial) {
        body_path const p{vec3(u(rng), u(rng), u(rng)), vec3(u(rng), u(rng), u(rng)),
                          vec3(u(rng), u(rng), u(rng)) * 4.0, 0.25};
        double const r = 0.1 + std::abs(u(rng)) * 0.1, until = 1.25;
        aabb const box = p.swept_box(until, r);
        for (int k = 0; k <= 1000; ++k) {
            double const t = p.t + (until - p.t) * k / 1000.0;
            aabb const sphere = aabb_of_sphere(p.position_at(t), r);
            EXPECT_TRUE((sphere.min.array() >= box.min.array() - 1e-12).all() &&
                        (sphere.max.array() <= box.max.array() + 1e-12).all())
                << "trial " << trial << " t " << t;
        }
    }
}

} // namespace
} // namespace kugel::physics
