// Phase 4 of the discrete step: momentum exchanged at the contacts.

#include "passes.hpp"

#include <algorithm>

namespace kugel::physics::discrete {

namespace {

/// A sphere touching a wall (to a relative 1e-9 of its radius) and moving into it meets it
/// (meet_wall): a stack's weight, pressing slower than the rest threshold, is carried by the
/// wall. Returns whether its velocity changed.
bool meet_touched_walls(detail::wall_set const& walls, packed_sphere const& s, vec3& v, vec3 const& a,
                        collision_settings const& settings, double h)
{
    double const reach = s.radius * (1.0 + 1e-9);
    if (walls.beyond(s.x, reach))
        return false;
    bool changed = false;
    for (wall const& w : walls.all)
        if (w.surface.normal.dot(s.x) <= w.surface.offset + reach)
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
            if (!step.walls.beyond(s.x, s.radius * (1.0 + 1e-9)))
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

} // namespace

// Each contact that approaches exchanges momentum along its normal (detail::
// respond_to_sphere_contact), and a sphere moving into a wall it touches meets it by the
// wall's rule; repeated, so a stack passes its weight down to the floor within the step
// instead of sinking into itself. A pass that changed no velocity leaves the next one the
// same state: the passes stop there.
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
    std::span<vec3> const v = step.bodies.v;
    each_slab(ws, step.loops, [&](contact_slab& slab) {
        for (std::size_t listed = 0; listed < slab.copied.size(); ++listed) {
            fetch_ahead(slab.copied, listed, [&](std::uint32_t later) { return &v[ws.grid.slot(later)]; });
            v[ws.grid.slot(slab.copied[listed])] = moving[slab.first_copied + listed].v;
        }
    });
}

} // namespace kugel::physics::discrete
