// Continuous collision mode: inside a step, contacts are handled in time order. Each sphere
// moves on its step path (body_path); the earliest predicted contact is taken first, the
// bodies involved are moved to that time and answered, and only their future contacts are
// predicted again. Nothing tunnels, at any speed: a contact is found from the paths, not from
// where the bodies happen to be at the end of the step.

#include "physics/collision_rules.hpp"
#include "physics/collisions.hpp"
#include "physics/continuous/touching.hpp"
#include "physics/discrete/discrete_step.hpp"
#include "physics/time_of_impact.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>
#include <functional>
#include <vector>

namespace kugel::physics {

using continuous::position_slack;
using continuous::touching_tolerance;

namespace {

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

class event_loop
{
public:
    event_loop(collision_settings const& settings, std::span<wall const> walls,
               std::span<obstacle const> obstacles, collision_bodies const& bodies, double h,
               continuous::workspace& ws, collision_stats& stats, parallel_for* loops)
        : settings_(settings), walls_(walls), obstacles_(obstacles), b_(bodies), h_(h), ws_(ws),
          stats_(stats), loops_(loops)
    {
        for (std::size_t k = 0; k < walls.size() && k < facings_.size(); ++k) {
            vec3 const& n = walls[k].surface.normal;
            Eigen::Index axis = 0;
            if (n.cwiseAbs().maxCoeff(&axis) == 1.0 && (n.array() == 0.0).count() == 2)
                facings_[k] = {static_cast<int>(axis), n[axis] > 0.0};
        }
        only_facing_walls_ = walls.size() <= facings_.size();
        for (std::size_t k = 0; k < walls.size() && only_facing_walls_; ++k) {
            facing const f = facings_[k];
            if (f.axis < 0) {
                only_facing_walls_ = false;
                break;
            }
            double& bound = (f.positive ? below_ : above_)[f.axis];
            bound = std::max(bound, walls[k].surface.offset);
        }
    }

    /// Returns false when an event cap (per step or per body) was reached.
    ///
    /// The step is taken in slices short enough that a sphere moves about a radius in each
    /// (one slice unless spheres move farther than that in a step): the grid holds each path's
    /// box over the slice, so a fast sphere's prediction looks at the spheres near it now, not
    /// at all it may pass in the step. Events are still predicted to the step's end and taken
    /// in one order: a pair is predicted from where the later of its two paths changed, with
    /// that body first, exactly as if it had been predicted when that path changed, so the
    /// slicing changes the cost, never an event.
    bool run()
    {
        ws_.queue.clear();
        start_paths();
        std::size_t const slices = slice_count();
        std::uint64_t handled = 0;
        double slice_start = 0.0;
        for (std::size_t s = 1; s <= slices; ++s) {
            slice_end_ = s == slices ? h_ : h_ * static_cast<double>(s) / static_cast<double>(slices);
            if (s > 1) // the first slice's boxes are the whole step's when it is the only one
                file_boxes(slice_start);
            else if (slices > 1)
                file_boxes(0.0);
            start_slice();
            bool const last = s == slices;
            while (!ws_.queue.empty() && (last || ws_.queue.front().time <= slice_end_)) {
                std::pop_heap(ws_.queue.begin(), ws_.queue.end(), std::greater<>{});
                event const e = ws_.queue.back();
                ws_.queue.pop_back();
                if (!current(e))
                    continue;
                if (handled == settings_.max_events_per_step || !take_part(e.body) ||
                    (e.kind() == continuous::event_kind::pair && !take_part(e.other())))
                    return false;
                ++handled;
                ++stats_.events;
                handle(e);
            }
            slice_start = slice_end_;
        }
        return true;
    }

    /// Moves every sphere to the end of the step and writes its state back.
    void finish()
    {
        for (std::uint32_t i : ws_.members) {
            note_segment(i, h_);
            ws_.paths[i].advance_to(h_);
            b_.x[i] = ws_.paths[i].x;
            b_.v[i] = ws_.paths[i].v;
        }
    }

private:
    using event = continuous::event;
    using event_kind = continuous::event_kind;

    /// A slice is as long as lets the mean sphere move about `slice_reach` of the mean radius;
    /// at most `most_slices` a step.
    static constexpr double slice_reach = 1.0;
    static constexpr std::size_t most_slices = 64;

    bool is_dynamic(std::uint32_t i) const { return b_.inverse_mass[i] > 0.0; }

