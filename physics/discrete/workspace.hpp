#pragma once

// The discrete step's one workspace: everything its phases read and write besides the bodies,
// kept from step to step so that a step in a steady state allocates nothing.

#include "physics/aabb.hpp"
#include "physics/broadphase.hpp"
#include "physics/contact_events.hpp"
#include "physics/continuous/path_grid.hpp"
#include "physics/discrete/sphere_grid.hpp"
#include "physics/discrete/stop_table.hpp"
#include "physics/vec.hpp"

#include <cstdint>
#include <memory>
#include <vector>

namespace kugel::physics {

class collision_workspace;

/// The sphere pairs of one slab of the sphere grid and what the passes changed. Spheres are
/// named by their position in the grid's cell order.
struct contact_slab
{
    std::vector<sphere_pair> near;      ///< boxes overlap, in resolution order
    std::vector<sphere_pair> contacts;  ///< the near pairs that touch, in the same order
    std::vector<vec3> normals;          ///< each contact's unit normal, from b to a
    /// Each contact's allowed approach, m/s: for spheres apart (a speculative contact) the
    /// closing speed that leaves them touching at the end of the step, at least 0; −1 for
    /// spheres that touch, which meet by the collision rule.
    std::vector<double> allowed;
    std::vector<std::uint32_t> copied;  ///< the spheres of its contacts that this slab lists
    std::uint32_t first_copied = 0;     ///< where its copies start in the workspace's `moving`
    std::vector<sphere_pair> moving_pairs; ///< its contacts, as positions in `moving`
    std::vector<std::uint32_t> touched; ///< the spheres a pass changed that this slab lists
    std::vector<std::uint32_t> pushed;  ///< the spheres its position passes moved (once per pass)
    std::uint64_t responses = 0;        ///< sphere–sphere responses
    bool changed = false;               ///< the last velocity pass changed a velocity
};

/// What the wall pass did to one chunk of bodies.
struct wall_chunk
{
    std::vector<std::uint32_t> moved; ///< the spheres that bounced
    std::uint64_t responses = 0;      ///< sphere–wall responses
    bool accelerated = false;         ///< some body's free motion changed its velocity
    double largest_change = 0.0;      ///< m/s, of a velocity in free motion
    sphere_extent extent;             ///< of the bodies where the pass left them
    std::vector<std::uint32_t> fast;  ///< the spheres that moved farther than the sweep's share of their radius
    std::vector<vec3> fast_start;     ///< and where each started the step
};

/// The sweep's (swept_pass.cpp): the fast bodies, the spheres near them, and their copies, on
/// which the continuous mode's events run.
struct swept_workspace
{
    std::vector<std::uint32_t> fast;  ///< body slots, ascending
    std::vector<vec3> fast_start;     ///< m, where each started the step
    std::vector<aabb> box;            ///< by body slot: its path's box over the step
    std::vector<std::uint8_t> member; ///< by body slot: swept in this step
    std::vector<std::uint32_t> others; ///< the spheres not fast whose boxes are in the grid, ascending
    continuous::path_grid grid;       ///< their boxes, to find those a swept path comes near
    std::vector<std::uint32_t> members; ///< the bodies swept: the fast ones and those near, ascending
    std::vector<vec3> x, v, x0, v0;   ///< their copies
    std::vector<double> inverse_mass, radius;
    std::vector<vec3> v_in;           ///< m/s, each copy's velocity before the events
    std::vector<std::uint32_t> placed; ///< the bodies the events changed (every fast one swept), ascending
    std::unique_ptr<collision_workspace> events; ///< the continuous mode's, over the copies
    /// Kept only when keep_contacts is set (a world that reports contacts): the events'
    /// responses to pairs of spheres, by body slot, and when (s from the step's start).
    bool keep_contacts = false;
    std::vector<pair_touch> touches;

