#include "forces.hpp"

#include <cmath>
#include <sstream>

namespace kugel::physics {

namespace {

void check_parameter(bool ok, char const* what)
{
    if (!ok)
        throw std::invalid_argument(what);
}

/// The pair loop shared by the two inverse-square laws. `coupling(i, j)` is the signed
/// strength s so that the force on i is s·(x_j − x_i)/(r² + ε²)^{3/2}; a zero coupling skips
/// the pair. Each pair is visited once and applied to both bodies.
template <class Coupling>
void add_inverse_square_forces(std::string_view model, double softening,
                               body_storage const& bodies, std::span<vec3 const> x,
                               std::span<vec3> forces, Coupling coupling)
{
    double const eps2 = softening * softening;
    std::size_t const n = x.size();
    for (std::size_t i = 0; i < n; ++i) {
        vec3 const xi = x[i];
        vec3 fi = vec3::Zero();
        for (std::size_t j = i + 1; j < n; ++j) {
            double const s = coupling(i, j);
            if (s == 0.0)
                continue;
            vec3 const d = x[j] - xi;
            double const r2 = d.squaredNorm() + eps2;
            double const inv_r = 1.0 / std::sqrt(r2);
            double const scale = s * inv_r * inv_r * inv_r;
            if (!std::isfinite(scale))
                throw_singular_pair(model, s, softening, bodies, x, i, j);
            vec3 const f = scale * d;
            fi += f;
            forces[j] -= f;
        }
        forces[i] += fi;
    }
}

template <class Coupling>
double inverse_square_potential(std::string_view model, double softening,
                                body_storage const& bodies, std::span<vec3 const> x,
                                Coupling coupling)
{
    double const eps2 = softening * softening;
    double u = 0.0;
    std::size_t const n = x.size();
    for (std::size_t i = 0; i < n; ++i) {
        for (std::size_t j = i + 1; j < n; ++j) {
            double const s = coupling(i, j);
            if (s == 0.0)
                continue;
            double const term = s / std::sqrt((x[j] - x[i]).squaredNorm() + eps2);
            if (!std::isfinite(term))
                throw_singular_pair(model, s, softening, bodies, x, i, j);
            u += term;
        }
    }
    return u;
}

} // namespace

void throw_singular_pair(std::string_view model, double coupling, double softening,
                         body_storage const& bodies, std::span<vec3 const> x, std::size_t i,
                         std::size_t j)
{
    double const r = (x[j] - x[i]).norm();
    std::ostringstream out;
    out << model << " is singular: bodies " << to_string(bodies.ids()[i]) << " and "
        << to_string(bodies.ids()[j]) << " at distance " << r << " m (positions "
        << x[i].transpose() << " and " << x[j].transpose() << "; softening " << softening
        << " m) pull with a force beyond the range of a double; ";
    if (!std::isfinite(coupling))
        out << "their coupling (" << model << "'s constant times their "
            << (model == "coulomb" ? "charges" : "masses") << ") overflows: use smaller ones";
    else if (softening == 0.0)
        out << "they coincide, where 1/r^2 overflows: give the model a softening > 0";
    else
        out << "their coupling " << coupling << " is too large for that distance: use smaller "
            << (model == "coulomb" ? "charges" : "masses") << " or a larger softening";
    throw singular_force_error(out.str(), bodies.ids()[i], bodies.ids()[j]);
}

std::optional<addition_refusal> check_inverse_square_addition(
    std::string_view model, double constant, double softening, std::span<double const> strength,
    double candidate_strength, body_storage const& bodies, body_desc const& candidate,
    addition_limits const& limits)
{
    if (strength.empty())
        return std::nullopt; // 0 for every body: no pair has a force
    double const eps2 = softening * softening;
    double const inverse_mass = candidate.is_static ? 0.0 : 1.0 / candidate.mass;
    auto const x = bodies.positions();
    auto const inverse_masses = bodies.inverse_masses();
    for (std::size_t j = 0; j < x.size(); ++j) {
        double const s = constant * candidate_strength * strength[j];
        if (s == 0.0)
            continue;
        double const r = (x[j] - candidate.position).norm();
        double const inv_r = 1.0 / std::sqrt(r * r + eps2);
        // |F| = |s|·r/(r² + ε²)^{3/2}, with the force loop's scale; a scale that is not
        // finite is a singular pair (its force is then ∞, or NaN at r = 0: shown as ∞).
        double const scale = s * inv_r * inv_r * inv_r;
        double const force = std::isfinite(scale) ? std::abs(scale) * r : std::numeric_limits<double>::infinity();
        double const acceleration = force * std::max(inverse_mass, inverse_masses[j]);
        if (!(force <= addition_limits::max_pair_force && acceleration < limits.max_acceleration))
            return addition_refusal{model, j, r, softening, force, acceleration};
    }
    return std::nullopt;
}

void uniform_field::add_forces(body_storage const& bodies, std::span<vec3 const>,
                               std::span<vec3> forces) const
{
    auto const m = bodies.masses();
    for (std::size_t i = 0; i < forces.size(); ++i)
        forces[i] += m[i] * g_;
}

double uniform_field::potential_energy(body_storage const& bodies, std::span<vec3 const> x) const
{
    auto const m = bodies.masses();
    double u = 0.0;
    for (std::size_t i = 0; i < x.size(); ++i)
        u -= m[i] * g_.dot(x[i]);
    return u;
}

newtonian_gravity::newtonian_gravity(double G, double softening) : G_(G), softening_(softening)
{
    check_parameter(std::isfinite(G) && G >= 0.0, "gravity G must be finite and >= 0");
    check_parameter(std::isfinite(softening) && softening >= 0.0,
                    "gravity softening must be finite and >= 0");
}

void newtonian_gravity::add_forces(body_storage const& bodies, std::span<vec3 const> x,
                                   std::span<vec3> forces) const
{
    auto const m = bodies.masses();
    add_inverse_square_forces(name(), softening_, bodies, x, forces,
                              [&](std::size_t i, std::size_t j) { return G_ * m[i] * m[j]; });
}

std::optional<addition_refusal> newtonian_gravity::check_addition(body_storage const& bodies,
                                                                  body_desc const& candidate,
                                                                  addition_limits const& limits) const
{
    return check_inverse_square_addition(name(), G_, softening_, bodies.masses(), candidate.mass,
                                         bodies, candidate, limits);
}

double newtonian_gravity::potential_energy(body_storage const& bodies,
                                           std::span<vec3 const> x) const
{
    auto const m = bodies.masses();
    return inverse_square_potential(name(), softening_, bodies, x, [&](std::size_t i, std::size_t j) {
        return -G_ * m[i] * m[j];
    });
}

coulomb::coulomb(double k, double softening) : k_(k), softening_(softening)
{
    check_parameter(std::isfinite(k) && k >= 0.0, "coulomb k must be finite and >= 0");
    check_parameter(std::isfinite(softening) && softening >= 0.0,
                    "coulomb softening must be finite and >= 0");
}

void coulomb::add_forces(body_storage const& bodies, std::span<vec3 const> x,
                         std::span<vec3> forces) const
{
    auto const q = bodies.charges();
    if (q.empty())
        return; // no charges: every pair's coupling is 0, which adds nothing
    add_inverse_square_forces(name(), softening_, bodies, x, forces,
                              [&](std::size_t i, std::size_t j) { return -k_ * q[i] * q[j]; });
}

std::optional<addition_refusal> coulomb::check_addition(body_storage const& bodies,
                                                        body_desc const& candidate,
                                                        addition_limits const& limits) const
{
    return check_inverse_square_addition(name(), -k_, softening_, bodies.charges(), candidate.charge,
                                         bodies, candidate, limits);
}

double coulomb::potential_energy(body_storage const& bodies, std::span<vec3 const> x) const
{
    auto const q = bodies.charges();
    if (q.empty())
        return 0.0;
    return inverse_square_potential(name(), softening_, bodies, x, [&](std::size_t i, std::size_t j) {
        return k_ * q[i] * q[j];
    });
}

} // namespace kugel::physics
