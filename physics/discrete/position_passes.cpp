// Phase 5 of the discrete step: overlapping pairs pushed apart.

#include "passes.hpp"

#include <algorithm>
#include <array>

namespace kugel::physics::discrete {

namespace {

/// The share of r_a + r_b by which the position passes let two spheres overlap: a push leaves
/// a pair touching only to the rounding of its coordinates, and about half the pairs a pass
/// pushed then overlap by a few units in the last place, which the next pass would push
/// again, and the next (bench/README.md, decisions). 2^-42 (10^-13 m between spheres of
/// 0.05 m) is far above that rounding for coordinates up to 10^3 radii, and far below any
/// overlap the eye or a test could see.
constexpr double rounding_overlap = 0x1p-42;

/// Pushes the pair apart in proportion to the inverse masses if it overlaps by more than
/// `slop` of r_a + r_b (at least rounding_overlap), listing both spheres as moved; returns
/// whether it did. Under forces (free accelerations given, by slot), a pair one above the
/// other (its normal within 60° of the pair's acceleration) pushes the upper sphere alone, as
/// support stops the upper sphere alone (velocity_passes.cpp): the lower one carries it.
/// Pushing both by their masses squeezed the bottom layer of a pile sideways along the floor,
/// a little every step.
[[gnu::always_inline]] inline bool separate(sphere_grid& grid, sphere_pair const& c, once_per_pass const& once,
                                            std::vector<std::uint32_t>& moved, std::span<vec3 const> free_a,
                                            std::span<vec3> v, double slop)
{
    packed_sphere& s = grid.sphere(c.a);
    packed_sphere& t = grid.sphere(c.b);
    double const reach = s.radius + t.radius;
    if ((s.x - t.x).squaredNorm() >= reach * reach)
        return false; // most near pairs are apart: no square root for them
    double const s_inverse_mass = grid.inverse_mass(c.a), t_inverse_mass = grid.inverse_mass(c.b);
    double const total = s_inverse_mass + t_inverse_mass;
    vec3 const d = s.x - t.x;
    double const distance = d.norm();
    double const gap = distance - reach;
    if (gap >= -slop * reach || total == 0.0)
        return false;
    vec3 const n = detail::contact_normal(d, distance);
    double share_s = s_inverse_mass / total, share_t = t_inverse_mass / total;
    if (!free_a.empty()) {
        vec3 const down = free_a[grid.slot(c.a)] + free_a[grid.slot(c.b)];
        double const along = n.dot(down); // n is from t to s: < 0 when s is above t
        if (std::abs(along) > 0.5 * down.norm() && s_inverse_mass > 0.0 && t_inverse_mass > 0.0) {
            share_s = along < 0.0 ? 1.0 : 0.0;
            share_t = 1.0 - share_s;
        }
    }
    s.x -= (gap * share_s) * n;
    t.x += (gap * share_t) * n;
    once.list(moved, c.a);
    once.list(moved, c.b);
    if (!free_a.empty()) {
        // Pushed apart, the pair keeps no speed into the overlap it was pushed out of (a
        // perfectly inelastic meeting, shared as the push was): otherwise a sphere held in a
        // pile by the pushes alone kept moving into its neighbour step after step, its
        // velocity no longer its motion, and passed that velocity up to the spheres it
        // carried by friction.
        vec3& v_s = v[grid.slot(c.a)];
        vec3& v_t = v[grid.slot(c.b)];
        double const closing = (v_s - v_t).dot(n);
        if (closing < 0.0) {
            v_s -= (closing * share_s) * n;
            v_t += (closing * share_t) * n;
        }
    }
    return true;
}

/// One position pass over a slab's near pairs. After the first pass, a pair whose spheres
/// neither the last pass nor this one has moved (marked before `recent`) is where it was when
/// the last pass found it apart: it is apart again, and its spheres are not read. About two in
/// five pairs are not, in no pattern a branch predictor could follow; so the pass lists a
/// block's pairs to check first, without a branch (each written, kept by advancing the count
/// by the test), and lists the rest of the block again after a push, which may have marked
/// more: the pairs checked are exactly those the test admits in order.
void separate_slab(sphere_grid& grid, contact_slab& slab, once_per_pass const& once, std::uint32_t recent,
                   std::span<vec3 const> free_a, std::span<vec3> v, double slop)
{
    slab.touched.clear(); // now: the spheres this pass moved
    sphere_pair const* const near = slab.near.data();
    std::size_t const pairs = slab.near.size();
    if (recent == 0) {
        for (std::size_t k = 0; k < pairs; ++k)
            separate(grid, near[k], once, slab.touched, free_a, v, slop);
        return;
    }
    constexpr std::size_t block = 16;
    std::array<std::uint32_t, block> due;
    std::uint32_t const* const mark = once.mark.data();
    for (std::size_t first = 0; first < pairs; first += block) {
        std::size_t const end = std::min(pairs, first + block);
        auto const list_due = [&](std::size_t from) {
            std::size_t listed = 0;
            for (std::size_t k = from; k < end; ++k) {
                due[listed] = static_cast<std::uint32_t>(k);
                listed += std::max(mark[near[k].a], mark[near[k].b]) >= recent ? 1U : 0U;
            }
            return listed;
        };
        std::size_t listed = list_due(first), at = 0;
        while (at < listed) {
            std::uint32_t const k = due[at++];
            if (separate(grid, near[k], once, slab.touched, free_a, v, slop)) { // it marked two spheres: list the rest again
                listed = list_due(k + 1);
                at = 0;
            }
        }
    }
}

} // namespace

// Every near pair that overlaps (near, not only the contacts: a push can bring two neighbours
// into overlap) is pushed apart, and walls push back in every pass, so stacks settle on them;
// a sphere pushed into a wall meets it too. Only the spheres a pass moved are checked against
// the walls; a pass that moved nothing leaves nothing for the next. The passes move the
// grid's copies of the positions, which write_back() returns to the bodies.
void position_passes(step_context const& step, free_accelerations free_a, discrete_workspace& ws)
{
    sphere_grid& grid = ws.grid;
    std::uint32_t stamp = ws.stamp; // the velocity passes' listing
    double const slop = std::max(step.settings.position_slop, rounding_overlap);
    for (int pass = 0; pass < step.settings.position_iterations; ++pass) {
        std::uint32_t const recent = pass == 0 ? 0 : stamp;
        once_per_pass const once{ws.mark, ++stamp};
        by_parity(ws, step.loops,
                  [&](contact_slab& slab) { separate_slab(grid, slab, once, recent, free_a.a, step.bodies.v, slop); });
        // The spheres moved meet the walls; the body slot is looked up only for the few that
        // touch one. Each goes on the slab's list to be written back, once for each pass that
        // moved it (writing the last position twice costs less than remembering whether it
        // is listed already: a sphere in a table of all, in no order, at 10^6 spheres), so a
        // sphere two neighbouring slabs moved is on both their lists.
        each_slab(ws, step.loops, [&](contact_slab& slab) {
            for (std::uint32_t k : slab.touched) {
                packed_sphere& p = grid.sphere(k);
                if (step.walls.clear(p.x, p.radius))
                    continue;
                std::uint32_t const i = grid.slot(k);
                detail::push_out_and_meet_walls(step.walls, p.x, step.bodies.v[i], p.radius, grid.inverse_mass(k),
                                                free_a[i], step.settings, step.h);
            }
            slab.pushed.insert(slab.pushed.end(), slab.touched.begin(), slab.touched.end());
        });
        if (std::all_of(ws.slabs.begin(), ws.slabs.end(), [](contact_slab const& slab) { return slab.touched.empty(); }))
            break;
    }
    ws.stamp = stamp;
}

} // namespace kugel::physics::discrete
