// A pile: spheres dropped into a box under gravity, with inelastic contacts and damped,
// frictional walls, must come to rest and stay there without sinking into each other. The
// answer is rest itself: no sphere moving and no overlap. Discrete mode's knobs trade its
// cost against how soon and how still the pile rests.
#include "physics/diagnostics.hpp"
#include "physics/world.hpp"
#include "problems.hpp"

#include <cmath>
#include <memory>
#include <numbers>
#include <random>

namespace kugel::tradeoff {

using namespace physics;

namespace {

constexpr double radius = 0.05;    // m, as the pile of 10^4
constexpr double density = 1000.0; // kg/m³

/// n spheres on a lattice over a box's floor (the pile of 10^4 of bench/README.md, its floor
/// a tenth as large), each with a velocity uniform in the ball of 0.5 m/s, so that they do
/// not fall as a stack.
world make_pile(int n, int substeps, int velocity_iterations, bool sleep)
{
    world_settings settings{.integrator = integrator_kind::semi_implicit_euler,
                            .substeps = substeps};
    settings.collisions.mode = collision_mode::discrete;
    settings.collisions.restitution = 0.5;
    settings.collisions.friction = 0.5;
    settings.collisions.velocity_iterations = velocity_iterations;
    settings.collisions.sleep = sleep;
    world w(settings);
    w.add_force(std::make_unique<uniform_field>(vec3(0, 0, -9.81)));
    double const half = 0.63 * std::sqrt(static_cast<double>(n) / 1000.0); // the floor's half side
    for (wall const& boundary : box_walls({vec3(-half, -half, 0.0), vec3(half, half, 4.0)}, 0.5, 0.5))
        w.add_wall(boundary); // the floor at 0, a lid at 4 m
    auto const per_row = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(n) / 10.0)));
    double const spacing = 2.0 * (half - 0.03) / per_row;
    double const mass = 4.0 / 3.0 * std::numbers::pi * radius * radius * radius * density;
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (int i = 0; i < n; ++i) {
        int const layer = i / (per_row * per_row), in_layer = i % (per_row * per_row);
        vec3 const x(-half + 0.03 + (in_layer % per_row + 0.5) * spacing,
                     -half + 0.03 + (in_layer / per_row + 0.5) * spacing,
                     0.1 + radius + 0.15 * layer);
        vec3 v;
        do
            v = vec3(u(rng), u(rng), u(rng));
        while (v.squaredNorm() > 1.0);
        w.add_body({x, 0.5 * v, mass, radius, 0.0, false});
    }
    return w;
}

} // namespace

