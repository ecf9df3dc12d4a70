#include "world.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <tuple>

namespace kugel::physics {

world::world(world_settings settings) : settings_(settings)
{
    if (settings_.substeps < 1)
        throw std::invalid_argument("world substeps must be >= 1");
    if (!(settings_.adaptive.tolerance >= step_control::min_tolerance && settings_.adaptive.tolerance < 1.0))
        throw std::invalid_argument("the adaptive integrator's tolerance must be in [1e-13, 1)");
    if (settings_.adaptive.max_steps < 1)
        throw std::invalid_argument("the adaptive integrator's max_steps must be >= 1");
}

body_id world::add_body(body_desc const& desc)
{
    body_id const id = bodies_.add(desc);
    if (sleep_columns_) {
        calm_.push_back(0.0);
        island_of_.push_back(awake);
    }
    workspace_.invalidate();
    wake_near(desc.position, desc.radius);
    return id;
}

bool world::remove_body(body_id id)
{
    auto const slot = bodies_.slot_of(id);
    if (!slot)
        return false;
    // What it carried wakes: its island, and the sleepers it touched (a static sphere is in
    // no island).
    if (asleep(*slot))
        wake_island(island_of_[*slot]);
    vec3 const x = bodies_.positions()[*slot];
    double const r = bodies_.radii()[*slot];
    bodies_.remove(id);
    if (reporting_ > 0)
        forget_contacts(id);
    // The storage moved its last body into the hole: so do the sleeping columns.
    if (sleep_columns_) {
        calm_[*slot] = calm_.back();
        calm_.pop_back();
        island_of_[*slot] = island_of_.back();
        island_of_.pop_back();
    }
    wake_near(x, r);
    workspace_.invalidate();
    return true;
}

void world::restore_clock(double time, double time_compensation, std::uint64_t steps)
{
    if (!(std::isfinite(time) && time >= 0.0 && std::isfinite(time_compensation)))
        throw std::invalid_argument("a restored time must be finite and >= 0");
    time_ = time;
    time_compensation_ = time_compensation;
    steps_ = steps;
}

bool world::apply_impulse(body_id id, vec3 const& impulse)
{
    auto const slot = bodies_.slot_of(id);
    if (!slot)
        return false;
    if (!impulse.allFinite())
        throw std::invalid_argument("impulse must be finite");
    if (asleep(*slot))
        wake_island(island_of_[*slot]);
    // Velocities do not enter the forces, so the cached accelerations stay valid.
    bodies_.velocities()[*slot] += bodies_.inverse_masses()[*slot] * impulse;
    return true;
}

bool world::set_state(body_id id, std::optional<vec3> const& position, std::optional<vec3> const& velocity)
{
    auto const slot = bodies_.slot_of(id);
    if (!slot)
        return false;
    if ((position && !position->allFinite()) || (velocity && !velocity->allFinite()))
        throw std::invalid_argument("a body's new position and velocity must be finite");
    if (velocity && bodies_.inverse_masses()[*slot] == 0.0 && !velocity->isZero(0.0))
        throw std::invalid_argument("a static body cannot move: its velocity stays zero");
    if (asleep(*slot))
        wake_island(island_of_[*slot]);
    if (sleep_columns_)
        calm_[*slot] = 0.0;
    double const r = bodies_.radii()[*slot];
    if (position) {
        wake_near(bodies_.positions()[*slot], r); // what it carried falls
        bodies_.positions()[*slot] = *position;
        wake_near(*position, r);
        workspace_.invalidate(); // the forces depend on the positions
    }
    if (velocity)
        bodies_.velocities()[*slot] = *velocity;
    return true;
}

void world::add_force(std::unique_ptr<force_model> model)
{
    forces_.push_back(std::move(model));
    workspace_.invalidate();
    wake_all();
}

bool world::forces_are_constant() const
{
    return std::all_of(forces_.begin(), forces_.end(),
                       [](auto const& model) { return model->is_constant(); });
}

void world::accelerations(std::span<vec3 const> x, std::span<vec3> a) const
{
    ++force_evaluations_;
    std::fill(a.begin(), a.end(), vec3::Zero());
    for (auto const& model : forces_)
        model->add_forces(bodies_, x, a);
    auto const inverse_mass = bodies_.inverse_masses();
    for (std::size_t i = 0; i < a.size(); ++i)
        a[i] *= inverse_mass[i];
}

void world::drift(double h, std::span<vec3> start)
{
    auto const x = bodies_.positions();
    auto const v = bodies_.velocities();
    // On the columns' doubles in a row (a vec3 is three doubles without padding), which the
    // compiler can do two at a time; with x₀ kept on the way when asked, one pass over memory
    // instead of two.
    run_chunks(loops(), x.size(), [&](std::size_t, std::size_t begin, std::size_t end) {
        if (begin == end)
            return;
        auto const doubles = [&](std::span<vec3 const> column) {
            return Eigen::Map<Eigen::ArrayXd const>(column[begin].data(), 3 * static_cast<Eigen::Index>(end - begin));
        };
        auto const writable = [&](std::span<vec3> column) {
            return Eigen::Map<Eigen::ArrayXd>(column[begin].data(), 3 * static_cast<Eigen::Index>(end - begin));
        };
        if (!start.empty())
            writable(start) = doubles(x);
        writable(x) += h * doubles(v);
    });
}

void world::move_freely(double h)
{
    phase_clock clock(timings_);
    if (forces_.empty()) {
        drift(h, {}); // no force named, no force loop: every integrator reduces to x += h·v
    } else {
        // Built here rather than stored, so a moved world never calls into its old address.
        acceleration_fn const a = [this](std::span<vec3 const> at, std::span<vec3> out) {
            accelerations(at, out);
        };
        advance(settings_.integrator, bodies_.positions(), bodies_.velocities(), h, a, workspace_,
                settings_.adaptive);
    }
    clock.lap(step_phase::free_motion);
}

namespace {

void check_response(double damping, double friction)
{
    if (!(damping >= 0.0 && damping <= 1.0))
        throw std::invalid_argument("damping must be in [0, 1]");
    if (!(friction >= 0.0 && friction <= 1.0))
        throw std::invalid_argument("friction must be in [0, 1]");
}

} // namespace

void world::add_wall(wall const& w)
{
    check_response(w.damping, w.friction);
    walls_.push_back({make_plane(w.surface.normal, w.surface.offset), w.damping, w.friction});
    wake_all();
}

void world::add_obstacle(obstacle const& o)
{
    check_response(o.damping, o.friction);
    obstacles_.push_back(o);
    wake_all();
}

double world::max_overlap() const
{
    return physics::max_overlap(walls_, obstacles_, bodies_.positions(), bodies_.radii(),
                                collision_workspace_);
}

std::size_t world::escaped() const
{
    std::size_t count = 0;
    auto const x = bodies_.positions();
    for (std::size_t i = 0; i < x.size(); ++i) {
        if (bodies_.radii()[i] <= 0.0 || bodies_.inverse_masses()[i] == 0.0)
            continue;
        for (wall const& w : walls_) {
            if (w.surface.normal.dot(x[i]) < w.surface.offset) {
                ++count;
                break;
            }
        }
    }
    return count;
}

void world::keep_start_and_move_freely(double h)
{
    auto const x = bodies_.positions();
    auto const v = bodies_.velocities();
    step_start_x_.resize(x.size());
    if (forces_.empty()) {
        phase_clock clock(timings_);
        drift(h, step_start_x_); // v₀ is v: a drift changes no velocity
        clock.lap(step_phase::free_motion);
        return;
    }
    step_start_v_.resize(v.size());
    run_chunks(loops(), x.size(), [&](std::size_t, std::size_t begin, std::size_t end) {
        std::copy(x.begin() + static_cast<std::ptrdiff_t>(begin), x.begin() + static_cast<std::ptrdiff_t>(end),
                  step_start_x_.begin() + static_cast<std::ptrdiff_t>(begin));
        std::copy(v.begin() + static_cast<std::ptrdiff_t>(begin), v.begin() + static_cast<std::ptrdiff_t>(end),
                  step_start_v_.begin() + static_cast<std::ptrdiff_t>(begin));
    });
    move_freely(h);
}

void world::collide(double h, bool drift_pending)
{
    bool const accelerated = !forces_.empty();
    resolve_collisions(settings_.collisions, walls_, obstacles_,
                       {bodies_.positions(), bodies_.velocities(), step_start_x_,
                        accelerated ? std::span<vec3 const>(step_start_v_) : bodies_.velocities(),
                        bodies_.inverse_masses(), bodies_.radii(), accelerated, drift_pending, bodies_.ids(),
                        bodies_.layout()},
                       h, collision_workspace_, collision_stats_, timings_, loops());
    workspace_.invalidate(); // contacts may have moved bodies
}

void world::sort_bodies_by_cell()
{
    sphere_grid const& grid = collision_workspace_.discrete.grid;
    std::size_t const n = bodies_.size();
    if (!grid.in_cell_order() || gathered_)
        return; // the grid declined the scene, or saw only the bodies near the awake ones
    cell_order_.clear();
    cell_order_.reserve(n);
    for (std::uint32_t k = 0; k < grid.sphere_count(); ++k)
        cell_order_.push_back(grid.slot(k));
    auto const radius = bodies_.radii();
    for (std::uint32_t i = 0; i < n; ++i) // the bodies that are not spheres, after them
        if (!(radius[i] > 0.0))
            cell_order_.push_back(i);
    bodies_.permute(cell_order_, loops());
    workspace_.invalidate();
    if (!sleep_columns_)
        return;
    std::vector<double> calm(cell_order_.size());
    std::vector<std::uint32_t> island(cell_order_.size());
    for (std::size_t k = 0; k < cell_order_.size(); ++k) {
        calm[k] = calm_[cell_order_[k]];
        island[k] = island_of_[cell_order_[k]];
    }
    calm_.swap(calm);
    island_of_.swap(island);
}

std::vector<body_id> world::non_finite_bodies() const
{
    std::vector<body_id> out;
    auto const x = bodies_.positions();
    auto const v = bodies_.velocities();
    for (std::size_t i = 0; i < x.size(); ++i)
        if (!(x[i].allFinite() && v[i].allFinite()))
            out.push_back(bodies_.ids()[i]);
    return out;
}

std::optional<addition_refusal> world::check_addition(body_desc const& desc,
                                                      addition_limits const& limits) const
{
    for (auto const& model : forces_)
        if (auto refusal = model->check_addition(bodies_, desc, limits))
            return refusal;
    return std::nullopt;
}

void world::step(double dt)
{
    if (!std::isfinite(dt) || dt < 0.0)
        throw std::invalid_argument("step dt must be finite and >= 0");
    bool const sleeping = sleeping_applies() && dt > 0.0;
    if (sleeping && !sleep_columns_) { // the first step that may put bodies to sleep
        calm_.assign(bodies_.size(), 0.0);
        island_of_.assign(bodies_.size(), awake);
        sleep_columns_ = true;
    }
    sensor_events_.clear();
    contact_events_.clear();
    if (sleeping) { // a step's islands start as one body each
        parent_.resize(bodies_.size());
        for (std::uint32_t i = 0; i < parent_.size(); ++i)
            parent_[i] = i;
        grounded_.assign(bodies_.size(), 0);
        held_awake_.assign(bodies_.size(), 0);
    }
    if (settings_.substeps > 1 && !forces_.empty()) {
        // A force can fail in a later substep: the substeps before it are undone, so that
        // a failed step changes nothing, as with one substep.
        undo_x_.assign(bodies_.positions().begin(), bodies_.positions().end());
        undo_v_.assign(bodies_.velocities().begin(), bodies_.velocities().end());
        auto const inside_before = inside_; // what the sensors held (empty without sensors)
        auto const touching_before = touching_; // the pairs touching (empty without reports)
        auto const undo = [&] {
            std::ranges::copy(undo_x_, bodies_.positions().begin());
            std::ranges::copy(undo_v_, bodies_.velocities().begin());
            workspace_.invalidate();
            inside_ = inside_before;
            sensor_events_.clear();
            touching_ = touching_before;
            contact_events_.clear();
        };
        try {
            substeps(dt);
        } catch (singular_force_error const&) {
            undo();
            throw;
        } catch (step_control_error const&) {
            undo();
            throw;
        }
    } else {
        substeps(dt);
    }
    // Compensated (Kahan) sum: after 10⁶ steps of 1/60 s the clock is still exact to an ulp.
    double const increment = dt - time_compensation_;
    double const sum = time_ + increment;
    time_compensation_ = (sum - time_) - increment;
    time_ = sum;
    ++steps_;
    if (sleeping)
        fall_asleep(dt);
    std::sort(sensor_events_.begin(), sensor_events_.end(), [](sensor_event const& a, sensor_event const& b) {
        if (a.time != b.time)
            return a.time < b.time;
        if (a.sensor != b.sensor)
            return a.sensor < b.sensor;
        return a.body.index != b.body.index ? a.body.index < b.body.index : a.body.generation < b.body.generation;
    });
    std::sort(contact_events_.begin(), contact_events_.end(), [](contact_event const& a, contact_event const& b) {
        auto const key = [](contact_event const& e) {
            return std::tuple(e.time, e.a.index, e.a.generation, e.b.index, e.b.generation);
        };
        return key(a) < key(b);
    });
}

void world::substeps(double dt)
{
    double const h = dt / settings_.substeps;
    collision_mode const mode = h > 0.0 ? settings_.collisions.mode : collision_mode::off;
    for (int substep = 0; substep < settings_.substeps; ++substep) {
        if (!sensors_.empty())
            keep_sensor_start();
        keep_touches();
        switch (mode) {
        case collision_mode::off:
            move_freely(h);               // forces where the integrator needs them, and the integrator
            break;
        case collision_mode::continuous:
            if (forces_.empty()) {
                collide(h, true);              // every contact along straight paths, the drift with them
            } else {
                keep_start_and_move_freely(h); // the same, keeping where each body's path starts
                collide(h, false);             // every contact, in time order along those paths
            }
            break;
        case collision_mode::discrete:
            if (forces_.empty()) {
                collide(h, true);          // a drift, made by the wall pass on its way; the overlaps
                gathered_ = false;
            } else if (sleeping_ > 0) {
                move_and_collide_around_sleepers(h); // the same for the awake bodies, sleepers still
            } else {
                keep_start_and_move_freely(h);
                collide(h, false);         // the overlaps at the end of free motion
                gathered_ = false;
            }
            if (sleeping_applies())
                note_contacts();           // islands, what they touch, sleepers to wake
            break;
        }
        if (!sensors_.empty())
            follow_sensors(h, time_ + static_cast<double>(substep) * h); // who entered and left a sensor, and when
        if (reporting_ > 0 && mode != collision_mode::off)
            note_touches(h, time_ + static_cast<double>(substep) * h); // which reported pairs began to touch
    }
    if (mode == collision_mode::discrete && bodies_.size() >= bodies_worth_sorting && steps_ % sort_interval == 0) {
        phase_clock clock(timings_);
        sort_bodies_by_cell();             // the bodies into the grid's cell order, now and then
        clock.lap(step_phase::reorder);
    }
}

} // namespace kugel::physics
