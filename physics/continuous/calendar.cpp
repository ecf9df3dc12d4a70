#include "physics/continuous/calendar.hpp"

#include "physics/collision_rules.hpp"
#include "physics/collisions.hpp"
#include "physics/continuous/touching.hpp"
#include "physics/time_of_impact.hpp"
#include "physics/wall_set.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>

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
void calendar::for_each_in_cells(std::array<std::uint32_t, 3> const& lo, std::array<std::uint32_t, 3> const& hi, F f)
{
    // The spheres listed first, then offered: the walk along the lists reads each sphere
    // while the next cells' reads are still on their way, where a prediction between two
    // reads made each wait for its own (10⁵ spheres: the neighbours' reads missed the cache).
    // Each row of cells along x is contiguous in head_: its index is found once.
    near_.clear();
    std::uint32_t const row_length = hi[0] - lo[0] + 1U;
    for (std::uint32_t z = lo[2]; z <= hi[2]; ++z)
        for (std::uint32_t y = lo[1]; y <= hi[1]; ++y) {
            std::uint32_t const* const row = head_.data() + cell_index(std::array<std::uint32_t, 3>{lo[0], y, z});
            if (row_length == 3U && (row[0] & row[1] & row[2]) == none)
                continue; // most rows of three are empty: one test (`none` is all ones)
            for (std::uint32_t x = 0; x < row_length; ++x)
                for (std::uint32_t j = row[x]; j != none; j = spheres_[j].next)
                    near_.push_back(j);
        }
    for (std::uint32_t j : near_)
        f(j);
}

void calendar::build(collision_bodies const& b)
{
    clock_ = 0.0;
    now_ = 0.0;
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
    queue_.clear();
    opened_events_.clear();
    lists_.clear();
    later_.assign(static_cast<std::size_t>(std::ceil(per_step * steps_in_ring)), event_lists::empty);
    latest_ = event_lists::empty;
    bucket_ = h_ > 0.0 ? h_ / per_step : 1.0;
    opened_ = 0;
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
    for (std::uint32_t i = 0; i < m; ++i) {
        predict_walls(i);
        predict_crossing(i);
        for (std::uint32_t j = spheres_[i].next; j != none; j = spheres_[j].next)
            predict_pair(i, j);
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
                        predict_pair(i, j);
                }
    }
    std::make_heap(queue_.begin(), queue_.end(), std::greater<>{});
    built_ = true;
}

bool calendar::notice_changes(collision_bodies const& b)
{
    // A command (an impulse, a teleport) changed these paths since the last step's end.
    changed_.clear();
    for (std::uint32_t i = 0; i < spheres_.size(); ++i) {
        std::uint32_t const s = slot_[i];
        if (!same(b.x0[s], position(i, clock_)) || !same(b.v0[s], spheres_[i].v)) {
            if (changed_.size() == changes_worth_following(spheres_.size()))
                return false;
            changed_.push_back(i);
        }
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
    for (std::uint32_t i : changed_)
        predict_body(i, none);
    return true;
}

void calendar::repath(std::uint32_t i, vec3 const& x, vec3 const& v, double t)
{
    sphere& s = spheres_[i];
    s.x = x;
    s.v = v;
    s.since = t;
    ++s.version;
}

void calendar::push(double time, event_kind kind, std::uint32_t body, std::uint32_t other)
{
    // A time of impact from an older path can round to just before the event that found it;
    // events after the calendar's span are never taken (no step it takes ends later).
    if (!(time <= clock_span))
        return;
    std::uint32_t const other_version = kind == event_kind::pair ? spheres_[other].version : 0;
    file({std::max(time, now_), kind, body, other, spheres_[body].version, other_version});
}

void calendar::file(event const& e)
{
    std::int64_t const bucket = bucket_of(e.time);
    if (bucket <= opened_) {
        queue_.push_back(e);
        if (built_)
            std::push_heap(queue_.begin(), queue_.end(), std::greater<>{});
    } else if (bucket - opened_ <= static_cast<std::int64_t>(later_.size())) {
        lists_.push(later_[static_cast<std::size_t>(bucket) % later_.size()], e);
    } else {
        lists_.push(latest_, e);
    }
}

void calendar::open_bucket()
{
    ++opened_;
    lists_.take(later_[static_cast<std::size_t>(opened_) % later_.size()], [&](event const& e) {
        if (current(e))
            opened_events_.push_back(e);
    });
    std::sort(opened_events_.begin(), opened_events_.end(), std::greater<>{});
    if (opened_ % static_cast<std::int64_t>(later_.size()) == 0) {
        // the ring's turn: the current events beyond it filed again, into the ring or
        // back among the latest (their blocks given back as they are read)
        lists_.take(latest_, [&](event const& e) {
            if (current(e))
                file(e);
        });
    }
}

bool calendar::current(event const& e) const
{
    return spheres_[e.body].version + (e.kind() == event_kind::pair ? spheres_[e.other()].version : 0U) == e.versions;
}

void calendar::predict_pair(std::uint32_t i, std::uint32_t j)
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
        push(p->since + *t, event_kind::pair, i, j);
}

