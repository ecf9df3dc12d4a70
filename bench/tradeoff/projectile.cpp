// Projectile in a uniform field: the parabola x(t) = x₀ + v₀t + g t²/2 is the answer, so the
// exact constant-force integrator (and Verlet and RK4, exact for a constant force too) meets
// it to rounding at any dt, while both Euler variants are off by exactly g·T·h/2.
#include "problems.hpp"

#include "physics/world.hpp"

#include <cmath>
#include <memory>

namespace kugel::tradeoff {

using namespace physics;

study projectile(problem_options const& options)
{
    vec3 const x0(0.0, 0.0, 0.0);
    vec3 const v0(14.142135623730951, 0.0, 14.142135623730951); // 20 m/s at 45° (scenes/projectile.json)
    vec3 const g(0.0, 0.0, -9.81);
    double const T = 2.0; // s, the ball is still in the air (flight time 2.88 s)
    vec3 const exact = x0 + v0 * T + 0.5 * T * T * g;

    study s;
    s.name = "projectile";
    s.title = "Projectile under a uniform field";
    s.reference = "A ball thrown at 20 m/s and 45° in the lecture's field g = 9.81 m/s² "
                  "(`scenes/projectile.json`). The answer is the parabola x(t) = x₀ + v₀t + g t²/2; "
                  "the error is the distance |x(T) − x_exact(T)| after T = 2 s.";
    s.knob_names = {"integrator", "dt (s)"};
    s.value_names = {"position error (m)", "ms per simulated s"};
    s.cost = 1;
    s.targets = {{{{0, 1e-6}}, "position error ≤ 1 µm after 2 s", std::nullopt}};

    std::vector<int> const step_counts =
        options.quick ? std::vector<int>{30, 120} : std::vector<int>{30, 60, 120, 240, 480, 960, 1920};
    for (auto const& entry : integrator_table()) {
        if (entry.adaptive)
            continue; // it picks its own steps: measured against its tolerance in eccentric_orbits.cpp
        for (int const n : step_counts) {
            double const h = T / n;
            vec3 end = vec3::Zero();
            double const seconds = median_cpu_seconds(options.budget, [&] {
                world w({.integrator = entry.kind, .substeps = 1});
                w.add_force(std::make_unique<uniform_field>(g));
                w.add_body({x0, v0, 0.43, 0.11, 0.0, false});
                double const start = thread_cpu_seconds();
                for (int i = 0; i < n; ++i)
                    w.step(h);
                double const spent = thread_cpu_seconds() - start;
                end = w.bodies().positions()[0];
                return spent;
            });
            double const error = (end - exact).norm();
            s.rows.push_back({std::string(entry.name), {std::string(entry.name), seconds_fraction(h)},
                              {error, 1e3 * seconds / T}});

            // The claims the report rests on, true on any machine.
            bool const exact_for_constant_force = entry.kind == integrator_kind::exact_constant_force ||
                                                  entry.kind == integrator_kind::velocity_verlet ||
                                                  entry.kind == integrator_kind::rk4;
            if (exact_for_constant_force) {
                s.check(error <= 1e-13 * exact.norm(),
                        std::string(entry.name) + " is exact for a constant force, yet misses the parabola by " +
                            number(error) + " m at dt = " + seconds_fraction(h));
            } else {
                // x_n = x₀ + v₀T + g·h²·n(n∓1)/2: the error is g·T·h/2 exactly
                double const expected = g.norm() * T * h / 2.0;
                s.check(std::abs(error - expected) <= 1e-9 * expected,
                        std::string(entry.name) + " error " + number(error, 6) + " m is not g·T·h/2 = " +
                            number(expected, 6) + " m at dt = " + seconds_fraction(h));
            }
        }
    }

    // Errors of the exact integrators are rounding (often exactly 0): drawn at 1e-16 m.
    s.plots.push_back({"projectile", "Projectile: position error after 2 s", "CPU ms per simulated second",
                       "position error (m)", true, true,
                       lines_of(s, [](row const& r) { return r.values[1]; },
                                [](row const& r) { return std::max(r.values[0], 1e-16); })});
    s.notes = "Verlet and RK4 are exact here too (a constant force has no higher derivatives), "
              "but cost the same or four times as much per step; both Euler variants are first "
              "order with the error exactly g·T·h/2, so the 1 µm target would need about 10⁷ "
              "steps per second. Exact errors (rounding, often exactly 0) are drawn at 1e-16 m.";
    return s;
}

} // namespace kugel::tradeoff
