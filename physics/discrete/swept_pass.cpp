// Phase 1b of the discrete step: the bodies that move far in a step, swept.
//
// A body that moves farther than collisions.sweep_fraction of its radius in one step can pass
// through a sphere between where it starts and where it ends, and the overlaps at the end of
// the step never see it (Jolt's linear-cast motion quality and Bullet's CCD threshold answer
// the same problem). Such a body, and every sphere whose path may meet it, is taken
// through the continuous mode's events in time order, on copies: the same times of impact and
// the same rules as that mode. The other bodies stay on the discrete path, which pays one
// comparison per body (in the wall pass) for this.

#include "passes.hpp"

#include "physics/time_of_impact.hpp"

#include <algorithm>
#include <cmath>

namespace kugel::physics {

swept_workspace::swept_workspace() = default;
swept_workspace::swept_workspace(swept_workspace&&) noexcept = default;
swept_workspace& swept_workspace::operator=(swept_workspace&&) noexcept = default;
swept_workspace::~swept_workspace() = default;

} // namespace kugel::physics

namespace kugel::physics::discrete {

namespace {

/// Every sphere is swept once the fast bodies are one in this many of the others.
constexpr std::size_t many_fast = 8;
/// Rounds of events, each drawing in the spheres the last one's paths met, before every
/// sphere is swept.
constexpr int most_attempts = 8;

bool finite(aabb const& box) { return box.min.allFinite() && box.max.allFinite(); }

} // namespace

// Which spheres are swept with the fast ones: first those whose paths' boxes overlap a fast
// body's path box; then, after the events, every sphere left out whose path meets a path a
// swept body took between two of its events (its time of impact, or its box where the paths
// are not straight lines alike), and the events run again with it, until no path does. The
// events then saw every contact a swept body had, and the spheres left out met only each
// other, as the discrete step sees them. When many bodies are fast, or a chain of contacts
// runs on for more than a few rounds, every sphere is swept at once.
void swept_pass(step_context const& step, wall_pass_result& walls_done, discrete_workspace& ws,
                collision_stats& stats)
{
    swept_workspace& sw = ws.swept;
    sw.touches.clear();
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
    // Each sphere's path as free motion made it (for one a wall bounced: the line it left on,
    // taken back to the step's start after a drift).
    auto const path_of = [&](std::uint32_t i) {
        return drift ? body_path{b.x[i] - h * b.v[i], b.v[i], vec3::Zero(), 0.0}
                     : body_path{b.x0[i], b.v0[i], free_a[i], 0.0};
    };

    // 1. The box of every sphere's path over the step as free motion made it (for one a wall
    //    bounced: with where the wall sent it).
    sw.box.resize(n);
    sw.member.assign(n, 0);
    std::size_t fast_count = 0;
    for (std::size_t k = 0; k < sw.fast.size(); ++k) {
        std::uint32_t const i = sw.fast[k];
        vec3 const& start = sw.fast_start[k];
        body_path const path = drift ? body_path{start, b.v[i], vec3::Zero(), 0.0}
                                     : body_path{start, b.v0[i], free_a[i], 0.0};
        aabb const box = path.swept_box(h, b.radius[i]);
        if (!finite(box)) { // a state beyond a double: the world reports it (non_finite_bodies)
            ++stats.unswept_fast_bodies;
            continue;
        }
        sw.box[i] = box;
        sw.member[i] = 1;
        ++fast_count;
    }
    if (fast_count == 0)
        return;
    sw.others.clear();
    for (std::uint32_t i = 0; i < n; ++i) {
        if (!(b.radius[i] > 0.0) || sw.member[i] != 0)
            continue;
        body_path const path = path_of(i);
        vec3 const r = vec3::Constant(b.radius[i]);
        aabb const box = merge(path.swept_box(h, b.radius[i]), aabb{b.x[i] - r, b.x[i] + r});
        if (finite(box)) {
            sw.box[i] = box;
            sw.others.push_back(i);
        }
    }
    // Many fast bodies (a fast gas): all of them, rather than a search that finds most.
    bool every_sphere = fast_count * many_fast >= sw.others.size();
    auto const draw_in_all = [&] {
        for (std::uint32_t j : sw.others)
            sw.member[j] = 1;
        every_sphere = true;
    };
    // Draws in every sphere left out whose box overlaps `box` and that `meets` says may have
    // met it; true when one was.
    auto const draw_in_near = [&](aabb const& box, auto meets) {
        bool drawn = false;
        auto const visit = [&](std::uint32_t j) {
            if (sw.member[j] == 0 && overlaps(box, sw.box[j]) && meets(j)) {
                sw.member[j] = 1;
                drawn = true;
            }
        };
        sw.grid.for_each_filed_near(box, visit);
        for (std::uint32_t j : sw.grid.listed_at_reset())
            visit(j);
        return drawn;
    };
    if (every_sphere) {
        draw_in_all();
    } else {
        sw.grid.reset(sw.box, sw.others);
        for (std::size_t k = 0; k < sw.fast.size(); ++k)
            if (sw.member[sw.fast[k]] != 0)
                draw_in_near(sw.box[sw.fast[k]], [](std::uint32_t) { return true; });
    }
    if (!sw.events)
        sw.events = std::make_unique<collision_workspace>();

    for (int attempt = 1;; ++attempt) {
        sw.events->continuous.keep_segments = !every_sphere; // the paths step 4 looks at
        sw.events->continuous.keep_contacts = sw.keep_contacts;
        sw.events->continuous.left_to_discrete = step.settings.sweep_fraction / h;
        // 2. Copies of the swept bodies, in slot order, on the paths free motion gave them.
        sw.members.clear();
        for (std::uint32_t i = 0; i < n; ++i)
            if (sw.member[i] != 0)
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
            while (f < sw.fast.size() && sw.fast[f] < i)
                ++f;
            bool const is_fast = f < sw.fast.size() && sw.fast[f] == i;
            body_path const path = is_fast ? body_path{sw.fast_start[f], drift ? b.v[i] : b.v0[i], vec3::Zero(), 0.0}
                                           : path_of(i);
            sw.x0[k] = path.x;
            sw.v0[k] = path.v;
            // the velocity free motion left (a body a wall bounced: before the bounce, which
            // the events make again)
            bool const bounced = !is_fast && std::binary_search(ws.moved.begin(), ws.moved.end(), i);
            sw.v[k] = drift || !bounced ? b.v[i] : vec3(b.v0[i] + h * free_a[i]);
            sw.v_in[k] = sw.v[k];
            sw.x[k] = b.x[i];
            sw.inverse_mass[k] = b.inverse_mass[i];
            sw.radius[k] = b.radius[i];
        }

        // 3. The events in time order, as in continuous mode; no sphere left inside a wall.
        collision_bodies const swept{sw.x, sw.v, sw.x0, sw.v0, sw.inverse_mass, sw.radius, b.accelerated && !drift};
        collision_stats found;
        // step by step: the calendar keeps events between steps, and these bodies are new each step
        collision_settings one_step = step.settings;
        one_step.event_calendar = false;
        resolve_continuous(one_step, step.walls.all, step.obstacles, swept, h, *sw.events, found, step.loops);
        bool const capped = found.capped_steps > 0; // finished in discrete mode: not swept to the end

        // 4. A swept body whose path (between two of its events) meets the path of a sphere
        //    left out may have passed through it: that sphere is drawn in, and the events run
        //    again. Past a few rounds, every sphere is.
        bool drawn = false;
        if (!every_sphere && !capped) {
            for (auto const& segment : sw.events->continuous.segments) {
                std::uint32_t const k = segment.body;
                double const until = segment.until;
                body_path const& path = segment.path;
                if (sw.events->continuous.events_of[k] == 0)
                    continue; // its one path, whose box was searched before the events
                double const r = sw.radius[k];
                drawn = draw_in_near(path.swept_box(until, r), [&](std::uint32_t j) {
                    // a body a wall bounced, or one on another acceleration: by the boxes alone
                    body_path other = path_of(j);
                    if (std::binary_search(ws.moved.begin(), ws.moved.end(), j) ||
                        (other.a.array() != path.a.array()).any())
                        return true;
                    other.advance_to(path.t);
                    return sphere_time_of_impact(path.x, path.v, r, other.x, other.v, b.radius[j], until - path.t)
                        .has_value();
                }) || drawn;
            }
            if (drawn && attempt == most_attempts)
                draw_in_all();
        }
        if (drawn)
            continue;
        stats.sphere_contacts += found.sphere_contacts;
        stats.wall_contacts += found.wall_contacts;
        stats.obstacle_contacts += found.obstacle_contacts;
        stats.capped_steps += found.capped_steps;
        stats.events += found.events;
        (capped ? stats.unswept_fast_bodies : stats.swept_bodies) += fast_count;
        for (auto const& t : sw.events->continuous.touches) // from the copies to the bodies
            sw.touches.push_back({sw.members[t.a], sw.members[t.b], t.time});
        break;
    }

    // 5. Back to the bodies: the fast ones, and the others the events changed.
    std::size_t const m = sw.members.size();
    for (std::size_t k = 0, f = 0; k < m; ++k) {
        std::uint32_t const i = sw.members[k];
        while (f < sw.fast.size() && sw.fast[f] < i)
            ++f;
        bool const is_fast = f < sw.fast.size() && sw.fast[f] == i;
        bool const met = sw.events->continuous.events_of[k] > 0 || (sw.v[k].array() != sw.v_in[k].array()).any();
        if (!is_fast && !met)
            continue; // met nothing: it keeps what the wall pass left
        b.x[i] = sw.x[k];
        b.v[i] = sw.v[k];
        sw.placed.push_back(i);
    }

    // 6. Where the bodies the events changed (every fast one swept among them) and the fast
    //    ones left out (a state beyond a double) now are: the extent, and the cell keys.
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
    for (std::uint32_t i : sw.placed)
        place(i);
    for (std::uint32_t i : sw.fast)
        if (sw.member[i] == 0)
            place(i);
}

} // namespace kugel::physics::discrete
