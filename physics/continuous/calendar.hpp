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
// With threads lent and a gas large enough, the box is cut in two halves across x by a
// layer of cells, the seam, and each half has a lane of its own: its queue, and a thread
// that takes the events of its spheres (they write only the half's cells, and read those
// beside them, the half's and the seam's, which nothing writes in a round). The events of
// the seam's spheres wait in a queue of their own and are taken between rounds, on one
// thread. A round takes every lane's events before the next
// seam event, the two lanes at once. A lane that meets a seam event earlier than that (one
// it predicted in the round, or one whose spheres are not its own) says so, and the other
// lane's events after it are undone: their spheres' paths and cells put back, and predicted
// again. Events are taken in the same order as on one thread, so the result is the same
// bits for any number of threads.
//
// The physics is the step-by-step loop's (the same times of impact, touching tolerance and
// contact rules); results differ from it in the last bits, since a path is kept from its last
// change instead of from each step's start.

#include "physics/continuous/event.hpp"
#include "physics/continuous/event_lists.hpp"
#include "physics/vec.hpp"

#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <mutex>
#include <span>
#include <vector>

namespace kugel::physics {
struct collision_settings;
struct collision_stats;
struct collision_bodies;
struct wall;
class parallel_for;
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
    /// afresh); b.x and b.v receive its end. Declined, it leaves b as it was. With `loops`
    /// (and a gas large enough), the halves' lanes take their events on two threads (above).
    outcome step(collision_settings const& settings, std::span<wall const> walls, collision_bodies const& b,
                 double h, collision_stats& stats, parallel_for* loops = nullptr);

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
        std::uint32_t version; ///< read and written atomically: a lane may read another's
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

    /// Events waiting, by time. The events of the slice (bucket) opened last, as it was
    /// opened: sorted, the earliest last. The events filed since into the slices opened so
    /// far: a min-heap by operator>. Later events, filed unsorted by the slice (`bucket_` s
    /// long) they fall in: the next `later.size()` slices' in a ring, the rest in `latest`.
    /// The next slice is taken, sorted, when the last one taken and the heap have run empty,
    /// and every ring's turn `latest` is filed again; stale events are dropped on the way.
    /// So the heap holds few events, and a push costs a heap's log only for events due very
    /// soon. (A slice sorted once costs fewer instructions than the same events popped one by
    /// one from a heap: 5 % of a step.) The lists share one pool of blocks.
    struct queue
    {
        std::vector<event> opened_events;
        std::vector<event> heap;
        event_lists lists;
        std::vector<event_lists::list> later;
        event_lists::list latest = event_lists::empty;
        std::int64_t opened = 0; ///< the last slice taken
    };

    /// Which part of the box a cell lies in, by its x: a half (0, 1), or the seam between
    /// them (2), one layer of cells. An event of a half's spheres writes only their cells and
    /// reads those beside them: the half's own cells and the seam's, which neither half writes.
    static constexpr int seam = 2;
    /// Who takes events: one lane for the whole box (`whole`), or a half's lane, or the
    /// seam's hand between rounds.
    static constexpr int whole = -1;

    /// An event a lane took in a round, and what undoing it puts back.
    struct taken
    {
        event e;
        vec3 x[2], v[2];
        double since[2];
        std::array<std::uint16_t, 3> cell;
        std::uint8_t contact; ///< it counted a contact (sphere or wall)
    };

    /// What takes events: its queue, its clock and scratch, what it counted; in a round, the
    /// events it files for others and what it took.
    struct alignas(128) lane
    {
        int part = whole; ///< whole, a half (0, 1) or the seam
        queue q;
        double now = 0.0; ///< the event being handled, or the step's start
        std::vector<std::uint32_t> near; ///< scratch: the spheres of the cells around one
        std::uint64_t events = 0, contacts = 0, sphere_contacts = 0, wall_contacts = 0;
        std::vector<event> for_other, for_seam; ///< filed in a round, for the serial part
        std::vector<taken> log;
        event furthest{}; ///< the last in order of the events in the log
    };

    bool fits(std::span<wall const> walls, collision_bodies const& b);
    void build(collision_bodies const& b);
    /// Paths a command changed, on the lent threads: whether they were few enough to follow.
    bool notice_changes(collision_bodies const& b, parallel_for* loops);
    /// b.x and b.v at time `at`, on the lent threads; with `clamp`, no sphere left inside a wall.
    void write_positions(collision_bodies const& b, double at, bool clamp, parallel_for* loops) const;

