// Continuous collision mode: inside a step, contacts are handled in time order. Each sphere
// moves on its step path (body_path); the earliest predicted contact is taken first, the
// bodies involved are moved to that time and answered, and only their future contacts are
// predicted again. Nothing tunnels, at any speed: a contact is found from the paths, not from
// where the bodies happen to be at the end of the step.

#include "physics/collision_rules.hpp"
#include "physics/collisions.hpp"
#include "physics/discrete/discrete_step.hpp"
#include "physics/time_of_impact.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>
#include <queue>
#include <vector>

namespace kugel::physics {


namespace {

enum class event_kind : std::uint8_t { pair, wall, obstacle };

struct event
{
    double time;
    event_kind kind;
    std::uint32_t body;
    std::uint32_t other; ///< body, wall or obstacle index
    std::uint32_t body_version;
    std::uint32_t other_version; ///< for pairs

    /// Earliest first; ties broken by kind and indices so the order never depends on the heap.
    friend bool operator>(event const& l, event const& r)
    {
        if (l.time != r.time)
            return l.time > r.time;
        if (l.kind != r.kind)
            return l.kind > r.kind;
        if (l.body != r.body)
            return l.body > r.body;
        return l.other > r.other;
    }
};

/// Relative gap below which two surfaces count as touching (and above which an event is only
/// a checkpoint on the way): 1e-9 of the contact distance, far above rounding in positions
/// yet far below anything visible.
constexpr double touching_tolerance = 1e-9;

/// Conservative advancement: repeatedly move to the time at which the gap could at most have
/// closed, given a bound on the closing speed, until the gap is within tolerance. Never steps
/// past the first contact. `gap(τ)` is the signed distance, `closing(τ)` the rate at which it
/// shrinks (> 0 approaching), `speed_bound(τ)` a bound on |closing| over [τ, limit].
template <class Gap, class Closing, class Bound>
std::optional<double> advance_to_contact(double limit, double tolerance, Gap gap, Closing closing,
                                         Bound speed_bound)
{
    double t = 0.0;
    for (int iteration = 0; iteration < 100; ++iteration) {
        double const g = gap(t);
        if (g <= tolerance) {
            if (closing(t) > 0.0)
                return t;
            // touching but parting: look a little later in case curved paths meet again
            t += limit / 1024.0;
        } else {
            double const bound = speed_bound(t);
            if (bound <= 0.0)
                return std::nullopt;
            t += g / bound;
        }
        if (t > limit)
            return std::nullopt;
    }
    return t; // not converged: a checkpoint; the event re-predicts from there
}

/// Cell key -> value by open addressing: linear probing in a power-of-two table at most half
/// full. The cells of a prediction are looked up 27 at a time, where std::unordered_map
/// chased a node for each. Keys are at most 63 bits (path_grid::key), so ~0 marks a free slot.
template <class V>
class cell_map
{
public:
    void clear()
    {
        std::fill(keys_.begin(), keys_.end(), free_slot);
        count_ = 0;
    }

    V* find(std::uint64_t key)
    {
        if (keys_.empty())
            return nullptr;
        for (std::size_t i = slot_of(key);; i = (i + 1) & mask_) {
            if (keys_[i] == key)
                return &values_[i];
            if (keys_[i] == free_slot)
                return nullptr;
        }
    }

    /// The value under key, put there as `value` when the key is new.
    V& find_or_put(std::uint64_t key, V const& value)
    {
        if (2 * (count_ + 1) > keys_.size())
            grow();
        for (std::size_t i = slot_of(key);; i = (i + 1) & mask_) {
            if (keys_[i] == key)
                return values_[i];
            if (keys_[i] == free_slot) {
                keys_[i] = key;
                values_[i] = value;
                ++count_;
                return values_[i];
            }
        }
    }

private:
    static constexpr std::uint64_t free_slot = ~std::uint64_t{0};

    std::size_t slot_of(std::uint64_t key) const
    {
        return static_cast<std::size_t>((key * 0x9E3779B97F4A7C15ULL) >> shift_) & mask_;
    }

