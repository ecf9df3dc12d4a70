// Phase 1 of the discrete step: each body on its own against the walls.

#include "passes.hpp"

#include "physics/time_of_impact.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace kugel::physics::discrete {

namespace {

/// A sphere (radius r) found inside a wall at x, the end of its path, is taken back to the
/// time it crossed, found by the lecture's linear interpolation between tᵢ and tᵢ₊₁, bounces
/// there, and finishes the step on its new path, which ends at the new x. Up to four walls per
/// step (a corner). Returns whether it bounced; counts the responses.
bool bounce_off_walls(collision_settings const& settings, detail::wall_set const& walls, body_path& path,
                      vec3& x, double r, double h, std::uint64_t& responses)
{
    bool bounced = false;
    for (int bounce = 0; bounce < 4; ++bounce) {
        wall const* hit = nullptr;
        double hit_time = std::numeric_limits<double>::infinity();
        for (wall const& w : walls.all) {
            if (w.surface.normal.dot(x) >= w.surface.offset + r)
                continue;
            double const t = std::clamp(plane_contact_time_linear(w.surface, r, path.x, path.t, x, h), path.t, h);
            if (t < hit_time) {
                hit_time = t;
                hit = &w;
            }
        }
        if (!hit)
            break;
        path.advance_to(hit_time);
        if (detail::respond_to_surface(path, hit->surface.normal, hit->surface.offset + r, hit->damping,
                                       hit->friction, settings, h))
            ++responses;
        x = path.position_at(h);
        bounced = true;
    }
    return bounced;
}

/// The wall pass over bodies [begin, end): makes a pending drift, notes each body's free
/// acceleration (unless free motion was a drift: then there is none), bounces the spheres
/// found inside a wall off it, and notes the bodies' extent where it leaves them and, given a
/// frame, the key of each sphere's cell there (and its x-cell, when asked). Compiled once for
/// each kind of free motion (drift_pending, accelerated, as in collision_bodies), so that the
/// loop over every body tests neither, and the extent is kept in a local until the end.
template <bool drift_pending, bool accelerated>
void walls_of_chunk(step_context const& step, std::span<vec3> free_a, cell_frame const* frame,
                    std::span<std::uint64_t> keys, std::span<std::uint32_t> x_cells, std::size_t begin,
                    std::size_t end, wall_chunk& out)
{
    collision_bodies const& b = step.bodies;
    double const h = step.h;
    double const fraction = step.settings.sweep_fraction;
    bool const sweep = step.settings.sweep;
    out.moved.clear();
    out.fast.clear();
    out.fast_start.clear();
    out.responses = 0;
    bool any_accelerated = false;
    double largest_change = 0.0; // of a velocity, squared
    sphere_extent extent;
    for (std::size_t k = begin; k < end; ++k) {
        auto const i = static_cast<std::uint32_t>(k);
        vec3 start = vec3::Zero();
        if constexpr (drift_pending) {
            start = b.x[i];
            b.x[i] += h * b.v[i];
        }
        if constexpr (accelerated) {
            // A body no force moved has no change, and then the quotient is zero too (0/h
            // keeps the sign of zero): the division, slow beside everything else here, is skipped.
            vec3 const change = b.v[i] - b.v0[i];
            bool const still = (change.array() == 0.0).all();
            free_a[i] = still ? change : vec3(change / h);
            any_accelerated |= !still;
            largest_change = std::max(largest_change, change.squaredNorm());
        }
        double const r = b.radius[i];
        // Farther than the sweep's share of its radius: noted for the sweep (swept_pass.cpp),
        // which then answers its walls too. One comparison for every other body.
        double const reach = fraction * r;
        vec3 const& from = drift_pending ? start : b.x0[i];
        if (r > 0.0 && (b.x[i] - from).squaredNorm() > reach * reach) {
            out.fast.push_back(i);
            out.fast_start.push_back(from);
            if (sweep) {
                extent.add(b.x[i], r);
                continue;
            }
        }
        if (!(r <= 0.0 || b.inverse_mass[i] == 0.0 || step.walls.clear(b.x[i], r))) {
            body_path path = drift_pending ? body_path{start, b.v[i], vec3::Zero(), 0.0}
                                           : body_path{b.x0[i], b.v0[i], accelerated ? free_a[i] : vec3::Zero(), 0.0};
            if (bounce_off_walls(step.settings, step.walls, path, b.x[i], r, h, out.responses)) {
                b.v[i] = path.velocity_at(h);
                out.moved.push_back(i);
            }
        }
        extent.add(b.x[i], r);
        if (frame && r > 0.0) {
            std::uint64_t x_cell = 0;
            keys[i] = frame->key(b.x[i], x_cell);
            if (!x_cells.empty())
                x_cells[i] = static_cast<std::uint32_t>(x_cell); // of use only when it fits
        }
    }
    out.accelerated = any_accelerated;
    out.largest_change = std::sqrt(largest_change);
    out.extent = extent;
}

} // namespace

