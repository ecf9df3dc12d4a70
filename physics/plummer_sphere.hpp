#pragma once

#include "body_storage.hpp"

#include <cstddef>
#include <cstdint>
#include <vector>

namespace kugel::physics {

/// A Plummer sphere: density ρ(r) ∝ (1 + r²/a²)^{−5/2}, the model star cluster of N-body
/// codes, in equilibrium under its own gravity.
struct plummer_settings
{
    std::size_t count = 0;
    double total_mass = 1.0;   ///< kg, > 0; each body gets total_mass / count
    double scale_radius = 1.0; ///< m, a > 0: half the mass lies within 1.305·a
    double G = 1.0;            ///< m³/(kg·s²): the gravity the velocities balance
    std::uint64_t seed = 1;
    double cutoff = 10.0; ///< bodies are drawn within cutoff·a (98.5% of the mass at 10)
};

/// Point masses drawn from the Plummer distribution function (Aarseth, Hénon and Wielen
/// 1974): radii by inverting the cumulative mass, speeds by rejection from
/// g(q) = q²(1 − q²)^{7/2}, q = v/v_escape, directions isotropic. Then shifted so that the
/// centre of mass is at the origin and the total momentum is zero. Seeded and built from
/// its own conversion of random bits to doubles: the same settings give the same bodies.
std::vector<body_desc> plummer_sphere(plummer_settings const& settings);

} // namespace kugel::physics