    /// Counts an event of body i; false when i already took part in its share.
    bool take_part(std::uint32_t i)
    {
        return ws_.events_of[i]++ < settings_.max_events_per_body;
    }

    /// Each sphere's path and its box over the whole step, and its walls' and boxes' events:
    /// chunks of spheres at a time (on the lent threads), each into a list of its own.
    void start_paths()
    {
        std::size_t const n = b_.x.size();
        ws_.paths.resize(n);
        ws_.path_box.resize(n);
        ws_.free_acceleration.resize(n);
        ws_.version.assign(n, 0);
        ws_.changed.assign(n, 0);
        ws_.events_of.assign(n, 0);
        ws_.segments.clear();
        ws_.touches.clear();
        ws_.members.clear();
        changes_ = 0;
        for (std::size_t i = 0; i < n; ++i)
            if (b_.radius[i] > 0.0) // point masses never collide and keep the integrator's result
                ws_.members.push_back(static_cast<std::uint32_t>(i));
        ws_.found.resize(std::max(ws_.found.size(), chunk_count(ws_.members.size())));
        run_chunks(loops_, ws_.members.size(), [&](std::size_t chunk, std::size_t begin, std::size_t end) {
            std::vector<event>& found = ws_.found[chunk];
            for (std::size_t k = begin; k < end; ++k) {
                std::uint32_t const i = ws_.members[k];
                vec3 const a = is_dynamic(i) ? vec3((b_.v[i] - b_.v0[i]) / h_) : vec3(vec3::Zero());
                body_path const& p = ws_.paths[i] = body_path{b_.x0[i], b_.v0[i], a, 0.0};
                ws_.free_acceleration[i] = a;
                // the path's box over the whole step: its walls' test, and the first slice's box
                ws_.path_box[i] = p.swept_box(h_, b_.radius[i]);
                predict_static(i, 0.0, p, ws_.path_box[i], &found);
            }
        });
        queue_found(chunk_count(ws_.members.size()));
    }

    /// Moves the events of the first `lists` lists found into the queue.
    void queue_found(std::size_t lists)
    {
        std::size_t added = 0;
        for (std::size_t c = 0; c < lists; ++c) {
            ws_.queue.insert(ws_.queue.end(), ws_.found[c].begin(), ws_.found[c].end());
            added += ws_.found[c].size();
            ws_.found[c].clear();
        }
        if (added > 0)
            std::make_heap(ws_.queue.begin(), ws_.queue.end(), std::greater<>{});
    }

    std::size_t slice_count() const
    {
        double travel = 0.0, reach = 0.0;
        for (std::uint32_t i : ws_.members) {
            body_path const& p = ws_.paths[i];
            travel += p.v.norm() * h_ + 0.5 * p.a.norm() * h_ * h_;
            reach += b_.radius[i];
        }
        double const slices = std::ceil(travel / (slice_reach * reach));
        // One slice when nothing moves or there is nothing to move (0/0), or a path is not
        // finite (the caller's business, not a reason to loop).
        if (!(slices > 1.0))
            return 1;
        return slices >= static_cast<double>(most_slices) ? most_slices : static_cast<std::size_t>(slices);
    }

    /// Each path's box over the slice, from where it is at the slice's start (or from its last
    /// change).
    void file_boxes(double from)
    {
        run_chunks(loops_, ws_.members.size(), [&](std::size_t, std::size_t begin, std::size_t end) {
            for (std::size_t k = begin; k < end; ++k) {
                std::uint32_t const i = ws_.members[k];
                body_path const& p = ws_.paths[i];
                ws_.path_box[i] = (p.t >= from ? p : path_from(i, from)).swept_box(slice_end_, b_.radius[i]);
            }
        });
    }

