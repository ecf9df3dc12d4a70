#include "headless.hpp"

#include "physics/barnes_hut.hpp"
#include "physics/diagnostics.hpp"
#include "physics/thread_pool.hpp"

#include <chrono>
#include <cmath>
#include <memory>
#include <optional>
#include <stdexcept>

namespace kugel::server {

namespace {

nlohmann::ordered_json to_json(physics::vec3 const& v) { return {v.x(), v.y(), v.z()}; }

/// (E_final − E_initial) / scale, with a scale that does not move with the origin. With forces
/// between bodies (an orbit, charges), |K₀ + U₀| without a uniform field's part: the
/// |ΔE/E₀| of celestial mechanics, which a close encounter's brief kinetic energy of a
/// billion times E₀ cannot hide. Otherwise the energy the run moved about: the largest
/// kinetic energy of any step plus the change of the potential energy from start to end.
/// Never |K₀| + |U₀| with a uniform field: its potential is measured from the origin, so a
/// ball bouncing 1e9 m from it would have a scale of m·g·1e9 and a drift a billion times
/// smaller than its error. Zero only when nothing moved; the drift is then the absolute
/// change.
double relative_drift(physics::diagnostics const& initial, physics::diagnostics const& final, double most_kinetic)
{
    double const bound = std::abs(initial.kinetic + initial.pair_potential);
    double const scale = initial.has_pair_potential && bound > 0.0
                             ? bound
                             : std::max({initial.kinetic, final.kinetic, most_kinetic}) +
                                   std::abs(final.potential - initial.potential);
    double const change = final.total - initial.total;
    return scale > 0.0 ? change / scale : change;
}

/// How each pairwise law is summed: {"gravity": {"method": "tree", "theta": 0.5}, ...}. A
/// tree's error is bounded relative to the force; for Coulomb with charges of both signs
/// only relative to each sign's field, and the summary says so.
nlohmann::ordered_json force_methods(scene::scene const& s, physics::world const& w)
{
    auto const describe = [](scene::force_method method, double theta) {
        nlohmann::ordered_json out;
        out["method"] = scene::name(method);
        if (method == scene::force_method::tree)
            out["theta"] = theta;
        return out;
    };
    nlohmann::ordered_json methods = nlohmann::ordered_json::object();
    if (auto const& g = s.forces.gravity)
        methods["gravity"] = describe(g->method, g->theta);
    if (auto const& c = s.forces.coulomb) {
        methods["coulomb"] = describe(c->method, c->theta);
        if (c->method == scene::force_method::tree && physics::has_mixed_charges(w.bodies()))
            methods["coulomb"]["error_bound"] =
                "per sign only: charges of both signs, so the tree's error is bounded relative "
                "to each sign's field, not to the net force, which can cancel";
    }
    return methods;
}

/// The first body (in slot order) whose position or velocity is not finite, and the kinetic
/// energy of the dynamic bodies before it (all of them when none is): one pass after a step.
std::optional<physics::body_id> first_not_finite(physics::world const& w, double& kinetic)
{
    auto const x = w.bodies().positions();
    auto const v = w.bodies().velocities();
    auto const inverse_mass = w.bodies().inverse_masses();
    auto const mass = w.bodies().masses();
    kinetic = 0.0;
    for (std::size_t i = 0; i < x.size(); ++i) {
        if (!(x[i].allFinite() && v[i].allFinite()))
            return w.bodies().ids()[i];
        if (inverse_mass[i] > 0.0)
            kinetic += 0.5 * mass[i] * v[i].squaredNorm();
    }
    return std::nullopt;
}

std::string finite_or_not(double x)
{
    return std::isfinite(x) ? nlohmann::json(x).dump() : std::string(std::isnan(x) ? "NaN" : "infinite");
}

std::string format(double x) { return nlohmann::json(x).dump(); }

} // namespace

nlohmann::ordered_json run_headless(scene::scene const& s, std::uint64_t steps,
                                    std::size_t physics_threads)
{
    if (physics_threads < 1)
        throw std::invalid_argument("physics_threads must be at least 1");
    // Declared before the world it is lent to, so that it outlives it.
    std::unique_ptr<physics::thread_pool> pool;
    if (physics_threads > 1)
        pool = std::make_unique<physics::thread_pool>(physics_threads);
    physics::world world = scene::build_world(s);
    world.set_parallel_for(pool.get());
    world.time_phases(true); // for phase_ms_per_step
    auto const initial = physics::measure(world);
    if (!(std::isfinite(initial.total) && initial.momentum.allFinite() && initial.angular_momentum.allFinite()))
        throw unmeasurable_scene("the scene's initial state has no finite energy or momentum (kinetic " +
                                 finite_or_not(initial.kinetic) + " J, potential " +
                                 finite_or_not(initial.potential) +
                                 " J): its masses, speeds or distances are beyond what doubles hold");
    auto const& integrator = physics::info(s.integrator);

    nlohmann::ordered_json summary;
    summary["scene"] = s.name;
    summary["bodies"] = world.bodies().size();
    summary["steps"] = steps;
    summary["dt"] = s.dt;
    summary["substeps"] = s.substeps;
    summary["physics_threads"] = physics_threads;
    summary["integrator"] = integrator.name;
    summary["integrator_order"] = integrator.order;
    summary["integrator_exact"] =
        s.integrator == physics::integrator_kind::exact_constant_force && world.forces_are_constant();
    if (integrator.adaptive)
        summary["tolerance"] = s.adaptive.tolerance;
    nlohmann::ordered_json forces = nlohmann::json::array();
    for (auto const& model : world.forces())
        forces.push_back(model->name());
    summary["forces"] = forces;
    summary["force_methods"] = force_methods(s, world);
    summary["collision_mode"] = physics::name(s.collisions.mode);
    if (s.collisions.mode != physics::collision_mode::off)
        summary["broadphase"] = physics::name(s.collisions.broadphase);

    std::uint64_t completed = 0;
    double most_kinetic = initial.kinetic; // over the steps, for the drift's scale
    auto const started = std::chrono::steady_clock::now();
    try {
        for (; completed < steps; ++completed) {
            world.step(s.dt);
            double kinetic = 0.0;
            if (auto const bad = first_not_finite(world, kinetic)) {
                ++completed; // the step ran; what it left is reported below
                summary["error"] = "step " + std::to_string(completed) + " left body " + std::to_string(physics::to_number(*bad)) +
                                   " with a position or velocity that is not finite (dt " + format(s.dt) +
                                   " s): the run stops there";
                break;
            }
            most_kinetic = std::max(most_kinetic, kinetic);
        }
    } catch (physics::singular_force_error const& e) {
        summary["error"] = e.what();
    } catch (physics::step_control_error const& e) {
        summary["error"] = e.what();
    }
    auto const elapsed = std::chrono::duration<double, std::milli>(
        std::chrono::steady_clock::now() - started);
    // The summary's measures need their own memory, the steps' is done with (at 10⁶ spheres
    // the calendar's 180 MB would otherwise be held beside the overlap test's 16).
    world.release_collision_memory();

    // A run stopped by a singular force may end where the potential is singular too: then the
    // energies are null (JSON has no infinity) and the motion is still reported.
    auto const motion = physics::measure_motion(world);
    std::optional<physics::diagnostics> final;
    try {
        final = physics::measure(world);
    } catch (physics::singular_force_error const&) {
    }
    if (!summary.contains("error") && final && !std::isfinite(final->total))
        summary["error"] = "the energy after step " + std::to_string(completed) +
                           " is not finite (kinetic " + finite_or_not(final->kinetic) + " J, potential " +
                           finite_or_not(final->potential) + " J): the state grew beyond what doubles hold";
    summary["steps_completed"] = completed;
    summary["time"] = world.time();
    summary["wall_ms"] = elapsed.count();
    summary["wall_ms_per_step"] = completed > 0 ? elapsed.count() / static_cast<double>(completed) : 0.0;
    // Where the steps went, phase by phase, for the phases the scene's models used.
    nlohmann::ordered_json phases = nlohmann::ordered_json::object();
    for (std::size_t p = 0; p < physics::step_phase_count; ++p)
        if (double const seconds = world.timings().seconds[p]; seconds > 0.0 && completed > 0)
            phases[std::string(physics::step_phase_names[p])] = 1e3 * seconds / static_cast<double>(completed);
    summary["phase_ms_per_step"] = std::move(phases);
    summary["force_evaluations"] = world.force_evaluations();
    if (integrator.adaptive) {
        // The steps the integrator chose inside the fixed ones, and the smallest it needed.
        auto const& taken = world.integration_steps();
        auto const seconds = [&](double step) {
            return taken.accepted > 0 ? nlohmann::ordered_json(step) : nlohmann::ordered_json();
        };
        summary["integration_steps"] = {{"accepted", taken.accepted},
                                        {"rejected", taken.rejected},
                                        {"smallest", seconds(taken.smallest)},
                                        {"largest", seconds(taken.largest)}};
    }
    summary["energy_initial"] = initial.total;
    summary["energy_final"] = final ? nlohmann::ordered_json(final->total) : nlohmann::ordered_json();
    summary["energy_rel_drift"] =
        final ? nlohmann::ordered_json(relative_drift(initial, *final, most_kinetic)) : nlohmann::ordered_json();
    summary["kinetic_final"] = motion.kinetic;
    summary["largest_speed_final"] = motion.largest_speed;
    summary["potential_final"] = final ? nlohmann::ordered_json(final->potential) : nlohmann::ordered_json();
    summary["momentum_initial"] = to_json(initial.momentum);
    summary["momentum_final"] = to_json(motion.momentum);
    summary["angular_momentum_initial"] = to_json(initial.angular_momentum);
    summary["angular_momentum_final"] = to_json(motion.angular_momentum);
    summary["centre_of_mass_final"] = to_json(motion.centre_of_mass);
    auto const& contacts = world.collisions();
    summary["collisions"] = contacts.contacts();
    summary["sphere_collisions"] = contacts.sphere_contacts;
    summary["wall_collisions"] = contacts.wall_contacts;
    summary["obstacle_collisions"] = contacts.obstacle_contacts;
    summary["events_capped"] = contacts.capped_steps;
    // The continuous mode's events (the sweep's too) and, by halves on two threads, its
    // rounds and the events a lane took past a seam event found late, undone and taken again.
    summary["events"] = contacts.events;
    summary["event_rounds"] = contacts.rounds;
    summary["events_undone"] = contacts.events_undone;
    // The discrete mode's sweep of fast bodies (collisions.sweep): bodies swept, and fast
    // bodies not swept, each a contact that may have been missed (zero while the sweep is on).
    summary["swept_bodies"] = contacts.swept_bodies;
    summary["unswept_fast_bodies"] = contacts.unswept_fast_bodies;
    summary["escaped"] = world.escaped();
    summary["max_overlap"] = world.max_overlap();
    auto const bounds = scene::scene_bounds(s, world);
    summary["bounds"] = {{"centre", to_json(bounds.centre)}, {"radius", bounds.radius}};
    return summary;
}

} // namespace kugel::server
