#pragma once

// The continuous mode across steps, for a world whose spheres fly straight between contacts
// (no forces) inside a closed box of walls: a gas. The step-by-step loop (event_loop.cpp)
// starts every step afresh and so predicts every pair of neighbours every step, although in
// a gas a sphere meets another only every few dozen steps. The calendar keeps what it
// predicted, as event-driven molecular dynamics codes (DynamO, Rapaport's) do: each sphere's
// path is kept from its last contact, each pair of neighbours is predicted once, when one of
// them changes path or they become neighbours, and a step takes only the events due in it.
//
// Spheres are filed by centre in cells at least a diameter wide, and each sphere's crossing
// into the next cell is an event like a contact (it changes no path): two spheres that touch
// are always in the same or neighbouring cells, so a sphere's contacts are predicted against
// the 27 cells around it when its path changes, and against the 9 cells that come into reach
// when it crosses a face. A step costs its events plus one pass over the spheres (to notice
// what a command changed, and to write their positions at the step's end).
//
// The physics is the step-by-step loop's (the same times of impact, touching tolerance and
// contact rules); results differ from it in the last bits, since a path is kept from its last
// change instead of from each step's start.

#include "physics/continuous/event.hpp"
#include "physics/continuous/event_lists.hpp"
#include "physics/vec.hpp"

#include <array>
#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

namespace kugel::physics {
struct collision_settings;
struct collision_stats;
struct collision_bodies;
struct wall;
} // namespace kugel::physics

namespace kugel::physics::continuous {

class calendar
{
public:
    enum class outcome {
        declined, ///< not a world the calendar takes (forces, boxes, open walls): nothing done
        done,     ///< the step is taken: b.x and b.v hold its end, no sphere inside a wall
        capped,   ///< an event cap was reached: b.x and b.v hold every path moved to the step's end
    };

    /// One step of h seconds. b.x0 and b.v0 hold the step's start, or b.x and b.v with
    /// b.drift_pending (a command may have changed any body since the last step: those are
    /// noticed and predicted again; bodies added, removed or reordered start the calendar
    /// afresh); b.x and b.v receive its end. Declined, it leaves b as it was.
    outcome step(collision_settings const& settings, std::span<wall const> walls, collision_bodies const& b,
                 double h, collision_stats& stats);

    /// The next step starts afresh.
    void forget() { built_ = false; }

private:
    /// A sphere as the calendar keeps it: its path from its last change, x(t) = x + v·(t −
    /// since), that path's version (events predicted from an older one are stale), and the
    /// next sphere in its cell's list. One cache line: what a prediction reads of a neighbour.
    struct sphere
    {
        vec3 x;
        vec3 v;
        double since;
        std::uint32_t version;
        std::uint32_t next;
    };
    struct shape
    {
        double radius;
        double inverse_mass;
    };
    /// A wall whose normal is ±e_axis.
    struct side
    {
        int axis;
        bool positive; ///< normal +e_axis: the wall is below the spheres on that axis
    };

    static constexpr std::uint32_t none = 0xffffffffU;

    bool fits(std::span<wall const> walls, collision_bodies const& b);
    void build(collision_bodies const& b);
    bool notice_changes(collision_bodies const& b);
    /// b.x and b.v at time `at`; with `clamp`, no sphere left inside a wall.
    void write_positions(collision_bodies const& b, double at, bool clamp) const;

    vec3 position(std::uint32_t i, double t) const
    {
        sphere const& s = spheres_[i];
        return s.x + (t - s.since) * s.v;
    }
    void repath(std::uint32_t i, vec3 const& x, vec3 const& v, double t);
    /// A cell by its coordinates, at most `most_cells_on_an_axis` on each axis: 6 bytes.
    using cell_coordinates = std::array<std::uint16_t, 3>;
    static constexpr std::uint32_t most_cells_on_an_axis = 0xffffU;

