// Phase 3 of the discrete step: the spheres sorted into cells, and the near pairs of each slab.

#include "kernels.hpp"
#include "passes.hpp"

#include "physics/time_of_impact.hpp"

#include <algorithm>

namespace kugel::physics::discrete {

namespace {

/// The near pairs from a broadphase other than the grid, put in the grid's order: each pair in
/// the slab of its first sphere in cell order, in that order, so that the broadphase changes
/// the cost only. With a contact margin m, every box is grown by m, which finds every pair the
/// grid's test would (one box grown by m, discrete/kernels.hpp) and some more, and the grid's
/// own test then keeps the same pairs it would have found.
void pairs_from_broadphase(broadphase_kind kind, collision_bodies const& b, discrete_workspace& ws)
{
    auto& other = ws.other;
    double const margin = ws.grid.contact_margin();
    boxes_of_spheres(b.x, b.radius, other.boxes, other.members, margin);
    find_overlapping_pairs(kind, other.boxes, other.pairs, other.broadphase);
    sphere_grid const& grid = ws.grid;
    grid.ranks(b.x.size(), other.ranks);
    auto const in_cell_order = [&](box_pair const& p) {
        std::uint32_t const i = other.ranks[other.members[p.a]], j = other.ranks[other.members[p.b]];
        return box_pair{std::min(i, j), std::max(i, j)};
    };
    std::sort(other.pairs.begin(), other.pairs.end(),
              [&](box_pair const& p, box_pair const& q) { return in_cell_order(p) < in_cell_order(q); });
    for (contact_slab& slab : ws.slabs) {
        slab.near.clear();
        slab.contacts.clear();
    }
    for (box_pair const& p : other.pairs) {
        box_pair const ranks = in_cell_order(p);
        sphere_pair const pair{ranks.a, ranks.b};
        packed_sphere const& s = grid.sphere(pair.a);
        packed_sphere const& t = grid.sphere(pair.b);
        if (margin > 0.0 && !sphere_box_plain(s, margin).meets(t))
            continue;
        contact_slab& slab = ws.slabs[grid.slab_of(pair.a)];
        slab.near.push_back(pair);
        if (spheres_overlap(s.x, s.radius + margin, t.x, t.radius))
            slab.contacts.push_back(pair); // of the pairs the broadphase found: boxes that overlap
    }
}

} // namespace

// The spheres are filed in the grid, and the slabs get their near pairs, the pairs whose boxes
// overlap at the end positions, and their contacts, the near pairs that touch. The grid finds
// the pairs itself, each slab's as soon as it is sorted, when the scene asks for it; when the
// grid cannot hold the scene, one slab holds every pair, in slot order.
std::size_t sort_into_cells(step_context const& step, wall_pass_result const& walls, discrete_workspace& ws)
{
    collision_bodies const& b = step.bodies;
    sphere_grid& grid = ws.grid;
    bool const own_pairs = step.settings.broadphase == broadphase_kind::uniform_grid;
    ws.slabs.resize(sphere_grid::most_slabs); // the grid's pairs are found while it is built
    sphere_grid::slab_ready const pairs_of = [&](std::size_t s) {
        grid.near_pairs(s, ws.slabs[s].near, ws.slabs[s].contacts);
    };
    sphere_grid::slab_ready const none;
    bool gridded = false;
    grid.set_contact_margin(walls.contact_margin);
    if (step.obstacles.empty()) { // boxes move spheres after the wall pass noted their extent
        std::optional<cell_keys> const keyed =
            walls.keying_frame ? std::optional<cell_keys>({ws.cell_keys, *walls.keying_frame, ws.cell_x})
                               : std::nullopt;
        gridded = grid.build(b.x, b.radius, b.inverse_mass, walls.extent, step.loops, own_pairs ? pairs_of : none,
                             keyed ? &*keyed : nullptr);
    } else {
        gridded = grid.build(b.x, b.radius, b.inverse_mass, step.loops, own_pairs ? pairs_of : none);
    }
    if (!gridded)
        grid.file_in_slot_order(b.x, b.radius, b.inverse_mass);
    std::size_t const slabs = grid.slab_count();
    ws.slabs.resize(slabs);
    if (!(gridded && own_pairs))
        pairs_from_broadphase(step.settings.broadphase, b, ws);
    return slabs;
}

} // namespace kugel::physics::discrete
