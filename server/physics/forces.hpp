#pragma once

#include "body_storage.hpp"
#include "vec.hpp"

#include <span>
#include <stdexcept>
#include <string>
#include <string_view>

namespace kugel::physics {

/// Thrown when a force is singular: two bodies coincide (or nearly so) under a 1/r² law with
/// softening 0. The step that hit it changes nothing; the message names the bodies and the fix.
class singular_force_error : public std::runtime_error
{
public:
    using std::runtime_error::runtime_error;
};

/// A force law. The world holds only the models its scene names, so a scene without forces
/// runs no force loop at all. Models see positions separately from the bodies because
/// multi-stage integrators evaluate forces at trial positions.
class force_model
{
public:
    virtual ~force_model() = default;

    /// The scene's name for this model ("uniform_field", "gravity", "coulomb").
    virtual std::string_view name() const = 0;

    /// Adds this model's force on every body, evaluated at positions `x`, to `forces` (N).
    virtual void add_forces(body_storage const& bodies, std::span<vec3 const> x,
                            std::span<vec3> forces) const = 0;

    /// The model's potential energy at positions `x` (J).
    virtual double potential_energy(body_storage const& bodies, std::span<vec3 const> x) const = 0;

    /// True when the force on each body does not depend on where the bodies are: then the
    /// exact constant-force integrator is exact.
    virtual bool is_constant() const { return false; }
};

/// F = m·g, the lecture's [0, 0, −m·g] for g = (0, 0, −9.81). Potential U = −Σ m·(g·x).
class uniform_field final : public force_model
{
public:
    explicit uniform_field(vec3 g) : g_(g) {}

    std::string_view name() const override { return "uniform_field"; }
    void add_forces(body_storage const& bodies, std::span<vec3 const> x,
                    std::span<vec3> forces) const override;
    double potential_energy(body_storage const& bodies, std::span<vec3 const> x) const override;
    bool is_constant() const override { return true; }

    vec3 const& g() const { return g_; }

private:
    vec3 g_; ///< m/s², the field's acceleration
};

/// Newtonian gravity between all pairs (lecture: F₁ = G·m₁m₂/|x₂−x₁|² · (x₂−x₁)/|x₂−x₁|),
/// with Plummer softening: |x₂−x₁|² becomes |x₂−x₁|² + ε². Each pair is computed once and
/// applied to both bodies with opposite signs, so total momentum is conserved to rounding.
/// Potential U = −Σ G·m₁m₂ / √(r² + ε²).
class newtonian_gravity final : public force_model
{
public:
    /// G in m³/(kg·s²) (6.674e-11 in SI; scenes often use G = 1); softening ε in m, >= 0.
    newtonian_gravity(double G, double softening);

    std::string_view name() const override { return "gravity"; }
    void add_forces(body_storage const& bodies, std::span<vec3 const> x,
                    std::span<vec3> forces) const override;
    double potential_energy(body_storage const& bodies, std::span<vec3 const> x) const override;

    double G() const { return G_; }
    double softening() const { return softening_; }

private:
    double G_;
    double softening_;
};

/// Coulomb's law as the lecture writes it: F₁ = −k·q₁q₂/|x₂−x₁|² · (x₂−x₁)/|x₂−x₁|, so like
/// charges repel. Same softening and symmetric pairs as gravity; uncharged bodies are skipped.
/// Potential U = +Σ k·q₁q₂ / √(r² + ε²).
class coulomb final : public force_model
{
public:
    /// k in N·m²/C² (8.9875517923e9 in SI); softening ε in m, >= 0.
    coulomb(double k, double softening);

    std::string_view name() const override { return "coulomb"; }
    void add_forces(body_storage const& bodies, std::span<vec3 const> x,
                    std::span<vec3> forces) const override;
    double potential_energy(body_storage const& bodies, std::span<vec3 const> x) const override;

    double k() const { return k_; }
    double softening() const { return softening_; }

private:
    double k_;
    double softening_;
};

} // namespace kugel::physics
