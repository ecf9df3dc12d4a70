// Phase 4 of the discrete step: momentum exchanged at the contacts.

#include "passes.hpp"

#include <algorithm>

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
            if (free_a.any())
                ws.moving_acceleration[c] = free_a[i];
            packed_sphere const& s = grid.sphere(k);
            if (!step.walls.beyond(s.x, touching_reach(s)))
                slab.touched.push_back(k);
        }
    });
    // The contacts as positions among the copies, and their normals: found once.
    each_slab(ws, step.loops, [&](contact_slab& slab) {
        slab.moving_pairs.resize(slab.contacts.size());
        slab.normals.resize(slab.contacts.size());
        for (std::size_t k = 0; k < slab.contacts.size(); ++k) {
            sphere_pair const& c = slab.contacts[k];
            slab.moving_pairs[k] = {ws.listed_at[c.a], ws.listed_at[c.b]};
            vec3 const d = grid.sphere(c.a).x - grid.sphere(c.b).x;
            slab.normals[k] = detail::contact_normal(d, d.norm());
        }
    });
}

/// Support, passed up a pile in one pass: after the velocity passes, the contacts in order
/// of depth along gravity (the deepest first), each one's upper sphere stopped against its
/// lower one as if the lower were immovable (shock propagation, Guendelman, Bridson and
/// Fedkiw 2003), where the lower one is supported: it touches a wall its acceleration presses
/// it into, or rests on a sphere that is supported. The passes before leave momentum
/// exchanged; this pass leaves no contact of a pile closing, whatever its height, where
/// Gauss–Seidel passes would need about as many passes as the pile has layers. Spheres that
/// nothing static carries (a cluster in free fall, two planets that meet) are left as the
/// passes left them, their momentum kept. One sequential pass: the order is the pile's, not
/// the slabs'.
void propagate_support(step_context const& step, discrete_workspace& ws)
{
    sphere_grid const& grid = ws.grid;
    auto& supported = ws.supported;
    supported.assign(ws.moving.size(), 0);
    for (contact_slab const& slab : ws.slabs) {
        for (std::uint32_t k : slab.touched) {
            packed_sphere const& s = grid.sphere(k);
            std::uint32_t const c = ws.listed_at[k];
            for (wall const& w : step.walls.all)
                if (touches(w, s) && w.surface.normal.dot(ws.moving_acceleration[c]) < 0.0)
                    supported[c] = 1;
        }
    }
    auto& order = ws.support_order;
    order.clear();
    for (std::uint32_t s = 0; s < ws.slabs.size(); ++s) {
        contact_slab const& slab = ws.slabs[s];
        for (std::uint32_t k = 0; k < slab.contacts.size(); ++k) {
            auto const [i, j] = slab.moving_pairs[k];
            vec3 const down = ws.moving_acceleration[i] + ws.moving_acceleration[j];
            sphere_pair const& c = slab.contacts[k];
            double const depth = (grid.sphere(c.a).x + grid.sphere(c.b).x).dot(down);
            order.push_back({depth, s, k});
        }
    }
    std::sort(order.begin(), order.end(), [](auto const& p, auto const& q) {
        return p.depth != q.depth ? p.depth > q.depth : (p.slab != q.slab ? p.slab < q.slab : p.contact < q.contact);
    });
    auto& moving = ws.moving;
    for (auto const& o : order) {
        contact_slab const& slab = ws.slabs[o.slab];
        auto const [i, j] = slab.moving_pairs[o.contact];
        sphere_pair const& c = slab.contacts[o.contact];
        vec3 const down = ws.moving_acceleration[i] + ws.moving_acceleration[j];
        // n points from b to a: a is the upper sphere when it lies against the acceleration
        bool const a_above = (grid.sphere(c.a).x - grid.sphere(c.b).x).dot(down) < 0.0;
        std::uint32_t const upper = a_above ? i : j, lower = a_above ? j : i;
        vec3 const n = a_above ? slab.normals[o.contact] : vec3(-slab.normals[o.contact]); // lower to upper
        if (!supported[lower] || moving[upper].inverse_mass == 0.0)
            continue;
        supported[upper] = 1;
        double const closing = (moving[upper].v - moving[lower].v).dot(n);
        if (closing < 0.0)
            moving[upper].v -= closing * n;
    }
}

} // namespace

// Each contact that approaches exchanges momentum along its normal (detail::
// respond_to_sphere_contact), and a sphere moving into a wall it touches meets it by the
// wall's rule; repeated, so a stack passes its weight down to the floor within the step
// instead of sinking into itself. A pass that changed no velocity leaves the next one the
// same state: the passes stop there. With forces, support is then passed up each pile
// (propagate_support), and each sphere the contacts changed moves as it would have with the
// velocity they leave it: free motion had moved it with its velocity before them, so a
// sphere resting on another sank by a·h² every step, to be pushed out again by the position
// passes. Without forces nothing sinks, and an elastic gas keeps its bits.
void velocity_passes(step_context const& step, free_accelerations free_a, discrete_workspace& ws)
{
    copy_contact_spheres(step, free_a, ws);
    auto& moving = ws.moving;
    vec3 const still = vec3::Zero();
    auto const acceleration = [&](std::uint32_t c) -> vec3 const& {
        return free_a.any() ? ws.moving_acceleration[c] : still;
    };
    for (int pass = 0; pass < std::max(step.settings.velocity_iterations, 1); ++pass) {
        by_parity(ws, step.loops, [&](contact_slab& slab) {
            slab.changed = false;
            for (std::size_t k = 0; k < slab.moving_pairs.size(); ++k) {
                auto const [i, j] = slab.moving_pairs[k];
                if (!detail::respond_to_sphere_contact(moving[i].v, moving[i].inverse_mass, acceleration(i),
                                                       moving[j].v, moving[j].inverse_mass, acceleration(j),
                                                       slab.normals[k], step.settings, step.h))
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
        propagate_support(step, ws);
    std::span<vec3> const v = step.bodies.v;
    std::span<vec3> const x = step.bodies.x;
    bool const move_by_change = free_a.any(); // without forces nothing sinks
    each_slab(ws, step.loops, [&](contact_slab& slab) {
        for (std::size_t listed = 0; listed < slab.copied.size(); ++listed) {
            fetch_ahead(slab.copied, listed, [&](std::uint32_t later) { return &v[ws.grid.slot(later)]; });
            std::uint32_t const k = slab.copied[listed];
            std::uint32_t const i = ws.grid.slot(k);
            vec3 const solved = moving[slab.first_copied + listed].v;
            if (move_by_change) {
                // Free motion moved the sphere with its velocity before the contacts: it
                // moves as it would have with the velocity they leave it.
                packed_sphere& p = ws.grid.sphere(k);
                p.x += step.h * (solved - v[i]);
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