    /// Files every path's box and predicts every pair whose boxes overlap: layers of the grid
    /// at a time (on the lent threads), each into a list of its own. The queue orders events
    /// by time and indices alone, so whichever list found an event, it is taken in its place.
    void start_slice()
    {
        ws_.grid.reset(ws_.path_box, ws_.members);
        std::size_t const layers = ws_.grid.layers();
        std::size_t const parts = loops_ == nullptr ? 1 : std::min<std::size_t>(layers, 16);
        ws_.pairs.resize(std::max(ws_.pairs.size(), parts));
        ws_.found.resize(std::max(ws_.found.size(), parts));
        run_loop(loops_, parts, [&](std::size_t part) {
            auto& pairs = ws_.pairs[part];
            ws_.grid.overlapping_pairs(layers * part / parts, layers * (part + 1) / parts, pairs);
            for (auto const& [i, j] : pairs)
                predict_between(i, j, &ws_.found[part]);
        });
        queue_found(parts);
        // The boxes too large for a cell: against those that fit near them, and among themselves.
        auto const listed = ws_.grid.listed_at_reset();
        if (listed.empty())
            return;
        ws_.listed_boxes.clear();
        for (std::uint32_t i : listed) {
            aabb const& box = ws_.path_box[i];
            ws_.listed_boxes.push_back(box);
            ws_.grid.for_each_filed_near(box, [&](std::uint32_t j) {
                if (overlaps(box, ws_.path_box[j]))
                    predict_between(i, j, nullptr);
            });
        }
        find_overlapping_pairs(broadphase_kind::uniform_grid, ws_.listed_boxes, ws_.listed_pairs, ws_.broadphase);
        for (box_pair const& p : ws_.listed_pairs)
            predict_between(listed[p.a], listed[p.b], nullptr);
    }

    /// Predicts i and j from where the later of their paths changed, that body first (the
    /// lower slot when neither changed in this step): what predict_body did when that path
    /// changed, so the same event, bit for bit, whenever it is found.
    void predict_between(std::uint32_t i, std::uint32_t j, std::vector<event>* into)
    {
        if (!is_dynamic(i) && !is_dynamic(j))
            return;
        std::uint32_t const ci = ws_.changed[i], cj = ws_.changed[j];
        if (cj > ci || (cj == ci && j < i))
            std::swap(i, j);
        predict_pair(i, j, ws_.paths[i].t, into);
    }

    /// After body i's path changed at time `now`: its contacts with everything.
    void predict_body(std::uint32_t i, double now)
    {
        ws_.changed[i] = ++changes_;
        predict_static(i, now);
        aabb const swept = path_from(i, now).swept_box(slice_end_, b_.radius[i]);
        ws_.grid.insert(i, swept);
        ws_.path_box[i] = swept;
        // j's box from when its path last changed holds its box from now on: a candidate
        // whose path cannot meet this one's in the slice is passed over without sweeping its
        // path again (predict_pair decides exactly for the rest; later slices look again).
        ws_.grid.for_each_near(swept, [&](std::uint32_t j) {
            if (j == i || (!is_dynamic(i) && !is_dynamic(j)))
                return;
            if (overlaps(swept, ws_.path_box[j]))
                predict_pair(i, j, now);
        });
    }

    /// i's path from `now`: its own when it was last changed then (no copy), else `scratch`
    /// moved there. The same numbers either way, up to the sign of a zero (advance_to(t) at t
    /// adds ±0), which no time of impact depends on.
    body_path const& path_at(std::uint32_t i, double now, body_path& scratch) const
    {
        body_path const& p = ws_.paths[i];
        if (p.t == now)
            return p;
        scratch = p;
        scratch.advance_to(now);
        return scratch;
    }

    body_path path_from(std::uint32_t i, double now) const
    {
        body_path p = ws_.paths[i];
        p.advance_to(now);
        return p;
    }

    /// Queues an event, or adds it to `into` when given (a list found on a lent thread).
    void push(double time, event_kind kind, std::uint32_t body, std::uint32_t other, std::vector<event>* into)
    {
        std::uint32_t const other_version = kind == event_kind::pair ? ws_.version[other] : 0;
        event const e{time, kind, body, other, ws_.version[body], other_version};
        if (into != nullptr) {
            into->push_back(e);
            return;
        }
        ws_.queue.push_back(e);
        std::push_heap(ws_.queue.begin(), ws_.queue.end(), std::greater<>{});
    }

    bool current(event const& e) const
    {
        return ws_.version[e.body] + (e.kind() == event_kind::pair ? ws_.version[e.other()] : 0U) == e.versions;
    }

    void predict_pair(std::uint32_t i, std::uint32_t j, double now, std::vector<event>* into = nullptr)
    {
        if (!is_dynamic(i) && !is_dynamic(j))
            return;
        body_path scratch_i, scratch_j;
        body_path const& pi = path_at(i, now, scratch_i);
        body_path const& pj = path_at(j, now, scratch_j);
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
        if (t && !left_to_discrete(pi, pj, a, *t, std::min(b_.radius[i], b_.radius[j])))
            push(now + *t, event_kind::pair, i, j, into);
    }

