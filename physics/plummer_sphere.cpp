#include "plummer_sphere.hpp"

#include <cmath>
#include <random>
#include <stdexcept>

namespace kugel::physics {

namespace {

/// A double in [0, 1) from 53 random bits, the same on every standard library.
double unit_random(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11U) * 0x1.0p-53; }

/// A direction uniform on the unit sphere, by rejection from the cube (no trigonometry, so
/// no libm differences).
vec3 random_direction(std::mt19937_64& rng)
{
    while (true) {
        vec3 const p(2.0 * unit_random(rng) - 1.0, 2.0 * unit_random(rng) - 1.0,
                     2.0 * unit_random(rng) - 1.0);
        double const r2 = p.squaredNorm();
        if (r2 > 1e-12 && r2 <= 1.0)
            return p / std::sqrt(r2);
    }
}

} // namespace

std::vector<body_desc> plummer_sphere(plummer_settings const& settings)
{
    auto const& p = settings;
    if (!(p.total_mass > 0.0 && std::isfinite(p.total_mass)) ||
        !(p.scale_radius > 0.0 && std::isfinite(p.scale_radius)) ||
        !(p.G > 0.0 && std::isfinite(p.G)) || !(p.cutoff > 0.0))
        throw std::invalid_argument(
            "plummer_sphere: total mass, scale radius, G and cutoff must be finite and > 0");
    std::mt19937_64 rng(p.seed);
    double const a = p.scale_radius;
    double const body_mass = p.total_mass / static_cast<double>(p.count);
    std::vector<body_desc> bodies;
    bodies.reserve(p.count);
    vec3 mean_x = vec3::Zero();
    vec3 mean_v = vec3::Zero();
    for (std::size_t i = 0; i < p.count; ++i) {
        // Mass fraction X inside r is r³/(r² + a²)^{3/2}, so r = a / √(X^{−2/3} − 1).
        double r = 0.0;
        do {
            double const cube_root = std::cbrt(unit_random(rng));
            r = a / std::sqrt(1.0 / (cube_root * cube_root) - 1.0);
        } while (!(r <= p.cutoff * a));
        // Speed: q = v / v_escape has density ∝ q²(1 − q²)^{7/2} (at most 0.092 < 0.1).
        double q = 0.0;
        while (true) {
            q = unit_random(rng);
            double const one_minus = 1.0 - q * q;
            if (0.1 * unit_random(rng) < q * q * one_minus * one_minus * one_minus * std::sqrt(one_minus))
                break;
        }
        double const v_escape = std::sqrt(2.0 * p.G * p.total_mass / std::sqrt(r * r + a * a));
        body_desc b;
        b.position = r * random_direction(rng);
        b.velocity = q * v_escape * random_direction(rng);
        b.mass = body_mass;
        mean_x += b.position;
        mean_v += b.velocity;
        bodies.push_back(b);
    }
    if (!bodies.empty()) { // equal masses: centre of mass and momentum are the plain means
        mean_x /= static_cast<double>(bodies.size());
        mean_v /= static_cast<double>(bodies.size());
        for (auto& b : bodies) {
            b.position -= mean_x;
            b.velocity -= mean_v;
        }
    }
    return bodies;
}

} // namespace kugel::physics