    template <class T>
    std::uint32_t cell_index(std::array<T, 3> const& c) const
    {
        return c[0] + dims_[0] * (c[1] + dims_[1] * c[2]);
    }
    cell_coordinates cell_of(vec3 const& x) const;
    /// A cell at one of the box's sides, the only cells from which a sphere can reach a wall.
    bool at_a_side(cell_coordinates const& c) const
    {
        return c[0] == 0U || c[1] == 0U || c[2] == 0U || c[0] + 1U == dims_[0] || c[1] + 1U == dims_[1] ||
               c[2] + 1U == dims_[2];
    }
    void link(std::uint32_t i);
    void unlink(std::uint32_t i);
    template <class F>
    void for_each_in_cells(std::array<std::uint32_t, 3> const& lo, std::array<std::uint32_t, 3> const& hi, F f);

    void push(double time, event_kind kind, std::uint32_t body, std::uint32_t other);
    std::int64_t bucket_of(double time) const { return static_cast<std::int64_t>(std::floor(time / bucket_)); }
    void file(event const& e);
    /// Takes the next bucket's current events, sorted, into opened_events_.
    void open_bucket();
    bool current(event const& e) const;
    void predict_pair(std::uint32_t i, std::uint32_t j);
    /// The first wall i reaches of those beside its cell (only on `only_axis`, if not −1).
    void predict_walls(std::uint32_t i, int only_axis = -1);
    void predict_crossing(std::uint32_t i);
    /// After i's path changed: its walls, its crossing and its neighbours but `except`.
    void predict_body(std::uint32_t i, std::uint32_t except);

    void handle_pair(event const& e);
    void handle_wall(event const& e);
    void handle_crossing(event const& e);

    // Set per step.
    collision_settings const* settings_ = nullptr;
    std::span<wall const> walls_;
    collision_stats* stats_ = nullptr;
    double h_ = 0.0;
    double now_ = 0.0; ///< the event being handled, or the step's start

    bool built_ = false;
    double clock_ = 0.0; ///< s since the calendar was built, at the step's start
    std::vector<side> sides_;
    std::vector<std::array<double, 4>> planes_; ///< the walls it was built for (n, d), to notice a change
    std::uint64_t layout_ = 0;         ///< the slots' layout it was built for (body_storage::layout)
    // By the calendar's own numbering of the spheres, in cell order when it was built, so
    // that neighbours lie near each other in memory.
    std::vector<sphere> spheres_;
    std::vector<shape> shapes_; ///< by number, or one for all (shape_mask_ 0)
    std::uint32_t shape_mask_ = ~0U;
    shape const& shape_of(std::uint32_t i) const { return shapes_[i & shape_mask_]; }
    std::vector<std::uint32_t> slot_; ///< the world's slot of each
    std::vector<std::uint32_t> events_of_; ///< contacts in this step, for the per-body cap
    std::vector<cell_coordinates> cell_;
    std::vector<std::uint32_t> previous_; ///< the one before in its cell's list
    std::vector<std::uint32_t> head_;     ///< by cell: the first sphere of its list
    std::size_t members_ = 0;             ///< the world's spheres (bodies of radius > 0)
    std::vector<std::uint32_t> changed_;  ///< scratch: the paths a command changed
    std::vector<std::uint32_t> near_;     ///< scratch: the spheres of the cells around one
    /// The events of the bucket opened last, as it was opened: sorted, the earliest last.
    std::vector<event> opened_events_;
    /// The events filed since into the buckets opened so far: a min-heap by operator>.
    std::vector<event> queue_;
    /// Later events, filed unsorted by the bucket (a slice of a step, `bucket_` s long) they
    /// fall in: the next `later_.size()` buckets' in a ring, the rest in `latest_`. The next
    /// bucket is taken, sorted, when the last one taken and the queue have run empty, and
    /// every ring's turn `latest_` is filed again; stale events are dropped on the way. So
    /// the queue holds few events, and a push costs a heap's log only for events due very
    /// soon. (A bucket sorted once costs fewer instructions than the same events popped one
    /// by one from a heap: 5 % of a step.) The lists share one pool of blocks.
    event_lists lists_;
    std::vector<event_lists::list> later_;
    event_lists::list latest_ = event_lists::empty;
    double bucket_ = 1.0;
    std::int64_t opened_ = 0; ///< the last bucket taken
    vec3 lo_ = vec3::Zero();
    vec3 width_ = vec3::Ones(), inverse_width_ = vec3::Ones();
    std::array<std::uint32_t, 3> dims_{1, 1, 1};
};

} // namespace kugel::physics::continuous