    /// The sweep's rule (workspace::left_to_discrete): whether a pair on these paths (from now),
    /// meeting in `t` with relative acceleration `a`, moves against the other so slowly that
    /// in a whole step it would go less than the sweep's share of the smaller radius: as slowly
    /// as a body the sweep leaves to the discrete step. Their whole relative speed, not its
    /// normal part: a grazing pair closes slowly, but one fast along the contact may be apart
    /// again at the step's end, and the discrete step would not see it.
    bool left_to_discrete(body_path const& pi, body_path const& pj, vec3 const& a, double t, double smaller) const
    {
        if (!(ws_.left_to_discrete > 0.0))
            return false;
        double const speed = (pi.v - pj.v + t * a).norm();
        return speed + 0.5 * a.norm() * h_ < ws_.left_to_discrete * smaller;
    }

    void predict_static(std::uint32_t i, double now)
    {
        if (!is_dynamic(i))
            return;
        body_path scratch;
        body_path const& p = path_at(i, now, scratch);
        predict_static(i, now, p, p.swept_box(h_, b_.radius[i]));
    }

    /// The same, given i's path from now and its box to the step's end.
    void predict_static(std::uint32_t i, double now, body_path const& p, aabb const& swept,
                        std::vector<event>* into = nullptr)
    {
        if (!is_dynamic(i))
            return;
        double const r = b_.radius[i];
        double const limit = h_ - now;
        vec3 const centre = swept.centre(), half = 0.5 * swept.extent();
        // Most boxes are clear of every wall (the same test as below, against the farthest
        // reaching wall of each axis and side at once).
        bool const clear = only_facing_walls_ &&
                           ((centre - half).array() > below_.array()).all() &&
                           ((-centre - half).array() > above_.array()).all();
        for (std::uint32_t k = 0; k < (clear ? 0U : walls_.size()); ++k) {
            plane const& surface = walls_[k].surface;
            // the nearest point of the swept box (already grown by r) stays clear of the wall:
            // n·centre − |n|·half, which for a normal ±e_k is ±centre_k − half_k
            facing const f = k < facings_.size() ? facings_[k] : facing{};
            double const nearest = f.axis >= 0 ? (f.positive ? centre[f.axis] : -centre[f.axis]) - half[f.axis]
                                               : surface.normal.dot(centre) - surface.normal.cwiseAbs().dot(half);
            if (nearest > surface.offset)
                continue;
            if (auto t = plane_time_of_impact(surface, r, p.x, p.v, p.a, limit))
                push(now + *t, event_kind::wall, i, k, into);
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
                push(now + *t, event_kind::obstacle, i, k, into);
        }
    }

    void handle(event const& e)
    {
        double const now = e.time;
        std::uint32_t const i = e.body;
        body_path& p = ws_.paths[i];
        note_segment(i, now);
        p.advance_to(now);
        double const r = b_.radius[i];
        bool answered = false;
        switch (e.kind()) {
        case event_kind::wall: {
            wall const& w = walls_[e.other()];
            double const height = w.surface.normal.dot(p.x);
            if (height <= w.surface.offset + r + touching_tolerance * r ||
                height <= w.surface.offset + r + position_slack(p.x, vec3::Zero()))
                answered = detail::respond_to_surface(p, w.surface.normal, w.surface.offset + r,
                                                      w.damping, w.friction, settings_, h_);
            stats_.wall_contacts += answered ? 1U : 0U;
            break;
        }
        case event_kind::obstacle: {
            obstacle const& o = obstacles_[e.other()];
            auto const c = sphere_vs_obb(p.x, r, o.box);
            if (c.distance <= touching_tolerance * r || c.distance <= position_slack(p.x, vec3::Zero()))
                answered = detail::respond_to_surface(p, c.normal, p.x.dot(c.normal) - c.distance,
                                                      o.damping, o.friction, settings_, h_);
            stats_.obstacle_contacts += answered ? 1U : 0U;
            break;
        }
        case event_kind::pair: {
            std::uint32_t const j = e.other();
            body_path& q = ws_.paths[j];
            note_segment(j, now);
            q.advance_to(now);
            vec3 const d = p.x - q.x;
            double const distance = d.norm();
            double const reach = r + b_.radius[j];
            if (distance <= reach * (1.0 + touching_tolerance) || distance <= reach + position_slack(p.x, q.x)) {
                vec3 const n = detail::contact_normal(d, distance);
                // the response's own test: a contact slower than the rest threshold rests
                double const closing = (p.v - q.v).dot(n);
                bool const rests = -closing * settings_.restitution < detail::rest_threshold(settings_, p.a - q.a, n, h_);
                if (detail::respond_to_sphere_contact(p.v, b_.inverse_mass[i], p.a, q.v, b_.inverse_mass[j],
                                                      q.a, n, settings_, h_)) {
                    // a body resting on a wall that is hit moves freely again; if it is still
                    // pressed on the wall, its wall contact is found again at once
                    p.a = ws_.free_acceleration[i];
                    q.a = ws_.free_acceleration[j];
                    if (rests) // held together by their forces: they rest against each other
                        detail::hold_resting_pair(p, b_.inverse_mass[i], q, b_.inverse_mass[j], n, reach);
                    ++stats_.sphere_contacts;
                    if (ws_.keep_contacts)
                        ws_.touches.push_back({i, j, now});
                }
            }
            ++ws_.version[j];
            predict_body(j, now);
            break;
        }
        case event_kind::crossing: // the calendar's alone
            break;
        }
        ++ws_.version[i];
        predict_body(i, now);
    }

