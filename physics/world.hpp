#pragma once

#include "body_storage.hpp"
#include "collisions.hpp"
#include "contact_events.hpp"
#include "forces.hpp"
#include "integrators.hpp"
#include "parallel_for.hpp"
#include "sensors.hpp"

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <utility>
#include <vector>

namespace kugel::physics {

struct world_settings
{
    integrator_kind integrator = integrator_kind::velocity_verlet;
    int substeps = 1; ///< >= 1: step(dt) runs this many integrator steps of dt/substeps
    step_control adaptive; ///< the adaptive integrator's tolerance and step cap (dormand_prince)
    collision_settings collisions;
};

/// The simulated world: bodies, the force models its scene named, and the integrator.
/// Free of I/O and of threads of its own; whoever owns it (a room, a headless run) drives
/// step(), and may lend it a parallel_for for its hot loops.
class world
{
public:
    explicit world(world_settings settings = {});

    /// Throws std::invalid_argument on a body the storage refuses (see body_storage::add).
    /// Wakes the sleeping bodies it touches.
    body_id add_body(body_desc const& desc);
    /// Room for n bodies in all, so that adding that many moves no storage (a large scene's
    /// bodies, added one at a time, would otherwise double every column on the way).
    void reserve(std::size_t n) { bodies_.reserve(n); }
    /// False when the id names no live body. Wakes its island and the sleeping bodies it
    /// touched (what it carried).
    bool remove_body(body_id id);

    /// Sleeping (discrete mode under forces, collision_settings::sleep): whether the body in
    /// this slot is asleep. A sleeping body has v = 0 exactly and keeps its x; free motion
    /// skips it and contacts take it as static. It wakes, with every body of its island, when
    /// an awake body touches it, when a command changes it (apply_impulse) or a body near it
    /// (add_body, remove_body), or when the world's forces, walls or boxes change.
    bool asleep(std::size_t slot) const { return sleep_columns_ && island_of_[slot] != awake; }
    /// Bodies asleep now.
    std::size_t sleeping_bodies() const { return sleeping_; }
    /// Wakes every sleeping body.
    void wake_all();

    /// Adds J/m to a dynamic body's velocity (lecture: F = m·a, integrated over the impulse),
    /// waking it (and its island) when asleep. False when the id names no live body; a static
    /// body ignores impulses.
    bool apply_impulse(body_id id, vec3 const& impulse);
    /// Sets a body's position and/or velocity (what is not given stays), waking it (and its
    /// island) when asleep, and the sleepers it touched where it was and touches where it is
    /// now (as remove_body and add_body do). False when the id names no live body; throws
    /// std::invalid_argument for a value that is not finite, or a velocity other than zero
    /// for a static body. The caller checks where the body may go (walls, other spheres).
    bool set_state(body_id id, std::optional<vec3> const& position, std::optional<vec3> const& velocity);

    void add_force(std::unique_ptr<force_model> model);

    /// Lends the world a parallel_for for the loops of discrete collisions and of keeping the
    /// step's start (nullptr: every loop on the calling thread), used while the world holds
    /// at least `from_bodies` bodies: below that, waking other threads for each loop costs
    /// more than it saves. Not owned: it must outlive every step() that uses it. Results are
    /// the same bits with or without it.
    void set_parallel_for(parallel_for* loops, std::size_t from_bodies = bodies_worth_sharing)
    {
        loops_ = loops;
        share_from_ = from_bodies;
    }

    /// Where a lent parallel_for starts to pay: below it, the hand-overs of a step's loops
    /// cost more than the second thread saves (bench/README.md, decisions).
    static constexpr std::size_t bodies_worth_sharing = 16 * 1024;

    /// Static geometry that spheres collide with (when collisions are on). Throws
    /// std::invalid_argument for damping or friction outside [0, 1].
    void add_wall(wall const& w);
    void add_obstacle(obstacle const& o);

    /// Adds a sensor (sensors.hpp) and returns its index; throws std::invalid_argument for one
    /// sensor::invalid() refuses. The bodies already inside it enter it in the next step.
    std::uint32_t add_sensor(sensor const& s);
    std::span<sensor const> sensors() const { return sensors_; }
    /// The bodies entering and leaving sensors in the last step(), by time (then sensor, then
    /// body id). Empty in a world without sensors.
    std::span<sensor_event const> sensor_events() const { return sensor_events_; }
    /// The bodies in sensor `index` after the last step, by id; a body added or removed since
    /// is counted from the next step (a removed body leaves no event).
    std::span<body_id const> bodies_in_sensor(std::uint32_t index) const { return inside_[index]; }

    /// Contact events (contact_events.hpp): whether the world tells when this body begins to
    /// touch another it reports. False when the id names no live body. A world that reports
    /// no body does no work for it; one that does takes a force-free gas through the
    /// step-by-step loop rather than the calendar (continuous/calendar.hpp): exact either way,
    /// the last bits differ.
    bool report_contacts(body_id id, bool on);
    bool reports_contacts(body_id id) const
    {
        return id.index < reports_.size() && reports_[id.index] != 0 && bodies_.contains(id);
    }
    /// The contacts that began in the last step() between two reported bodies, by time (then
    /// by a, then b). Empty in a world that reports no body.
    std::span<contact_event const> contact_events() const { return contact_events_; }

