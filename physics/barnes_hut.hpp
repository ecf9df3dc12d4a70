#pragma once

#include "forces.hpp"

#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

namespace kugel::physics {

/// The largest opening angle θ a tree accepts. Up to 1 the acceptance test below also keeps
/// every body outside any cell whose monopole it uses (see `source_tree`).
inline constexpr double max_opening_angle = 1.0;

/// Barnes–Hut octree over the bodies that carry a source strength of one sign: masses, or
/// the positive charges, or the negative ones. Built afresh for each evaluation.
///
/// Cells split into eight until they hold at most `leaf_size` sources or reach `max_depth`
/// (so many coincident points end in one deep leaf instead of splitting for ever); building
/// and walking are loops with explicit, bounded stacks, never recursion.
///
/// A cell of side s whose sources have total strength S and centre (of mass or charge) c is
/// used as one point source S at c (monopole) for a target y when
///
///     s / (|y − c| − δ) < θ,  δ = |c − cell centre|,
///
/// Barnes' criterion with d measured from the centre of mass, made safe by δ: with θ <= 1
/// it puts y outside the cell's circumscribed sphere, so a body never takes a monopole of a
/// cell that holds itself, however lopsided the cell. Otherwise the cell is opened; a leaf
/// that is opened is summed body by body. θ = 0 opens everything: direct summation.
class source_tree
{
public:
    static constexpr std::size_t leaf_size = 8;
    static constexpr std::size_t max_depth = 32;

    /// The field of the sources at a point, without the coupling constant.
    struct sample
    {
        vec3 field = vec3::Zero(); ///< Σ s_j·(x_j − y)/(|x_j − y|² + ε²)^{3/2}
        double potential = 0.0;    ///< Σ s_j/√(|x_j − y|² + ε²), when asked for
        /// A source at distance 0 with ε = 0 (the sum is singular), or none.
        std::size_t singular_with = no_body;
        std::size_t interactions = 0; ///< monopoles and single sources summed: the cost
        std::size_t pair_terms = 0; ///< of which single sources (opened leaves)
    };
    static constexpr std::size_t no_body = std::numeric_limits<std::size_t>::max();

    /// Builds over the points x[i] whose strength[i] > 0; the others are left out. θ in
    /// [0, max_opening_angle].
    void build(std::span<vec3 const> x, std::span<double const> strength, double theta);

    /// The sources' field at y, leaving out the source of body `self` (no_body: none).
    /// Potential only when `with_potential`.
    sample field_at(vec3 const& y, std::size_t self, double softening,
                    bool with_potential) const;

    /// The bodies in the tree, in tree order (nearby bodies next to each other).
    std::span<std::uint32_t const> bodies() const { return body_; }
    std::size_t cell_count() const { return cells_.size(); }
    /// The deepest cell built: max_depth means some leaf was cut off by the cap.
    std::size_t depth() const { return depth_; }

private:
    /// What the walk reads, 64 bytes. Children of a cell are consecutive.
    struct cell
    {
        vec3 source_centre = vec3::Zero(); ///< strength-weighted mean of the sources
        double open_radius2 = 0.0;         ///< (s/θ + δ)²: monopole when |y − c|² exceeds it
        double strength = 0.0;             ///< total, > 0
        std::uint32_t first = 0;           ///< first source, in tree order
        std::uint32_t count = 0;           ///< sources inside
        std::uint32_t first_child = 0;
        std::uint32_t child_count = 0; ///< 0: a leaf
    };

    std::vector<cell> cells_;
    std::vector<vec3> x_;            ///< sources' positions, in tree order
    std::vector<double> s_;          ///< sources' strengths, in tree order
    std::vector<std::uint32_t> body_; ///< sources' body indices, in tree order
    std::size_t depth_ = 0;
};

/// Newtonian gravity through the tree: the same law as `newtonian_gravity` (G, Plummer
/// softening ε applied to each pair and to each monopole alike), O(N log N) per evaluation
/// with the monopole error of the opening angle θ. Forces are not pairwise symmetric (body
/// i may see j's cell while j sees i alone), so Σ F = 0 holds only to the approximation.
/// The potential energy goes through the same tree: U = −½·G·Σ m_i·φ_i, exact for θ = 0.
class tree_gravity final : public force_model
{
public:
    /// G >= 0 and softening >= 0 as for newtonian_gravity; θ in [0, 1] (0: exact).
    tree_gravity(double G, double softening, double theta);

    std::string_view name() const override { return "gravity"; }
    void add_forces(body_storage const& bodies, std::span<vec3 const> x,
                    std::span<vec3> forces) const override;
    double potential_energy(body_storage const& bodies, std::span<vec3 const> x) const override;
    std::optional<addition_refusal> check_addition(body_storage const& bodies, body_desc const& candidate,
                                                   addition_limits const& limits) const override;

    double G() const { return G_; }
    double softening() const { return softening_; }
    double theta() const { return theta_; }

private:
    double G_;
    double softening_;
    double theta_;
};

/// Coulomb's law through two trees, one over the positive charges and one over the
/// negative ones, each with charge magnitudes as its strengths. Every cell then holds
/// charge of one sign and its monopole has the same error bound as gravity's, relative to
/// the field of that sign. With charges of both signs the net force is the difference of
/// the two fields, which can cancel: the error stays bounded by the per-sign fields, not
/// by the net force, so a nearly neutral cloud can see a large relative error. (Keeping a
/// positive and a negative centre per region captures its dipole moment exactly.)
class tree_coulomb final : public force_model
{
public:
    /// k >= 0 and softening >= 0 as for coulomb; θ in [0, 1] (0: exact).
    tree_coulomb(double k, double softening, double theta);

    std::string_view name() const override { return "coulomb"; }
    void add_forces(body_storage const& bodies, std::span<vec3 const> x,
                    std::span<vec3> forces) const override;
    double potential_energy(body_storage const& bodies, std::span<vec3 const> x) const override;
    std::optional<addition_refusal> check_addition(body_storage const& bodies, body_desc const& candidate,
                                                   addition_limits const& limits) const override;

    double k() const { return k_; }
    double softening() const { return softening_; }
    double theta() const { return theta_; }

private:
    double k_;
    double softening_;
    double theta_;
};

/// True when some body has a positive and another a negative charge: then a tree's Coulomb
/// error bound holds per sign only (see tree_coulomb).
bool has_mixed_charges(body_storage const& bodies);

} // namespace kugel::physics
