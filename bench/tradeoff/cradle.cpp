// Newton's cradle: a striker hits a row of four touching equal balls; elastic contacts pass
// the momentum down the row, and the last ball leaves with the striker's speed while the
// others stop. The faster the striker, the deeper it lands inside its neighbour in one
// step, which discrete mode must undo after the fact.
#include "problems.hpp"

#include "physics/diagnostics.hpp"
#include "physics/world.hpp"

#include <cmath>

namespace kugel::tradeoff {

using namespace physics;

study cradle(problem_options const& options)
{
    double const tick = 1.0 / 60.0;
    double const gap = 0.01; // m between the balls of the row

    study s;
    s.name = "cradle";
    s.title = "Newton's cradle";
    s.reference = "Five equal balls (radius 0.5 m, 1 kg) without strings, as in `scenes/cradle.json`: a striker "
                  "2 m from a row of four balls hung 1 cm apart, restitution 1, no forces, stepped at the tick of "
                  "1/60 s until the striker would have travelled 3 m. The answer: the last ball leaves with "
                  "the striker's velocity, the other four are at rest (with exactly touching balls both modes "
                  "are exact, as `NewtonsCradlePassesTheMomentumThroughTheChain` tests; the gaps make the "
                  "contacts follow one another inside a step). **Error**: the largest |v − v_exact| "
                  "of any ball over the striker's speed; the energy error is |ΔK/K|.";
    s.knob_names = {"collisions", "substeps of 1/60 s", "striker speed (m/s)"};
    s.value_names = {"velocity error (relative)", "energy error", "ms per simulated s"};
    s.cost = 2;
    s.targets = {{{{0, 1e-6}}, "every ball's velocity within 1e-6 of the striker's speed", 2}};

    std::vector<double> const speeds = options.quick ? std::vector<double>{1.0, 30.0}
                                                     : std::vector<double>{0.3, 1.0, 3.0, 10.0, 30.0, 100.0};
    std::vector<int> const substeps = options.quick ? std::vector<int>{1} : std::vector<int>{1, 4, 16};
    for (auto const mode : {collision_mode::discrete, collision_mode::continuous}) {
        for (int const sub : substeps) {
            std::string const series = std::string(name(mode)) + ", " + std::to_string(sub) + (sub == 1 ? " substep" : " substeps");
            for (double const speed : speeds) {
                auto const n = static_cast<int>(std::ceil(3.0 / speed / tick));
                double const T = n * tick;
                double error = 0.0, energy_error = 0.0;
                double const seconds = median_cpu_seconds(options.budget, [&] {
                    world_settings settings{.substeps = sub};
                    settings.collisions.mode = mode;
                    world w(settings);
                    w.add_body({vec3(-3.0, 0, 0), vec3(speed, 0, 0), 1.0, 0.5, 0.0, false});
                    for (int k = 0; k < 4; ++k)
                        w.add_body({vec3(k * (1.0 + gap), 0, 0), vec3::Zero(), 1.0, 0.5, 0.0, false});
                    double const k0 = measure_motion(w).kinetic;
                    double const start = thread_cpu_seconds();
                    for (int i = 0; i < n; ++i)
                        w.step(tick);
                    double const spent = thread_cpu_seconds() - start;
                    error = 0.0;
                    for (std::size_t b = 0; b < 5; ++b) {
                        vec3 const exact = b == 4 ? vec3(speed, 0, 0) : vec3::Zero();
                        error = std::max(error, (w.bodies().velocities()[b] - exact).norm() / speed);
                    }
                    energy_error = std::abs(measure_motion(w).kinetic / k0 - 1.0);
                    return spent;
                });
                s.rows.push_back({series, {std::string(name(mode)), std::to_string(sub), number(speed)},
                                  {error, energy_error, 1e3 * seconds / T}});
                if (mode == collision_mode::continuous)
                    s.check(error <= 1e-12, "continuous mode leaves a velocity error of " + number(error) + " at " +
                                                number(speed) + " m/s");
            }
        }
    }
    s.notes = "Continuous mode takes the contacts in time order and is exact at every speed. Discrete "
              "mode is exact while the striker and the pulse move little per step; once one step "
              "carries a ball across a gap and deep into the next, it answers several overlaps at "
              "once and the wrong ball leaves (error 1). Substeps push that speed up, at their cost.";
    s.plots.push_back({"cradle", "Newton's cradle: velocity error against the striker's speed", "striker speed (m/s)",
                       "velocity error (relative)", true, true,
                       lines_of(s, [](row const& r) { return std::stod(r.knobs[2]); },
                                [](row const& r) { return std::max(r.values[0], 1e-16); })});
    return s;
}

} // namespace kugel::tradeoff