void calendar::predict_walls(std::uint32_t i, int only_axis)
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
        double const t = std::max(p.since + (gap > 0.0 ? gap / -towards : 0.0), now_); // as push() files it
        if (t < soonest) {
            soonest = t;
            first = k;
        }
    }
    if (soonest < forever)
        push(soonest, event_kind::wall, i, first);
}

void calendar::predict_crossing(std::uint32_t i)
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
        push(p.since + std::max(soonest, 0.0), event_kind::crossing, i,
             2U * axis + (p.v[static_cast<int>(axis)] > 0.0 ? 1U : 0U));
}

void calendar::predict_body(std::uint32_t i, std::uint32_t except)
{
    predict_walls(i);
    predict_crossing(i);
    auto const& c = cell_[i];
    std::array<std::uint32_t, 3> lo{}, hi{};
    for (std::size_t a = 0; a < 3; ++a) {
        lo[a] = c[a] > 0U ? c[a] - 1U : 0U;
        hi[a] = std::min(c[a] + 1U, dims_[a] - 1U);
    }
    for_each_in_cells(lo, hi, [&](std::uint32_t j) {
        if (j != i && j != except)
            predict_pair(i, j);
    });
}

void calendar::handle_pair(event const& e)
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
            ++stats_->sphere_contacts;
    }
    repath(i, xi, vi, e.time);
    repath(j, xj, vj, e.time);
    predict_body(i, j);
    predict_body(j, none);
}

void calendar::handle_wall(event const& e)
{
    std::uint32_t const i = e.body;
    wall const& w = walls_[e.other()];
    double const r = shape_of(i).radius;
    body_path p{position(i, e.time), spheres_[i].v, vec3::Zero(), e.time};
    double const height = w.surface.normal.dot(p.x);
    if (height <= w.surface.offset + r + touching_tolerance * r ||
        height <= w.surface.offset + r + position_slack(p.x, vec3::Zero())) {
        if (detail::respond_to_surface(p, w.surface.normal, w.surface.offset + r, w.damping, w.friction, *settings_,
                                       h_))
            ++stats_->wall_contacts;
    }
    repath(i, p.x, p.v, e.time);
    predict_body(i, none);
}

void calendar::handle_crossing(event const& e)
{
    std::uint32_t const i = e.body;
    auto const axis = static_cast<std::size_t>(e.other() / 2U);
    bool const up = (e.other() & 1U) != 0U;
    unlink(i);
    cell_[i][axis] = static_cast<std::uint16_t>(up ? cell_[i][axis] + 1U : cell_[i][axis] - 1U);
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
        for_each_in_cells(lo, hi, [&](std::uint32_t j) { predict_pair(i, j); });
    } else {
        predict_walls(i, static_cast<int>(axis)); // into the cells beside a wall on this axis
    }
    predict_crossing(i);
}