// Each body's acceleration over the step from free motion alone, before any response, is
// noted here, where each body is handled on its own: in chunks, any number at a time,
// gathered in chunk order. Where the bodies' extent is known at the end of this pass (no box
// moves a sphere after it), the pass also numbers the spheres' cells in the grid's last frame
// (and, for a grid sorted slab by slab on threads, notes their x-cells), sparing the grid
// another pass over the bodies when the frame holds (sphere_grid::keying_frame).
wall_pass_result wall_pass(step_context const& step, discrete_workspace& ws, collision_stats& stats)
{
    collision_bodies const& bodies = step.bodies;
    std::size_t const n = bodies.x.size();
    auto& free_a = ws.free_acceleration;
    free_a.resize(bodies.accelerated ? n : 0);
    ws.wall_chunks.resize(chunk_count(n));
    wall_pass_result out;
    if (step.obstacles.empty() && step.settings.broadphase == broadphase_kind::uniform_grid)
        out.keying_frame = ws.grid.keying_frame();
    ws.cell_keys.resize(out.keying_frame ? n : 0);
    ws.cell_x.resize(out.keying_frame && step.loops ? n : 0);
    cell_frame const* const frame = out.keying_frame ? &*out.keying_frame : nullptr;
    run_chunks(step.loops, n, [&](std::size_t c, std::size_t begin, std::size_t end) {
        auto const pass = bodies.drift_pending ? walls_of_chunk<true, false>
                          : bodies.accelerated ? walls_of_chunk<false, true>
                                               : walls_of_chunk<false, false>;
        pass(step, free_a, frame, ws.cell_keys, ws.cell_x, begin, end, ws.wall_chunks[c]);
    });
    ws.moved.clear();
    bool accelerated = false;
    double largest_change = 0.0;
    ws.swept.fast.clear();
    ws.swept.fast_start.clear();
    ws.swept.placed.clear();
    for (wall_chunk const& chunk : ws.wall_chunks) {
        ws.moved.insert(ws.moved.end(), chunk.moved.begin(), chunk.moved.end());
        ws.swept.fast.insert(ws.swept.fast.end(), chunk.fast.begin(), chunk.fast.end());
        ws.swept.fast_start.insert(ws.swept.fast_start.end(), chunk.fast_start.begin(), chunk.fast_start.end());
        stats.wall_contacts += chunk.responses;
        out.extent.add(chunk.extent);
        accelerated |= chunk.accelerated;
        largest_change = std::max(largest_change, chunk.largest_change);
    }
    // A pair falling together ends free motion as far apart as it began, to a rounding error
    // on either side: the contact between them is found with a margin, the most one step of
    // acceleration moves a sphere from where it would be at rest (|Δv|·h), so that the one
    // below being stopped does not leave the one above falling (speculative contacts). At most
    // half the largest radius, which keeps the grid's cells near a diameter.
    out.contact_margin = accelerated ? std::min(largest_change * step.h, 0.5 * out.extent.largest_radius) : 0.0;
    // When no body accelerated, no rest threshold has an acceleration in it, and the
    // accelerations are not read by slot at all.
    out.free_a = {accelerated ? std::span<vec3 const>(free_a) : std::span<vec3 const>()};
    return out;
}

} // namespace kugel::physics::discrete
