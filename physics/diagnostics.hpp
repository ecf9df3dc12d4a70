#pragma once

#include "vec.hpp"

#include <cstddef>

namespace kugel::physics {

class world;

/// Conserved (or not) quantities of a world, for tests, headless summaries and the server.
struct diagnostics
{
    double kinetic = 0.0;                 ///< J, Σ ½·m·v² over dynamic bodies
    double potential = 0.0;               ///< J, summed over the world's force models
    /// J, the part of `potential` between bodies (gravity, Coulomb): unlike a uniform
    /// field's, it does not change when the origin moves
    double pair_potential = 0.0;
    bool has_pair_potential = false;      ///< a force model between bodies is in the world
    double total = 0.0;                   ///< J, kinetic + potential
    vec3 momentum = vec3::Zero();         ///< kg·m/s, Σ m·v
    vec3 angular_momentum = vec3::Zero(); ///< kg·m²/s, Σ m·x × v about the origin
    vec3 centre_of_mass = vec3::Zero();   ///< m, mass-weighted mean position (origin if no mass)
    double mass = 0.0;                    ///< kg, total
    double largest_speed = 0.0;           ///< m/s, the fastest dynamic body's
    std::size_t bodies = 0;
};

/// Measures a world. Costs one potential-energy evaluation of every force model (O(n²) for
/// the pairwise laws). Throws singular_force_error where the potential is singular (two
/// bodies coincide with softening 0).
diagnostics measure(world const& w);

/// Everything but the potential energy (potential = 0, total = kinetic): never throws, O(n).
diagnostics measure_motion(world const& w);

} // namespace kugel::physics