study pile(problem_options const& options)
{
    double const tick = 1.0 / 60.0;
    int const n = options.quick ? 100 : 1000;
    double const settle = options.quick ? 2.0 : 10.0,
                 after = 2.0; // s: the pile's time to rest, then at rest

    study s;
    s.name = "pile";
    s.title = "A pile at rest";
    s.reference =
        std::to_string(n) +
        " spheres (radius 0.05 m, ρ = 1000 kg/m³) dropped from up to 1.5 m into a box under "
        "g = 9.81 m/s², discrete mode: restitution 0.5 and friction μ = 0.5 between spheres, walls "
        "of damping "
        "0.5 and friction 0.5 (the pile of 10⁴ of `bench/README.md`, on a floor a tenth as large), "
        "stepped at "
        "the tick of 1/60 s. The answer: after " +
        number(settle) +
        " s every sphere at rest, and none sunk "
        "into another. **Error**: the fastest sphere and the kinetic energy left after " +
        number(settle) +
        " s, the deepest overlap then, in radii; the share of spheres asleep. **Cost**: CPU ms per "
        "simulated s "
        "while the pile forms (0 to " +
        number(settle) + " s) and once it rests (the " + number(after) + " s after).";
    s.knob_names = {"sleeping", "substeps of 1/60 s", "velocity iterations"};
    s.value_names = {"fastest (m/s)", "kinetic energy (J)",          "overlap (radii)",
                     "asleep",        "ms per simulated s, forming", "ms per simulated s, at rest"};
    s.cost = 4;
    s.targets = {{{{0, 1e-3}, {1, 1e-3}, {2, 0.05}},
                  "every sphere below 1 mm/s and under 1 mJ in all after " + number(settle) +
                      " s, overlaps at most 5% of a radius",
                  std::nullopt}};

    std::vector<int> const substeps = options.quick ? std::vector<int>{1} : std::vector<int>{1, 2};
    std::vector<int> const iterations =
        options.quick ? std::vector<int>{4} : std::vector<int>{2, 4, 8};
    for (bool const sleep : {true, false}) {
        for (int const sub : substeps) {
            std::string const series = std::string(sleep ? "sleeping" : "awake") + ", " +
                                       std::to_string(sub) + (sub == 1 ? " substep" : " substeps");
            for (int const passes : iterations) {
                double fastest = 0.0, kinetic = 0.0, overlap = 0.0, asleep = 0.0,
                       resting_seconds = 0.0;
                double const seconds = median_cpu_seconds(options.budget, [&] {
                    world w = make_pile(n, sub, passes, sleep);
                    double const start = thread_cpu_seconds();
                    for (int i = 0; i < static_cast<int>(std::lround(settle / tick)); ++i)
                        w.step(tick);
                    double const spent = thread_cpu_seconds() - start;
                    kinetic = measure_motion(w).kinetic;
                    fastest = 0.0;
                    for (vec3 const& v : w.bodies().velocities())
                        fastest = std::max(fastest, v.norm());
                    overlap = w.max_overlap() / radius;
                    asleep = static_cast<double>(w.sleeping_bodies()) / n;
                    double const rest_start = thread_cpu_seconds();
                    for (int i = 0; i < static_cast<int>(std::lround(after / tick)); ++i)
                        w.step(tick);
                    resting_seconds = thread_cpu_seconds() - rest_start;
                    return spent;
                });
                s.rows.push_back(
                    {series,
                     {sleep ? "on" : "off", std::to_string(sub), std::to_string(passes)},
                     {fastest, kinetic, overlap, asleep, 1e3 * seconds / settle,
                      1e3 * resting_seconds / after}});
                if (!options.quick && sleep && sub == 1 && passes == 4)
                    s.check(fastest <= 1e-3 && kinetic <= 1e-3 && overlap <= 0.05,
                            "the pile at the default settings after " + number(settle) +
                                " s: fastest " + number(fastest) + " m/s, " + number(kinetic) +
                                " J, overlap " + number(overlap) + " radii");
            }
        }
    }
    s.plots.push_back({"pile_cost", "A pile: cost while it forms against velocity iterations",
                       "velocity iterations", "CPU ms per simulated second", false, false,
                       lines_of(
                           s, [](row const& r) { return std::stod(r.knobs[2]); },
                           [](row const& r) { return r.values[4]; })});
    s.notes =
        "Sleeping is what makes a pile still: an island of spheres slower than the sleep speed "
        "(0.05 m/s) for half a second, carried by the floor, stops exactly (v = 0, x kept) and "
        "costs a "
        "step almost nothing until something touches it. Awake, the contacts keep passing a little "
        "energy around: the pile settles to centimetres per second but never stops, and costs as "
        "much "
        "at rest as while it forms. Support is passed up the pile in one ordered pass whatever its "
        "height (`physics/discrete/velocity_passes.cpp`), so the default four velocity iterations "
        "at "
        "one step per tick are enough; two, at one step per tick, leave the last avalanches moving "
        "at 10 s, and more iterations or substeps only cost more. Continuous mode is not made for "
        "piles: with restitution "
        "below 1 the spheres of a pile meet ever more often (inelastic collapse), so it reaches "
        "its "
        "event cap in nearly every step and finishes those steps in discrete mode, which the "
        "headless "
        "summary and /metrics count as capped steps, at about a hundred times the cost "
        "(`bench/README.md`); it is the mode for what must be exact (the gas and the bouncing ball "
        "above).";
    return s;
}

} // namespace kugel::tradeoff