    /// Advances the world by dt seconds (dt finite and >= 0, else std::invalid_argument).
    /// Throws singular_force_error when a force is singular, and step_control_error when the
    /// adaptive integrator cannot meet its tolerance; the world is then unchanged (with
    /// substeps too: a failing substep undoes those before it).
    /// A world of bodies_worth_sorting bodies or more in discrete mode also moves its bodies
    /// to new slots on every sort_interval-th step (ids stay; see bodies_worth_sorting).
    void step(double dt);

    /// From this many bodies, a world in discrete mode keeps its bodies' slots in the
    /// collision grid's cell order (sphere_grid.hpp), sorting them again on every
    /// sort_interval-th step (the first included): the discrete step then reads and writes the
    /// bodies nearly in sequence, where slots in no order sent it to memory for nearly every
    /// sphere. From about this many the bodies outgrow a core's own cache (bench/README.md,
    /// decisions).
    static constexpr std::size_t bodies_worth_sorting = 64 * 1024;
    /// The order decays slowly, as spheres move a fraction of a cell per step.
    static constexpr std::uint64_t sort_interval = 16;

    /// The accelerations of all bodies at positions x (what the integrator calls).
    void accelerations(std::span<vec3 const> x, std::span<vec3> a) const;

    body_storage const& bodies() const { return bodies_; }
    std::span<std::unique_ptr<force_model> const> forces() const { return forces_; }
    std::span<wall const> walls() const { return walls_; }
    std::span<obstacle const> obstacles() const { return obstacles_; }
    collision_stats const& collisions() const { return collision_stats_; }

    /// The deepest overlap left between spheres, or a sphere and a wall or box (m).
    double max_overlap() const;

    /// Frees what the collision modes keep from step to step for speed alone (the continuous
    /// calendar, the discrete grid and support stops): at a run's end, before its summary.
    /// A later step builds them again, with the same contacts; its bits may differ as after
    /// a checkpoint (a force-free continuous world's calendar starts afresh, the discrete
    /// solver starts cold).
    void release_collision_memory() { collision_workspace_ = collision_workspace{}; }
    /// The bodies whose position or velocity is no longer finite (a step overflowed), in
    /// slot order.
    std::vector<body_id> non_finite_bodies() const;
    /// Why adding `desc` would give a force beyond `limits` (force_model::check_addition of
    /// each model the world holds); nothing when it would not.
    std::optional<addition_refusal> check_addition(body_desc const& desc, addition_limits const& limits) const;
    /// Dynamic spheres whose centre is behind a wall: they got out.
    std::size_t escaped() const;
    world_settings const& settings() const { return settings_; }

    double time() const { return time_; }                ///< s since the start
    std::uint64_t steps() const { return steps_; }        ///< calls to step()
    std::uint64_t force_evaluations() const { return force_evaluations_; }
    /// The steps the adaptive integrator took inside the world's steps (all zero for the
    /// others).
    adaptive_steps const& integration_steps() const { return workspace_.steps(); }
    /// The rounding the compensated sum of time still owes (s); saved with a checkpoint.
    double time_compensation() const { return time_compensation_; }
    /// Sets the clock a checkpoint recorded, so a restored world continues the same sum of
    /// dt's and step count. Throws std::invalid_argument for a non-finite or negative time.
    void restore_clock(double time, double time_compensation, std::uint64_t steps);

    /// True when every force named is constant (or none is): the exact integrator is exact.
    bool forces_are_constant() const;

    /// Seconds spent in each phase of the steps since the world was made, while timed.
    step_timings const& timings() const { return timings_; }
    /// Turns the timing of each phase on (what a room and a headless run report) or off (the
    /// default: a step then reads no clock).
    void time_phases(bool on) { timings_.on = on; }

private:
    void substeps(double dt); ///< what step(dt) does but advance the clock
    /// Free motion over h: the integrator, which evaluates the forces where its method needs
    /// them; without forces, the drift x += h·v.
    void move_freely(double h);
    /// x += h·v for every body, keeping x₀ in `start` on the way unless it is empty.
    void drift(double h, std::span<vec3> start);
    /// x₀, v₀ (where the collision modes find each body's path to start), then free motion.
    void keep_start_and_move_freely(double h);
    /// The contacts of a substep of length h in the scene's mode; drift_pending: discrete
    /// mode makes the drift itself (collision_bodies::drift_pending).
    void collide(double h, bool drift_pending);
    /// Moves the bodies into the last collision step's cell order (bodies_worth_sorting).
    void sort_bodies_by_cell();

    // Sensors (world_sensors.cpp)
    /// Before a substep in a world with sensors: where each body starts, and in continuous
    /// mode the contacts' paths kept for follow_sensors().
    void keep_sensor_start();
    /// After a substep of length h that started at world time `start`: the events of every
    /// body's path through every sensor.
    void follow_sensors(double h, double start);

