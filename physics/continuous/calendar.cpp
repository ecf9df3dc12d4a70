#include "physics/continuous/calendar.hpp"

#include "physics/collision_rules.hpp"
#include "physics/collisions.hpp"
#include "physics/continuous/touching.hpp"
#include "physics/parallel_for.hpp"
#include "physics/time_of_impact.hpp"
#include "physics/wall_set.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <thread>

namespace kugel::physics::continuous {

namespace {

constexpr double forever = std::numeric_limits<double>::infinity();

/// The calendar starts afresh before a step that would end later than this (s), so that its
/// clock, and with it every event time, stays as precise as a step's: at 16 s a time is
/// known to 4e-15 s.
constexpr double clock_span = 16.0;

/// The event calendar's buckets: so many a step that a bucket holds about this many events,
/// so that the queue (a heap) stays small, and a ring of them for this many steps. Events
/// come about twice as often as cell crossings. At speed 50 a bucket of a sixteenth of a
/// step held about 800, and the heap took 16 % of the step; 32 to 256 a bucket measured
/// the same within the noise (bench/README.md), fewer lists being the lighter.
constexpr double events_per_bucket = 128.0;
constexpr double steps_in_ring = 4.0;
constexpr double fewest_buckets_per_step = 16.0, most_buckets_per_step = 4096.0;

/// Cells are this much wider than the largest diameter, so that a centre filed in a cell a
/// rounding error off its true one still has every sphere it can touch in a neighbour.
constexpr double cell_margin = 1e-6;

/// Paths changed by commands in one step beyond which the calendar starts afresh instead.
constexpr std::size_t changes_worth_following(std::size_t members) { return members / 8 + 16; }

/// Spheres below which the box is not cut into halves (a step of a few thousand takes some
/// hundred microseconds, and each round's hand-over between threads a microsecond), and the
/// cells along x below which it is not (each half needs cells of its own beside the seam).
constexpr std::size_t fewest_for_halves = 2000;
constexpr std::uint32_t fewest_cells_for_halves = 8;

/// The helper's mail in a round.
enum mail : int { idle, posted, done, stop };

/// A pause in a thread's spin, while it waits for the other.
void pause()
{
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#else
    std::this_thread::yield();
#endif
}

/// After every event of a step that ends at `end`, before any later one.
event step_end(double end)
{
    return {end, event_kind::crossing, 0xffffffffU, event::most_indexed - 1U, 0, 0};
}

bool same(vec3 const& a, vec3 const& b) { return (a.array() == b.array()).all(); }

std::array<double, 4> plane_of(wall const& w)
{
    vec3 const& n = w.surface.normal;
    return {n.x(), n.y(), n.z(), w.surface.offset};
}

} // namespace

bool calendar::fits(std::span<wall const> walls, collision_bodies const& b)
{
    // Paths straight between contacts, and the slots' layout known from step to step.
    if (b.accelerated || b.layout == 0)
        return false;
    // A closed box: every wall faces along an axis, and each axis has both sides.
    sides_.clear();
    vec3 below = vec3::Constant(-forever), above = vec3::Constant(forever);
    for (wall const& w : walls) {
        vec3 const& n = w.surface.normal;
        Eigen::Index axis = 0;
        if (!(n.cwiseAbs().maxCoeff(&axis) == 1.0 && (n.array() == 0.0).count() == 2))
            return false;
        bool const positive = n[axis] > 0.0;
        sides_.push_back({static_cast<int>(axis), positive});
        if (positive)
            below[axis] = std::max(below[axis], w.surface.offset);
        else
            above[axis] = std::min(above[axis], -w.surface.offset);
    }
    if (!(below.array() < above.array()).all() || !below.allFinite() || !above.allFinite())
        return false;
    // Spheres of alike sizes, every centre inside the box: cells a largest diameter wide.
    members_ = 0;
    double largest = 0.0, total = 0.0;
    for (std::uint32_t i = 0; i < b.x0.size(); ++i) {
        double const r = b.radius[i];
        if (!(r > 0.0))
            continue;
        if (!((b.x0[i].array() >= below.array()).all() && (b.x0[i].array() <= above.array()).all()) ||
            !b.v0[i].allFinite())
            return false;
        ++members_;
        largest = std::max(largest, r);
        total += r;
    }
    if (members_ == 0 || largest > 4.0 * total / static_cast<double>(members_))
        return false;
    double reach = 2.0 * largest * (1.0 + cell_margin);
    vec3 const extent = above - below;
    // At most 8 cells a sphere (4 bytes each): a gas of fill 0.1 then gets cells of one
    // diameter (about 5 a sphere). With 4 its cells were 1.2 diameters wide, and each
    // prediction and crossing read more neighbours: 10⁴ spheres 1.81 → 1.72 ms a step,
    // speed 50 7.7 → 7.0 ms (bench/README.md). A dilute gas stops at 8 a sphere.
    double const most = 8.0 * static_cast<double>(members_) + 64.0;
    // (At most 65,535 on an axis, so that a cell's coordinates fit 6 bytes: a longer box
    // gets wider cells along it.)
    auto const cells_on = [&](int k) {
        return std::clamp(std::floor(extent[k] / reach), 1.0, static_cast<double>(most_cells_on_an_axis));
    };
    for (;;) {
        double cells = 1.0;
        for (int k = 0; k < 3; ++k)
            cells *= cells_on(k);
        if (cells <= most)
            break;
        reach *= std::max(std::cbrt(cells / most), 1.0 + 1e-6);
    }
    for (int k = 0; k < 3; ++k) {
        auto const a = static_cast<std::size_t>(k);
        double const count = cells_on(k);
        dims_[a] = static_cast<std::uint32_t>(count);
        width_[k] = extent[k] / count;
        inverse_width_[k] = 1.0 / width_[k];
    }
    lo_ = below;
    return true;
}

calendar::cell_coordinates calendar::cell_of(vec3 const& x) const
{
    cell_coordinates c{};
    for (int k = 0; k < 3; ++k) {
        auto const a = static_cast<std::size_t>(k);
        double const u = std::floor((x[k] - lo_[k]) * inverse_width_[k]);
        c[a] = static_cast<std::uint16_t>(u <= 0.0                                   ? 0U
                                          : u >= static_cast<double>(dims_[a] - 1U) ? dims_[a] - 1U
                                                                                   : static_cast<std::uint32_t>(u));
    }
    return c;
}

std::uint32_t calendar::cell_x_of(double x) const
{
    double const u = std::floor((x - lo_[0]) * inverse_width_[0]);
    return u <= 0.0 ? 0U : u >= static_cast<double>(dims_[0] - 1U) ? dims_[0] - 1U : static_cast<std::uint32_t>(u);
}

int calendar::part_of_event(event const& e) const
{
    std::uint32_t const i = e.body;
    auto const at = [&](std::uint32_t k) {
        sphere const& s = spheres_[k];
        return part_of(cell_x_of(s.x[0] + (e.time - s.since) * s.v[0]));
    };
    switch (e.kind()) {
    case event_kind::crossing: {
        int const from = part_of(cell_[i][0]);
        if (e.other() / 2U != 0U)
            return from;
        return part_of(x_crossed_into(e)) == from ? from : seam;
    }
    case event_kind::pair: {
        int const p = at(i);
        return at(e.other()) == p ? p : seam;
    }
    default:
        return at(i);
    }
}

void calendar::link(std::uint32_t i)
{
    std::uint32_t& head = head_[cell_index(cell_[i])];
    previous_[i] = none;
    spheres_[i].next = head;
    if (head != none)
        previous_[head] = i;
    head = i;
}

void calendar::unlink(std::uint32_t i)
{
    std::uint32_t const next = spheres_[i].next;
    if (previous_[i] != none)
        spheres_[previous_[i]].next = next;
    else
        head_[cell_index(cell_[i])] = next;
    if (next != none)
        previous_[next] = previous_[i];
}

template <class F>
void calendar::for_each_in_cells(lane& w, std::array<std::uint32_t, 3> const& lo,
                                 std::array<std::uint32_t, 3> const& hi, F f)
{
    // The spheres listed first, then offered: the walk along the lists reads each sphere
    // while the next cells' reads are still on their way, where a prediction between two
    // reads made each wait for its own (10⁵ spheres: the neighbours' reads missed the cache).
    // Each row of cells along x is contiguous in head_: its index is found once.
    std::vector<std::uint32_t>& near = w.near;
    near.clear();
    std::uint32_t const row_length = hi[0] - lo[0] + 1U;
    for (std::uint32_t z = lo[2]; z <= hi[2]; ++z)
        for (std::uint32_t y = lo[1]; y <= hi[1]; ++y) {
            std::uint32_t const* const row = head_.data() + cell_index(std::array<std::uint32_t, 3>{lo[0], y, z});
            if (row_length == 3U && (row[0] & row[1] & row[2]) == none)
                continue; // most rows of three are empty: one test (`none` is all ones)
            for (std::uint32_t x = 0; x < row_length; ++x)
                for (std::uint32_t j = row[x]; j != none; j = spheres_[j].next)
                    near.push_back(j);
        }
    for (std::uint32_t j : near)
        f(j);
}

void calendar::build(collision_bodies const& b)
{
    clock_ = 0.0;
    layout_ = b.layout;
    planes_.clear();
    for (wall const& w : walls_)
        planes_.push_back(plane_of(w));
    // Buckets for the events the spheres' speeds promise: each crosses about |v_k|/w_k faces
    // a second on axis k, and meets others about as often.
    // (The spheres are the bodies of radius > 0, fits() made sure: each is read in place,
    // in slot order, where a list of them weighed 4 bytes a sphere.)
    auto const is_sphere = [&](std::uint32_t s) { return b.radius[s] > 0.0; };
    auto const slots = static_cast<std::uint32_t>(b.x0.size());
    double crossings = 0.0;
    for (std::uint32_t s = 0; s < slots; ++s)
        if (is_sphere(s))
            crossings += b.v0[s].cwiseAbs().dot(inverse_width_);
    double const per_step =
        std::clamp(std::isfinite(crossings) ? 2.0 * crossings * h_ / events_per_bucket : most_buckets_per_step,
                   fewest_buckets_per_step, most_buckets_per_step);
    bucket_ = h_ > 0.0 ? h_ / per_step : 1.0;
    auto const ring = static_cast<std::size_t>(std::ceil(per_step * steps_in_ring));
    for (lane& w : lanes_) {
        queue& q = w.q;
        q.heap.clear();
        q.opened_events.clear();
        q.lists.clear();
        q.later.assign(ring, event_lists::empty);
        q.latest = event_lists::empty;
        q.opened = 0;
        w.now = 0.0;
    }
    seam_.clear();
    seam_hand_.now = 0.0;
    cut_ = dims_[0] / 2U;
    lanes_[0].part = halves_ ? 0 : whole;
    lanes_[1].part = 1;
    seam_hand_.part = seam;
    // Numbered in cell order (a counting sort by cell), each cell's list in that order.
    std::size_t const cells = std::size_t{dims_[0]} * dims_[1] * dims_[2];
    std::size_t const m = members_;
    head_.assign(cells + 1, 0);
    for (std::uint32_t s = 0; s < slots; ++s)
        if (is_sphere(s))
            ++head_[cell_index(cell_of(b.x0[s])) + 1];
    for (std::size_t c = 0; c < cells; ++c)
        head_[c + 1] += head_[c];
    slot_.resize(m);
    for (std::uint32_t s = 0; s < slots; ++s)
        if (is_sphere(s))
            slot_[head_[cell_index(cell_of(b.x0[s]))]++] = s;
    head_.assign(cells, none);
    spheres_.resize(m);
    // One shape for all when the spheres are alike (a gas of one kind: 16 bytes a sphere).
    bool const alike = std::all_of(slot_.begin(), slot_.end(), [&](std::uint32_t s) {
        return b.radius[s] == b.radius[slot_[0]] && b.inverse_mass[s] == b.inverse_mass[slot_[0]];
    });
    shapes_.assign(alike ? 1 : m, shape{});
    shapes_.shrink_to_fit();
    shape_mask_ = alike ? 0U : ~0U;
    cell_.resize(m);
    previous_.resize(m);
    events_of_.assign(m, 0);
    for (std::uint32_t i = static_cast<std::uint32_t>(m); i-- > 0;) { // each list in number order
        std::uint32_t const s = slot_[i];
        spheres_[i] = {b.x0[s], b.v0[s], 0.0, 0, none};
        shapes_[i & shape_mask_] = {b.radius[s], b.inverse_mass[s]};
        cell_[i] = cell_of(b.x0[s]);
        link(i);
    }
    // Every pair of neighbours once: each sphere against the rest of its cell's list and the
    // lists of the 13 neighbouring cells that come after its own.
    lane& w = halves_ ? seam_hand_ : lanes_[0];
    for (std::uint32_t i = 0; i < m; ++i) {
        predict_walls(w, i);
        predict_crossing(w, i);
        for (std::uint32_t j = spheres_[i].next; j != none; j = spheres_[j].next)
            predict_pair(w, i, j);
        auto const& c = cell_[i];
        for (int dz = 0; dz <= 1; ++dz)
            for (int dy = dz == 0 ? 0 : -1; dy <= 1; ++dy)
                for (int dx = dz == 0 && dy == 0 ? 1 : -1; dx <= 1; ++dx) {
                    std::int64_t const x = std::int64_t{c[0]} + dx, y = std::int64_t{c[1]} + dy,
                                       z = std::int64_t{c[2]} + dz;
                    if (x < 0 || y < 0 || x >= dims_[0] || y >= dims_[1] || z >= dims_[2])
                        continue;
                    std::array<std::uint32_t, 3> const at{static_cast<std::uint32_t>(x), static_cast<std::uint32_t>(y),
                                                          static_cast<std::uint32_t>(z)};
                    for (std::uint32_t j = head_[cell_index(at)]; j != none; j = spheres_[j].next)
                        predict_pair(w, i, j);
                }
    }
    for (lane& l : lanes_)
        std::make_heap(l.q.heap.begin(), l.q.heap.end(), std::greater<>{});
    std::make_heap(seam_.begin(), seam_.end(), std::greater<>{});
    built_ = true;
}

bool calendar::notice_changes(collision_bodies const& b, parallel_for* loops)
{
    // A command (an impulse, a teleport) changed these paths since the last step's end:
    // found by chunks of spheres (on the lent threads), each into a list of its own.
    std::size_t const most = changes_worth_following(spheres_.size());
    changed_in_.resize(chunk_count(spheres_.size()));
    run_chunks(loops, spheres_.size(), [&](std::size_t chunk, std::size_t begin, std::size_t end) {
        std::vector<std::uint32_t>& found = changed_in_[chunk];
        found.clear();
        // (what the loop reads, in locals: a write to `found` could otherwise alias them)
        sphere const* const spheres = spheres_.data();
        std::uint32_t const* const slots = slot_.data();
        vec3 const* const x0 = b.x0.data();
        vec3 const* const v0 = b.v0.data();
        double const now = clock_;
        for (auto i = static_cast<std::uint32_t>(begin); i < end; ++i) {
            sphere const& p = spheres[i];
            std::uint32_t const s = slots[i];
            if (!same(x0[s], p.x + (now - p.since) * p.v) || !same(v0[s], p.v)) {
                if (found.size() > most)
                    break;
                found.push_back(i);
            }
        }
    });
    changed_.clear();
    for (std::vector<std::uint32_t> const& found : changed_in_) {
        changed_.insert(changed_.end(), found.begin(), found.end());
        if (changed_.size() > most)
            return false;
    }
    vec3 const hi = lo_ + width_.cwiseProduct(vec3(dims_[0], dims_[1], dims_[2]));
    for (std::uint32_t i : changed_) {
        vec3 const& x = b.x0[slot_[i]];
        vec3 const& v = b.v0[slot_[i]];
        if (!((x.array() >= lo_.array()).all() && (x.array() <= hi.array()).all()) || !v.allFinite())
            return false; // put outside the box: the step-by-step loop's business
        unlink(i);
        cell_[i] = cell_of(x);
        link(i);
        repath(i, x, v, clock_);
    }
    lane& w = halves_ ? seam_hand_ : lanes_[0];
    w.now = clock_;
    for (std::uint32_t i : changed_)
        predict_body(w, i, none);
    return true;
}

void calendar::repath(std::uint32_t i, vec3 const& x, vec3 const& v, double t)
{
    sphere& s = spheres_[i];
    s.x = x;
    s.v = v;
    s.since = t;
    std::atomic_ref<std::uint32_t>(s.version).store(s.version + 1U, std::memory_order_relaxed);
}

[[gnu::always_inline]] inline void calendar::push(lane& w, double time, event_kind kind, std::uint32_t body, std::uint32_t other)
{
    // A time of impact from an older path can round to just before the event that found it;
    // events after the calendar's span are never taken (no step it takes ends later).
    if (!(time <= clock_span))
        return;
    // (Both are the lane's own or the seam's: no other lane writes them in a round.)
    std::uint32_t const other_version = kind == event_kind::pair ? spheres_[other].version : 0;
    event const e{std::max(time, w.now), kind, body, other, spheres_[body].version, other_version};
    if (w.part == whole) {
        file(w.q, e);
        return;
    }
    int const part = part_of_event(e);
    if (w.part == seam) { // between rounds: straight where it goes
        if (part == seam)
            file_seam(e);
        else
            file(lanes_[static_cast<std::size_t>(part)].q, e);
    } else if (part == w.part) {
        file(w.q, e);
    } else if (part == seam) {
        hand_over(w, e);
    } else { // the other half's: not before the seam event its spheres cross first
        w.for_other.push_back(e);
    }
}

void calendar::file(queue& q, event const& e)
{
    std::int64_t const bucket = bucket_of(e.time);
    if (bucket <= q.opened) {
        q.heap.push_back(e);
        if (built_)
            std::push_heap(q.heap.begin(), q.heap.end(), std::greater<>{});
    } else if (bucket - q.opened <= static_cast<std::int64_t>(q.later.size())) {
        q.lists.push(q.later[static_cast<std::size_t>(bucket) % q.later.size()], e);
    } else {
        q.lists.push(q.latest, e);
    }
}

void calendar::file_seam(event const& e)
{
    seam_.push_back(e);
    if (built_)
        std::push_heap(seam_.begin(), seam_.end(), std::greater<>{});
}

void calendar::open_slice(queue& q)
{
    ++q.opened;
    q.lists.take(q.later[static_cast<std::size_t>(q.opened) % q.later.size()], [&](event const& e) {
        if (current(e))
            q.opened_events.push_back(e);
    });
    std::sort(q.opened_events.begin(), q.opened_events.end(), std::greater<>{});
    if (q.opened % static_cast<std::int64_t>(q.later.size()) == 0) {
        // the ring's turn: the current events beyond it filed again, into the ring or
        // back among the latest (their blocks given back as they are read)
        q.lists.take(q.latest, [&](event const& e) {
            if (current(e))
                file(q, e);
        });
    }
}

[[gnu::always_inline]] inline event const* calendar::peek(queue& q, std::int64_t last)
{
    // The opened slice's events and the heap hold the events of the slices opened so far,
    // every other event is later: the earlier of their earliest is the next, and when both
    // are empty the next slice is opened.
    while (q.opened_events.empty() && q.heap.empty()) {
        if (q.opened >= last)
            return nullptr;
        open_slice(q);
    }
    if (q.opened_events.empty() || (!q.heap.empty() && q.opened_events.back() > q.heap.front()))
        return &q.heap.front();
    return &q.opened_events.back();
}

[[gnu::always_inline]] inline event calendar::pop(queue& q)
{
    event e{};
    if (q.opened_events.empty() || (!q.heap.empty() && q.opened_events.back() > q.heap.front())) {
        std::pop_heap(q.heap.begin(), q.heap.end(), std::greater<>{});
        e = q.heap.back();
        q.heap.pop_back();
    } else {
        e = q.opened_events.back();
        q.opened_events.pop_back();
    }
    if (!q.opened_events.empty()) {
        // The next event's spheres, on their way while this one is handled: in a large
        // gas two events in a row lie far apart, and each waited for its spheres' reads.
        event const& soon = q.opened_events.back();
        __builtin_prefetch(&spheres_[soon.body]);
        __builtin_prefetch(&cell_[soon.body]);
        if (soon.kind() == event_kind::pair)
            __builtin_prefetch(&spheres_[soon.other()]);
    }
    return e;
}

[[gnu::always_inline]] inline bool calendar::current(event const& e) const
{
    // By halves, a stale event may name a sphere another lane is moving: its version is
    // read atomically (it only rises, so a sum that differs once always will).
    std::uint32_t const other = e.kind() == event_kind::pair ? e.other() : none;
    if (halves_)
        return version_of(e.body) + (other != none ? version_of(other) : 0U) == e.versions;
    return spheres_[e.body].version + (other != none ? spheres_[other].version : 0U) == e.versions;
}

void calendar::predict_pair(lane& w, std::uint32_t i, std::uint32_t j)
{
    if (shape_of(i).inverse_mass == 0.0 && shape_of(j).inverse_mass == 0.0)
        return;
    // From the later of the two paths' starts, that body first (the lower number on a tie):
    // the same event whenever the pair is found.
    sphere const* p = &spheres_[i];
    sphere const* q = &spheres_[j];
    if (q->since > p->since || (q->since == p->since && j < i)) {
        std::swap(i, j);
        std::swap(p, q);
    }
    vec3 const xq = q->x + (p->since - q->since) * q->v;
    if (surely_misses(p->x - xq, p->v - q->v, shape_of(i).radius + shape_of(j).radius))
        return; // most neighbours: no call
    if (auto t = sphere_time_of_impact(p->x, p->v, shape_of(i).radius, xq, q->v, shape_of(j).radius, forever))
        push(w, p->since + *t, event_kind::pair, i, j);
}

void calendar::predict_walls(lane& w, std::uint32_t i, int only_axis)
{
    if (shape_of(i).inverse_mass == 0.0)
        return;
    auto const& c = cell_[i];
    if (!at_a_side(c))
        return; // most spheres: no wall beside their cell (the test of every wall below)
    sphere const& p = spheres_[i];
    // Only the first wall it reaches: a wall event always starts a new path (handle_wall),
    // so the events of the walls after it would be stale by their time. (A tie goes to the
    // lower wall, the one the queue would take first.)
    double soonest = forever;
    std::uint32_t first = 0;
    for (std::uint32_t k = 0; k < walls_.size(); ++k) {
        // only the walls of the cells at the box's side it is in: a cell is wider than a
        // diameter, so a sphere reaches a wall only from the cells beside it, and it is
        // predicted again when it crosses into them (handle_crossing); in a large box most
        // spheres then keep no wall event at all
        side const s = sides_[k];
        auto const a = static_cast<std::size_t>(s.axis);
        if ((only_axis >= 0 && s.axis != only_axis) || c[a] != (s.positive ? 0U : dims_[a] - 1U))
            continue;
        // only the walls it moves towards (n·v < 0, exact for a normal ±e_axis); the gap
        // ±x − d − r, plainly, errs by a few units in the last place of x, within the touching
        // slack (position_slack) that answers the contact when its time comes
        double const towards = s.positive ? p.v[s.axis] : -p.v[s.axis];
        if (!(towards < 0.0))
            continue;
        double const gap = ((s.positive ? p.x[s.axis] : -p.x[s.axis]) - walls_[k].surface.offset) - shape_of(i).radius;
        double const t = std::max(p.since + (gap > 0.0 ? gap / -towards : 0.0), w.now); // as push() files it
        if (t < soonest) {
            soonest = t;
            first = k;
        }
    }
    if (soonest < forever)
        push(w, soonest, event_kind::wall, i, first);
}

void calendar::predict_crossing(lane& w, std::uint32_t i)
{
    sphere const& p = spheres_[i];
    auto const& c = cell_[i];
    // The three faces' times first, then the soonest: the divisions overlap. Compared as each
    // came, every comparison waited for its division and its branch often went the other way.
    std::array<double, 3> t{};
    for (int k = 0; k < 3; ++k) {
        auto const a = static_cast<std::size_t>(k);
        double const v = p.v[k];
        bool const up = v > 0.0;
        bool const open = up ? c[a] + 1U < dims_[a] : v < 0.0 && c[a] > 0U;
        double const boundary = lo_[k] + static_cast<double>(c[a] + (up ? 1U : 0U)) * width_[k];
        double const time = (boundary - p.x[k]) / (open ? v : 1.0);
        t[a] = open ? time : forever;
    }
    std::uint32_t axis = 0;
    double soonest = t[0];
    if (t[1] < soonest) {
        soonest = t[1];
        axis = 1;
    }
    if (t[2] < soonest) {
        soonest = t[2];
        axis = 2;
    }
    if (soonest < forever)
        push(w, p.since + std::max(soonest, 0.0), event_kind::crossing, i,
             2U * axis + (p.v[static_cast<int>(axis)] > 0.0 ? 1U : 0U));
}

void calendar::predict_body(lane& w, std::uint32_t i, std::uint32_t except)
{
    predict_walls(w, i);
    predict_crossing(w, i);
    auto const& c = cell_[i];
    std::array<std::uint32_t, 3> lo{}, hi{};
    for (std::size_t a = 0; a < 3; ++a) {
        lo[a] = c[a] > 0U ? c[a] - 1U : 0U;
        hi[a] = std::min(c[a] + 1U, dims_[a] - 1U);
    }
    for_each_in_cells(w, lo, hi, [&](std::uint32_t j) {
        if (j != i && j != except)
            predict_pair(w, i, j);
    });
}

void calendar::handle_pair(lane& w, event const& e)
{
    std::uint32_t const i = e.body, j = e.other();
    vec3 const xi = position(i, e.time), xj = position(j, e.time);
    vec3 vi = spheres_[i].v, vj = spheres_[j].v;
    vec3 const d = xi - xj;
    double const distance = d.norm();
    double const reach = shape_of(i).radius + shape_of(j).radius;
    if (distance <= reach * (1.0 + touching_tolerance) || distance <= reach + position_slack(xi, xj)) {
        vec3 const n = detail::contact_normal(d, distance);
        if (detail::respond_to_sphere_contact(vi, shape_of(i).inverse_mass, vec3::Zero(), vj, shape_of(j).inverse_mass,
                                              vec3::Zero(), n, *settings_, h_))
            ++w.sphere_contacts;
    }
    repath(i, xi, vi, e.time);
    repath(j, xj, vj, e.time);
    predict_body(w, i, j);
    predict_body(w, j, none);
}

void calendar::handle_wall(lane& w, event const& e)
{
    std::uint32_t const i = e.body;
    wall const& wa = walls_[e.other()];
    double const r = shape_of(i).radius;
    body_path p{position(i, e.time), spheres_[i].v, vec3::Zero(), e.time};
    double const height = wa.surface.normal.dot(p.x);
    if (height <= wa.surface.offset + r + touching_tolerance * r ||
        height <= wa.surface.offset + r + position_slack(p.x, vec3::Zero())) {
        if (detail::respond_to_surface(p, wa.surface.normal, wa.surface.offset + r, wa.damping, wa.friction,
                                       *settings_, h_))
            ++w.wall_contacts;
    }
    repath(i, p.x, p.v, e.time);
    predict_body(w, i, none);
}

void calendar::handle_crossing(lane& w, event const& e)
{
    std::uint32_t const i = e.body;
    auto const axis = static_cast<std::size_t>(e.other() / 2U);
    bool const up = (e.other() & 1U) != 0U;
    unlink(i);
    std::uint16_t& moved = cell_[i][axis];
    std::atomic_ref<std::uint16_t>(moved).store(static_cast<std::uint16_t>(up ? moved + 1U : moved - 1U),
                                                std::memory_order_relaxed);
    link(i);
    // The layer of cells that came into reach, one beyond the new cell along the axis.
    auto const& c = cell_[i];
    bool const beyond = up ? c[axis] + 1U < dims_[axis] : c[axis] > 0U;
    if (beyond) {
        std::array<std::uint32_t, 3> lo{}, hi{};
        for (std::size_t a = 0; a < 3; ++a) {
            lo[a] = c[a] > 0U ? c[a] - 1U : 0U;
            hi[a] = std::min(c[a] + 1U, dims_[a] - 1U);
        }
        lo[axis] = hi[axis] = up ? c[axis] + 1U : c[axis] - 1U;
        for_each_in_cells(w, lo, hi, [&](std::uint32_t j) { predict_pair(w, i, j); });
    } else {
        predict_walls(w, i, static_cast<int>(axis)); // into the cells beside a wall on this axis
    }
    predict_crossing(w, i);
}

void calendar::write_positions(collision_bodies const& b, double at, bool clamp, parallel_for* loops) const
{
    detail::wall_set const walls(walls_);
    run_chunks(loops, spheres_.size(), [&](std::size_t, std::size_t begin, std::size_t end) {
        // (what the loop reads, in locals: the writes to x and v could otherwise alias them)
        sphere const* const spheres = spheres_.data();
        std::uint32_t const* const slots = slot_.data();
        cell_coordinates const* const cells = cell_.data();
        vec3* const x = b.x.data();
        vec3* const v = b.v.data();
        for (auto i = static_cast<std::uint32_t>(begin); i < end; ++i) {
            sphere const& p = spheres[i];
            std::uint32_t const s = slots[i];
            x[s] = p.x + (at - p.since) * p.v;
            v[s] = p.v;
            // Rounding may leave a sphere inside a wall by an ulp, and only one in the cells
            // beside a wall can be (a cell is wider than a diameter): the clamp every
            // continuous step ends with (clamp_to_walls), without a pass over the rest.
            if (clamp && at_a_side(cells[i]))
                detail::clamp_to_walls(walls, x[s], v[s], shape_of(i).radius, shape_of(i).inverse_mass);
        }
    });
}

bool calendar::take_whole(double end)
{
    lane& w = lanes_[0];
    for (;;) {
        event const* next = peek(w.q, last_);
        if (next == nullptr || next->time > end)
            return false;
        event const e = pop(w.q);
        if (current(e) && take_one(w, e))
            return true;
    }
}

[[gnu::always_inline]] inline bool calendar::take_one(lane& w, event const& e)
{
    w.now = e.time;
    ++w.events;
    if (e.kind() == event_kind::crossing) {
        handle_crossing(w, e);
        return false;
    }
    bool const pair = e.kind() == event_kind::pair;
    if (contacts_ == settings_->max_events_per_step || events_of_[e.body]++ >= settings_->max_events_per_body ||
        (pair && events_of_[e.other()]++ >= settings_->max_events_per_body))
        return true;
    ++contacts_;
    if (pair)
        handle_pair(w, e);
    else
        handle_wall(w, e);
    return false;
}

void calendar::hand_over(lane& w, event const& e)
{
    w.for_seam.push_back(e);
    // An event filed at the time of the one being handled may sort before it (its time
    // rounded up to now, a tie broken by kind and indices), as may the events after that:
    // one queue would take it next, after every event the lane has taken. So the round ends
    // after the furthest of those.
    event const after = !w.log.empty() && w.furthest > e ? w.furthest : e;
    if (after.time > signals_.bound_time.load(std::memory_order_relaxed))
        return;
    std::lock_guard const held(signals_.lock);
    if (signals_.bound > after) {
        signals_.bound = after;
        signals_.bound_time.store(after.time, std::memory_order_relaxed);
    }
}

void calendar::take_lane(lane& w, std::uint64_t budget)
{
    std::uint64_t const most = settings_->max_events_per_body;
    for (;;) {
        event const* next = peek(w.q, last_);
        if (next == nullptr)
            return;
        // Up to the round's bound, which the other lane may lower at any time: a tie in time
        // is settled by the whole order, under the lock.
        double const bound = signals_.bound_time.load(std::memory_order_relaxed);
        if (next->time > bound)
            return;
        if (next->time == bound) {
            std::lock_guard const held(signals_.lock);
            if (!(signals_.bound > *next))
                return;
        }
        event const e = pop(w.q);
        if (!current(e))
            continue; // (versions only rise: an event stale once stays so)
        std::uint32_t const i = e.body;
        bool const pair = e.kind() == event_kind::pair;
        bool const crossing = e.kind() == event_kind::crossing;
        bool own = part_of_sphere(i) == w.part;
        if (crossing && e.other() / 2U == 0U)
            own = own && part_of(x_crossed_into(e)) == w.part;
        if (pair)
            own = own && part_of_sphere(e.other()) == w.part;
        if (!own || (!crossing && (w.contacts >= budget || events_of_[i] >= most ||
                                   (pair && events_of_[e.other()] >= most)))) {
            hand_over(w, e); // the seam's, or at a cap: taken between rounds
            return;
        }
        w.now = e.time;
        if (w.log.empty() || e > w.furthest)
            w.furthest = e;
        taken& t = w.log.emplace_back();
        t.e = e;
        t.contact = 0;
        ++w.events;
        if (crossing) {
            t.cell = cell_[i];
            handle_crossing(w, e);
            continue;
        }
        sphere const& s = spheres_[i];
        t.x[0] = s.x;
        t.v[0] = s.v;
        t.since[0] = s.since;
        ++events_of_[i];
        ++w.contacts;
        std::uint64_t const before = w.sphere_contacts + w.wall_contacts;
        if (pair) {
            sphere const& o = spheres_[e.other()];
            t.x[1] = o.x;
            t.v[1] = o.v;
            t.since[1] = o.since;
            ++events_of_[e.other()];
            handle_pair(w, e);
        } else {
            handle_wall(w, e);
        }
        t.contact = static_cast<std::uint8_t>(w.sphere_contacts + w.wall_contacts - before);
    }
}

void calendar::undo_after(event const& bound)
{
    undone_spheres_.clear();
    for (lane& w : lanes_) {
        // Every event a lane took after the first one past the bound (those after it in the
        // lane may sort before it, when filed at its time, but one queue takes them after it).
        auto const first = std::find_if(w.log.begin(), w.log.end(), [&](taken const& t) { return t.e > bound; });
        while (w.log.end() != first) {
            taken const& t = w.log.back();
            std::uint32_t const i = t.e.body;
            undone_spheres_.push_back(i);
            if (t.e.kind() == event_kind::crossing) {
                unlink(i);
                cell_[i] = t.cell;
                link(i);
            } else {
                bool const pair = t.e.kind() == event_kind::pair;
                std::size_t const n = pair ? 2 : 1;
                for (std::size_t k = 0; k < n; ++k) {
                    sphere& s = spheres_[k == 0 ? i : t.e.other()];
                    s.x = t.x[k];
                    s.v = t.v[k];
                    s.since = t.since[k];
                }
                --events_of_[i];
                if (pair) {
                    --events_of_[t.e.other()];
                    undone_spheres_.push_back(t.e.other());
                    w.sphere_contacts -= t.contact;
                } else {
                    w.wall_contacts -= t.contact;
                }
                --w.contacts;
            }
            --w.events;
            ++undone_;
            w.log.pop_back();
        }
    }
    // Each sphere put back starts a path of its own (its events, filed before and in the
    // round, stale), and is predicted as when its path began: the same events at the same
    // times, since no event before the bound is left untaken.
    std::sort(undone_spheres_.begin(), undone_spheres_.end());
    undone_spheres_.erase(std::unique(undone_spheres_.begin(), undone_spheres_.end()), undone_spheres_.end());
    for (std::uint32_t i : undone_spheres_)
        ++spheres_[i].version;
    seam_hand_.now = bound.time;
    for (std::uint32_t i : undone_spheres_)
        predict_body(seam_hand_, i, none);
}

void calendar::file_handed()
{
    for (std::size_t k = 0; k < 2; ++k) {
        lane& w = lanes_[k];
        for (event const& e : w.for_other)
            if (current(e))
                file(lanes_[1 - k].q, e);
        for (event const& e : w.for_seam)
            if (current(e))
                file_seam(e);
        w.for_other.clear();
        w.for_seam.clear();
    }
}

void calendar::round(event const& bound, std::uint64_t budget, bool two_threads)
{
    signals_.bound = bound;
    signals_.bound_time.store(bound.time, std::memory_order_relaxed);
    for (lane& w : lanes_) {
        w.log.clear();
        w.contacts = 0;
    }
    if (two_threads) {
        signals_.budget = budget;
        signals_.mail.store(posted, std::memory_order_release);
        take_lane(lanes_[0], budget);
        while (signals_.mail.load(std::memory_order_acquire) != done)
            pause();
        signals_.mail.store(idle, std::memory_order_relaxed);
    } else {
        take_lane(lanes_[0], budget);
        take_lane(lanes_[1], budget);
    }
    ++rounds_;
    if (bound > signals_.bound)
        undo_after(signals_.bound);
    contacts_ += lanes_[0].contacts + lanes_[1].contacts;
    file_handed();
}

bool calendar::take_by_halves(double end, parallel_for* loops)
{
    auto const take = [&](bool two_threads) {
        event const last = step_end(end);
        for (;;) {
            // The next seam event (stale ones dropped): the bound of the lanes' round, if
            // either has an event before it.
            while (!seam_.empty() && !current(seam_.front())) {
                std::pop_heap(seam_.begin(), seam_.end(), std::greater<>{});
                seam_.pop_back();
            }
            bool const seam_next = !seam_.empty() && last > seam_.front();
            event const bound = seam_next ? seam_.front() : last;
            bool lanes_first = false;
            for (lane& w : lanes_) {
                event const* n = peek(w.q, last_);
                lanes_first = lanes_first || (n != nullptr && bound > *n);
            }
            if (lanes_first) {
                std::uint64_t const left = settings_->max_events_per_step - contacts_;
                round(bound, left / 2U, two_threads && signals_.helping.load(std::memory_order_acquire));
                continue;
            }
            if (!seam_next)
                return false;
            std::pop_heap(seam_.begin(), seam_.end(), std::greater<>{});
            event const e = seam_.back();
            seam_.pop_back();
            if (take_one(seam_hand_, e)) // (current: stale ones were dropped above)
                return true;
        }
    };
    if (loops == nullptr)
        return take(false);
    // Two tasks: the first to start takes the events, the other takes the upper half's lane
    // in each round posted to it until it is told to stop (if the two run one after the
    // other, the first takes both lanes itself).
    signals_.arrived.store(0, std::memory_order_relaxed);
    signals_.mail.store(idle, std::memory_order_relaxed);
    signals_.helping.store(false, std::memory_order_relaxed);
    bool capped = false;
    loops->run(2, [&](std::size_t) {
        if (signals_.arrived.fetch_add(1, std::memory_order_acq_rel) == 0) {
            struct stopper
            {
                std::atomic<int>& mail;
                ~stopper() { mail.store(stop, std::memory_order_release); }
            } const stops{signals_.mail};
            capped = take(true);
            return;
        }
        signals_.helping.store(true, std::memory_order_release);
        for (;;) {
            int const m = signals_.mail.load(std::memory_order_acquire);
            if (m == posted) {
                take_lane(lanes_[1], signals_.budget);
                signals_.mail.store(done, std::memory_order_release);
            } else if (m == stop) {
                return;
            } else {
                pause();
            }
        }
    });
    return capped;
}

void calendar::refile(bool halves)
{
    // Every current event out of the queues, then filed again as the new cut says.
    refiled_.clear();
    auto const keep = [&](event const& e) {
        if (current(e))
            refiled_.push_back(e);
    };
    std::int64_t opened = 0;
    for (lane& w : lanes_) {
        queue& q = w.q;
        opened = std::max(opened, q.opened);
        std::for_each(q.opened_events.begin(), q.opened_events.end(), keep);
        std::for_each(q.heap.begin(), q.heap.end(), keep);
        q.opened_events.clear();
        q.heap.clear();
        for (event_lists::list& l : q.later)
            q.lists.take(l, keep);
        q.lists.take(q.latest, keep);
    }
    std::for_each(seam_.begin(), seam_.end(), keep);
    seam_.clear();
    halves_ = halves;
    lanes_[0].part = halves ? 0 : whole;
    for (lane& w : lanes_)
        w.q.opened = opened;
    for (event const& e : refiled_) {
        int const part = halves ? part_of_event(e) : 0;
        if (part == seam)
            file_seam(e);
        else
            file(lanes_[static_cast<std::size_t>(part)].q, e);
    }
}

calendar::outcome calendar::step(collision_settings const& settings, std::span<wall const> walls,
                                 collision_bodies const& b, double h, collision_stats& stats, parallel_for* loops)
{
    settings_ = &settings;
    h_ = h;
    bool const same_walls = built_ && std::equal(walls.begin(), walls.end(), planes_.begin(), planes_.end(),
                                                 [](wall const& w, auto const& p) { return plane_of(w) == p; });
    bool const same_bodies = built_ && b.layout == layout_;
    for (lane& w : lanes_)
        w.now = clock_;
    seam_hand_.now = clock_;
    lanes_[0].part = halves_ ? 0 : whole;
    lanes_[1].part = 1;
    seam_hand_.part = seam;
    // The step's start: x itself while the drift is pending (the paths make it), else x0.
    collision_bodies start = b;
    if (b.drift_pending) {
        start.x0 = b.x;
        start.v0 = b.v;
    }
    if (!(same_walls && same_bodies && clock_ + h <= clock_span && notice_changes(start, loops))) {
        built_ = false;
        walls_ = walls;
        if (!fits(walls, start))
            return outcome::declined;
        halves_ = loops != nullptr && members_ >= fewest_for_halves && dims_[0] >= fewest_cells_for_halves;
        build(start);
    }
    walls_ = walls;
    // By halves where threads are lent (a step taken either way gives the same bits).
    bool const halves = loops != nullptr && members_ >= fewest_for_halves && dims_[0] >= fewest_cells_for_halves;
    if (halves != halves_)
        refile(halves);

    double const end = clock_ + h;
    last_ = bucket_of(end);
    std::fill(events_of_.begin(), events_of_.end(), 0U);
    contacts_ = 0;
    for (lane* w : {&lanes_[0], &lanes_[1], &seam_hand_})
        w->events = w->sphere_contacts = w->wall_contacts = 0;
    rounds_ = undone_ = 0;
    bool const capped = halves_ ? take_by_halves(end, loops) : take_whole(end);
    stats.rounds += rounds_;
    stats.events_undone += undone_;
    for (lane const* w : {&lanes_[0], &lanes_[1], &seam_hand_}) {
        stats.events += w->events;
        stats.sphere_contacts += w->sphere_contacts;
        stats.wall_contacts += w->wall_contacts;
    }
    if (capped) {
        write_positions(b, end, false, loops);
        built_ = false;
        return outcome::capped;
    }
    clock_ = end;
    write_positions(b, end, true, loops);
    return outcome::done;
}

} // namespace kugel::physics::continuous