    swept_workspace();
    swept_workspace(swept_workspace&&) noexcept;
    swept_workspace& operator=(swept_workspace&&) noexcept;
    ~swept_workspace();
};

struct discrete_workspace
{
    // The wall pass and the obstacles
    std::vector<wall_chunk> wall_chunks;  ///< one per chunk of bodies
    std::vector<vec3> free_acceleration;  ///< each body's acceleration from free motion alone
    std::vector<std::uint64_t> cell_keys; ///< cell key by body slot, from the wall pass
    std::vector<std::uint32_t> cell_x;    ///< with threads: and the cell's x-coordinate
    std::vector<std::uint32_t> moved;     ///< the spheres walls and boxes moved
    /// Under forces: the spheres walls, boxes or the sweep moved from where free motion left
    /// them, ascending (the velocity passes' to know)
    std::vector<std::uint32_t> placed;
    swept_workspace swept;                ///< the fast bodies' sweep

    // Cells and near pairs
    sphere_grid grid;                   ///< the spheres in cell order
    std::vector<contact_slab> slabs;    ///< one per slab of the grid
    /// With a broadphase other than the grid: its boxes, their bodies and its pairs, and each
    /// body's position in cell order.
    struct other_broadphase
    {
        broadphase_workspace broadphase;
        std::vector<aabb> boxes;
        std::vector<std::uint32_t> members; ///< body slot of each box
        std::vector<box_pair> pairs;
        std::vector<std::uint32_t> ranks;   ///< position in cell order by body slot
    } other;

    // The velocity and position passes
    std::vector<std::uint32_t> mark;    ///< the pass that last listed a sphere
    std::uint32_t stamp = 0;            ///< the last pass's stamp, from step to step
    /// A contact sphere as the velocity passes see it.
    struct moving_sphere
    {
        vec3 v;              ///< m/s
        double inverse_mass; ///< 1/kg
    };
    std::vector<moving_sphere> moving;     ///< the contacts' spheres, as listed
    std::vector<vec3> moving_acceleration; ///< and their free accelerations
    std::vector<std::uint64_t> moving_id;  ///< and their bodies' id numbers, when known
    std::vector<std::uint32_t> moving_rank; ///< and, with forces, their positions in the grid's cell order
    std::vector<std::uint32_t> listed_at;  ///< where in `moving`, by cell order
    /// A contact in the order support is passed up a pile: under its upper sphere (a
    /// position in `moving`), at that sphere's depth along its acceleration.
    struct support_entry
    {
        double depth;
        std::uint32_t upper;
        std::uint32_t slab;
        std::uint32_t contact;
        bool a_above; ///< the upper sphere is the contact's a
    };
    std::vector<support_entry> support_order;
    /// Scratch of order_support(): the spheres that are upper ones, at their depths, and
    /// each one's count of contacts, then where its contacts go.
    struct support_upper
    {
        double depth;
        std::uint32_t upper;
    };
    std::vector<support_upper> support_uppers;
    std::vector<std::uint32_t> support_count;
    std::vector<support_entry> support_scratch;
    /// One sphere's stops against its supports while support is passed up (velocity_passes.cpp).
    struct support_stop
    {
        vec3 n;                          ///< unit normal, from the lower sphere to it
        double allowed;                  ///< m/s of approach it may keep
        vec3 lower_v;                    ///< the lower sphere's velocity, held still meanwhile (a wall: 0)
        double mu;                       ///< Coulomb's friction coefficient here
        std::uint64_t lower_id;          ///< the lower body's id number, or the wall's index
        double pushed = 0.0;             ///< m/s, the normal change summed over the sweeps
        vec3 friction = vec3::Zero();    ///< m/s, the tangential change summed likewise
    };
    std::vector<support_stop> support_stops;
    /// The stops' sums of the last step and of this one, by their bodies' ids (warm starting)
    discrete::stop_table last_stops, stops;
    /// The first support pass's sums, each sphere's side by side (`resting_first`: where each
    /// sphere's begin, in the order of the pass), for the last pass to add its own to.
    std::vector<discrete::kept_stop> resting_stops, merged_stops;
    std::vector<std::uint32_t> resting_first;
    std::vector<std::uint8_t> supported; ///< by position in `moving`: carried by a wall
};

} // namespace kugel::physics
