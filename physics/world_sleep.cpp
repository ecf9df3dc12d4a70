// Sleeping: bodies at rest in discrete mode cost a step nothing and keep their state exactly.
//
// As in Box2D and Jolt: the bodies a step's contacts join are an island (union–find over the
// contacts between awake bodies); each body counts how long it has been slower than the
// scene's sleep_speed; an island whose bodies have all been that calm for sleep_time, and which
// something static carries (a wall, a box, a static sphere), falls asleep as a whole. A
// sleeping body keeps v = 0 and its x to the bit; free motion leaves it where it is, and the
// collision step takes it as static, like a fixed sphere, so the awake bodies rest on it. Its
// island wakes as a whole: when an awake body touches one of its bodies, when a command
// changes one of them (apply_impulse), adds or removes a body touching one (add_body,
// remove_body: what a removed sphere carried falls), or when the world's forces, walls or
// boxes change.

#include "world.hpp"

#include <algorithm>
#include <limits>

namespace kugel::physics {

bool world::sleeping_applies() const
{
    // Only under constant forces (a uniform field): a sleeping body does not feel the forces,
    // and between bodies they change as the awake ones move. Without forces nothing rests,
    // and a gas keeps its bits.
    return settings_.collisions.mode == collision_mode::discrete && settings_.collisions.sleep && !forces_.empty() &&
           forces_are_constant();
}

void world::move_and_collide_around_sleepers(double h)
{
    auto const inverse_mass = bodies_.inverse_masses();
    auto const moves = [&](std::size_t i) { return island_of_[i] == awake && inverse_mass[i] > 0.0; };
    std::size_t const n = bodies_.size();
    active_.clear();
    gathered_ = true;
    std::size_t first_awake = 0;
    while (first_awake < n && !moves(first_awake))
        ++first_awake;
    if (first_awake == n)
        return; // everything that could move sleeps: the step costs nothing more
    // Free motion for every body, then the sleepers put back: the forces are the world's, and a
    // uniform field costs a few operations per body.
    keep_start_and_move_freely(h);
    auto const x = bodies_.positions();
    auto const v = bodies_.velocities();
    auto const radius = bodies_.radii();
    for (std::size_t i = 0; i < n; ++i) {
        if (island_of_[i] != awake) {
            x[i] = step_start_x_[i];
            v[i] = step_start_v_[i]; // zero
        }
    }
    // The collision step sees the awake bodies and the still spheres (asleep, or static) near
    // them: those whose centre lies within three of the largest radii of the awake spheres'
    // box, beyond which no contact, contact margin (at most half a radius) or push reaches.
    vec3 low = vec3::Constant(std::numeric_limits<double>::infinity());
    vec3 high = -low;
    double largest = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
        largest = std::max(largest, radius[i]);
        if (moves(i) && radius[i] > 0.0) {
            low = low.cwiseMin(x[i]);
            high = high.cwiseMax(x[i]);
        }
    }
    low.array() -= 3.0 * largest;
    high.array() += 3.0 * largest;
    for (std::uint32_t i = 0; i < n; ++i) {
        bool const near = radius[i] > 0.0 && (x[i].array() >= low.array()).all() && (x[i].array() <= high.array()).all();
        if (moves(i) || near)
            active_.push_back(i);
    }
    std::size_t const m = active_.size();
    active_x_.resize(m);
    active_v_.resize(m);
    active_x0_.resize(m);
    active_v0_.resize(m);
    active_inverse_mass_.resize(m);
    active_radius_.resize(m);
    active_ids_.resize(m);
    auto const ids = bodies_.ids();
    for (std::size_t k = 0; k < m; ++k) {
        std::uint32_t const i = active_[k];
        active_x_[k] = x[i];
        active_v_[k] = v[i];
        active_x0_[k] = step_start_x_[i];
        active_v0_[k] = step_start_v_[i];
        active_inverse_mass_[k] = island_of_[i] == awake ? inverse_mass[i] : 0.0; // a sleeper is static
        active_radius_[k] = radius[i];
        active_ids_[k] = ids[i];
    }
    resolve_collisions(settings_.collisions, walls_, obstacles_,
                       {active_x_, active_v_, active_x0_, active_v0_, active_inverse_mass_, active_radius_, true, false,
                        active_ids_},
                       h, collision_workspace_, collision_stats_, timings_, loops());
    for (std::size_t k = 0; k < m; ++k) {
        std::uint32_t const i = active_[k];
        if (moves(i)) {
            x[i] = active_x_[k];
            v[i] = active_v_[k];
        }
    }
    workspace_.invalidate(); // contacts may have moved bodies
}

std::uint32_t world::find_root(std::uint32_t slot)
{
    while (parent_[slot] != slot) {
        parent_[slot] = parent_[parent_[slot]]; // path halving
        slot = parent_[slot];
    }
    return slot;
}

