// Coulomb scattering off a fixed charge against Rutherford's deflection angle
// tan(Θ/2) = k·q·Q / (m·v∞²·b). The run starts and ends at a finite distance, so each
// state's asymptote is taken from its conserved quantities (energy, angular momentum and
// the Runge–Lenz vector): that is exact for the hyperbola through the state, and leaves
// only what the integrator did wrong.
#include "problems.hpp"

#include "physics/diagnostics.hpp"
#include "physics/world.hpp"

#include <cmath>
#include <memory>

namespace kugel::tradeoff {

using namespace physics;

namespace {

constexpr double kappa = 1.0; // k·q·Q: k = 1, q = Q = 1 (repulsive)
constexpr double mass = 1.0;

/// The repulsive hyperbola through a state (r, v) in the xy plane about a fixed centre.
struct hyperbola
{
    double energy;   ///< ½·m·v² + κ/r
    double angular;  ///< L_z = m·(r × v)_z
    double periapsis_angle; ///< direction of the Runge–Lenz vector A = p × L + m·κ·r̂
    double half_angle;      ///< ψ = arccos(1/e): asymptotes at periapsis_angle ± ψ

    explicit hyperbola(vec3 const& r, vec3 const& v)
    {
        energy = 0.5 * mass * v.squaredNorm() + kappa / r.norm();
        vec3 const L = mass * r.cross(v);
        angular = L.z();
        vec3 const A = (mass * v).cross(L) + mass * kappa * r.normalized();
        periapsis_angle = std::atan2(A.y(), A.x());
        double const e = std::sqrt(1.0 + 2.0 * energy * angular * angular / (mass * kappa * kappa));
        half_angle = std::acos(1.0 / e);
    }
    double sense() const { return angular >= 0.0 ? 1.0 : -1.0; }
    /// Direction of travel far out on the way in and on the way out.
    vec3 incoming() const
    {
        double const from = periapsis_angle - sense() * half_angle; // where it came from
        return -vec3(std::cos(from), std::sin(from), 0.0);
    }
    vec3 outgoing() const
    {
        double const to = periapsis_angle + sense() * half_angle;
        return vec3(std::cos(to), std::sin(to), 0.0);
    }
};

double angle_between(vec3 const& a, vec3 const& b) { return std::atan2(a.cross(b).norm(), a.dot(b)); }

} // namespace

study coulomb_scattering(problem_options const& options)
{
    vec3 const x0(-20.0, 1.0, 0.0); // 20 m out, 1 m off axis
    vec3 const v0(1.0, 0.0, 0.0);
    double const T = 40.0; // s: in, past the charge (closest approach 2.5 m) and 20 m out again

    // Rutherford for the hyperbola the run starts on: v∞ and b from its energy and L.
    hyperbola const start(x0, v0);
    double const v_inf = std::sqrt(2.0 * start.energy / mass);
    double const b = std::abs(start.angular) / (mass * v_inf);
    double const rutherford = 2.0 * std::atan(kappa / (mass * v_inf * v_inf * b));

    study s;
    s.name = "coulomb";
    s.title = "Coulomb scattering against Rutherford";
    s.reference = "A charge (q = 1, m = 1) flies past a fixed like charge (Q = 1, k = 1, no softening) from 20 m "
                  "out, 1 m off axis, at 1 m/s, for " + number(T) + " s. Rutherford's angle "
                  "tan(Θ/2) = k·q·Q/(m·v∞²·b), with v∞ and b of the hyperbola the run starts on, is Θ = " +
                  number(rutherford, 6) + " rad. The run's own deflection is the angle between the "
                  "incoming asymptote of the first state and the outgoing asymptote of the last, each "
                  "taken from the state's energy, angular momentum and Runge–Lenz vector (exact for the "
                  "hyperbola through that state, so the finite start and end distance cost nothing). "
                  "**Error**: |Θ_run − Θ|.";
    s.knob_names = {"integrator", "dt (s)"};
    s.value_names = {"deflection error (rad)", "energy error", "ms per simulated s"};
    s.cost = 2;
    s.targets = {{{{0, 1e-6}}, "deflection error ≤ 1e-6 rad", std::nullopt}};

    std::vector<double> const steps =
        options.quick ? std::vector<double>{0.1, 0.025} : std::vector<double>{0.4, 0.2, 0.1, 0.05, 0.025, 0.0125, 0.00625, 0.003125, 0.0015625};
    for (auto const& entry : integrator_table()) {
        if (entry.adaptive)
            continue; // it picks its own steps: measured against its tolerance in eccentric_orbits.cpp
        std::vector<double> errors;
        for (double const h : steps) {
            auto const n = static_cast<int>(std::lround(T / h));
            double error = 0.0, energy_error = 0.0;
            double const seconds = median_cpu_seconds(options.budget, [&] {
                world w({.integrator = entry.kind, .substeps = 1});
                w.add_force(std::make_unique<coulomb>(1.0, 0.0));
                w.add_body({vec3::Zero(), vec3::Zero(), 1.0, 0.0, 1.0, true});
                w.add_body({x0, v0, mass, 0.0, 1.0, false});
                double const e0 = measure(w).total;
                double const started = thread_cpu_seconds();
                for (int i = 0; i < n; ++i)
                    w.step(h);
                double const spent = thread_cpu_seconds() - started;
                hyperbola const end(w.bodies().positions()[1], w.bodies().velocities()[1]);
                error = std::abs(angle_between(start.incoming(), end.outgoing()) - rutherford);
                energy_error = std::abs(measure(w).total / e0 - 1.0);
                return spent;
            });
            errors.push_back(error);
            s.rows.push_back({std::string(entry.name), {std::string(entry.name), number(h)},
                              {error, energy_error, 1e3 * seconds / T}});
        }
        // Order of accuracy, checked where it is 2 or more (Verlet, RK4).
        if (options.quick) {
            double const order = std::log(errors[0] / errors[1]) / std::log(4.0);
            s.check(info(entry.kind).order < 2 || std::abs(order - info(entry.kind).order) < 0.5,
                    std::string(entry.name) + " deflection error falls as dt^" + number(order) + ", not dt^" +
                        std::to_string(info(entry.kind).order));
        }
    }
    // The reference itself: the asymptote of the starting state, taken backwards, is Rutherford's.
    s.check(std::abs(angle_between(start.incoming(), start.outgoing()) - rutherford) < 1e-12,
            "the starting hyperbola's own asymptotes are not Rutherford's angle apart");

    s.notes = "The close pass (2.5 m from the charge) is where the step size matters; the orders show "
              "as slopes: 1 for both Euler variants and the exact constant-force integrator (the force "
              "is not constant here), 2 for Verlet, 4 for RK4 until rounding.";
    s.plots.push_back({"coulomb", "Coulomb scattering: deflection error against Rutherford",
                       "CPU ms per simulated second", "deflection error (rad)", true, true,
                       lines_of(s, [](row const& r) { return r.values[2]; },
                                [](row const& r) { return std::max(r.values[0], 1e-16); })});
    return s;
}

} // namespace kugel::tradeoff
