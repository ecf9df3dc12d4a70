#include "collisions.hpp"

#include "collision_rules.hpp"
#include "discrete/discrete_step.hpp"
#include "wall_set.hpp"

#include <algorithm>
#include <array>

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

void resolve_collisions(collision_settings const& settings, std::span<wall const> walls,
                        std::span<obstacle const> obstacles, collision_bodies const& bodies,
                        double h, collision_workspace& workspace, collision_stats& stats,
                        step_timings& timings, parallel_for* loops)
{
    // Neither mode leaves a sphere inside a wall: discrete mode clamps the spheres it moved,
    // continuous mode every sphere.
    if (settings.mode == collision_mode::discrete) {
        resolve_discrete(settings, walls, obstacles, bodies, h, workspace.discrete, stats, timings, loops);
    } else if (settings.mode == collision_mode::continuous) {
        phase_clock clock(timings);
        resolve_continuous(settings, walls, obstacles, bodies, h, workspace, stats, loops);
        clamp_to_walls(walls, bodies);
        clock.lap(step_phase::continuous);
    }
}

void clamp_to_walls(std::span<wall const> walls, collision_bodies const& b)
{
    detail::wall_set const wall_tests(walls);
    for (std::size_t i = 0; i < b.x.size(); ++i)
        detail::clamp_to_walls(wall_tests, b.x[i], b.v[i], b.radius[i], b.inverse_mass[i]);
}

double max_overlap(std::span<wall const> walls, std::span<obstacle const> obstacles,
                   std::span<vec3 const> x, std::span<double const> radius,
                   collision_workspace& ws)
{
    double worst = 0.0;
    boxes_of_spheres(x, radius, ws.boxes, ws.members);
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
