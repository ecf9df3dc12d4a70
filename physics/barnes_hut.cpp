#include "barnes_hut.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <sstream>
#include <string>

namespace kugel::physics {

namespace {

void check_parameters(std::string_view model, char const* constant, double value,
                      double softening, double theta)
{
    std::string const name(model);
    if (!(std::isfinite(value) && value >= 0.0))
        throw std::invalid_argument(name + " " + constant + " must be finite and >= 0");
    if (!(std::isfinite(softening) && softening >= 0.0))
        throw std::invalid_argument(name + " softening must be finite and >= 0");
    if (!(theta >= 0.0 && theta <= max_opening_angle))
        throw std::invalid_argument(name + " theta must be between 0 and 1");
}

/// The cube a cell covers: needed while building only.
struct cell_box
{
    vec3 centre;
    double side;
    std::size_t depth;
};

unsigned octant_of(vec3 const& p, vec3 const& centre)
{
    return (p.x() >= centre.x() ? 1U : 0U) | (p.y() >= centre.y() ? 2U : 0U) |
           (p.z() >= centre.z() ? 4U : 0U);
}

} // namespace

void source_tree::build(std::span<vec3 const> x, std::span<double const> strength, double theta)
{
    cells_.clear();
    x_.clear();
    s_.clear();
    body_.clear();
    depth_ = 0;
    std::vector<std::uint32_t> order;
    for (std::size_t i = 0; i < x.size(); ++i)
        if (strength[i] > 0.0)
            order.push_back(static_cast<std::uint32_t>(i));
    if (order.empty())
        return;
    auto const n = static_cast<std::uint32_t>(order.size());

    // The root: the bounding cube of the sources.
    vec3 lo = x[order[0]];
    vec3 hi = lo;
    for (auto const i : order) {
        lo = lo.cwiseMin(x[i]);
        hi = hi.cwiseMax(x[i]);
    }
    std::vector<cell_box> boxes;
    cells_.push_back({.first = 0, .count = n});
    boxes.push_back({(lo + hi) / 2.0, (hi - lo).maxCoeff(), 0});

    // Split cells in creation order (breadth first): a cell's children always come after
    // it and next to each other. Each split is a counting sort of the cell's range by octant.
    std::vector<std::uint32_t> scratch(n);
    std::vector<std::uint8_t> octant(n);
    for (std::size_t k = 0; k < cells_.size(); ++k) {
        std::uint32_t const first = cells_[k].first;
        std::uint32_t const end = first + cells_[k].count;
        cell_box const box = boxes[k];
        depth_ = std::max(depth_, box.depth);
        if (cells_[k].count <= leaf_size || box.depth >= max_depth)
            continue; // a leaf
        std::array<std::uint32_t, 8> counts{};
        for (std::uint32_t j = first; j < end; ++j) {
            unsigned const o = octant_of(x[order[j]], box.centre);
            octant[j] = static_cast<std::uint8_t>(o);
            ++counts[o];
        }
        std::array<std::uint32_t, 8> starts{};
        for (std::size_t o = 1; o < 8; ++o)
            starts[o] = starts[o - 1] + counts[o - 1];
        auto cursor = starts;
        for (std::uint32_t j = first; j < end; ++j)
            scratch[first + cursor[octant[j]]++] = order[j];
        std::copy(scratch.begin() + first, scratch.begin() + end, order.begin() + first);

        auto const first_child = static_cast<std::uint32_t>(cells_.size());
        std::uint32_t children = 0;
        double const quarter = box.side / 4.0;
        for (unsigned o = 0; o < 8; ++o) {
            if (counts[o] == 0)
                continue;
            vec3 const offset((o & 1U) ? quarter : -quarter, (o & 2U) ? quarter : -quarter,
                              (o & 4U) ? quarter : -quarter);
            cells_.push_back({.first = first + starts[o], .count = counts[o]});
            boxes.push_back({box.centre + offset, box.side / 2.0, box.depth + 1});
            ++children;
        }
        cells_[k].first_child = first_child;
        cells_[k].child_count = children;
    }

    // Sources in tree order, so a leaf reads consecutive memory.
    x_.resize(n);
    s_.resize(n);
    body_ = std::move(order);
    for (std::uint32_t j = 0; j < n; ++j) {
        x_[j] = x[body_[j]];
        s_[j] = strength[body_[j]];
    }

    // Monopoles from the leaves up (children come after their parent), then each cell's
    // opening radius s/θ + δ.
    for (std::size_t k = cells_.size(); k-- > 0;) {
        cell& c = cells_[k];
        double total = 0.0;
        vec3 moment = vec3::Zero();
        if (c.child_count == 0) {
            for (std::uint32_t j = c.first; j < c.first + c.count; ++j) {
                total += s_[j];
                moment += s_[j] * x_[j];
            }
        } else {
            for (std::uint32_t child = c.first_child; child < c.first_child + c.child_count; ++child) {
                total += cells_[child].strength;
                moment += cells_[child].strength * cells_[child].source_centre;
            }
        }
        c.strength = total;
        c.source_centre = moment / total;
        double const offset = (c.source_centre - boxes[k].centre).norm();
        double const radius = theta > 0.0 ? boxes[k].side / theta + offset
                                          : std::numeric_limits<double>::infinity();
        c.open_radius2 = radius * radius;
    }
}

source_tree::sample source_tree::field_at(vec3 const& y, std::size_t self, double softening,
                                          bool with_potential) const
{
    sample out;
    if (cells_.empty())
        return out;
    double const eps2 = softening * softening;
    // Adds a point source; false when 1/r³ overflows (distance 0 without softening).
    auto const add = [&](double strength, vec3 const& d, double r2) {
        double const inv_r = 1.0 / std::sqrt(r2 + eps2);
        double const inv_r3 = inv_r * inv_r * inv_r;
        if (!std::isfinite(inv_r3))
            return false;
        ++out.interactions;
        out.field += (strength * inv_r3) * d;
        if (with_potential)
            out.potential += strength * inv_r;
        return true;
    };

    // Depth first with a fixed stack: along the path down, each level leaves at most seven
    // siblings waiting, and the depth is capped.
    std::array<std::uint32_t, 8 * (max_depth + 1)> stack;
    std::size_t top = 0;
    stack[top++] = 0;
    while (top > 0) {
        cell const& c = cells_[stack[--top]];
        vec3 const d = c.source_centre - y;
        double const r2 = d.squaredNorm();
        if (r2 > c.open_radius2) { // far enough: the cell's monopole
            if (!add(c.strength, d, r2)) {
                out.singular_with = body_[c.first];
                return out;
            }
        } else if (c.child_count == 0) { // an opened leaf: body by body
            out.pair_terms += c.count;
            for (std::uint32_t j = c.first; j < c.first + c.count; ++j) {
                if (body_[j] == self)
                    continue;
                vec3 const dj = x_[j] - y;
                if (!add(s_[j], dj, dj.squaredNorm())) {
                    out.singular_with = body_[j];
                    return out;
                }
            }
        } else {
            for (std::uint32_t child = c.first_child; child < c.first_child + c.child_count; ++child)
                stack[top++] = child;
        }
    }
    return out;
}

tree_gravity::tree_gravity(double G, double softening, double theta)
    : G_(G), softening_(softening), theta_(theta)
{
    check_parameters("gravity", "G", G, softening, theta);
}

void tree_gravity::add_forces(body_storage const& bodies, std::span<vec3 const> x,
                              std::span<vec3> forces) const
{
    auto const m = bodies.masses();
    source_tree tree;
    tree.build(x, m, theta_);
    for (std::size_t const i : tree.bodies()) { // tree order: neighbours walk alike
        auto const s = tree.field_at(x[i], i, softening_, false);
        if (s.singular_with != source_tree::no_body)
            throw_singular_pair(name(), G_ * m[i] * m[s.singular_with], softening_, bodies, x, i, s.singular_with);
        forces[i] += (G_ * m[i]) * s.field;
    }
}

std::optional<addition_refusal> tree_gravity::check_addition(body_storage const& bodies,
                                                             body_desc const& candidate,
                                                             addition_limits const& limits) const
{
    return check_inverse_square_addition(name(), G_, softening_, bodies.masses(), candidate.mass,
                                         bodies, candidate, limits);
}

double tree_gravity::potential_energy(body_storage const& bodies, std::span<vec3 const> x) const
{
    auto const m = bodies.masses();
    source_tree tree;
    tree.build(x, m, theta_);
    double sum = 0.0; // Σ m_i·φ_i counts every pair twice
    for (std::size_t const i : tree.bodies()) {
        auto const s = tree.field_at(x[i], i, softening_, true);
        if (s.singular_with != source_tree::no_body)
            throw_singular_pair(name(), G_ * m[i] * m[s.singular_with], softening_, bodies, x, i, s.singular_with);
        sum += m[i] * s.potential;
    }
    return -0.5 * G_ * sum;
}

tree_coulomb::tree_coulomb(double k, double softening, double theta)
    : k_(k), softening_(softening), theta_(theta)
{
    check_parameters("coulomb", "k", k, softening, theta);
}

namespace {

/// The two one-sign trees of the charges at x.
struct charge_trees
{
    source_tree positive;
    source_tree negative;