void calendar::write_positions(collision_bodies const& b, double at, bool clamp) const
{
    detail::wall_set const walls(walls_);
    for (std::uint32_t i = 0; i < spheres_.size(); ++i) {
        std::uint32_t const s = slot_[i];
        b.x[s] = position(i, at);
        b.v[s] = spheres_[i].v;
        // Rounding may leave a sphere inside a wall by an ulp, and only one in the cells
        // beside a wall can be (a cell is wider than a diameter): the clamp every continuous
        // step ends with (clamp_to_walls), without a pass over the rest.
        if (clamp && at_a_side(cell_[i]))
            detail::clamp_to_walls(walls, b.x[s], b.v[s], shape_of(i).radius, shape_of(i).inverse_mass);
    }
}

calendar::outcome calendar::step(collision_settings const& settings, std::span<wall const> walls,
                                 collision_bodies const& b, double h, collision_stats& stats)
{
    settings_ = &settings;
    stats_ = &stats;
    h_ = h;
    bool const same_walls = built_ && std::equal(walls.begin(), walls.end(), planes_.begin(), planes_.end(),
                                                 [](wall const& w, auto const& p) { return plane_of(w) == p; });
    bool const same_bodies = built_ && b.layout == layout_;
    now_ = clock_;
    // The step's start: x itself while the drift is pending (the paths make it), else x0.
    collision_bodies start = b;
    if (b.drift_pending) {
        start.x0 = b.x;
        start.v0 = b.v;
    }
    if (!(same_walls && same_bodies && clock_ + h <= clock_span && notice_changes(start))) {
        built_ = false;
        walls_ = walls;
        if (!fits(walls, start))
            return outcome::declined;
        build(start);
    }
    walls_ = walls;

    double const end = clock_ + h;
    std::int64_t const last = bucket_of(end);
    std::fill(events_of_.begin(), events_of_.end(), 0U);
    std::uint64_t contacts = 0;
    for (;;) {
        // The opened bucket's events and the queue hold the events of the buckets opened so
        // far, every other event is later: the earlier of their earliest is the next, and
        // when both are empty the next bucket is opened.
        if (opened_events_.empty() && queue_.empty()) {
            if (opened_ >= last)
                break;
            open_bucket();
            continue;
        }
        bool const queued = opened_events_.empty() || (!queue_.empty() && opened_events_.back() > queue_.front());
        if ((queued ? queue_.front() : opened_events_.back()).time > end)
            break;
        event e{};
        if (queued) {
            std::pop_heap(queue_.begin(), queue_.end(), std::greater<>{});
            e = queue_.back();
            queue_.pop_back();
        } else {
            e = opened_events_.back();
            opened_events_.pop_back();
        }
        if (!opened_events_.empty()) {
            // The next event's spheres, on their way while this one is handled: in a large
            // gas two events in a row lie far apart, and each waited for its spheres' reads.
            event const& soon = opened_events_.back();
            __builtin_prefetch(&spheres_[soon.body]);
            __builtin_prefetch(&cell_[soon.body]);
            if (soon.kind() == event_kind::pair)
                __builtin_prefetch(&spheres_[soon.other()]);
        }
        if (!current(e))
            continue;
        now_ = e.time;
        ++stats.events;
        if (e.kind() == event_kind::crossing) {
            handle_crossing(e);
            continue;
        }
        bool const pair = e.kind() == event_kind::pair;
        if (contacts == settings.max_events_per_step || events_of_[e.body]++ >= settings.max_events_per_body ||
            (pair && events_of_[e.other()]++ >= settings.max_events_per_body)) {
            write_positions(b, end, false);
            built_ = false;
            return outcome::capped;
        }
        ++contacts;
        if (pair)
            handle_pair(e);
        else
            handle_wall(e);
    }
    clock_ = end;
    write_positions(b, end, true);
    return outcome::done;
}

} // namespace kugel::physics::continuous
