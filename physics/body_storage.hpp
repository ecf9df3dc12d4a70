#pragma once

#include "body_id.hpp"
#include "parallel_for.hpp"
#include "vec.hpp"

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

namespace kugel::physics {

/// What it takes to create a body.
struct body_desc
{
    vec3 position = vec3::Zero(); ///< m
    vec3 velocity = vec3::Zero(); ///< m/s; must be zero for a static body
    double mass = 1.0;            ///< kg; > 0 for a dynamic body, >= 0 for a static one
    double radius = 0.0;          ///< m, >= 0; 0 makes a point mass, which never collides
    double charge = 0.0;          ///< C (or the scene's charge unit)
    bool is_static = false;       ///< never moves: inverse mass 0, yet still attracts and repels
};

/// m = ρ · 4/3 · π · r³ (lecture: "Masse m = ρ · V = ρ · 4π/3 · r³").
double mass_from_density(double density, double radius);

/// Bodies as a structure of arrays: one contiguous array per quantity, one dense slot per
/// live body. Removal moves the last body into the hole, and permute() reorders the slots, so
/// slots change on removal and reordering but ids do not. Order is deterministic: same
/// calls, same slots.
class body_storage
{
public:
    /// The most body ids a storage hands out (2^30, about 10⁹: over 100 GB of bodies): the
    /// continuous mode names a body in 30 bits of an event (continuous/event.hpp).
    static constexpr std::size_t most_bodies = std::size_t{1} << 30U;

    /// Adds a body; throws std::invalid_argument naming the bad field (non-finite values,
    /// negative radius, non-positive mass of a dynamic body, velocity on a static body), and
    /// std::length_error when most_bodies ids are in use.
    body_id add(body_desc const& desc);

    /// Removes a body; false when the id names no live body.
    bool remove(body_id id);

    /// Moves every body to a new slot: the body in slot order[k] goes to slot k. `order` holds
    /// each slot once (std::invalid_argument names what is wrong otherwise, and nothing moves).
    /// Each quantity is moved on the threads of `loops`, when given.
    void permute(std::span<std::uint32_t const> order, parallel_for* loops = nullptr);

    bool contains(body_id id) const { return slot_of(id).has_value(); }

    /// The dense slot of a live body, or nothing.
    std::optional<std::size_t> slot_of(body_id id) const;

    std::size_t size() const { return positions_.size(); }
    bool empty() const { return positions_.empty(); }
    void reserve(std::size_t n);

    std::span<vec3> positions() { return positions_; }
    std::span<vec3 const> positions() const { return positions_; }
    std::span<vec3> velocities() { return velocities_; }
    std::span<vec3 const> velocities() const { return velocities_; }
    std::span<double const> masses() const { return masses_; }
    std::span<double const> inverse_masses() const { return inverse_masses_; }
    std::span<double const> radii() const { return radii_; }
    /// Every body's charge by slot, or nothing while no body has carried one (every charge
    /// 0: a world without charges keeps no column of them, 8 bytes a body).
    std::span<double const> charges() const { return charges_; }
    double charge(std::size_t slot) const { return charges_.empty() ? 0.0 : charges_[slot]; }
    std::span<body_id const> ids() const { return ids_; }
    /// Changes whenever a body is added, removed or moved to another slot, and is never 0:
    /// while it stays the same, each slot holds the same body (the continuous calendar keeps
    /// its numbering by it, where it compared every id every step).
    std::uint64_t layout() const { return layout_; }

    /// Rebuilds a body's description from its slot (for checkpoints and tests).
    body_desc describe(std::size_t slot) const;

private:
    /// 8 bytes: no flag beside the slot, which is `dead` while no body has this index.
    struct slot_entry
    {
        static constexpr std::uint32_t dead = 0xffffffffU; ///< beyond any slot (most_bodies)
        std::uint32_t generation = 1;    ///< of the body in (or last in) this id index
        std::uint32_t dense = dead;      ///< its dense slot while alive
    };

    // Hot: read every step.
    std::vector<vec3> positions_;       ///< m
    std::vector<vec3> velocities_;      ///< m/s
    std::vector<double> inverse_masses_; ///< 1/kg, 0 for static bodies
    std::vector<double> radii_;         ///< m, >= 0
    // Read by force models and diagnostics.
    std::vector<double> masses_;  ///< kg
    std::vector<double> charges_; ///< C; empty until a body carries a charge
    std::vector<body_id> ids_;

    std::vector<slot_entry> sparse_;          ///< indexed by body_id::index
    std::uint64_t layout_ = 1;
    // permute() gathers each quantity into one of these and keeps the old array in its place:
    // a world that sorts its bodies every few steps then reuses the same memory.
    std::vector<vec3> spare_vectors_;
    std::vector<double> spare_numbers_;
    std::vector<body_id> spare_ids_;
    std::vector<std::uint8_t> spare_bytes_;
    std::vector<std::uint32_t> free_indices_; ///< reused last-in first-out
};

} // namespace kugel::physics