    void grow()
    {
        std::vector<std::uint64_t> old_keys = std::move(keys_);
        std::vector<V> old_values = std::move(values_);
        std::size_t const size = std::max<std::size_t>(64, 2 * old_keys.size());
        keys_.assign(size, free_slot);
        values_.assign(size, V{});
        mask_ = size - 1;
        shift_ = 64U - static_cast<unsigned>(std::countr_zero(size));
        count_ = 0;
        for (std::size_t i = 0; i < old_keys.size(); ++i)
            if (old_keys[i] != free_slot)
                find_or_put(old_keys[i], old_values[i]);
    }

    std::vector<std::uint64_t> keys_;
    std::vector<V> values_;
    std::size_t mask_ = 0;
    unsigned shift_ = 64;
    std::size_t count_ = 0;
};

/// The swept boxes of this step's paths, for finding who a changed path may meet. Each box
/// at the start of the step is filed under the grid cell of its centre (cells at least as
/// large as the box, so a query looks one cell further). Every path that changes during the
/// step is filed in each cell its new box overlaps (a few), as event-driven codes file each
/// change where it happens, so that a query looks only at the changes near it: scanning a
/// list of every change so far made a step of many events cost their square. A box over
/// more than `most_cells` cells goes to a short list that queries scan, one entry per body.
/// A body filed again leaves its older filings stale, and queries pass over them; the boxes
/// at the start of the step stay, so a query sees a superset of the current paths, which the
/// caller checks exactly. The order in which it sees them does not matter: events are ordered
/// by time and indices alone.
class path_grid
{
public:
    void reset(std::span<aabb const> boxes, std::span<std::uint32_t const> members, std::size_t bodies)
    {
        entries_.clear();
        start_head_.clear();
        listed_.clear();
        listed_at_.assign(bodies, not_listed);
        changed_head_.clear();
        changed_.clear();
        filing_.assign(bodies, 0);
        seen_.assign(bodies, 0);
        stamp_ = 0;
        double extent = 0.0;
        for (aabb const& box : boxes)
            extent += box.extent().maxCoeff();
        cell_ = boxes.empty() ? 1.0 : std::max(2.0 * extent / static_cast<double>(boxes.size()), 1e-12);
        for (std::size_t k = 0; k < boxes.size(); ++k) {
            if (boxes[k].extent().maxCoeff() > cell_) {
                list(members[k], boxes[k]);
                continue;
            }
            // Each cell's entries are a chain found by a hash of its key: sorting them and a
            // binary search for each of a query's 27 cells were most of a step of a gas.
            std::uint32_t& head = start_head_.find_or_put(key(cell_of(boxes[k].centre())), no_change);
            entries_.push_back({members[k], head});
            head = static_cast<std::uint32_t>(entries_.size() - 1);
        }
    }

    /// Files `box` as body's current box: in the cells it overlaps, or in the list of large
    /// boxes, replacing the one it had there.
    void insert(std::uint32_t body, aabb const& box)
    {
        auto const lo = cell_of(box.min), hi = cell_of(box.max);
        std::int64_t const cells = cell_count(lo, hi, 0);
        if (cells <= 0 || cells > most_cells)
            return list(body, box);
        std::uint32_t const filing = ++filing_[body]; // its earlier filings are stale now
        for_each_cell(lo, hi, 0, [&](std::uint64_t k) {
            std::uint32_t& head = changed_head_.find_or_put(k, no_change);
            changed_.push_back({body, filing, head});
            head = static_cast<std::uint32_t>(changed_.size() - 1);
        });
    }

