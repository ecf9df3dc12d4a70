#include "collisions.hpp"

#include "collision_rules.hpp"
#include "sse2.hpp"
#include "time_of_impact.hpp"

#include <algorithm>
#include <array>
#include <limits>
#include <utility>

namespace kugel::physics {

void resolve_continuous(collision_settings const& settings, std::span<wall const> walls,
                        std::span<obstacle const> obstacles, collision_bodies const& bodies,
                        double h, collision_workspace& workspace, collision_stats& stats);
void resolve_discrete(collision_settings const& settings, std::span<wall const> walls,
                      std::span<obstacle const> obstacles, collision_bodies const& bodies,
                      double h, collision_workspace& workspace, collision_stats& stats,
                      parallel_for* loops);

namespace {

constexpr std::array<std::string_view, 3> mode_names{"off", "discrete", "continuous"};

/// Fills workspace.boxes and .members with the boxes of every sphere (radius > 0) at x.
void sphere_boxes(std::span<vec3 const> x, std::span<double const> radius, collision_workspace& ws)
{
    ws.boxes.clear();
    ws.members.clear();
    for (std::size_t i = 0; i < x.size(); ++i) {
        if (radius[i] > 0.0) {
            ws.boxes.push_back(aabb_of_sphere(x[i], radius[i]));
            ws.members.push_back(static_cast<std::uint32_t>(i));
        }
    }
}

/// The walls, with the axis-aligned ones (normal ±e_k, as make_plane stores them) also kept
/// as bounds per coordinate: for those, n·x is ±x_k exactly, so "n·x >= offset + r for every
/// wall" becomes two comparisons per axis, bit for bit the same test. Built once per step.
class wall_set
{
public:
    explicit wall_set(std::span<wall const> walls) : all(walls)
    {
        for (wall const& w : walls) {
            vec3 const& n = w.surface.normal;
            Eigen::Index axis = 0;
            if (n.cwiseAbs().maxCoeff(&axis) == 1.0 && (n.array() == 0.0).count() == 2) {
                (n[axis] > 0.0 ? below_ : above_)[axis] = std::max((n[axis] > 0.0 ? below_ : above_)[axis],
                                                                   w.surface.offset);
            } else {
                oblique_.push_back(w);
            }
        }
    }

    /// True when a sphere of radius r at x is clear of every wall (n·x >= offset + r for all):
    /// the common case, tested without a branch per wall.
    bool clear(vec3 const& x, double r) const
    {
#if defined(KUGEL_SSE2)
        // The same six comparisons, two at a time (every wall pass asks this of every sphere).
        __m128d const reach = _mm_set1_pd(r);
        __m128d const xy = _mm_loadu_pd(x.data());
        __m128d const minus_xy = _mm_sub_pd(_mm_setzero_pd(), xy); // 0 − x: −x, also for x = 0
        __m128d const lanes =
            _mm_and_pd(_mm_and_pd(_mm_cmpge_pd(xy, _mm_add_pd(_mm_loadu_pd(below_.data()), reach)),
                                  _mm_cmpge_pd(minus_xy, _mm_add_pd(_mm_loadu_pd(above_.data()), reach))),
                       _mm_cmpge_pd(_mm_set_pd(-x.z(), x.z()), _mm_add_pd(_mm_set_pd(above_.z(), below_.z()), reach)));
        bool clear = _mm_movemask_pd(lanes) == 3;
#else
        bool clear = x.x() >= below_.x() + r; // &=, not &&: no branch per wall
        clear &= x.y() >= below_.y() + r;
        clear &= x.z() >= below_.z() + r;
        clear &= -x.x() >= above_.x() + r;
        clear &= -x.y() >= above_.y() + r;
        clear &= -x.z() >= above_.z() + r;
#endif
        for (wall const& w : oblique_)
            clear &= w.surface.normal.dot(x) >= w.surface.offset + r;
        return clear;
    }

    /// True when a sphere at x is farther than `reach` from every wall (n·x > offset + reach
    /// for all).
    bool beyond(vec3 const& x, double reach) const
    {
        bool beyond = x.x() > below_.x() + reach;
        beyond &= x.y() > below_.y() + reach;
        beyond &= x.z() > below_.z() + reach;
        beyond &= -x.x() > above_.x() + reach;
        beyond &= -x.y() > above_.y() + reach;
        beyond &= -x.z() > above_.z() + reach;
        for (wall const& w : oblique_)
            beyond &= w.surface.normal.dot(x) > w.surface.offset + reach;
        return beyond;
    }

