#pragma once

#include "aabb.hpp"
#include "body_id.hpp"
#include "body_path.hpp"
#include "broadphase.hpp"
#include "physics/continuous/workspace.hpp"
#include "physics/discrete/workspace.hpp"
#include "obb.hpp"
#include "parallel_for.hpp"
#include "plane.hpp"
#include "step_timings.hpp"
#include "vec.hpp"

#include <cstdint>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

namespace kugel::physics {

/// A static wall: the lecture's plane {x : n·x = d} with outer unit normal n, and the
/// response parameters of the lecture's w = (1 − μ)·v_t − (1 − α)·v_n.
struct wall
{
    plane surface;        ///< unit outer normal, pointing to where the spheres are
    double damping = 0.0;  ///< α in [0, 1]: 0 reflects the normal speed fully, 1 stops it
    /// μ in [0, 1]: the share of tangential speed lost per contact; in discrete mode under
    /// forces, a sphere resting against the wall in a pile is held by Coulomb's law with this μ
    double friction = 0.0;
};

/// The six walls of a box (region.min < region.max on every axis), normals pointing in: on
/// each axis the wall at min, then the one at max. A scene's `box` is these.
std::vector<wall> box_walls(aabb const& region, double damping, double friction);

/// A static box that spheres bounce off, with the same response rule as a wall.
struct obstacle
{
    obb box;
    double damping = 0.0;  ///< α in [0, 1]
    double friction = 0.0; ///< μ in [0, 1]
};

enum class collision_mode {
    off,        ///< bodies pass through each other and through walls
    discrete,   ///< overlaps at the end of the step: respond, then separate
    continuous, ///< contacts in time order inside the step: nothing tunnels
};

std::optional<collision_mode> collision_mode_from_name(std::string_view name);
std::string_view name(collision_mode mode);

struct collision_settings
{
    collision_mode mode = collision_mode::off;
    broadphase_kind broadphase = broadphase_kind::uniform_grid;
    double restitution = 1.0; ///< e in [0, 1] for sphere–sphere contacts; 1 is elastic
    /// μ in [0, 1] for sphere–sphere contacts, by Coulomb's law: their relative tangential
    /// speed loses at most μ times the change a contact makes to their normal speed (0: none).
    double friction = 0.0;
    /// m/s: a contact whose outgoing normal speed is below this comes to rest (speed 0) instead
    /// of bouncing again. Unset: twice the normal speed the body's own acceleration adds in
    /// one step (2·|Δv·n|), which is zero without forces, so a gas stays exactly elastic.
    std::optional<double> rest_speed;
    /// Discrete mode under forces: bodies at rest sleep (world.hpp, sleeping). An island of
    /// bodies touching each other, carried by something static, falls asleep once every one
    /// of them has been slower than sleep_speed for sleep_time; asleep, its bodies keep v = 0
    /// and x exactly and cost a step nothing, until a command or an awake body touches them.
    bool sleep = true;
    double sleep_speed = 0.05; ///< m/s, > 0
    double sleep_time = 0.5;   ///< s, >= 0
    int velocity_iterations = 4; ///< discrete mode: momentum-exchange passes over contacts at most
    int position_iterations = 4; ///< discrete mode: separation passes over overlapping pairs
    /// Discrete mode: the share of r_a + r_b by which two spheres may overlap before the
    /// position passes push them apart (Box2D's linear slop, Jolt's penetration slop), in
    /// [0, 0.1]. 0 pushes every overlap out to the rounding of the coordinates. Under gravity
    /// a resting contact closes by the support solve's tolerance every step (about 1e-9 m
    /// for a 0.05 m sphere); chased to rounding, that kept every pass moving most of a pile.
    double position_slop = 0.0;
    /// Discrete mode under forces: sweeps of each sphere's solve against its supports at most
    /// (velocity_passes.cpp), in [1, 64]. Warm-started from the last step, a pile at rest needs
    /// one; a sphere wedged between others takes every one it is given.
    int support_sweeps = 16;
    /// Continuous mode: events handled per step at most; past it the step finishes in
    /// discrete mode and the step is counted in collision_stats::capped_steps.
    std::uint64_t max_events_per_step = 100'000;
    /// Continuous mode: events one body may take part in per step; past it the step finishes
    /// as at max_events_per_step. A light sphere squeezed between a wall and a much heavier
    /// one collides about π·√(M/m) times before the heavy one turns, ever faster, and at
    /// such speeds its swept box covers every body, so each of its events re-predicts them
    /// all: this bound keeps that case to a bounded cost instead of the whole step's cap.
    std::uint64_t max_events_per_body = 1'000;
    /// Continuous mode in a world without forces or boxes, inside a closed box of walls (a
    /// gas): keep predicted events from step to step (continuous/calendar.hpp) rather than
    /// predict every pair afresh each step. The same physics, exact either way, at a fraction
    /// of the cost; results differ in the last bits. Off: every step by the step-by-step
    /// loop, whose results its tests pin bit for bit.
    bool event_calendar = true;
    /// Discrete mode: bodies that move farther than sweep_fraction of their radius in a step
    /// are swept: their paths, and those of the spheres near them, are taken through the
    /// continuous mode's events in time order, against walls, boxes and spheres, before the
    /// overlaps of the step are answered; every other body stays on the discrete path. Off,
    /// such a body may pass through a sphere or a box, and is counted in
    /// collision_stats::unswept_fast_bodies.
    bool sweep = true;
    /// The share of its radius a body must move in a step to be swept, in (0, 1]. Below a
    /// radius per step, two spheres that meet head on end the step overlapping by less than
    /// the sum of their radii, their centres not yet past each other: the discrete step finds
    /// them and answers them along the right normal. Above it they may pass through.
    double sweep_fraction = 1.0;
};

/// Counters since the world was made.
struct collision_stats
{
    std::uint64_t sphere_contacts = 0;   ///< sphere–sphere responses
    std::uint64_t wall_contacts = 0;     ///< sphere–wall responses
    std::uint64_t obstacle_contacts = 0; ///< sphere–box responses
    std::uint64_t capped_steps = 0;      ///< continuous steps (or discrete sweeps) that hit an event cap
    std::uint64_t events = 0;            ///< continuous-mode events processed (the sweep's too)
    /// Continuous mode by halves (continuous/calendar.hpp): the rounds in which the two lanes
    /// took their events up to the next seam event, and the events a lane took past a seam
    /// event found late, undone and taken again (not in `events` twice)
    std::uint64_t rounds = 0;
    std::uint64_t events_undone = 0;
    /// Discrete mode: bodies that moved farther than sweep_fraction of their radius in a step
    /// and were swept (once per body and step)
    std::uint64_t swept_bodies = 0;
    /// Discrete mode: bodies that moved that far and were not swept, or not to the end, each
    /// a contact that may have been missed (a sphere passed through): the sweep off, its
    /// events capped (then capped_steps counts the step too), or a path not finite. Zero
    /// while the sweep is on and nothing was capped.
    std::uint64_t unswept_fast_bodies = 0;

