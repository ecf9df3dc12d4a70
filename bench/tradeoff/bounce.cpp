// Bouncing ball: a ball dropped onto a floor of damping α keeps (1−α)² of its apex height
// per bounce, so the apex after bounce k is h₀·(1−α)^(2k). Continuous mode finds each
// contact on the exact parabola; discrete mode by the lecture's linear interpolation.
#include "problems.hpp"

#include "physics/world.hpp"

#include <cmath>
#include <memory>

namespace kugel::tradeoff {

using namespace physics;

study bounce(problem_options const& options)
{
    double const g = 9.81, alpha = 0.2, radius = 0.5, drop = 1.0; // drop: apex height above rest
    int const bounces = 5;
    double const tick = 1.0 / 60.0;
    double const T = 3.0; // s: five bounces take 2.9 s

    study s;
    s.name = "bounce";
    s.title = "Bouncing ball";
    s.reference = "A ball (radius 0.5 m) dropped from 1 m above its resting height onto a floor of damping "
                  "α = 0.2, g = 9.81 m/s², stepped at the server's tick of 1/60 s split into substeps. "
                  "The apex after bounce k is h₀·(1−α)^(2k) (the lecture's wall rule keeps (1−α) of "
                  "the normal speed). Each apex is read at the top of its arc, from the last state on the way "
                  "up, as z − r + v_z²/(2g) (exact for the parabola through that state). "
                  "**Error**: the worst relative apex error over the first five bounces.";
    s.knob_names = {"collisions", "integrator", "substeps of 1/60 s"};
    s.value_names = {"apex error (relative)", "ms per simulated s"};
    s.cost = 1;
    s.targets = {{{{0, 1e-3}}, "every apex within 0.1%", std::nullopt}};

    std::vector<int> const substeps = options.quick ? std::vector<int>{1, 8} : std::vector<int>{1, 2, 4, 8, 16, 32, 64};
    for (auto const mode : {collision_mode::discrete, collision_mode::continuous}) {
        for (auto const kind : {integrator_kind::semi_implicit_euler, integrator_kind::exact_constant_force}) {
            std::string const series = std::string(name(mode)) + ", " + std::string(info(kind).name);
            for (int const sub : substeps) {
                std::vector<double> apexes;
                double const seconds = median_cpu_seconds(options.budget, [&] {
                    world_settings settings{.integrator = kind, .substeps = sub};
                    settings.collisions.mode = mode;
                    world w(settings);
                    w.add_force(std::make_unique<uniform_field>(vec3(0, 0, -g)));
                    w.add_wall({make_plane(vec3::UnitZ(), 0.0), alpha, 0.0});
                    w.add_body({vec3(0, 0, radius + drop), vec3::Zero(), 1.0, radius, 0.0, false});
                    apexes.clear();
                    double previous_z = 0.0, previous_vz = 0.0;
                    double const start = thread_cpu_seconds();
                    for (int i = 0; i < static_cast<int>(std::lround(T / tick)); ++i) {
                        w.step(tick);
                        double const z = w.bodies().positions()[0].z();
                        double const vz = w.bodies().velocities()[0].z();
                        // at the top of an arc: the apex of the parabola through the last
                        // state on the way up (what the integrator reached, not a prediction
                        // from the bounce)
                        if (previous_vz > 0.0 && vz <= 0.0 && static_cast<int>(apexes.size()) < bounces)
                            apexes.push_back(previous_z - radius + previous_vz * previous_vz / (2.0 * g));
                        previous_z = z;
                        previous_vz = vz;
                    }
                    return thread_cpu_seconds() - start;
                });
                double error = apexes.size() == static_cast<std::size_t>(bounces) ? 0.0 : 1.0; // a bounce lost
                for (std::size_t k = 0; k < apexes.size(); ++k) {
                    double const exact = drop * std::pow(1.0 - alpha, 2.0 * static_cast<double>(k + 1));
                    error = std::max(error, std::abs(apexes[k] / exact - 1.0));
                }
                s.rows.push_back({series, {std::string(name(mode)), std::string(info(kind).name), std::to_string(sub)},
                                  {error, 1e3 * seconds / T}});
                if (mode == collision_mode::continuous && kind == integrator_kind::exact_constant_force)
                    s.check(error <= 1e-9, "continuous mode on the exact parabola misses an apex by " + number(error) +
                                               " (relative) with " + std::to_string(sub) + " substeps");
            }
        }
    }
    s.notes = "Continuous mode finds each contact on the exact parabola, and with collisions on it "
              "ends every step on the parabola through the step's start with the step's acceleration "
              "(the collision path, `body_path`): under a uniform field that makes semi-implicit Euler "
              "exact too, at every substep count. Discrete mode reflects at the lecture's linearly "
              "interpolated crossing: with the exact integrator its error falls faster than dt, with "
              "semi-implicit Euler it stays first order (the integrator's own error).";
    s.plots.push_back({"bounce", "Bouncing ball: worst apex error over five bounces", "CPU ms per simulated second",
                       "apex error (relative)", true, true,
                       lines_of(s, [](row const& r) { return r.values[1]; },
                                [](row const& r) { return std::max(r.values[0], 1e-16); })});
    return s;
}

} // namespace kugel::tradeoff