    /// Calls f(j) once for every body that may have had a box overlapping `box`.
    template <class F>
    void for_each_near(aabb const& box, F f)
    {
        ++stamp_;
        auto visit = [&](std::uint32_t j) {
            if (seen_[j] != stamp_) {
                seen_[j] = stamp_;
                f(j);
            }
        };
        for (auto const& [j, listed_box] : listed_)
            if (overlaps(box, listed_box))
                visit(j);
        auto const lo = cell_of(box.min), hi = cell_of(box.max);
        // The changes: a box that overlaps this one shares a cell with it.
        std::int64_t const own = cell_count(lo, hi, 0);
        if (own <= 0 || own > static_cast<std::int64_t>(changed_.size())) {
            for (auto const& filed : changed_)
                if (filed.filing == filing_[filed.body])
                    visit(filed.body);
        } else {
            for_each_cell(lo, hi, 0, [&](std::uint64_t k) {
                std::uint32_t* const head = changed_head_.find(k);
                // Stale filings are unlinked on the way, so that a cell's chain holds about
                // one filing per body there, however often they change.
                for (std::uint32_t* link = head; link && *link != no_change;) {
                    filed_change const& filed = changed_[*link];
                    if (filed.filing != filing_[filed.body]) {
                        *link = filed.next;
                        continue;
                    }
                    visit(filed.body);
                    link = &changed_[*link].next;
                }
            });
        }
        // The boxes at the start of the step, filed by centre: one cell further.
        std::int64_t const cells = cell_count(lo, hi, 1);
        if (cells > static_cast<std::int64_t>(entries_.size()) || cells <= 0) {
            for (auto const& filed : entries_)
                visit(filed.body);
            return;
        }
        for_each_cell(lo, hi, 1, [&](std::uint64_t k) {
            std::uint32_t const* const head = start_head_.find(k);
            for (std::uint32_t e = head ? *head : no_change; e != no_change; e = entries_[e].next)
                visit(entries_[e].body);
        });
    }

private:
    /// A box at the start of the step, in its cell's chain.
    struct entry
    {
        std::uint32_t body;
        std::uint32_t next; ///< the cell's entry before it, or no_change
    };
    /// A changed path filed in one cell: the cell's changes are a chain, newest first.
    struct filed_change
    {
        std::uint32_t body;
        std::uint32_t filing; ///< which of the body's filings: stale once it is filed again
        std::uint32_t next;   ///< the cell's change before it, or no_change
    };

    /// Files `box` in the list of large boxes, replacing body's entry there.
    void list(std::uint32_t body, aabb const& box)
    {
        if (listed_at_[body] == not_listed) {
            listed_at_[body] = static_cast<std::uint32_t>(listed_.size());
            listed_.push_back({body, box});
        } else {
            listed_[listed_at_[body]].second = box;
        }
    }

    std::array<std::int64_t, 3> cell_of(vec3 const& p) const
    {
        std::array<std::int64_t, 3> c{};
        for (int axis = 0; axis < 3; ++axis)
            c[static_cast<std::size_t>(axis)] = static_cast<std::int64_t>(
                std::clamp(std::floor(p[axis] / cell_), -1099511627776.0, 1099511627776.0));
        return c;
    }

    using cell = std::array<std::int64_t, 3>;

    /// Cells from lo to hi, widened by `more` on every side (<= 0 when the count overflows).
    static std::int64_t cell_count(cell const& lo, cell const& hi, std::int64_t more)
    {
        return (hi[0] - lo[0] + 1 + 2 * more) * (hi[1] - lo[1] + 1 + 2 * more) * (hi[2] - lo[2] + 1 + 2 * more);
    }

    /// Calls f(key) for each cell from lo to hi, widened by `more` on every side.
    template <class F>
    static void for_each_cell(cell const& lo, cell const& hi, std::int64_t more, F const& f)
    {
        for (std::int64_t x = lo[0] - more; x <= hi[0] + more; ++x)
            for (std::int64_t y = lo[1] - more; y <= hi[1] + more; ++y)
                for (std::int64_t z = lo[2] - more; z <= hi[2] + more; ++z)
                    f(key({x, y, z}));
    }

    /// 21 bits per axis; cells that wrap onto the same key only add candidates.
    static std::uint64_t key(std::array<std::int64_t, 3> const& c)
    {
        auto const bits = [](std::int64_t v) { return static_cast<std::uint64_t>(v) & 0x1FFFFFU; };
        return (bits(c[0]) << 42U) | (bits(c[1]) << 21U) | bits(c[2]);
    }