    /// For the caller that asks: body i's path from its last change to `until`.
    void note_segment(std::uint32_t i, double until)
    {
        if (ws_.keep_segments)
            ws_.segments.push_back({i, until, ws_.paths[i]});
    }

    collision_settings const& settings_;
    std::span<wall const> walls_;
    std::span<obstacle const> obstacles_;
    collision_bodies const& b_;
    double h_;
    continuous::workspace& ws_;
    collision_stats& stats_;
    parallel_for* loops_;
    /// A wall whose normal is ±e_axis (as make_plane stores those), for its one-coordinate
    /// test; axis −1 for any other wall, and for walls past the first few.
    struct facing
    {
        int axis = -1;
        bool positive = true;
    };
    std::array<facing, 8> facings_{};
    /// Every wall faces along an axis: below_ (normals +e_k) and above_ (−e_k) hold, per axis,
    /// the largest offset of those walls, −∞ where there is none.
    bool only_facing_walls_ = false;
    vec3 below_ = vec3::Constant(-std::numeric_limits<double>::infinity());
    vec3 above_ = vec3::Constant(-std::numeric_limits<double>::infinity());
    double slice_end_ = 0.0;
    std::uint32_t changes_ = 0; ///< paths changed so far in the step
};

} // namespace

void resolve_continuous(collision_settings const& settings, std::span<wall const> walls,
                        std::span<obstacle const> obstacles, collision_bodies const& bodies,
                        double h, collision_workspace& workspace, collision_stats& stats, parallel_for* loops)
{
    continuous::calendar& kept = workspace.continuous.kept;
    auto outcome = continuous::calendar::outcome::declined;
    if (settings.event_calendar && obstacles.empty() && !workspace.continuous.keep_segments &&
        !workspace.continuous.keep_contacts)
        outcome = kept.step(settings, walls, bodies, h, stats, loops);
    else
        kept.forget();
    bool complete = outcome == continuous::calendar::outcome::done;
    if (outcome == continuous::calendar::outcome::declined) {
        // The step-by-step loop wants the step's start and its free motion: the drift, when
        // it is still to come (a world without forces), made here. The calendar needs neither
        // (its paths are the drift), so a gas keeps no second copy of every position.
        collision_bodies moved = bodies;
        if (bodies.drift_pending) {
            std::vector<vec3>& start = workspace.continuous.start;
            start.resize(bodies.x.size());
            run_chunks(loops, bodies.x.size(), [&](std::size_t, std::size_t begin, std::size_t end) {
                for (std::size_t i = begin; i < end; ++i) { // x₀ kept on the way: one pass
                    start[i] = bodies.x[i];
                    bodies.x[i] += h * bodies.v[i];
                }
            });
            moved.x0 = start;
            moved.v0 = bodies.v;
            moved.drift_pending = false;
        }
        event_loop loop(settings, walls, obstacles, moved, h, workspace.continuous, stats, loops);
        complete = loop.run();
        loop.finish();
    }
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
    // Rounding may leave a sphere inside a wall by an ulp; the calendar clamped its spheres
    // (the few beside a wall) as it wrote them.
    if (outcome != continuous::calendar::outcome::done)
        clamp_to_walls(walls, bodies);
}

} // namespace kugel::physics