    vec3 position(std::uint32_t i, double t) const
    {
        sphere const& s = spheres_[i];
        return s.x + (t - s.since) * s.v;
    }
    std::uint32_t version_of(std::uint32_t i) const
    {
        return std::atomic_ref(const_cast<std::uint32_t&>(spheres_[i].version)).load(std::memory_order_relaxed);
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
    std::uint32_t cell_x_of(double x) const;
    /// A cell at one of the box's sides, the only cells from which a sphere can reach a wall.
    bool at_a_side(cell_coordinates const& c) const
    {
        return c[0] == 0U || c[1] == 0U || c[2] == 0U || c[0] + 1U == dims_[0] || c[1] + 1U == dims_[1] ||
               c[2] + 1U == dims_[2];
    }
    /// The part of the box (a half or the seam) of cells at x.
    int part_of(std::uint32_t x) const { return x < cut_ ? 0 : x > cut_ ? 1 : seam; }
    /// The part of sphere i's cell; read atomically, since another lane may move it.
    int part_of_sphere(std::uint32_t i) const
    {
        return part_of(std::atomic_ref(const_cast<std::uint16_t&>(cell_[i][0])).load(std::memory_order_relaxed));
    }
    /// The x of the cell a crossing along x takes its sphere into.
    std::uint32_t x_crossed_into(event const& e) const
    {
        std::uint32_t const x = cell_[e.body][0];
        return (e.other() & 1U) != 0U ? x + 1U : x - 1U;
    }
    /// The part an event falls in, from its spheres' cells at its time.
    int part_of_event(event const& e) const;
    void link(std::uint32_t i);
    void unlink(std::uint32_t i);
    template <class F>
    void for_each_in_cells(lane& w, std::array<std::uint32_t, 3> const& lo, std::array<std::uint32_t, 3> const& hi,
                           F f);

    void push(lane& w, double time, event_kind kind, std::uint32_t body, std::uint32_t other);
    std::int64_t bucket_of(double time) const { return static_cast<std::int64_t>(std::floor(time / bucket_)); }
    void file(queue& q, event const& e);
    /// The seam's event: into the seam's heap.
    void file_seam(event const& e);
    /// Takes the next slice's current events, sorted, into q.opened_events.
    void open_slice(queue& q);
    /// The next event of q before the step's last slice ends, or nullptr.
    event const* peek(queue& q, std::int64_t last);
    event pop(queue& q);
    bool current(event const& e) const;
    void predict_pair(lane& w, std::uint32_t i, std::uint32_t j);
    /// The first wall i reaches of those beside its cell (only on `only_axis`, if not −1).
    void predict_walls(lane& w, std::uint32_t i, int only_axis = -1);
    void predict_crossing(lane& w, std::uint32_t i);
    /// After i's path changed: its walls, its crossing and its neighbours but `except`.
    void predict_body(lane& w, std::uint32_t i, std::uint32_t except);

    void handle_pair(lane& w, event const& e);
    void handle_wall(lane& w, event const& e);
    void handle_crossing(lane& w, event const& e);

    /// The step's events on one lane: whether a cap was reached.
    bool take_whole(double end);
    /// A current event taken by w alone, counted against the step's caps: whether one was
    /// reached (the event then not taken).
    bool take_one(lane& w, event const& e);
    /// The step's events by halves, their lanes on two threads if `helper` (else one after
    /// the other): whether a cap was reached.
    bool take_by_halves(double end, parallel_for* loops);
    /// One round: each half's lane takes its events before `bound` (or a seam event found
    /// earlier); events after the earliest such are undone.
    void round(event const& bound, std::uint64_t budget, bool two_threads);
    /// A half's lane in a round: its events before the bound, `budget` contacts at most.
    void take_lane(lane& w, std::uint64_t budget);
    /// An event lane w cannot take itself: for the seam's hand, and the round's bound.
    void hand_over(lane& w, event const& e);
    /// Events the lanes took after `bound` put back, their spheres predicted again.
    void undo_after(event const& bound);
    /// Files every waiting event again, for one lane or for halves.
    void refile(bool halves);
    /// The events the lanes filed in a round for another lane or the seam, filed.
    void file_handed();

    // Set per step.
    collision_settings const* settings_ = nullptr;
    std::span<wall const> walls_;
    double h_ = 0.0;
    std::int64_t last_ = 0; ///< the step's last slice

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
    std::vector<std::vector<std::uint32_t>> changed_in_; ///< scratch: changed_ by chunk of spheres
    std::vector<event> refiled_;          ///< scratch: events on their way between lanes

    // The lanes: lanes_[0] alone for the whole box; by halves, lanes_[0] and [1] for the
    // halves and seam_hand_ between rounds, with the seam's events in seam_ (a min-heap).
    bool halves_ = false;
    std::uint32_t cut_ = 0; ///< the seam's cells along x
    std::array<lane, 2> lanes_;
    lane seam_hand_;
    std::vector<event> seam_;
    std::uint64_t contacts_ = 0; ///< contacts in this step so far, for the step's cap
    std::vector<std::uint32_t> undone_spheres_; ///< scratch
    /// The round's bound: the earliest event a lane has handed over, or the next seam event.
    /// Its time is read on every event; the event itself, on a tie in time, under the lock.
    /// Set afresh by every round: a calendar moved between steps moves none of it.
    struct alignas(128) signals
    {
        std::atomic<double> bound_time{0.0};
        alignas(64) std::mutex lock;
        event bound{};
        alignas(64) std::atomic<int> mail{0}; ///< the helper's round: 0 idle, 1 posted, 2 done, 3 stop
        std::atomic<int> arrived{0};
        std::atomic<bool> helping{false};
        std::uint64_t budget = 0;
        signals() = default;
        signals(signals&&) noexcept {}
        signals& operator=(signals&&) noexcept { return *this; }
    };
    signals signals_;
    std::uint64_t rounds_ = 0, undone_ = 0; ///< this step's (collision_stats)

    double bucket_ = 1.0;
    vec3 lo_ = vec3::Zero();
    vec3 width_ = vec3::Ones(), inverse_width_ = vec3::Ones();
    std::array<std::uint32_t, 3> dims_{1, 1, 1};
};

} // namespace kugel::physics::continuous