    /// Cells a changed box is filed in at most; a box of about the mean size overlaps up to 8.
    static constexpr std::int64_t most_cells = 27;
    double cell_ = 1.0;
    std::vector<entry> entries_;
    cell_map<std::uint32_t> start_head_; ///< cell key: its last entry
    static constexpr std::uint32_t not_listed = 0xffffffffU;
    static constexpr std::uint32_t no_change = 0xffffffffU;
    std::vector<std::pair<std::uint32_t, aabb>> listed_;
    std::vector<std::uint32_t> listed_at_; ///< per body: its place in listed_, or not_listed
    cell_map<std::uint32_t> changed_head_; ///< cell key: its newest change
    std::vector<filed_change> changed_;
    std::vector<std::uint32_t> filing_; ///< per body: its latest filing in the cells
    std::vector<std::uint32_t> seen_;
    std::uint32_t stamp_ = 0;
};

class event_loop
{
public:
    event_loop(collision_settings const& settings, std::span<wall const> walls,
               std::span<obstacle const> obstacles, collision_bodies const& bodies, double h,
               collision_workspace& ws, collision_stats& stats)
        : settings_(settings), walls_(walls), obstacles_(obstacles), b_(bodies), h_(h), ws_(ws),
          stats_(stats)
    {}

    /// Returns false when an event cap (per step or per body) was reached.
    bool run()
    {
        start_paths();
        predict_all();
        std::uint64_t handled = 0;
        while (!queue_.empty()) {
            event const e = queue_.top();
            queue_.pop();
            if (!current(e))
                continue;
            if (handled == settings_.max_events_per_step || !take_part(e.body) ||
                (e.kind == event_kind::pair && !take_part(e.other)))
                return false;
            ++handled;
            ++stats_.events;
            handle(e);
        }
        return true;
    }

    /// Moves every sphere to the end of the step and writes its state back.
    void finish()
    {
        for (std::uint32_t i : ws_.members) {
            ws_.paths[i].advance_to(h_);
            b_.x[i] = ws_.paths[i].x;
            b_.v[i] = ws_.paths[i].v;
        }
    }

private:
    bool is_dynamic(std::uint32_t i) const { return b_.inverse_mass[i] > 0.0; }

    /// Counts an event of body i; false when i already took part in its share.
    bool take_part(std::uint32_t i)
    {
        return ws_.events_of[i]++ < settings_.max_events_per_body;
    }

    void start_paths()
    {
        std::size_t const n = b_.x.size();
        ws_.paths.resize(n);
        ws_.path_box.resize(n);
        ws_.free_acceleration.resize(n);
        ws_.version.assign(n, 0);
        ws_.events_of.assign(n, 0);
        ws_.members.clear();
        ws_.boxes.clear();
        for (std::size_t i = 0; i < n; ++i) {
            if (b_.radius[i] <= 0.0)
                continue; // point masses never collide and keep the integrator's result
            vec3 const a = is_dynamic(static_cast<std::uint32_t>(i)) ? vec3((b_.v[i] - b_.v0[i]) / h_)
                                                                     : vec3(vec3::Zero());
            ws_.paths[i] = body_path{b_.x0[i], b_.v0[i], a, 0.0};
            ws_.free_acceleration[i] = a;
            ws_.members.push_back(static_cast<std::uint32_t>(i));
            ws_.boxes.push_back(ws_.paths[i].swept_box(h_, b_.radius[i]));
            ws_.path_box[i] = ws_.boxes.back();
        }
    }

    /// Every pair whose swept boxes meet, and every sphere against the static geometry.
    void predict_all()
    {
        grid_ready_ = false;
        find_overlapping_pairs(settings_.broadphase, ws_.boxes, ws_.pairs, ws_.broadphase);
        for (box_pair const& p : ws_.pairs)
            predict_pair(ws_.members[p.a], ws_.members[p.b], 0.0);
        for (std::uint32_t i : ws_.members)
            predict_static(i, 0.0);
    }