    std::uint64_t contacts() const { return sphere_contacts + wall_contacts + obstacle_contacts; }
};

/// The bodies' state around one collision step: where they were at its start (x0, v0) and
/// where free motion took them (x, v, updated in place by the resolution).
struct collision_bodies
{
    std::span<vec3> x;
    std::span<vec3> v;
    std::span<vec3 const> x0;
    std::span<vec3 const> v0;
    std::span<double const> inverse_mass;
    std::span<double const> radius;
    /// False when free motion was a drift (a scene without forces): no velocity changed, so
    /// no body accelerated, and v0 may be v itself (read only before v is written).
    bool accelerated = true;
    /// Without forces: free motion is still to come, a drift x += h·v of every body, which
    /// discrete mode's first pass over the bodies makes on its way and continuous mode's paths
    /// make (x is then the step's start; x0 and v0 are not read). Requires accelerated = false.
    bool drift_pending = false;
    /// Each body's id, by slot (or none): discrete mode under forces finds last step's
    /// support stops by them (discrete/stop_table.hpp), whatever slot each body is in now.
    std::span<body_id const> ids = {};
    /// The slots' layout (body_storage::layout), or 0 when not known: the continuous mode's
    /// calendar keeps what it predicted only while it stays the same.
    std::uint64_t layout = 0;
};

/// Scratch space reused across steps.
class collision_workspace
{
public:
    discrete_workspace discrete;       ///< discrete mode's
    continuous::workspace continuous;  ///< continuous mode's
    /// A sphere filed by its centre for max_overlap(): its cell's key and its body slot.
    struct filed_centre
    {
        std::uint64_t key;
        std::uint32_t slot;
    };
    std::vector<filed_centre> filed; ///< max_overlap()'s spheres, by cell
    // max_overlap()'s broadphase, for coordinates its cells cannot number:
    broadphase_workspace broadphase;
    std::vector<aabb> boxes;
    std::vector<std::uint32_t> members; ///< body slot of each box
    std::vector<box_pair> pairs;
};

/// Resolves the contacts of one step of length h in the given mode (not `off`), timing its
/// phases into `timings`. Discrete mode runs its loops over bodies and slabs through `loops`
/// when given one; the result is the same bits with or without it.
void resolve_collisions(collision_settings const& settings, std::span<wall const> walls,
                        std::span<obstacle const> obstacles, collision_bodies const& bodies,
                        double h, collision_workspace& workspace, collision_stats& stats,
                        step_timings& timings, parallel_for* loops = nullptr);

/// The continuous mode's step over `bodies` alone (continuous/event_loop.cpp): every contact
/// in time order along their paths, then each body at the end of the step; past an event cap,
/// the step finished in discrete mode (in workspace.discrete) and counted in capped_steps.
/// No sphere is left inside a wall (clamp_to_walls, or the calendar's own clamp of the
/// spheres beside the walls).
void resolve_continuous(collision_settings const& settings, std::span<wall const> walls,
                        std::span<obstacle const> obstacles, collision_bodies const& bodies,
                        double h, collision_workspace& workspace, collision_stats& stats, parallel_for* loops);

/// Pushes every sphere out of every wall it is inside and removes its velocity into the wall:
/// the guarantee that no step leaves a position inside a wall.
void clamp_to_walls(std::span<wall const> walls, collision_bodies const& bodies);

/// The deepest overlap between any two spheres or a sphere and a wall or box (m, >= 0).
double max_overlap(std::span<wall const> walls, std::span<obstacle const> obstacles,
                   std::span<vec3 const> x, std::span<double const> radius,
                   collision_workspace& workspace);

} // namespace kugel::physics
