#pragma once

#include "body_storage.hpp"
#include "vec.hpp"

#include <limits>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>

namespace kugel::physics {

/// Thrown when a force is singular: a 1/r² law between two bodies gives what no double
/// holds, because they coincide (or nearly so) with softening 0, or because their coupling
/// (G·m·m, k·q·q) overflows. The step that hit it changes nothing; the message names the
/// bodies, the cause and the fix, and `first`, `second` the bodies.
class singular_force_error : public std::runtime_error
{
public:
    singular_force_error(std::string const& what, body_id a, body_id b)
        : std::runtime_error(what), first(a), second(b)
    {
    }
    body_id first, second;
};

/// What a body may add to a world's forces (force_model::check_addition): no pair force
/// above max_pair_force (N), so that the sum over any number of bodies a world can hold
/// stays finite; and no acceleration of either body of a pair at or above max_acceleration
/// (m/s²).
struct addition_limits
{
    double max_acceleration = std::numeric_limits<double>::infinity();
    static constexpr double max_pair_force = 1e300;
};

/// Why a body may not be added: the pair (with the body in slot `other`) whose force would
/// pass the limits, and its figures (a figure that overflowed is infinite).
struct addition_refusal
{
    std::string_view model; ///< the force model's name
    std::size_t other;      ///< the slot of the other body of the pair
    double distance;        ///< m, between the two
    double softening;       ///< m, the model's
    double force;           ///< N, the pair's
    double acceleration;    ///< m/s², the larger of the pair's two
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

    /// Why adding `candidate` to `bodies` would give a force beyond `limits` at the bodies'
    /// positions now; nothing when it would not. O(n): each pair with the candidate.
    virtual std::optional<addition_refusal> check_addition(body_storage const& bodies,
                                                           body_desc const& candidate,
                                                           addition_limits const& limits) const
    {
        (void)bodies, (void)candidate, (void)limits;
        return std::nullopt;
    }
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
    std::optional<addition_refusal> check_addition(body_storage const& bodies, body_desc const& candidate,
                                                   addition_limits const& limits) const override;

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
    std::optional<addition_refusal> check_addition(body_storage const& bodies, body_desc const& candidate,
                                                   addition_limits const& limits) const override;

    double k() const { return k_; }
    double softening() const { return softening_; }

private:
    double k_;
    double softening_;
};

// Shared by the direct and the tree (barnes_hut.hpp) forms of the two 1/r² laws.

/// Throws singular_force_error for the pair (i, j) at positions `x` of the 1/r² law `model`,
/// whose signed strength for the pair is `coupling` (G·m_i·m_j, −k·q_i·q_j): the message says
/// whether the bodies coincide with softening 0 (give a softening) or the coupling is too
/// large for a double at their distance (smaller masses or charges).
[[noreturn]] void throw_singular_pair(std::string_view model, double coupling, double softening,
                                      body_storage const& bodies, std::span<vec3 const> x,
                                      std::size_t i, std::size_t j);

/// check_addition of a 1/r² law whose coupling of bodies a and b is
/// constant · strength[a] · strength[b] (gravity: G and the masses; Coulomb: −k and the
/// charges), `candidate_strength` the candidate's. An empty `strength` is 0 for every body
/// (body_storage::charges before any body carries one): nothing is refused.
std::optional<addition_refusal> check_inverse_square_addition(
    std::string_view model, double constant, double softening, std::span<double const> strength,
    double candidate_strength, body_storage const& bodies, body_desc const& candidate,
    addition_limits const& limits);

} // namespace kugel::physics
