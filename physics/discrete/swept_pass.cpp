// Phase 1b of the discrete step: the bodies that move far in a step, swept.
//
// A body that moves farther than collisions.sweep_fraction of its radius in one step can pass
// through a sphere between where it starts and where it ends, and the overlaps at the end of
// the step never see it (Jolt's linear-cast motion quality and Bullet's CCD threshold answer
// the same problem). Such a body, and every sphere whose path comes near its reach, is taken
// through the continuous mode's events in time order, on copies: the same times of impact and
// the same rules as that mode. The other bodies stay on the discrete path, which pays one
// comparison per body (in the wall pass) for this.

#include "passes.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace kugel::physics {

swept_workspace::swept_workspace() = default;
swept_workspace::swept_workspace(swept_workspace&&) noexcept = default;
swept_workspace& swept_workspace::operator=(swept_workspace&&) noexcept = default;
swept_workspace::~swept_workspace() = default;

} // namespace kugel::physics

namespace kugel::physics::discrete {

namespace {

constexpr std::uint32_t none = std::numeric_limits<std::uint32_t>::max();

bool finite(aabb const& box) { return box.min.allFinite() && box.max.allFinite(); }

bool inside(aabb const& inner, aabb const& outer)
{
    return (inner.min.array() >= outer.min.array()).all() && (inner.max.array() <= outer.max.array()).all();
}

aabb grown(aabb box, double by)
{
    vec3 const margin = vec3::Constant(by);
    return {box.min - margin, box.max + margin};
}

} // namespace

// Which spheres are swept with the fast ones: each fast body reaches its path's box grown by
// twice its displacement in the step. A sphere it meets leaves no faster than it came, unless
// lighter (a body of equal or larger mass, or a wall, sends it on at most at the fast body's
// speed), so what the two do after the meeting stays within that reach; every sphere whose
// own path box comes into it is swept with them. A body the sweep changed whose last path
// still leaves the reach of the fast body that drew it in, and comes near a sphere left out,
// is counted in unswept_fast_bodies: it may have passed through that sphere. When every
// sphere is swept, none is outside.
void swept_pass(step_context const& step, wall_pass_result& walls_done, discrete_workspace& ws,
                collision_stats& stats)
{
    swept_workspace& sw = ws.swept;
    if (sw.fast.empty())
        return;
    if (!step.settings.sweep) {
        stats.unswept_fast_bodies += sw.fast.size();
        return;
    }
    collision_bodies const& b = step.bodies;
    double const h = step.h;
    std::size_t const n = b.x.size();
    bool const drift = b.drift_pending; // x₀, v₀ not kept: each body's path is a line to x at v
    free_accelerations const free_a = walls_done.free_a;
    // A body's path over the step as free motion made it (for one a wall bounced, the line it
    // left on, taken back to the step's start after a drift: it moved less than its radius).
    auto const path_of = [&](std::uint32_t i) {
        return drift ? body_path{b.x[i] - h * b.v[i], b.v[i], vec3::Zero(), 0.0}
                     : body_path{b.x0[i], b.v0[i], free_a[i], 0.0};
    };

    // 1. Each fast body's reach; home[i]: the reach that draws body i in (a fast body its own).
    sw.home.assign(n, none);
    sw.boxes.clear();
    sw.box_body.clear();
    aabb all_reaches{vec3::Constant(std::numeric_limits<double>::infinity()),
                     vec3::Constant(-std::numeric_limits<double>::infinity())};
    for (std::size_t k = 0; k < sw.fast.size(); ++k) {
        std::uint32_t const i = sw.fast[k];
        vec3 const& start = sw.fast_start[k];
        body_path const path = drift ? body_path{start, b.v[i], vec3::Zero(), 0.0}
                                     : body_path{start, b.v0[i], free_a[i], 0.0};
        aabb const reach = grown(path.swept_box(h, b.radius[i]), 2.0 * (b.x[i] - start).norm());
        if (!finite(reach)) { // a state beyond a double: the world reports it (non_finite_bodies)
            ++stats.unswept_fast_bodies;
            continue;
        }
        sw.home[i] = static_cast<std::uint32_t>(sw.boxes.size());
        sw.boxes.push_back(reach);
        sw.box_body.push_back(i);
        all_reaches = merge(all_reaches, reach);
    }
    std::size_t const fast_boxes = sw.boxes.size();

    // 2. The spheres whose paths come into a reach, found by a broadphase over the reaches and
    //    the paths inside their common box.
    for (std::uint32_t i = 0; i < n; ++i) {
        if (!(b.radius[i] > 0.0) || sw.home[i] != none)
            continue;
        aabb const box = path_of(i).swept_box(h, b.radius[i]);
        if (finite(box) && overlaps(box, all_reaches)) {
            sw.boxes.push_back(box);
            sw.box_body.push_back(i);
        }
    }
    find_overlapping_pairs(broadphase_kind::sweep_and_prune, sw.boxes, sw.pairs, sw.broadphase);
    for (box_pair const& p : sw.pairs) // sorted by (a, b): a sphere's home is the first reach it meets
        if (p.a < fast_boxes && p.b >= fast_boxes && sw.home[sw.box_body[p.b]] == none)
            sw.home[sw.box_body[p.b]] = p.a;

    // 3. Copies of the swept bodies, in slot order, on the paths free motion gave them.
    sw.members.clear();
    for (std::uint32_t i = 0; i < n; ++i)
        if (sw.home[i] != none)
            sw.members.push_back(i);
    std::size_t const m = sw.members.size();
    sw.x.resize(m);
    sw.v.resize(m);
    sw.x0.resize(m);
    sw.v0.resize(m);
    sw.inverse_mass.resize(m);
    sw.radius.resize(m);
    sw.v_in.resize(m);
    for (std::size_t k = 0, f = 0; k < m; ++k) {
        std::uint32_t const i = sw.members[k];
        bool const is_fast = sw.home[i] < fast_boxes && sw.box_body[sw.home[i]] == i;
        while (is_fast && sw.fast[f] != i)
            ++f;
        body_path const path = is_fast ? body_path{sw.fast_start[f], drift ? b.v[i] : b.v0[i], vec3::Zero(), 0.0}
                                       : path_of(i);
        sw.x0[k] = path.x;
        sw.v0[k] = path.v;
        // the velocity free motion left (a body a wall bounced: before the bounce, which the
        // events make again)
        bool const bounced = !is_fast && std::binary_search(ws.moved.begin(), ws.moved.end(), i);
        sw.v[k] = drift || !bounced ? b.v[i] : vec3(b.v0[i] + h * free_a[i]);
        sw.v_in[k] = sw.v[k];
        sw.x[k] = b.x[i];
        sw.inverse_mass[k] = b.inverse_mass[i];
        sw.radius[k] = b.radius[i];
    }

    // 4. The events in time order, as in continuous mode; no sphere left inside a wall.
    if (!sw.events)
        sw.events = std::make_unique<collision_workspace>();
    collision_bodies const swept{sw.x, sw.v, sw.x0, sw.v0, sw.inverse_mass, sw.radius, b.accelerated && !drift};
    std::uint64_t const capped_before = stats.capped_steps;
    // step by step: the calendar keeps events between steps, and these bodies are new each step
    collision_settings one_step = step.settings;
    one_step.event_calendar = false;
    resolve_continuous(one_step, step.walls.all, step.obstacles, swept, h, *sw.events, stats, step.loops);
    clamp_to_walls(step.walls.all, swept);
    if (stats.capped_steps > capped_before) // finished in discrete mode: not swept to the end
        stats.unswept_fast_bodies += fast_boxes;
    else
        stats.swept_bodies += fast_boxes;

    // 5. Back to the bodies: the fast ones, and the others the events changed. A body whose
    //    last path leaves the reach that drew it in may still have met only swept spheres:
    //    it may have passed through another only if that path's box meets the path box of a
    //    sphere left out (those near the reaches are among the boxes; any other lies clear of
    //    the box around every reach).
    bool const every_sphere = m == std::size_t{walls_done.extent.spheres};
    auto const may_meet_unswept = [&](aabb const& last) {
        if (!inside(last, all_reaches))
            return true;
        for (std::size_t k = fast_boxes; k < sw.boxes.size(); ++k)
            if (sw.home[sw.box_body[k]] == none && overlaps(last, sw.boxes[k]))
                return true;
        return false;
    };
    for (std::size_t k = 0; k < m; ++k) {
        std::uint32_t const i = sw.members[k];
        std::uint32_t const home = sw.home[i];
        bool const is_fast = home < fast_boxes && sw.box_body[home] == i;
        bool const met = sw.events->continuous.events_of[k] > 0 || (sw.v[k].array() != sw.v_in[k].array()).any();
        if (!is_fast && !met)
            continue; // met nothing: it keeps what the wall pass left
        b.x[i] = sw.x[k];
        b.v[i] = sw.v[k];
        if (!every_sphere) {
            vec3 const before = sw.x[k] - h * sw.v[k];
            aabb const last = grown({before.cwiseMin(sw.x[k]), before.cwiseMax(sw.x[k])}, sw.radius[k]);
            if (!inside(last, sw.boxes[home]) && may_meet_unswept(last))
                ++stats.unswept_fast_bodies;
        }
        if (!is_fast)
            sw.moved_others.push_back(i);
    }

    // 6. Where the fast bodies (and the others moved) now are: the extent, and the cell keys.
    sphere_extent& extent = walls_done.extent;
    cell_frame const* const frame = walls_done.keying_frame ? &*walls_done.keying_frame : nullptr;
    auto const place = [&](std::uint32_t i) {
        extent.lowest = extent.lowest.cwiseMin(b.x[i]);
        extent.highest = extent.highest.cwiseMax(b.x[i]);
        if (frame) {
            std::uint64_t x_cell = 0;
            ws.cell_keys[i] = frame->key(b.x[i], x_cell);
            if (!ws.cell_x.empty())
                ws.cell_x[i] = static_cast<std::uint32_t>(x_cell);
        }
    };
    for (std::uint32_t i : sw.fast)
        place(i);
    for (std::uint32_t i : sw.moved_others)
        place(i);
    sw.moved_others.clear();
}

} // namespace kugel::physics::discrete
