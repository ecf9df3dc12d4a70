// Phase 4 of the discrete step: momentum exchanged at the contacts.

#include "passes.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <utility>

namespace kugel::physics::discrete {

namespace {

/// How far from its centre a wall counts as touching a sphere: its radius, to a relative 1e-9.
double touching_reach(packed_sphere const& s) { return s.radius * (1.0 + 1e-9); }

bool touches(wall const& w, packed_sphere const& s)
{
    return w.surface.normal.dot(s.x) <= w.surface.offset + touching_reach(s);
}

/// A sphere touching a wall and moving into it meets it (meet_wall): a stack's weight,
/// pressing slower than the rest threshold, is carried by the wall. Returns whether its
/// velocity changed.
bool meet_touched_walls(detail::wall_set const& walls, packed_sphere const& s, vec3& v, vec3 const& a,
                        collision_settings const& settings, double h)
{
    if (walls.beyond(s.x, touching_reach(s)))
        return false;
    bool changed = false;
    for (wall const& w : walls.all)
        if (touches(w, s))
            changed |= detail::meet_wall(w, v, a, settings, h);
    return changed;
}

/// The passes work on copies of the contacts' spheres' velocities and inverse masses (and free
/// accelerations), taken once from the body slots and put back after, side by side in the
/// order they were listed: the passes then read a few megabytes at 10^6 spheres, where reading
/// by slot waited on memory for most contacts in every pass. Each slab lists its contacts'
/// spheres that no slab listed before it, into a range of the copies of its own (room for two
/// per contact), so slabs of one parity list at the same time. The spheres in contacts that
/// touch a wall are listed too (in `touched`): the passes stop them at it. Positions do not
/// change in these passes, so that list, and the contacts' normals, hold for all of them.
void copy_contact_spheres(step_context const& step, free_accelerations free_a, discrete_workspace& ws)
{
    sphere_grid const& grid = ws.grid;
    std::uint32_t copies = 0;
    for (contact_slab& slab : ws.slabs) {
        slab.first_copied = copies;
        copies += 2 * static_cast<std::uint32_t>(slab.contacts.size());
    }
    ws.moving.resize(copies);
    ws.moving_acceleration.resize(free_a.any() ? copies : 0);
    bool const identified = free_a.any() && !step.bodies.ids.empty();
    ws.moving_id.resize(identified ? copies : 0);
    ws.moving_rank.resize(free_a.any() ? copies : 0);
    ws.listed_at.resize(grid.sphere_count());
    once_per_pass const once{ws.mark, next_stamp(ws, grid.sphere_count())};
    std::span<vec3> const v = step.bodies.v;
    by_parity(ws, step.loops, [&](contact_slab& slab) {
        slab.copied.clear();
        slab.pushed.clear();
        slab.responses = 0;
        for (sphere_pair const& p : slab.contacts) {
            once.list(slab.copied, p.a);
            once.list(slab.copied, p.b);
        }
        slab.touched.clear();
        for (std::size_t listed = 0; listed < slab.copied.size(); ++listed) {
            std::uint32_t const k = slab.copied[listed];
            std::uint32_t const i = grid.slot(k);
            auto const c = static_cast<std::uint32_t>(slab.first_copied + listed);
            fetch_ahead(slab.copied, listed, [&](std::uint32_t later) { return &v[grid.slot(later)]; });
            ws.listed_at[k] = c;
            ws.moving[c] = {v[i], grid.inverse_mass(k)};
            if (free_a.any()) {
                ws.moving_acceleration[c] = free_a[i];
                ws.moving_rank[c] = k;
            }
            if (identified)
                ws.moving_id[c] = to_number(step.bodies.ids[i]);
            packed_sphere const& s = grid.sphere(k);
            if (!step.walls.beyond(s.x, touching_reach(s)))
                slab.touched.push_back(k);
        }
    });
    // The contacts as positions among the copies, their normals, and what each allows: found
    // once. A pair apart at the end of free motion (a speculative contact, found within the
    // grid's margin) would end the step a gap g apart: it may approach faster than it did in
    // free motion by g/h and still end touching, so its velocities after the passes may close
    // at up to g/h − closing before (and no less than 0, which the position passes answer).
    auto const& moving = ws.moving;
    each_slab(ws, step.loops, [&](contact_slab& slab) {
        slab.moving_pairs.resize(slab.contacts.size());
        slab.normals.resize(slab.contacts.size());
        slab.allowed.resize(slab.contacts.size());
        for (std::size_t k = 0; k < slab.contacts.size(); ++k) {
            sphere_pair const& c = slab.contacts[k];
            auto const pair = sphere_pair{ws.listed_at[c.a], ws.listed_at[c.b]};
            slab.moving_pairs[k] = pair;
            packed_sphere const& a = grid.sphere(c.a);
            packed_sphere const& b = grid.sphere(c.b);
            vec3 const d = a.x - b.x;
            double const distance = d.norm();
            vec3 const n = detail::contact_normal(d, distance);
            slab.normals[k] = n;
            double const gap = distance - (a.radius + b.radius);
            double const closing = (moving[pair.a].v - moving[pair.b].v).dot(n);
            slab.allowed[k] = gap > 0.0 ? std::max(gap / step.h - closing, 0.0) : -1.0;
        }
    });
}

/// The contacts in the order propagate_support() takes them: each under its upper sphere,
/// which lies against the pair's acceleration; the upper sphere's depth along its own
/// acceleration orders them (the deepest first), and keeps each sphere's contacts together.
/// Positions do not change in the velocity passes: one order serves every support pass.
///
/// The upper spheres are sorted, not the contacts (a sphere's contacts share its depth): a
/// sphere rests on about three, and a sort of the contacts took 9 % of a forming pile's
/// step. Each sphere's contacts then follow in the order they were listed, by slab and
/// place in it, as the sort of the contacts had them.
void order_support(discrete_workspace& ws)
{
    sphere_grid const& grid = ws.grid;
    auto& listed = ws.support_scratch;
    auto& uppers = ws.support_uppers;
    auto& count = ws.support_count;
    listed.clear();
    uppers.clear();
    count.assign(ws.moving.size(), 0);
    for (std::uint32_t s = 0; s < ws.slabs.size(); ++s) {
        contact_slab const& slab = ws.slabs[s];
        for (std::uint32_t k = 0; k < slab.contacts.size(); ++k) {
            auto const [i, j] = slab.moving_pairs[k];
            vec3 const down = ws.moving_acceleration[i] + ws.moving_acceleration[j];
            sphere_pair const& c = slab.contacts[k];
            bool const a_above = (grid.sphere(c.a).x - grid.sphere(c.b).x).dot(down) < 0.0;
            std::uint32_t const upper = a_above ? i : j;
            double const depth = grid.sphere(a_above ? c.a : c.b).x.dot(ws.moving_acceleration[upper]);
            listed.push_back({depth, upper, s, k, a_above});
            if (count[upper]++ == 0)
                uppers.push_back({depth, upper});
        }
    }
    std::sort(uppers.begin(), uppers.end(), [](auto const& p, auto const& q) {
        return p.depth != q.depth ? p.depth > q.depth : p.upper < q.upper;
    });
    std::uint32_t at = 0;
    for (auto const& u : uppers)
        at += std::exchange(count[u.upper], at);
    auto& order = ws.support_order;
    order.resize(listed.size());
    for (auto const& e : listed)
        order[count[e.upper]++] = e;
}

/// Keeps what a sphere's stops that pushed summed, by the lower body: the first support pass's
/// for the last one, which adds its own to them (first pass first, as the sums ran) and files
/// the sphere's sums of the step for the next step's first pass.
void keep_stops(discrete_workspace& ws, std::uint64_t upper_id, std::span<discrete_workspace::support_stop const> stops,
                std::size_t group, bool resting_only)
{
    auto const pushing = [](auto const& stop) { return stop.pushed > 0.0; };
    if (resting_only) {
        for (auto const& stop : stops)
            if (pushing(stop))
                ws.resting_stops.push_back({stop.lower_id, stop.pushed, stop.friction});
        return;
    }
    auto& merged = ws.merged_stops;
    std::uint32_t const begin = ws.resting_first[group];
    std::uint32_t const end = group + 1 < ws.resting_first.size() ? ws.resting_first[group + 1]
                                                                   : static_cast<std::uint32_t>(ws.resting_stops.size());
    merged.assign(ws.resting_stops.begin() + begin, ws.resting_stops.begin() + end);
    for (auto const& stop : stops) {
        if (!pushing(stop))
            continue;
        if (kept_stop* const kept = find(std::span(merged), stop.lower_id)) {
            kept->pushed += stop.pushed;
            kept->friction += stop.friction;
        } else {
            merged.push_back({stop.lower_id, stop.pushed, stop.friction});
        }
    }
    ws.stops.file(upper_id, merged);
}

/// Support, passed up a pile in one pass: each sphere in order of depth along gravity (the
/// deepest first) is stopped against the spheres it rests on as if they were immovable (shock
/// propagation, Guendelman, Bridson and Fedkiw 2003), those of them that are supported: that
/// are static, touch a wall their acceleration presses them into, or rest on a sphere that is
/// supported. A sphere in the hollow of three or four below is stopped against all of them
/// together (below), as stopping it against one in turn left it closing on another or pushed
/// it up and off. The passes before leave momentum exchanged; this pass leaves no contact of a pile
/// closing, whatever its height, where Gauss–Seidel passes would need about as many passes as
/// the pile has layers. Spheres that nothing static carries (a cluster in free fall, two
/// planets that meet) are left as the passes left them, their momentum kept. One sequential
/// pass: the order is the pile's, not the slabs'. Friction acts at each stop by Coulomb's law,
/// within μ times the stop's normal change, so a sphere on a slope shallower than atan μ stays.
///
/// It runs twice. First, before the momentum-exchange passes, on the resting contacts alone
/// (`resting_only`: those that would not bounce by the rest threshold of the upper sphere's
/// own acceleration; under uniform gravity the pair's relative acceleration is zero and tells
/// nothing): a pile at rest then stays at rest, each layer stopped on the one below, instead of
/// every layer first pushing the one below it aside by exchanging momentum with it. Then,
/// after those passes, on every contact.
void propagate_support(step_context const& step, discrete_workspace& ws, bool resting_only)
{
    sphere_grid const& grid = ws.grid;
    auto& supported = ws.supported;
    supported.resize(ws.moving.size());
    for (std::size_t c = 0; c < supported.size(); ++c) // a static sphere carries like a wall
        supported[c] = ws.moving[c].inverse_mass == 0.0 ? 1 : 0;
    for (contact_slab const& slab : ws.slabs) {
        for (std::uint32_t k : slab.touched) {
            packed_sphere const& s = grid.sphere(k);
            std::uint32_t const c = ws.listed_at[k];
            for (wall const& w : step.walls.all)
                if (touches(w, s) && w.surface.normal.dot(ws.moving_acceleration[c]) < 0.0)
                    supported[c] = 1;
        }
    }
    auto const& order = ws.support_order;
    // Each stop's sums are kept by its bodies' ids, when the step knows them: the first pass of
    // the next step starts from them (warm starting).
    bool const remembered = !ws.moving_id.empty();
    if (remembered && resting_only) {
        std::swap(ws.last_stops, ws.stops);
        ws.stops.clear(ws.support_uppers.size());
        ws.resting_stops.clear();
        ws.resting_first.clear();
    }
    // One sphere against its supports, held still: projected Gauss–Seidel on its own velocity,
    // each stop's normal change and friction summed over the sweeps (so a later sweep can take
    // back what an earlier one gave too much of: summed normal change >= 0, friction within
    // μ times it), until no sweep changes the velocity by more than 2^-20 of one step's
    // acceleration, or for at most `support_sweeps` (16 unless the scene says). The first pass
    // starts each stop from its sums of the last step: a sphere at rest needs the same ones, and
    // then the first sweep changes nothing.
    int const most_sweeps = step.settings.support_sweeps;
    auto& moving = ws.moving;
    auto& stops = ws.support_stops;
    for (std::size_t first = 0, last = 0, group = 0; first < order.size(); first = last, ++group) {
        std::uint32_t const upper = order[first].upper;
        for (last = first; last < order.size() && order[last].upper == upper; ++last) {}
        if (remembered && resting_only)
            ws.resting_first.push_back(static_cast<std::uint32_t>(ws.resting_stops.size()));
        if (moving[upper].inverse_mass == 0.0)
            continue;
        vec3& v = moving[upper].v;
        stops.clear();
        for (std::size_t e = first; e < last; ++e) {
            auto const& o = order[e];
            contact_slab const& slab = ws.slabs[o.slab];
            auto const [i, j] = slab.moving_pairs[o.contact];
            std::uint32_t const lower = o.a_above ? j : i;
            if (!supported[lower])
                continue;
            // n points from b to a: from the lower sphere to the upper
            vec3 const n = o.a_above ? slab.normals[o.contact] : vec3(-slab.normals[o.contact]);
            double const allowed = std::max(slab.allowed[o.contact], 0.0); // touching: none
            double const closing = (v - moving[lower].v).dot(n);
            if (resting_only && slab.allowed[o.contact] < 0.0 &&
                -closing * step.settings.restitution >=
                    detail::rest_threshold(step.settings, ws.moving_acceleration[upper], n, step.h))
                continue; // a bounce: the passes answer it
            if (closing <= -allowed) // it ends the step on the lower one
                supported[upper] = 1;
            stops.push_back({n, allowed, moving[lower].v, step.settings.friction, remembered ? ws.moving_id[lower] : 0});
        }
        // The walls it touches and does not hang from: each a stop, with the wall's friction by
        // Coulomb's law, so that a sphere pressed against a side wall by the pile can rest there
        // (the lecture's rule, a share of the sliding speed at each touch, lets it creep down at
        // about g·h per step) and one on the floor is held by its own stops and the floor together.
        packed_sphere const& s = grid.sphere(ws.moving_rank[upper]);
        vec3 const& a = ws.moving_acceleration[upper];
        if (!step.walls.beyond(s.x, touching_reach(s))) {
            for (std::uint32_t w = 0; w < step.walls.all.size(); ++w) {
                wall const& wall_w = step.walls.all[w];
                vec3 const& n = wall_w.surface.normal;
                if (!touches(wall_w, s) || n.dot(a) > 0.0)
                    continue;
                double const closing = v.dot(n);
                if (resting_only && -closing * (1.0 - wall_w.damping) >= detail::resting_threshold(step.settings, a, a, step.h))
                    continue; // a bounce: the passes answer it
                stops.push_back({n, 0.0, vec3::Zero(), wall_w.friction, w});
            }
        }
        double const tolerance = 0x1p-20 * ws.moving_acceleration[upper].norm() * step.h;
        if (remembered && resting_only) {
            auto const kept_here = ws.last_stops.of(ws.moving_id[upper]);
            for (auto& stop : stops) {
                kept_stop const* kept = find(kept_here, stop.lower_id);
                if (!kept)
                    continue;
                // Last step's friction, in this step's tangent plane and within μ of the push.
                vec3 friction = kept->friction - kept->friction.dot(stop.n) * stop.n;
                double const bound = stop.mu * kept->pushed, size = friction.norm();
                if (size > bound)
                    friction *= bound / size;
                stop.pushed = kept->pushed;
                stop.friction = friction;
                v += stop.pushed * stop.n + stop.friction;
            }
        }
        // A sweep's largest change is kept squared and its root taken once a sweep, not once
        // a stop in the chain of operations every stop waits on: the root of a double's
        // square is its magnitude (for changes between 1e-154 and 1e154 m/s, whose squares
        // neither underflow nor overflow), so the test and its outcome are the same.
        for (int sweep = 0; sweep < most_sweeps && !stops.empty(); ++sweep) {
            double largest_squared = 0.0;
            for (auto& stop : stops) {
                vec3 const& lower_v = stop.lower_v;
                double const closing = (v - lower_v).dot(stop.n);
                double const pushed = std::max(stop.pushed - stop.allowed - closing, 0.0);
                double const change = pushed - stop.pushed;
                v += change * stop.n;
                largest_squared = std::max(largest_squared, change * change);
                stop.pushed = pushed;
                if (stop.mu > 0.0) {
                    vec3 const relative = v - lower_v;
                    vec3 friction = stop.friction - (relative - relative.dot(stop.n) * stop.n);
                    double const bound = stop.mu * stop.pushed, size_squared = friction.squaredNorm();
                    // Within μ times the push: a square below (1 − 2^-50) of the bound's
                    // square has a root at most the bound, so only friction near or past it
                    // waits on a root (the same outcome for bounds below 1e154 m/s).
                    if (size_squared > bound * bound * (1.0 - 0x1p-50)) {
                        double const size = std::sqrt(size_squared);
                        if (size > bound)
                            friction *= bound / size;
                    }
                    v += friction - stop.friction;
                    largest_squared = std::max(largest_squared, (friction - stop.friction).squaredNorm());
                    stop.friction = friction;
                }
            }
            if (std::sqrt(largest_squared) <= tolerance)
                break;
        }
        for (auto const& stop : stops)
            if (stop.pushed > 0.0)
                supported[upper] = 1;
        if (remembered)
            keep_stops(ws, ws.moving_id[upper], stops, group, resting_only);
    }
}

} // namespace

// Each contact that approaches exchanges momentum along its normal (detail::
// respond_to_sphere_contact), and a sphere moving into a wall it touches meets it by the
// wall's rule; repeated, so a stack passes its weight down to the floor within the step
// instead of sinking into itself. A pass that changed no velocity leaves the next one the
// same state: the passes stop there. With forces, support is passed up each pile before them
// over the resting contacts and after them over all (propagate_support), and each sphere the
// contacts changed moves as it would have with the velocity they leave it: free motion had
// moved it with its velocity before them, so a sphere resting on another sank by a·h² every
// step, to be pushed out again by the position passes. Without forces nothing sinks, and an
// elastic gas keeps its bits.
void velocity_passes(step_context const& step, free_accelerations free_a, discrete_workspace& ws)
{
    copy_contact_spheres(step, free_a, ws);
    auto& moving = ws.moving;
    vec3 const still = vec3::Zero();
    auto const acceleration = [&](std::uint32_t c) -> vec3 const& {
        return free_a.any() ? ws.moving_acceleration[c] : still;
    };
    if (free_a.any()) {
        order_support(ws);
        propagate_support(step, ws, true);
    }
    for (int pass = 0; pass < std::max(step.settings.velocity_iterations, 1); ++pass) {
        by_parity(ws, step.loops, [&](contact_slab& slab) {
            slab.changed = false;
            for (std::size_t k = 0; k < slab.moving_pairs.size(); ++k) {
                auto const [i, j] = slab.moving_pairs[k];
                double const allowed = slab.allowed[k];
                bool const responded =
                    allowed < 0.0
                        ? detail::respond_to_sphere_contact(
                              moving[i].v, moving[i].inverse_mass, moving[j].v, moving[j].inverse_mass,
                              slab.normals[k], step.settings,
                              detail::resting_threshold(step.settings, acceleration(i), acceleration(j), step.h))
                        : detail::respond_to_speculative_contact(moving[i].v, moving[i].inverse_mass, moving[j].v,
                                                                 moving[j].inverse_mass, slab.normals[k], allowed,
                                                                 step.settings);
                if (!responded)
                    continue;
                slab.responses += pass == 0 ? 1U : 0U;
                slab.changed = true;
            }
        });
        each_slab(ws, step.loops, [&](contact_slab& slab) {
            for (std::uint32_t k : slab.touched) {
                std::uint32_t const c = ws.listed_at[k];
                slab.changed |= meet_touched_walls(step.walls, ws.grid.sphere(k), moving[c].v, acceleration(c),
                                                   step.settings, step.h);
            }
        });
        if (std::none_of(ws.slabs.begin(), ws.slabs.end(), [](contact_slab const& slab) { return slab.changed; }))
            break;
    }
    if (free_a.any())
        propagate_support(step, ws, false);
    std::span<vec3> const v = step.bodies.v;
    std::span<vec3> const x = step.bodies.x;
    bool const move_by_change = free_a.any(); // without forces nothing sinks
    auto& placed = ws.placed;
    if (move_by_change) {
        placed.clear();
        std::set_union(ws.moved.begin(), ws.moved.end(), ws.swept.placed.begin(), ws.swept.placed.end(),
                       std::back_inserter(placed));
    }
    std::span<vec3 const> const x0 = step.bodies.x0;
    each_slab(ws, step.loops, [&](contact_slab& slab) {
        for (std::size_t listed = 0; listed < slab.copied.size(); ++listed) {
            fetch_ahead(slab.copied, listed, [&](std::uint32_t later) { return &v[ws.grid.slot(later)]; });
            std::uint32_t const k = slab.copied[listed];
            std::uint32_t const i = ws.grid.slot(k);
            vec3 const solved = moving[slab.first_copied + listed].v;
            if (move_by_change) {
                // Free motion moved the sphere with its velocity before the contacts: it
                // moves as it would have with the velocity they leave it, from where it
                // started, x₀ + h·v (a semi-implicit Euler step; free motion by another
                // integrator went farther or less far than h·v, by what `beyond` says: a
                // sphere stopped on another kept that, and a pile rose and fell by ½·a·h²
                // every other step, and never came to rest). A sphere a wall, a box or the
                // sweep moved has no such start: it moves by the change alone.
                // (Zero for semi-implicit Euler: the search for a placed sphere is skipped.)
                packed_sphere& p = ws.grid.sphere(k);
                vec3 const beyond = p.x - (x0[i] + step.h * v[i]);
                p.x += step.h * (solved - v[i]);
                if (!beyond.isZero(0.0) && !std::binary_search(placed.begin(), placed.end(), i))
                    p.x -= beyond;
                v[i] = solved;
                detail::push_out_and_meet_walls(step.walls, p.x, v[i], p.radius, ws.grid.inverse_mass(k),
                                                free_a[i], step.settings, step.h);
                x[i] = p.x;
            } else {
                v[i] = solved;
            }
        }
    });
}

} // namespace kugel::physics::discrete
