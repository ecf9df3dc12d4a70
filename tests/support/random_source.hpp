#pragma once

// Test support: random inputs that are the same on every machine and standard library.

#include "physics/vec.hpp"

#include <Eigen/Geometry>

#include <cstddef>
#include <cstdint>
#include <random>

namespace kugel::test_support {

/// Seeded numbers that are the same with every standard library (the distributions of <random>
/// are not specified exactly; the engine is).
using physics::vec3;

class random_source
{
public:
    explicit random_source(std::uint64_t seed) : engine_(seed) {}

    double uniform() { return static_cast<double>(engine_() >> 11) * 0x1.0p-53; } // [0, 1)
    double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
    std::size_t below(std::size_t n)
    {
        return static_cast<std::size_t>(uniform() * static_cast<double>(n));
    }

    vec3 in_cube(double half)
    {
        return {uniform(-half, half), uniform(-half, half), uniform(-half, half)};
    }

    vec3 in_ball(double radius)
    {
        for (;;) {
            vec3 const p = in_cube(1.0);
            if (p.squaredNorm() < 1.0)
                return radius * p;
        }
    }

    vec3 on_sphere(double radius = 1.0)
    {
        for (;;) {
            vec3 const p = in_ball(1.0);
            if (p.squaredNorm() > 1e-4)
                return radius * p.normalized();
        }
    }

    Eigen::Matrix3d rotation()
    {
        Eigen::Quaterniond q;
        do {
            q.coeffs() =
                Eigen::Vector4d(uniform(-1, 1), uniform(-1, 1), uniform(-1, 1), uniform(-1, 1));
        } while (q.coeffs().norm() < 0.1 || q.coeffs().norm() > 1.0);
        return q.normalized().toRotationMatrix();
    }

private:
    std::mt19937_64 engine_;
};

} // namespace kugel::test_support