    charge_trees(std::span<double const> q, std::span<vec3 const> x, double theta)
    {
        std::vector<double> magnitude(q.size());
        for (std::size_t i = 0; i < q.size(); ++i)
            magnitude[i] = std::max(q[i], 0.0);
        positive.build(x, magnitude, theta);
        for (std::size_t i = 0; i < q.size(); ++i)
            magnitude[i] = std::max(-q[i], 0.0);
        negative.build(x, magnitude, theta);
    }
};

} // namespace

void tree_coulomb::add_forces(body_storage const& bodies, std::span<vec3 const> x,
                              std::span<vec3> forces) const
{
    auto const q = bodies.charges();
    if (q.empty())
        return; // no charges: no field
    charge_trees const trees(q, x, theta_);
    for (source_tree const* targets : {&trees.positive, &trees.negative}) {
        for (std::size_t const i : targets->bodies()) {
            auto const plus = trees.positive.field_at(x[i], i, softening_, false);
            auto const minus = trees.negative.field_at(x[i], i, softening_, false);
            for (std::size_t const j : {plus.singular_with, minus.singular_with})
                if (j != source_tree::no_body)
                    throw_singular_pair(name(), -k_ * q[i] * q[j], softening_, bodies, x, i, j);
            // F_i = −k·q_i·Σ q_j·(x_j − x_i)/r³: like charges repel.
            forces[i] -= (k_ * q[i]) * (plus.field - minus.field);
        }
    }
}

std::optional<addition_refusal> tree_coulomb::check_addition(body_storage const& bodies,
                                                             body_desc const& candidate,
                                                             addition_limits const& limits) const
{
    return check_inverse_square_addition(name(), -k_, softening_, bodies.charges(), candidate.charge,
                                         bodies, candidate, limits);
}

double tree_coulomb::potential_energy(body_storage const& bodies, std::span<vec3 const> x) const
{
    auto const q = bodies.charges();
    if (q.empty())
        return 0.0;
    charge_trees const trees(q, x, theta_);
    double sum = 0.0;
    for (source_tree const* targets : {&trees.positive, &trees.negative}) {
        for (std::size_t const i : targets->bodies()) {
            auto const plus = trees.positive.field_at(x[i], i, softening_, true);
            auto const minus = trees.negative.field_at(x[i], i, softening_, true);
            for (std::size_t const j : {plus.singular_with, minus.singular_with})
                if (j != source_tree::no_body)
                    throw_singular_pair(name(), -k_ * q[i] * q[j], softening_, bodies, x, i, j);
            sum += q[i] * (plus.potential - minus.potential);
        }
    }
    return 0.5 * k_ * sum;
}

bool has_mixed_charges(body_storage const& bodies)
{
    bool positive = false;
    bool negative = false;
    for (double const q : bodies.charges()) {
        positive = positive || q > 0.0;
        negative = negative || q < 0.0;
    }
    return positive && negative;
}

} // namespace kugel::physics