void world::note_contacts()
{
    if (gathered_ && active_.empty())
        return; // no collision step ran
    auto const inverse_mass = bodies_.inverse_masses();
    auto const moves = [&](std::uint32_t i) { return island_of_[i] == awake && inverse_mass[i] > 0.0; };
    discrete_workspace const& ws = collision_workspace_.discrete;
    auto const slot = [&](std::uint32_t rank) {
        std::uint32_t const i = ws.grid.slot(rank);
        return gathered_ ? active_[i] : i;
    };
    to_wake_.clear();
    for (contact_slab const& slab : ws.slabs) {
        for (sphere_pair const& c : slab.contacts) {
            std::uint32_t const i = slot(c.a), j = slot(c.b);
            bool const moves_i = moves(i), moves_j = moves(j);
            if (moves_i && moves_j) {
                std::uint32_t const a = find_root(i), b = find_root(j);
                if (a != b)
                    parent_[std::max(a, b)] = std::min(a, b);
            } else if (moves_i || moves_j) {
                std::uint32_t const body = moves_i ? i : j, still = moves_i ? j : i;
                if (island_of_[still] != awake) { // an awake body touched a sleeper: it wakes
                    to_wake_.push_back(island_of_[still]);
                    held_awake_[body] = 1; // and the two islands sleep together or not at all
                } else {
                    grounded_[body] = 1; // a static sphere carries it
                }
            }
        }
    }
    for (std::uint32_t island : to_wake_)
        wake_island(island);
}

void world::fall_asleep(double dt)
{
    collision_settings const& settings = settings_.collisions;
    std::size_t const n = bodies_.size();
    auto const v = bodies_.velocities();
    auto const x = bodies_.positions();
    auto const radius = bodies_.radii();
    auto const inverse_mass = bodies_.inverse_masses();
    // Bodies woken during the step (wake_island) are awake now and in no island yet: they
    // count as islands of their own, calm 0.
    auto const moves = [&](std::uint32_t i) { return island_of_[i] == awake && inverse_mass[i] > 0.0; };
    double const slow = settings.sleep_speed * settings.sleep_speed;
    island_calm_.assign(n, std::numeric_limits<double>::infinity());
    for (std::uint32_t i = 0; i < n; ++i) {
        if (!moves(i))
            continue;
        calm_[i] = v[i].squaredNorm() < slow ? calm_[i] + dt : 0.0;
        std::uint32_t const root = find_root(i);
        island_calm_[root] = std::min(island_calm_[root], calm_[i]);
        grounded_[root] |= grounded_[i];
        held_awake_[root] |= held_awake_[i];
    }
    // A wall or a box carries an island that is calm enough: looked for only there.
    auto const ready = [&](std::uint32_t root) {
        return island_calm_[root] >= settings.sleep_time && !held_awake_[root];
    };
    for (std::uint32_t i = 0; i < n; ++i) {
        if (!moves(i) || !(radius[i] > 0.0))
            continue;
        std::uint32_t const root = find_root(i);
        if (grounded_[root] || !ready(root))
            continue;
        double const reach = radius[i] * (1.0 + 1e-6); // touching, to rounding
        bool touches = std::any_of(walls_.begin(), walls_.end(), [&](wall const& w) {
            return w.surface.normal.dot(x[i]) <= w.surface.offset + reach;
        });
        touches = touches || std::any_of(obstacles_.begin(), obstacles_.end(), [&](obstacle const& o) {
                      return sphere_vs_obb(x[i], reach, o.box).touching;
                  });
        if (touches)
            grounded_[root] = 1;
    }
    // Each ready island falls asleep as a whole. An island's number is kept at its root in
    // island_calm_, no longer needed there, as a negative whole number.
    auto const ids = bodies_.ids();
    for (std::uint32_t i = 0; i < n; ++i) {
        if (!moves(i))
            continue;
        std::uint32_t const root = find_root(i);
        if (!(grounded_[root] && (island_calm_[root] < 0.0 || ready(root))))
            continue;
        if (island_calm_[root] >= 0.0) { // its first body, in slot order: number the island
            std::uint32_t number = 0;
            if (!free_islands_.empty()) {
                number = free_islands_.back();
                free_islands_.pop_back();
            } else {
                sleeping_islands_.emplace_back();
                number = static_cast<std::uint32_t>(sleeping_islands_.size());
            }
            island_calm_[root] = -static_cast<double>(number);
        }
        auto const number = static_cast<std::uint32_t>(-island_calm_[root]);
        island_of_[i] = number;
        v[i] = vec3::Zero();
        sleeping_islands_[number - 1].push_back(ids[i]);
        ++sleeping_;
    }
}

void world::wake_island(std::uint32_t island)
{
    auto& members = sleeping_islands_[island - 1];
    if (members.empty())
        return; // woken already
    for (body_id const id : members) {
        auto const slot = bodies_.slot_of(id);
        if (slot && island_of_[*slot] == island) {
            island_of_[*slot] = awake;
            calm_[*slot] = 0.0;
            --sleeping_;
        }
    }
    members.clear();
    free_islands_.push_back(island);
}

void world::wake_all()
{
    for (std::uint32_t island = 1; island <= sleeping_islands_.size(); ++island)
        wake_island(island);
}

void world::wake_near(vec3 const& x, double r)
{
    if (sleeping_ == 0 || !(r > 0.0))
        return;
    auto const positions = bodies_.positions();
    auto const radius = bodies_.radii();
    for (std::size_t j = 0; j < positions.size(); ++j) {
        if (island_of_[j] == awake || !(radius[j] > 0.0))
            continue;
        double const reach = 1.1 * (r + radius[j]); // touching, or nearly
        if ((positions[j] - x).squaredNorm() < reach * reach)
            wake_island(island_of_[j]);
    }
}

} // namespace kugel::physics
