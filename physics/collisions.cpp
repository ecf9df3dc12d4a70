#include "collisions.hpp"

#include "collision_rules.hpp"
#include "discrete/discrete_step.hpp"
#include "cells.hpp"
#include "wall_set.hpp"

#include <algorithm>
#include <array>
#include <limits>
#include <optional>

namespace kugel::physics {

namespace {

constexpr std::array<std::string_view, 3> mode_names{"off", "discrete", "continuous"};

} // namespace

std::optional<collision_mode> collision_mode_from_name(std::string_view name)
{
    for (std::size_t i = 0; i < mode_names.size(); ++i)
        if (mode_names[i] == name)
            return static_cast<collision_mode>(i);
    return std::nullopt;
}

std::string_view name(collision_mode mode) { return mode_names[static_cast<std::size_t>(mode)]; }

std::vector<wall> box_walls(aabb const& region, double damping, double friction)
{
    std::vector<wall> walls;
    for (int axis = 0; axis < 3; ++axis) {
        vec3 n = vec3::Zero();
        n[axis] = 1.0;
        walls.push_back({make_plane(n, region.min[axis]), damping, friction});
        walls.push_back({make_plane(-n, -region.max[axis]), damping, friction});
    }
    return walls;
}

void resolve_collisions(collision_settings const& settings, std::span<wall const> walls,
                        std::span<obstacle const> obstacles, collision_bodies const& bodies,
                        double h, collision_workspace& workspace, collision_stats& stats,
                        step_timings& timings, parallel_for* loops)
{
    // Neither mode leaves a sphere inside a wall: discrete mode clamps the spheres it moved,
    // continuous mode every sphere that can be (resolve_continuous).
    if (settings.mode == collision_mode::discrete) {
        resolve_discrete(settings, walls, obstacles, bodies, h, workspace.discrete, stats, timings, loops);
    } else if (settings.mode == collision_mode::continuous) {
        phase_clock clock(timings);
        resolve_continuous(settings, walls, obstacles, bodies, h, workspace, stats, loops);
        clock.lap(step_phase::continuous);
    }
}

void clamp_to_walls(std::span<wall const> walls, collision_bodies const& b)
{
    detail::wall_set const wall_tests(walls);
    for (std::size_t i = 0; i < b.x.size(); ++i)
        detail::clamp_to_walls(wall_tests, b.x[i], b.v[i], b.radius[i], b.inverse_mass[i]);
}

namespace {

using filed_centre = collision_workspace::filed_centre;

/// The deepest overlap of two spheres, from their centres filed into cells as wide as the
/// largest diameter (cells.hpp) and sorted by cell: 16 bytes a sphere, where boxes and a
/// broadphase took about 140 (at 10⁶ spheres the summary of a run weighed more than its
/// step). Nothing when the cells cannot be numbered (coordinates too far out for the
/// largest sphere, or not finite): the broadphase's answer is asked for then.
std::optional<double> deepest_pair_overlap(std::span<vec3 const> x, std::span<double const> radius,
                                           std::vector<filed_centre>& filed)
{
    double largest = 0.0;
    vec3 lo = vec3::Constant(std::numeric_limits<double>::infinity());
    vec3 hi = -lo;
    std::size_t spheres = 0;
    for (std::size_t i = 0; i < x.size(); ++i) {
        if (!(radius[i] > 0.0))
            continue;
        if (!x[i].allFinite())
            return std::nullopt;
        ++spheres;
        largest = std::max(largest, radius[i]);
        lo = lo.cwiseMin(x[i]);
        hi = hi.cwiseMax(x[i]);
    }
    if (largest == 0.0)
        return 0.0;
    double const extent = 2.0 * largest;
    double const reach = std::max(lo.cwiseAbs().maxCoeff(), hi.cwiseAbs().maxCoeff()) / extent;
    if (!(reach <= cells::largest_cell_coordinate))
        return std::nullopt;
    double const width = cells::widened_cell_size(extent, reach);
    // Cells counted from the lowest centre's, with one cell of padding on every side, so
    // that the neighbours of a column in the keys' order never wrap into another column.
    std::array<std::int64_t, 3> first{}, size{};
    for (int a = 0; a < 3; ++a) {
        first[static_cast<std::size_t>(a)] = cells::floor_to_integer(lo[a] / width) - 1;
        size[static_cast<std::size_t>(a)] = cells::floor_to_integer(hi[a] / width) + 2 - first[static_cast<std::size_t>(a)];
    }
    auto const column = cells::checked_product(static_cast<std::uint64_t>(size[1]), static_cast<std::uint64_t>(size[2]));
    if (!column || !cells::checked_product(*column, static_cast<std::uint64_t>(size[0])))
        return std::nullopt;
    auto const cell_key = [&](vec3 const& p) {
        std::array<std::uint64_t, 3> c{};
        for (int a = 0; a < 3; ++a)
            c[static_cast<std::size_t>(a)] = static_cast<std::uint64_t>(
                cells::floor_to_integer(p[a] / width) - first[static_cast<std::size_t>(a)]);
        return (c[0] * static_cast<std::uint64_t>(size[1]) + c[1]) * static_cast<std::uint64_t>(size[2]) + c[2];
    };
    filed.clear();
    filed.reserve(spheres); // as many as there are: grown by doubling, the old and the new were both held
    for (std::size_t i = 0; i < x.size(); ++i)
        if (radius[i] > 0.0)
            filed.push_back({cell_key(x[i]), static_cast<std::uint32_t>(i)});
    std::sort(filed.begin(), filed.end(), [](filed_centre const& l, filed_centre const& r) {
        return l.key != r.key ? l.key < r.key : l.slot < r.slot;
    });

    // Each pair once: a sphere against those after it in its own column (its cell and the
    // one above in z), and against the columns of the half shell, (0, +1), (+1, −1), (+1, 0)
    // and (+1, +1) in (x, y), z − 1 to z + 1 in each. A column's start only moves on as the
    // spheres' keys grow, so each is followed by a cursor.
    auto const z_step = std::uint64_t{1};
    auto const y_step = static_cast<std::uint64_t>(size[2]);
    auto const x_step = *column;
    std::array<std::uint64_t, 4> const offsets{y_step, x_step - y_step, x_step, x_step + y_step};
    std::array<std::size_t, 4> cursor{};
    double worst = 0.0;
    auto const test = [&](std::uint32_t i, std::uint32_t j) {
        worst = std::max(worst, radius[i] + radius[j] - (x[i] - x[j]).norm());
    };
    for (std::size_t k = 0; k < filed.size(); ++k) {
        std::uint64_t const key = filed[k].key;
        for (std::size_t m = k + 1; m < filed.size() && filed[m].key <= key + z_step; ++m)
            test(filed[k].slot, filed[m].slot);
        for (std::size_t c = 0; c < offsets.size(); ++c) {
            std::uint64_t const from = key + offsets[c] - z_step, to = key + offsets[c] + z_step;
            std::size_t& m = cursor[c];
            while (m < filed.size() && filed[m].key < from)
                ++m;
            for (std::size_t n = m; n < filed.size() && filed[n].key <= to; ++n)
                test(filed[k].slot, filed[n].slot);
        }
    }
    return worst;
}

} // namespace

double max_overlap(std::span<wall const> walls, std::span<obstacle const> obstacles,
                   std::span<vec3 const> x, std::span<double const> radius,
                   collision_workspace& ws)
{
    double worst = 0.0;
    if (auto const pairs = deepest_pair_overlap(x, radius, ws.filed)) {
        worst = *pairs;
    } else {
        boxes_of_spheres(x, radius, ws.boxes, ws.members);
        find_overlapping_pairs(broadphase_kind::uniform_grid, ws.boxes, ws.pairs, ws.broadphase);
        for (box_pair const& p : ws.pairs) {
            std::size_t const i = ws.members[p.a], j = ws.members[p.b];
            worst = std::max(worst, radius[i] + radius[j] - (x[i] - x[j]).norm());
        }
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