    std::span<wall const> all;

private:
    static constexpr double none = -std::numeric_limits<double>::infinity();
    vec3 below_ = vec3::Constant(none); ///< largest offset of the walls with normal +e_k
    vec3 above_ = vec3::Constant(none); ///< largest offset of the walls with normal −e_k
    std::vector<wall> oblique_;         ///< every other wall
};

/// Each body's acceleration over the step from free motion alone, by body slot: none after a
/// drift, when nothing was written.
struct free_accelerations
{
    std::span<vec3 const> a; ///< empty when no body accelerated

    vec3 operator[](std::size_t i) const { return a.empty() ? vec3::Zero() : a[i]; }
    bool any() const { return !a.empty(); }
};

/// Pushes a sphere (radius r, inverse mass 1/m) at x out of every wall it is inside; at each
/// such wall, meet(wall) answers for its velocity.
template <class Meet>
void push_out_of_walls(wall_set const& walls, vec3& x, double r, double inverse_mass, Meet const& meet)
{
    if (r <= 0.0 || inverse_mass == 0.0 || walls.clear(x, r))
        return;
    for (wall const& w : walls.all) {
        double const depth = w.surface.offset + r - w.surface.normal.dot(x);
        if (depth <= 0.0)
            continue;
        x += depth * w.surface.normal;
        meet(w);
    }
}

/// Pushes a sphere out of every wall it is inside and removes its velocity v into that wall
/// (continuous mode's guard against rounding).
void clamp_to_walls(wall_set const& walls, vec3& x, vec3& v, double r, double inverse_mass)
{
    push_out_of_walls(walls, x, r, inverse_mass, [&](wall const& w) {
        vec3 const& n = w.surface.normal;
        double const vn = v.dot(n);
        if (vn < 0.0)
            v -= vn * n;
    });
}

void clamp_body_to_walls(wall_set const& walls, collision_bodies const& b, std::size_t i)
{
    clamp_to_walls(walls, b.x[i], b.v[i], b.radius[i], b.inverse_mass[i]);
}

/// A sphere (free acceleration a) moving into a wall it touches meets it by the wall's rule,
/// as a bounce in the wall pass does: it leaves with the lecture's
/// w = (1 − μ)·v_t − (1 − α)·v_n or, slower than the rest threshold, rests on the wall (no
/// normal speed). Removing the normal speed outright would make every such meeting
/// perfectly inelastic: an elastic gas in discrete mode lost 29 % of its energy in 600 steps
/// that way, where a stack under gravity rests as before. Returns whether v changed.
bool meet_wall(wall const& w, vec3& v, vec3 const& a, collision_settings const& settings, double h)
{
    vec3 const& n = w.surface.normal;
    if (!(v.dot(n) < 0.0))
        return false;
    v = reflect_off_plane(v, n, w.damping, w.friction);
    double const outgoing = v.dot(n);
    if (outgoing < detail::rest_threshold(settings, a, n, h))
        v -= outgoing * n;
    return true;
}

/// The discrete step's clamp: pushed out of every wall it is inside, the sphere meets it
/// (meet_wall) instead of losing its speed into it.
void push_out_and_meet_walls(wall_set const& walls, vec3& x, vec3& v, double r, double inverse_mass,
                             vec3 const& a, collision_settings const& settings, double h)
{
    push_out_of_walls(walls, x, r, inverse_mass, [&](wall const& w) { meet_wall(w, v, a, settings, h); });
}

void push_body_out_of_walls(wall_set const& walls, collision_bodies const& b, std::size_t i,
                            free_accelerations free_a, collision_settings const& settings, double h)
{
    push_out_and_meet_walls(walls, b.x[i], b.v[i], b.radius[i], b.inverse_mass[i], free_a[i], settings, h);
}

/// Discrete walls: a sphere (radius r) found inside a wall at x, the end of its path, is taken
/// back to the time it crossed, found by the lecture's linear interpolation between tᵢ and
/// tᵢ₊₁, bounces there, and finishes the step on its new path, which ends at the new x. Up to
/// four walls per step (a corner). Returns whether it bounced; counts the responses.
bool bounce_off_walls(collision_settings const& settings, wall_set const& walls, body_path& path,
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

/// The discrete wall pass over bodies [begin, end), each on its own: makes a pending drift,
/// notes each body's free acceleration (unless free motion was a drift: then there is none),
/// bounces the spheres found inside a wall off it, and notes the bodies' extent where it
/// leaves them and, given a frame, the key of each sphere's cell there (and its x-cell, when
/// asked). Compiled once for each kind of free motion (drift_pending, accelerated, as in
/// collision_bodies), so that the loop over every body tests neither, and the extent is kept
/// in a local until the end, not in `out`.
template <bool drift_pending, bool accelerated>
void resolve_walls_discrete(collision_settings const& settings, wall_set const& walls,
                            collision_bodies const& b, double h, std::span<vec3> free_a,
                            cell_frame const* frame, std::span<std::uint64_t> keys,
                            std::span<std::uint32_t> x_cells, std::size_t begin, std::size_t end,
                            wall_chunk& out)
{
    out.moved.clear();
    out.responses = 0;
    bool any_accelerated = false;
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
        }
        double const r = b.radius[i];
        if (!(r <= 0.0 || b.inverse_mass[i] == 0.0 || walls.clear(b.x[i], r))) {
            body_path path = drift_pending ? body_path{start, b.v[i], vec3::Zero(), 0.0}
                                           : body_path{b.x0[i], b.v0[i], accelerated ? free_a[i] : vec3::Zero(), 0.0};
            if (bounce_off_walls(settings, walls, path, b.x[i], r, h, out.responses)) {
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
    out.extent = extent;
}

/// Discrete boxes: a sphere overlapping a box is pushed out along the contact normal and
/// bounces by the wall rule.
void resolve_obstacles_discrete(collision_settings const& settings, wall_set const& walls,
                                std::span<obstacle const> obstacles, collision_bodies const& b,
                                double h, free_accelerations free_a, collision_workspace& ws,
                                collision_stats& stats)
{
    for (obstacle const& o : obstacles) {
        aabb const bounds = aabb_of(o.box);
        for (std::uint32_t i = 0; i < b.x.size(); ++i) {
            double const r = b.radius[i];
            if (r <= 0.0 || b.inverse_mass[i] == 0.0 || !overlaps(bounds, aabb_of_sphere(b.x[i], r)))
                continue;
            auto const contact = sphere_vs_obb(b.x[i], r, o.box);
            if (!contact.touching)
                continue;
            body_path path{b.x[i] - contact.distance * contact.normal, b.v[i], free_a[i], h};
            if (detail::respond_to_surface(path, contact.normal, path.x.dot(contact.normal),
                                           o.damping, o.friction, settings, h))
                ++stats.obstacle_contacts;
            b.x[i] = path.x;
            b.v[i] = path.v;
            push_body_out_of_walls(walls, b, i, free_a, settings, h);
            ws.moved.push_back(i);
        }
    }
}

/// A sphere touching a wall (to a relative 1e-9 of its radius) and moving into it meets it
/// (meet_wall): a stack's weight, pressing slower than the rest threshold, is carried by the
/// wall. Returns whether its velocity changed.
bool meet_touched_walls(wall_set const& walls, packed_sphere const& s, vec3& v, vec3 const& a,
                        collision_settings const& settings, double h)
{
    double const reach = s.radius * (1.0 + 1e-9);
    if (walls.beyond(s.x, reach))
        return false;
    bool changed = false;
    for (wall const& w : walls.all)
        if (w.surface.normal.dot(s.x) <= w.surface.offset + reach)
            changed |= meet_wall(w, v, a, settings, h);
    return changed;
}

/// The share of r_a + r_b by which the discrete step's position passes let two spheres
/// overlap: a push leaves a pair touching only to the rounding of its coordinates, and about
/// half the pairs a pass pushed then overlap by a few units in the last place, which the next
/// pass pushed again, and the next (in a gas of 10^5 spheres, 3,300 such pushes in each of
/// passes 1 to 3, after 6,400 in pass 0). 2^-42 (10^-13 m between spheres of 0.05 m) is far
/// above that rounding for coordinates up to 10^3 radii, and far below any overlap the eye or
/// a test could see.
constexpr double rounding_overlap = 0x1p-42;

/// In a loop over a list of spheres in cell order that reads or writes each one's body by
/// slot, in no order: fetches the body of the sphere 8 entries further on (address(rank)
/// gives it), so that the loop does not wait on a cache miss for nearly every entry.
template <class Address>
void fetch_ahead(std::vector<std::uint32_t> const& list, std::size_t at, Address const& address)
{
    constexpr std::size_t distance = 8;
    if (at + distance < list.size())
        __builtin_prefetch(address(list[at + distance]), 1);
}

/// Files the spheres in the grid and fills the slabs' near pairs, the pairs whose boxes
/// overlap at the end positions, and their contacts, the near pairs that touch: each pair in
/// the slab of its first sphere in the grid's cell order, in that order. The grid finds the
/// pairs itself when the scene asks for it; another broadphase's pairs are put in the same
/// order, so that the broadphase changes the cost only. When the grid cannot hold the scene,
/// one slab holds every pair, in slot order. `extent` is the bodies', when known. Returns the
/// number of slabs.
std::size_t find_near_pairs(collision_settings const& settings, collision_bodies const& b,
                            std::optional<sphere_extent> const& extent, cell_keys const* keyed,
                            collision_workspace& ws, parallel_for* loops)
{
    sphere_grid& grid = ws.grid;
    bool const own_pairs = settings.broadphase == broadphase_kind::uniform_grid;
    ws.slabs.resize(sphere_grid::most_slabs); // the grid's pairs are found while it is built
    sphere_grid::slab_ready const pairs_of = [&](std::size_t s) {
        grid.near_pairs(s, ws.slabs[s].near, ws.slabs[s].contacts);
    };
    sphere_grid::slab_ready const none;
    bool const gridded = extent ? grid.build(b.x, b.radius, b.inverse_mass, *extent, loops, own_pairs ? pairs_of : none, keyed)
                                : grid.build(b.x, b.radius, b.inverse_mass, loops, own_pairs ? pairs_of : none);
    if (!gridded)
        grid.file_in_slot_order(b.x, b.radius, b.inverse_mass);
    std::size_t const slabs = grid.slab_count();
    ws.slabs.resize(slabs);
    if (gridded && own_pairs)
        return slabs;
    sphere_boxes(b.x, b.radius, ws);
    find_overlapping_pairs(settings.broadphase, ws.boxes, ws.pairs, ws.broadphase);
    grid.ranks(b.x.size(), ws.ranks);
    auto const in_cell_order = [&](box_pair const& p) {
        std::uint32_t const i = ws.ranks[ws.members[p.a]], j = ws.ranks[ws.members[p.b]];
        return box_pair{std::min(i, j), std::max(i, j)};
    };
    std::sort(ws.pairs.begin(), ws.pairs.end(), [&](box_pair const& p, box_pair const& q) {
        return in_cell_order(p) < in_cell_order(q);
    });
    for (contact_slab& slab : ws.slabs) {
        slab.near.clear();
        slab.contacts.clear();
    }
    for (box_pair const& p : ws.pairs) {
        box_pair const ranks = in_cell_order(p);
        sphere_pair const pair{ranks.a, ranks.b};
        contact_slab& slab = ws.slabs[grid.slab_of(pair.a)];
        slab.near.push_back(pair);
        packed_sphere const& s = grid.sphere(pair.a);
        packed_sphere const& t = grid.sphere(pair.b);
        double const reach = s.radius + t.radius;
        if (!((s.x - t.x).squaredNorm() > reach * reach))
            slab.contacts.push_back(pair);
    }
    return slabs;
}

/// Discrete sphere pairs. The near pairs at the end positions are found first; those that
/// touch are the step's contacts. Velocity passes: each contact that approaches exchanges
/// momentum along its normal (restitution e, none below the rest threshold), and a sphere
/// moving into a wall it touches meets it by the wall's rule (meet_wall: a bounce, or rest
/// below the threshold); repeated, so a stack passes its weight down to the floor within the
/// step instead of sinking into itself. Position passes: every near pair that overlaps by
/// then (by more than rounding_overlap) is pushed apart in proportion to the inverse masses
/// (near, not only the contacts: a push can bring two neighbours into overlap), and walls
/// push back in every pass, so stacks
/// settle on them; a sphere pushed into a wall meets it too. Only the spheres whose velocity or
/// position a pass changed are checked against the walls (each sphere on its own, so order
/// does not matter); a pass that moved nothing leaves nothing for the next.
///
/// Pairs are visited slab by slab, the even slabs first and then the odd ones, each in cell
/// order (sphere_grid.hpp). The slabs of one parity share no sphere, so they run at the same
/// time and the outcome is that order's, whatever the number of threads. A sphere listed by
/// one slab in a pass is marked, so that no other slab lists it again. The position passes
/// move the packed copies, which go back to the bodies at the end.
void resolve_pairs_discrete(collision_settings const& settings, wall_set const& walls,
                            collision_bodies const& b, double h, free_accelerations free_a,
                            std::optional<sphere_extent> const& extent, cell_keys const* keyed,
                            collision_workspace& ws, collision_stats& stats, parallel_for* loops)
{
    std::size_t const slabs = find_near_pairs(settings, b, extent, keyed, ws, loops);
    sphere_grid& grid = ws.grid;
    auto const packed = [&](std::uint32_t k) -> packed_sphere& { return grid.sphere(k); };
    auto const slot_of = [&](std::uint32_t k) { return grid.slot(k); };
    std::uint32_t const spheres = grid.slab_begin(slabs);
    auto const by_parity = [&](auto const& work) {
        for (std::size_t parity = 0; parity < 2; ++parity)
            run_loop(loops, (slabs + 1 - parity) / 2,
                     [&](std::size_t k) { work(ws.slabs[2 * k + parity]); });
    };
    auto const each_slab = [&](auto const& work) {
        run_loop(loops, slabs, [&](std::size_t s) { work(ws.slabs[s]); });
    };
    // Marks are stamps that only grow, from step to step too, so that every mark left by an
    // earlier step is below this step's first stamp and the table need not be cleared (4 MB
    // at 10^6 spheres, on one thread). Cleared only before the stamps would wrap.
    if (ws.stamp > std::numeric_limits<std::uint32_t>::max() - 64) {
        ws.mark.assign(spheres, 0);
        ws.stamp = 0;
    }
    ws.mark.resize(spheres); // new entries 0, below every stamp
    std::uint32_t stamp = ++ws.stamp;
    auto const list_once = [&](std::vector<std::uint32_t>& list, std::uint32_t k) {
        if (std::exchange(ws.mark[k], stamp) != stamp)
            list.push_back(k);
    };

    // The velocity passes work on copies of the contacts' spheres' velocities and inverse
    // masses (and free accelerations), taken once from the body slots and put back after,
    // side by side in the order they were listed: the passes then read a few megabytes at
    // 10^6 spheres, where reading by slot waited on memory for most contacts in every pass
    // (and copies by position in cell order, scattered over all spheres, for many). Each slab
    // lists its contacts' spheres that no slab listed before it, into a range of the copies
    // of its own (room for two per contact), so slabs of one parity list at the same time.
    // The spheres in contacts that touch a wall are listed too: the velocity passes stop them
    // at it. Positions do not change in those passes, so that list, and the contacts' normals,
    // hold for all of them.
    std::uint32_t copies = 0;
    for (contact_slab& slab : ws.slabs) {
        slab.first_copied = copies;
        copies += 2 * static_cast<std::uint32_t>(slab.contacts.size());
    }
    auto& moving = ws.moving;
    auto& a = ws.moving_acceleration;
    moving.resize(copies);
    a.resize(free_a.any() ? copies : 0);
    ws.listed_at.resize(spheres);
    by_parity([&](contact_slab& slab) {
        slab.copied.clear();
        slab.pushed.clear();
        slab.responses = 0;
        for (sphere_pair const& p : slab.contacts) {
            list_once(slab.copied, p.a);
            list_once(slab.copied, p.b);
        }
        slab.touched.clear();
        for (std::size_t listed = 0; listed < slab.copied.size(); ++listed) {
            std::uint32_t const k = slab.copied[listed];
            std::uint32_t const i = slot_of(k);
            auto const c = static_cast<std::uint32_t>(slab.first_copied + listed);
            fetch_ahead(slab.copied, listed, [&](std::uint32_t later) { return &b.v[slot_of(later)]; });
            ws.listed_at[k] = c;
            moving[c] = {b.v[i], grid.inverse_mass(k)};
            if (free_a.any())
                a[c] = free_a[i];
            if (!walls.beyond(packed(k).x, packed(k).radius * (1.0 + 1e-9)))
                slab.touched.push_back(k);
        }
    });
    auto const acceleration = [&](std::uint32_t c) { return free_a.any() ? a[c] : vec3::Zero(); };

    auto normal_of = [&](std::uint32_t p, std::uint32_t q, double& gap) {
        vec3 const d = packed(p).x - packed(q).x;
        double const distance = d.norm();
        gap = distance - (packed(p).radius + packed(q).radius);
        return distance > 0.0 ? vec3(d / distance) : vec3(vec3::UnitZ());
    };
    // The contacts as positions among the copies, and their normals: found once.
    each_slab([&](contact_slab& slab) {
        slab.moving_pairs.resize(slab.contacts.size());
        slab.normals.resize(slab.contacts.size());
        for (std::size_t k = 0; k < slab.contacts.size(); ++k) {
            sphere_pair const& c = slab.contacts[k];
            slab.moving_pairs[k] = {ws.listed_at[c.a], ws.listed_at[c.b]};
            double gap = 0.0;
            slab.normals[k] = normal_of(c.a, c.b, gap);
        }
    });
    for (int pass = 0; pass < std::max(settings.velocity_iterations, 1); ++pass) {
        by_parity([&](contact_slab& slab) {
            slab.changed = false;
            for (std::size_t k = 0; k < slab.moving_pairs.size(); ++k) {
                auto const [i, j] = slab.moving_pairs[k];
                vec3 const& n = slab.normals[k];
                double const closing = (moving[i].v - moving[j].v).dot(n);
                if (closing >= 0.0)
                    continue;
                double const threshold = detail::rest_threshold(
                    settings, free_a.any() ? vec3(a[i] - a[j]) : vec3::Zero(), n, h);
                double const e = -closing * settings.restitution < threshold ? 0.0 : settings.restitution;
                auto const w = collide_spheres(moving[i].v, moving[i].inverse_mass, moving[j].v,
                                               moving[j].inverse_mass, n, e);
                moving[i].v = w.first;
                moving[j].v = w.second;
                slab.responses += pass == 0 ? 1U : 0U;
                slab.changed = true;
            }
        });
        each_slab([&](contact_slab& slab) {
            for (std::uint32_t k : slab.touched) {
                std::uint32_t const c = ws.listed_at[k];
                slab.changed |= meet_touched_walls(walls, packed(k), moving[c].v, acceleration(c), settings, h);
            }
        });
        // A pass that changed no velocity leaves the next one the same state: it would
        // change none either.
        if (std::none_of(ws.slabs.begin(), ws.slabs.end(), [](contact_slab const& slab) { return slab.changed; }))
            break;
    }
    each_slab([&](contact_slab& slab) {
        for (std::size_t listed = 0; listed < slab.copied.size(); ++listed) {
            fetch_ahead(slab.copied, listed, [&](std::uint32_t later) { return &b.v[slot_of(later)]; });
            std::uint32_t const k = slab.copied[listed];
            b.v[slot_of(k)] = moving[slab.first_copied + listed].v;
        }
    });
    for (int pass = 0; pass < settings.position_iterations; ++pass) {
        // After the first pass, a pair whose spheres neither the last pass nor this one has
        // moved (marked before `recent`) is where it was when the last pass found it apart:
        // it is apart again, and its spheres are not read. About two in five pairs are not,
        // in no pattern a branch predictor could follow; so the pass lists a block's pairs
        // to check first, without a branch (each written, kept by advancing the count by
        // the test), and lists the rest of the block again after a push, which may have
        // marked more: the pairs checked are exactly those the test admits in order.
        std::uint32_t const recent = pass == 0 ? 0 : stamp;
        ++stamp;
        by_parity([&](contact_slab& slab) {
            slab.touched.clear(); // now: the spheres this pass moved
            // Pushes the pair apart if it overlaps; returns whether it did.
            auto const separate = [&](sphere_pair const& c) {
                packed_sphere& s = packed(c.a);
                packed_sphere& t = packed(c.b);
                double const reach = s.radius + t.radius;
                if ((s.x - t.x).squaredNorm() >= reach * reach)
                    return false; // most near pairs are apart: no square root for them
                double const s_inverse_mass = grid.inverse_mass(c.a), t_inverse_mass = grid.inverse_mass(c.b);
                double const total = s_inverse_mass + t_inverse_mass;
                double gap = 0.0;
                vec3 const n = normal_of(c.a, c.b, gap);
                if (gap >= -rounding_overlap * reach || total == 0.0)
                    return false;
                s.x -= (gap * s_inverse_mass / total) * n;
                t.x += (gap * t_inverse_mass / total) * n;
                list_once(slab.touched, c.a);
                list_once(slab.touched, c.b);
                return true;
            };
            sphere_pair const* const near = slab.near.data();
            std::size_t const pairs = slab.near.size();
            if (recent == 0) {
                for (std::size_t k = 0; k < pairs; ++k)
                    separate(near[k]);
                return;
            }
            constexpr std::size_t block = 16;
            std::array<std::uint32_t, block> due;
            std::uint32_t const* const mark = ws.mark.data();
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
                    if (separate(near[k])) { // it marked two spheres: list the rest again
                        listed = list_due(k + 1);
                        at = 0;
                    }
                }
            }
        });
        // The spheres moved meet the walls; the body slot is looked up only for the few that
        // touch one. Each goes on the slab's list to be written back, once for each pass that
        // moved it (writing the last position twice costs less than remembering whether it
        // is listed already: a sphere in a table of all, in no order, at 10^6 spheres), so a
        // sphere two neighbouring slabs moved is on both their lists.
        each_slab([&](contact_slab& slab) {
            for (std::uint32_t k : slab.touched) {
                packed_sphere& p = packed(k);
                if (walls.clear(p.x, p.radius))
                    continue;
                std::uint32_t const i = slot_of(k);
                push_out_and_meet_walls(walls, p.x, b.v[i], p.radius, grid.inverse_mass(k), free_a[i], settings, h);
            }
            slab.pushed.insert(slab.pushed.end(), slab.touched.begin(), slab.touched.end());
        });
        if (std::all_of(ws.slabs.begin(), ws.slabs.end(),
                        [](contact_slab const& slab) { return slab.touched.empty(); }))
            break;
    }
    // A sphere may be on the lists of two slabs (each moved it in some pass), always
    // neighbours: so the even slabs write back, then the odd ones, never one body at once.
    by_parity([&](contact_slab& slab) {
        for (std::size_t listed = 0; listed < slab.pushed.size(); ++listed) {
            fetch_ahead(slab.pushed, listed, [&](std::uint32_t later) { return &b.x[slot_of(later)]; });
            std::uint32_t const k = slab.pushed[listed];
            b.x[slot_of(k)] = packed(k).x;
        }
    });
    ws.stamp = stamp;
    for (contact_slab const& slab : ws.slabs)
        stats.sphere_contacts += slab.responses;
}

} // namespace

std::optional<collision_mode> collision_mode_from_name(std::string_view name)
{
    for (std::size_t i = 0; i < mode_names.size(); ++i)
        if (mode_names[i] == name)
            return static_cast<collision_mode>(i);
    return std::nullopt;
}

std::string_view name(collision_mode mode) { return mode_names[static_cast<std::size_t>(mode)]; }

void resolve_discrete(collision_settings const& settings, std::span<wall const> walls,
                      std::span<obstacle const> obstacles, collision_bodies const& bodies,
                      double h, collision_workspace& workspace, collision_stats& stats,
                      parallel_for* loops)
{
    // Each body's acceleration over the step from free motion alone, before any response,
    // is noted by the wall pass, which handles each body on its own: in chunks, any number
    // at a time, gathered in chunk order.
    wall_set const wall_tests(walls);
    std::size_t const n = bodies.x.size();
    auto& free_a = workspace.free_acceleration;
    free_a.resize(bodies.accelerated ? n : 0);
    workspace.wall_chunks.resize(chunk_count(n));
    // Where the bodies' extent is known at the end of this pass (no box moves a sphere after
    // it), the pass also numbers the spheres' cells in the grid's last frame (and, for a grid
    // sorted slab by slab on threads, notes their x-cells), sparing the grid another pass over
    // the bodies when the frame holds (sphere_grid::keying_frame).
    std::optional<cell_frame> const keying_frame =
        obstacles.empty() && settings.broadphase == broadphase_kind::uniform_grid
            ? workspace.grid.keying_frame()
            : std::nullopt;
    workspace.cell_keys.resize(keying_frame ? n : 0);
    workspace.cell_x.resize(keying_frame && loops ? n : 0);
    run_chunks(loops, n, [&](std::size_t c, std::size_t begin, std::size_t end) {
        auto const pass = bodies.drift_pending ? resolve_walls_discrete<true, false>
                          : bodies.accelerated ? resolve_walls_discrete<false, true>
                                               : resolve_walls_discrete<false, false>;
        pass(settings, wall_tests, bodies, h, free_a, keying_frame ? &*keying_frame : nullptr,
             workspace.cell_keys, workspace.cell_x, begin, end, workspace.wall_chunks[c]);
    });
    workspace.moved.clear();
    sphere_extent extent;
    for (wall_chunk const& chunk : workspace.wall_chunks) {
        workspace.moved.insert(workspace.moved.end(), chunk.moved.begin(), chunk.moved.end());
        stats.wall_contacts += chunk.responses;
        extent.add(chunk.extent);
    }
    // When no body accelerated, no rest threshold has an acceleration in it, and the
    // accelerations are not read by slot at all.
    bool const accelerated = std::any_of(workspace.wall_chunks.begin(), workspace.wall_chunks.end(),
                                         [](wall_chunk const& chunk) { return chunk.accelerated; });
    free_accelerations const free_motion{accelerated ? std::span<vec3 const>(free_a) : std::span<vec3 const>()};
    resolve_obstacles_discrete(settings, wall_tests, obstacles, bodies, h, free_motion, workspace, stats);
    if (!obstacles.empty()) { // a sphere a wall moved may also have met a box, or two boxes
        std::sort(workspace.moved.begin(), workspace.moved.end());
        workspace.moved.erase(std::unique(workspace.moved.begin(), workspace.moved.end()), workspace.moved.end());
    }
    // Boxes move spheres after the wall pass noted where they were.
    auto const known_extent = obstacles.empty() ? std::optional<sphere_extent>(extent) : std::nullopt;
    std::optional<cell_keys> const keyed =
        keying_frame ? std::optional<cell_keys>({workspace.cell_keys, *keying_frame, workspace.cell_x})
                     : std::nullopt;
    resolve_pairs_discrete(settings, wall_tests, bodies, h, free_motion, known_extent,
                           keyed ? &*keyed : nullptr, workspace, stats, loops);

    // No sphere is left inside a wall: the spheres walls and boxes moved are clamped here, once
    // each, and the position passes clamp every sphere they move after each pass (the velocity
    // passes move none); every other sphere was clear of every wall when the wall pass looked
    // at it and has not moved since, so clamping it would change nothing. (Clamping a bounced
    // sphere before the pair passes instead of after them left stacks settling four times
    // worse.)
    for (std::uint32_t i : workspace.moved)
        push_body_out_of_walls(wall_tests, bodies, i, free_motion, settings, h);
}

void resolve_collisions(collision_settings const& settings, std::span<wall const> walls,
                        std::span<obstacle const> obstacles, collision_bodies const& bodies,
                        double h, collision_workspace& workspace, collision_stats& stats,
                        parallel_for* loops)
{
    // Neither mode leaves a sphere inside a wall: discrete mode clamps the spheres it moved,
    // continuous mode every sphere.
    if (settings.mode == collision_mode::discrete) {
        resolve_discrete(settings, walls, obstacles, bodies, h, workspace, stats, loops);
    } else if (settings.mode == collision_mode::continuous) {
        resolve_continuous(settings, walls, obstacles, bodies, h, workspace, stats);
        clamp_to_walls(walls, bodies);
    }
}

void clamp_to_walls(std::span<wall const> walls, collision_bodies const& b)
{
    wall_set const wall_tests(walls);
    for (std::size_t i = 0; i < b.x.size(); ++i)
        clamp_body_to_walls(wall_tests, b, i);
}

double max_overlap(std::span<wall const> walls, std::span<obstacle const> obstacles,
                   std::span<vec3 const> x, std::span<double const> radius,
                   collision_workspace& ws)
{
    double worst = 0.0;
    sphere_boxes(x, radius, ws);
    find_overlapping_pairs(broadphase_kind::uniform_grid, ws.boxes, ws.pairs, ws.broadphase);
    for (box_pair const& p : ws.pairs) {
        std::size_t const i = ws.members[p.a], j = ws.members[p.b];
        worst = std::max(worst, radius[i] + radius[j] - (x[i] - x[j]).norm());
    }
    for (std::size_t i = 0; i < x.size(); ++i) {
        if (radius[i] <= 0.0)
            continue;
        for (wall const& w : walls)
            worst = std::max(worst, w.surface.offset + radius[i] - w.surface.normal.dot(x[i]));
        for (obstacle const& o : obstacles)
            worst = std::max(worst, -sphere_vs_obb(x[i], radius[i], o.box).distance);
    }
    return worst;
}

} // namespace kugel::physics