    /// After body i's path changed at time `now`: its contacts with everything.
    void predict_body(std::uint32_t i, double now)
    {
        predict_static(i, now);
        aabb const swept = path_from(i, now).swept_box(h_, b_.radius[i]);
        if (!grid_ready_) { // most steps of a dilute gas have no event: build on demand
            grid_.reset(ws_.boxes, ws_.members, b_.x.size());
            grid_ready_ = true;
        }
        grid_.insert(i, swept);
        ws_.path_box[i] = swept;
        // j's box from when its path last changed holds its box from now on: a candidate
        // whose path cannot meet this one's is passed over without sweeping its path again
        // (predict_pair decides exactly for the rest).
        grid_.for_each_near(swept, [&](std::uint32_t j) {
            if (j == i || (!is_dynamic(i) && !is_dynamic(j)))
                return;
            if (overlaps(swept, ws_.path_box[j]))
                predict_pair(i, j, now);
        });
    }

    body_path path_from(std::uint32_t i, double now) const
    {
        body_path p = ws_.paths[i];
        p.advance_to(now);
        return p;
    }

    void push(double time, event_kind kind, std::uint32_t body, std::uint32_t other)
    {
        std::uint32_t const other_version = kind == event_kind::pair ? ws_.version[other] : 0;
        queue_.push({time, kind, body, other, ws_.version[body], other_version});
    }

    bool current(event const& e) const
    {
        return ws_.version[e.body] == e.body_version &&
               (e.kind != event_kind::pair || ws_.version[e.other] == e.other_version);
    }

    void predict_pair(std::uint32_t i, std::uint32_t j, double now)
    {
        if (!is_dynamic(i) && !is_dynamic(j))
            return;
        body_path const pi = path_from(i, now), pj = path_from(j, now);
        double const limit = h_ - now;
        double const reach = b_.radius[i] + b_.radius[j];
        vec3 const a = pi.a - pj.a;
        std::optional<double> t;
        if (a.isZero(0.0)) {
            // Same acceleration (no forces, a uniform field): relative motion is a straight
            // line and the lecture's reduction gives the time exactly.
            t = sphere_time_of_impact(pi.x, pi.v, b_.radius[i], pj.x, pj.v, b_.radius[j], limit);
        } else {
            vec3 const d0 = pi.x - pj.x, v0 = pi.v - pj.v;
            double const a_norm = a.norm();
            t = advance_to_contact(
                limit, touching_tolerance * reach,
                [&](double s) { return (d0 + s * v0 + (0.5 * s * s) * a).norm() - reach; },
                [&](double s) {
                    vec3 const d = d0 + s * v0 + (0.5 * s * s) * a;
                    return -d.dot(v0 + s * a);
                },
                [&](double s) { return (v0 + s * a).norm() + a_norm * (limit - s); });
        }
        if (t)
            push(now + *t, event_kind::pair, i, j);
    }

    void predict_static(std::uint32_t i, double now)
    {
        if (!is_dynamic(i))
            return;
        body_path const p = path_from(i, now);
        double const r = b_.radius[i];
        double const limit = h_ - now;
        aabb const swept = p.swept_box(h_, r);
        vec3 const centre = swept.centre(), half = 0.5 * swept.extent();
        for (std::uint32_t k = 0; k < walls_.size(); ++k) {
            plane const& surface = walls_[k].surface;
            // the nearest point of the swept box (already grown by r) stays clear of the wall
            if (surface.normal.dot(centre) - surface.normal.cwiseAbs().dot(half) > surface.offset)
                continue;
            if (auto t = plane_time_of_impact(surface, r, p.x, p.v, p.a, limit))
                push(now + *t, event_kind::wall, i, k);
        }
        if (obstacles_.empty())
            return;
        double const a_norm = p.a.norm();
        for (std::uint32_t k = 0; k < obstacles_.size(); ++k) {
            obb const& box = obstacles_[k].box;
            if (!overlaps(swept, aabb_of(box)))
                continue;
            auto t = advance_to_contact(
                limit, touching_tolerance * r,
                [&](double s) { return sphere_vs_obb(p.position_at(now + s), r, box).distance; },
                [&](double s) {
                    auto const c = sphere_vs_obb(p.position_at(now + s), r, box);
                    return -c.normal.dot(p.velocity_at(now + s));
                },
                [&](double s) { return p.velocity_at(now + s).norm() + a_norm * (limit - s); });
            if (t)
                push(now + *t, event_kind::obstacle, i, k);
        }
    }

