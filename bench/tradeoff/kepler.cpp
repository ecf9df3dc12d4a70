// Kepler orbit of eccentricity 0.5 (scenes/kepler.json): after K whole periods the pair is
// back at periapsis with its initial energy. The phase error is how far the separation's
// angle has turned away from the periapsis direction; the energy error is |ΔE/E|.
#include "problems.hpp"

#include "physics/diagnostics.hpp"
#include "physics/world.hpp"

#include <cmath>
#include <memory>
#include <numbers>

namespace kugel::tradeoff {

using namespace physics;

namespace {

constexpr double pi = std::numbers::pi;

/// Two bodies (masses 1 and 0.1, G = 1) on an orbit of semi-major axis 1 and eccentricity
/// 0.5, at periapsis along +x with the centre of mass at rest.
struct kepler_pair
{
    double m1 = 1.0, m2 = 0.1, G = 1.0, a = 1.0, e = 0.5;

    double mu() const { return G * (m1 + m2); }
    double period() const { return 2.0 * pi * std::sqrt(a * a * a / mu()); } // 5.9908
    double energy() const { return -G * m1 * m2 / (2.0 * a); }

    world make(integrator_kind kind, double softening = 0.0) const
    {
        double const M = m1 + m2;
        double const r = a * (1.0 - e);                                 // periapsis distance
        double const v = std::sqrt(mu() * (1.0 + e) / (a * (1.0 - e))); // speed there (vis-viva)
        world w({.integrator = kind, .substeps = 1});
        w.add_force(std::make_unique<newtonian_gravity>(G, softening));
        w.add_body({vec3(-m2 / M * r, 0, 0), vec3(0, -m2 / M * v, 0), m1, 0.0, 0.0, false});
        w.add_body({vec3(m1 / M * r, 0, 0), vec3(0, m1 / M * v, 0), m2, 0.0, 0.0, false});
        return w;
    }
};

struct orbit_outcome
{
    double phase_error = 0.0;  ///< rad, |angle of x₂ − x₁| after whole periods
    double energy_error = 0.0; ///< |ΔE/E|
};

orbit_outcome outcome(world const& w, kepler_pair const& pair)
{
    vec3 const r = w.bodies().positions()[1] - w.bodies().positions()[0];
    return {std::abs(std::atan2(r.y(), r.x())), std::abs(measure(w).total / pair.energy() - 1.0)};
}

} // namespace

study kepler(problem_options const& options)
{
    kepler_pair const pair;
    int const orbits = options.quick ? 1 : 10;
    double const T = orbits * pair.period();
    std::string const after = "after " + std::to_string(orbits) + (orbits == 1 ? " orbit" : " orbits");

    study s;
    s.name = "kepler";
    s.title = "Kepler orbit, eccentricity 0.5";
    s.reference = "Two bodies (masses 1 and 0.1, G = 1, no softening) on an orbit of semi-major axis 1 "
                  "and eccentricity 0.5, started at periapsis (`scenes/kepler.json`); period "
                  "P = 2π·√(a³/G(m₁+m₂)) = 5.9908. The step is dt = P/n for n steps per orbit, so after K = " +
                  std::to_string(orbits) +
                  " orbits the exact answer is back at periapsis with energy E = −G·m₁m₂/(2a) = −0.05. "
                  "**Phase error**: the angle between the final separation x₂ − x₁ and the periapsis "
                  "direction; **energy error**: |E − E₀|/|E₀| at the end.";
    s.knob_names = {"integrator", "steps per orbit", "dt (s)"};
    s.value_names = {"phase error (rad)", "energy error", "ms per simulated s"};
    s.cost = 2;
    s.targets = {{{{0, 1e-3}}, "phase error ≤ 1e-3 rad " + after, std::nullopt},
                 {{{1, 1e-6}}, "energy error ≤ 1e-6 " + after, std::nullopt}};

    std::vector<int> const steps_per_orbit =
        options.quick ? std::vector<int>{100, 400}
                      : std::vector<int>{25, 50, 100, 200, 400, 800, 1600, 3200, 6400, 12800, 25600};
    for (auto const& entry : integrator_table()) {
        if (entry.adaptive)
            continue; // it picks its own steps: measured against its tolerance in eccentric_orbits.cpp
        std::vector<double> phase_errors;
        for (int const n : steps_per_orbit) {
            double const h = pair.period() / n;
            orbit_outcome out;
            double const seconds = median_cpu_seconds(options.budget, [&] {
                world w = pair.make(entry.kind);
                double const start = thread_cpu_seconds();
                for (int i = 0; i < n * orbits; ++i)
                    w.step(h);
                double const spent = thread_cpu_seconds() - start;
                out = outcome(w, pair);
                return spent;
            });
            phase_errors.push_back(out.phase_error);
            s.rows.push_back({std::string(entry.name), {std::string(entry.name), std::to_string(n), number(h)},
                              {out.phase_error, out.energy_error, 1e3 * seconds / T}});
        }
        // Halving dt in the asymptotic range divides the error by 2^order. (Not checked for the
        // first-order ones: after whole orbits semi-implicit Euler's phase error cancels to
        // second order, and the other two have spiralled far from the asymptotic range.)
        if (options.quick) {
            double const reduction = phase_errors[0] / phase_errors[1]; // dt / 4
            double const order = std::log(reduction) / std::log(4.0);
            s.check(info(entry.kind).order < 2 || std::abs(order - info(entry.kind).order) < 0.5,
                    std::string(entry.name) + " phase error falls as dt^" + number(order) + ", not dt^" +
                        std::to_string(info(entry.kind).order));
        }
    }

    // Softening changes the law, not the cost: what it does to the answer at a fixed setting.
    if (!options.quick) {
        int const n = 1600;
        for (double const eps : {1e-3, 1e-2, 0.05}) {
            world w = pair.make(integrator_kind::velocity_verlet, eps);
            for (int i = 0; i < n * orbits; ++i)
                w.step(pair.period() / n);
            s.notes += (s.notes.empty() ? "" : ", ") + std::string("ε = ") + number(eps) + ": phase error " +
                       number(outcome(w, pair).phase_error) + " rad";
        }
        s.notes = "Softening ε (velocity_verlet, 1600 steps per orbit) changes the law rather than the cost "
                  "and moves the answer: " + s.notes + ". It buys robustness at close passes, not speed.";
    }
    s.notes = "Explicit Euler and the exact constant-force integrator (first order, not symplectic) "
              "spiral outwards: at these step counts their phase is meaningless and their energy "
              "error falls only as dt. Semi-implicit Euler and velocity Verlet keep the energy "
              "error bounded (Verlet's falls as dt²); RK4 costs four force evaluations per step "
              "and still reaches a small phase error most cheaply. " + s.notes;

    s.plots.push_back({"kepler_phase", "Kepler orbit (e = 0.5): phase error " + after,
                       "CPU ms per simulated second", "phase error (rad)", true, true,
                       lines_of(s, [](row const& r) { return r.values[2]; },
                                [](row const& r) { return std::max(r.values[0], 1e-16); })});
    s.plots.push_back({"kepler_energy", "Kepler orbit (e = 0.5): energy error " + after,
                       "CPU ms per simulated second", "|ΔE/E|", true, true,
                       lines_of(s, [](row const& r) { return r.values[2]; },
                                [](row const& r) { return std::max(r.values[1], 1e-16); })});
    return s;
}

} // namespace kugel::tradeoff