    // Contact events (world_contacts.cpp)
    /// Before a substep's collisions: whether the collision modes note their pairs' touches.
    void keep_touches();
    /// After a substep's collisions, which started at world time `start` and took h: the
    /// contacts that began.
    void note_touches(double h, double start);
    /// A removed body's contacts end.
    void forget_contacts(body_id id);

    // Sleeping (world_sleep.cpp)
    static constexpr std::uint32_t awake = 0; ///< island_of_ of an awake body
    /// Whether this step puts bodies to sleep and keeps sleepers still: discrete mode, under
    /// forces, sleep on.
    bool sleeping_applies() const;
    /// The contacts of a discrete step with sleepers: free motion for the awake bodies only,
    /// then the collision step over them and the sleeping or static spheres near them, which
    /// it takes as static.
    void move_and_collide_around_sleepers(double h);
    /// After a substep's collisions: links the awake bodies its contacts join into islands,
    /// notes which touch something static, and wakes the sleepers an awake body touched.
    void note_contacts();
    /// After a step: the calm time of each awake body, and the islands that fall asleep.
    void fall_asleep(double dt);
    void wake_island(std::uint32_t island);
    /// Wakes the islands of the sleeping spheres within reach of a sphere at x of radius r.
    void wake_near(vec3 const& x, double r);
    std::uint32_t find_root(std::uint32_t slot);

    world_settings settings_;
    body_storage bodies_;
    std::vector<std::unique_ptr<force_model>> forces_;
    std::vector<wall> walls_;
    std::vector<obstacle> obstacles_;
    integrator_workspace workspace_;
    mutable collision_workspace collision_workspace_;
    collision_stats collision_stats_;
    step_timings timings_;
    std::vector<vec3> step_start_x_, step_start_v_;
    /// x, v before a step of several substeps with forces, restored should one fail (kept
    /// from step to step, so the step allocates nothing once they have grown)
    std::vector<vec3> undo_x_, undo_v_;
    std::vector<std::uint32_t> cell_order_; ///< scratch for sort_bodies_by_cell()
    std::vector<sensor> sensors_;
    std::vector<std::vector<body_id>> inside_; ///< by sensor: the bodies in it, by id
    std::vector<sensor_event> sensor_events_;  ///< of the last step
    std::vector<vec3> sensor_x0_, sensor_v0_;  ///< each body at the substep's start
    std::vector<std::uint8_t> held_;           ///< scratch: by id index, some sensor held the body
    // Contact events, by body id index: whether the body is reported (cleared on removal)
    std::vector<std::uint8_t> reports_;
    std::size_t reporting_ = 0;                ///< bodies reported
    /// The reported pairs touching after the last substep, a before b, sorted
    std::vector<std::pair<body_id, body_id>> touching_;
    std::vector<std::pair<body_id, body_id>> touching_next_; ///< note_touches' list being made
    std::vector<contact_event> contact_events_; ///< of the last step
    std::vector<contact_event> touches_;        ///< scratch: a substep's touches, as events
    // Sleeping, by slot (moved with the bodies by remove_body and sort_bodies_by_cell), kept
    // from the first step sleeping applies to: a world that never sleeps (a gas, any
    // continuous world) does without them, 12 bytes a body
    bool sleep_columns_ = false;
    std::vector<double> calm_;              ///< s the body has been slower than sleep_speed
    std::vector<std::uint32_t> island_of_;  ///< its sleeping island's number, or awake
    /// The bodies of each sleeping island, by number − 1 (empty: the number is free)
    std::vector<std::vector<body_id>> sleeping_islands_;
    std::vector<std::uint32_t> free_islands_; ///< numbers to reuse
    std::size_t sleeping_ = 0;              ///< bodies asleep
    // A step's islands of awake bodies (union–find by slot), and what they touch
    std::vector<std::uint32_t> parent_;
    std::vector<std::uint8_t> grounded_;    ///< by root: touches a wall, a box or a static sphere
    std::vector<std::uint8_t> held_awake_;  ///< by root: touched a sleeper, which wakes
    std::vector<double> island_calm_;       ///< by root: the least calm time of its bodies
    std::vector<std::uint32_t> to_wake_;
    // The collision step around sleepers: the bodies it sees, by slot, and their copies
    std::vector<std::uint32_t> active_;
    bool gathered_ = false; ///< the last collision step saw active_, not every body
    std::vector<vec3> active_x_, active_v_, active_x0_, active_v0_;
    std::vector<double> active_inverse_mass_, active_radius_;
    std::vector<body_id> active_ids_;
    parallel_for* loops_ = nullptr; ///< lent by the owner, or none
    std::size_t share_from_ = bodies_worth_sharing; ///< loops_ is used from this many bodies
    /// loops_ when the world holds enough bodies for it to pay, else none.
    parallel_for* loops() const { return bodies_.size() >= share_from_ ? loops_ : nullptr; }
    double time_ = 0.0;
    double time_compensation_ = 0.0; ///< rounding lost from time_, fed back into the next sum
    std::uint64_t steps_ = 0;
    mutable std::uint64_t force_evaluations_ = 0;
};

} // namespace kugel::physics