    void handle(event const& e)
    {
        double const now = e.time;
        std::uint32_t const i = e.body;
        body_path& p = ws_.paths[i];
        p.advance_to(now);
        double const r = b_.radius[i];
        bool answered = false;
        switch (e.kind) {
        case event_kind::wall: {
            wall const& w = walls_[e.other];
            if (w.surface.normal.dot(p.x) <= w.surface.offset + r + touching_tolerance * r)
                answered = detail::respond_to_surface(p, w.surface.normal, w.surface.offset + r,
                                                      w.damping, w.friction, settings_, h_);
            stats_.wall_contacts += answered ? 1U : 0U;
            break;
        }
        case event_kind::obstacle: {
            obstacle const& o = obstacles_[e.other];
            auto const c = sphere_vs_obb(p.x, r, o.box);
            if (c.distance <= touching_tolerance * r)
                answered = detail::respond_to_surface(p, c.normal, p.x.dot(c.normal) - c.distance,
                                                      o.damping, o.friction, settings_, h_);
            stats_.obstacle_contacts += answered ? 1U : 0U;
            break;
        }
        case event_kind::pair: {
            std::uint32_t const j = e.other;
            body_path& q = ws_.paths[j];
            q.advance_to(now);
            vec3 const d = p.x - q.x;
            double const distance = d.norm();
            double const reach = r + b_.radius[j];
            if (distance <= reach * (1.0 + touching_tolerance)) {
                vec3 const n = detail::contact_normal(d, distance);
                if (detail::respond_to_sphere_contact(p.v, b_.inverse_mass[i], p.a, q.v, b_.inverse_mass[j],
                                                      q.a, n, settings_, h_)) {
                    // a body resting on a wall that is hit moves freely again; if it is still
                    // pressed on the wall, its wall contact is found again at once
                    p.a = ws_.free_acceleration[i];
                    q.a = ws_.free_acceleration[j];
                    ++stats_.sphere_contacts;
                }
            }
            ++ws_.version[j];
            predict_body(j, now);
            break;
        }
        }
        ++ws_.version[i];
        predict_body(i, now);
    }

    collision_settings const& settings_;
    std::span<wall const> walls_;
    std::span<obstacle const> obstacles_;
    collision_bodies const& b_;
    double h_;
    collision_workspace& ws_;
    collision_stats& stats_;
    std::priority_queue<event, std::vector<event>, std::greater<>> queue_;
    path_grid grid_;
    bool grid_ready_ = false;
};

} // namespace

void resolve_continuous(collision_settings const& settings, std::span<wall const> walls,
                        std::span<obstacle const> obstacles, collision_bodies const& bodies,
                        double h, collision_workspace& workspace, collision_stats& stats)
{
    event_loop loop(settings, walls, obstacles, bodies, h, workspace, stats);
    bool const complete = loop.run();
    loop.finish();
    if (!complete) {
        // Too many events (a dense resting pile): finish the step as the discrete mode would,
        // starting from where the events left the bodies.
        ++stats.capped_steps;
        std::vector<vec3> const x0(bodies.x.begin(), bodies.x.end());
        std::vector<vec3> const v0(bodies.v.begin(), bodies.v.end());
        collision_bodies const settled{bodies.x, bodies.v, x0, v0, bodies.inverse_mass, bodies.radius};
        step_timings within_continuous; // counted as the continuous phase's
        resolve_discrete(settings, walls, obstacles, settled, h, workspace.discrete, stats, within_continuous);
    }
}

} // namespace kugel::physics
