// The world's sensors (sensors.hpp): after each substep, every body's path through every
// sensor. A world without sensors never comes here.

#include "world.hpp"

#include <algorithm>
#include <stdexcept>

namespace kugel::physics {

namespace {

bool overlap(aabb const& a, aabb const& b)
{
    return (a.min.array() <= b.max.array()).all() && (b.min.array() <= a.max.array()).all();
}

aabb merged(aabb const& a, aabb const& b) { return {a.min.cwiseMin(b.min), a.max.cwiseMax(b.max)}; }

} // namespace

std::uint32_t world::add_sensor(sensor const& s)
{
    if (auto why = s.invalid())
        throw std::invalid_argument(*why);
    sensors_.push_back(s);
    inside_.emplace_back();
    return static_cast<std::uint32_t>(sensors_.size() - 1);
}

void world::keep_sensor_start()
{
    auto const x = bodies_.positions();
    auto const v = bodies_.velocities();
    sensor_x0_.assign(x.begin(), x.end());
    sensor_v0_.assign(v.begin(), v.end());
    // in continuous mode the sphere's own pieces of path (the step-by-step loop keeps them)
    collision_workspace_.continuous.keep_segments = settings_.collisions.mode == collision_mode::continuous;
}

void world::follow_sensors(double h, double start)
{
    auto const x = bodies_.positions();
    auto const v = bodies_.velocities();
    auto const ids = bodies_.ids();
    auto const& ws = collision_workspace_.continuous;
    bool const continuous = settings_.collisions.mode == collision_mode::continuous && h > 0.0;
    bool const discrete = settings_.collisions.mode == collision_mode::discrete;

    // The continuous loop's pieces of path, by body: each body's in time order (as noted).
    std::vector<std::uint32_t> first(continuous ? x.size() + 1 : 0, 0);
    std::vector<std::uint32_t> order;
    if (continuous) {
        for (auto const& piece : ws.segments)
            ++first[piece.body + 1];
        for (std::size_t k = 0; k < x.size(); ++k)
            first[k + 1] += first[k];
        order.resize(ws.segments.size());
        std::vector<std::uint32_t> next(first.begin(), first.end() - 1);
        for (std::uint32_t k = 0; k < ws.segments.size(); ++k)
            order[next[ws.segments[k].body]++] = k;
    }

    std::vector<std::vector<body_id>> now_inside(sensors_.size());
    std::vector<aabb> bounds;
    for (sensor const& s : sensors_)
        bounds.push_back(s.bounds());
    // Most bodies are nowhere near a sensor: one box around them all, and a mark (by id
    // index) on each body some sensor holds, let those pass with one test.
    aabb all = bounds.front();
    for (aabb const& b : bounds)
        all = merged(all, b);
    held_.clear();
    for (auto const& in : inside_)
        for (body_id const id : in) {
            if (held_.size() <= id.index)
                held_.resize(std::size_t{id.index} + 1, 0);
            held_[id.index] = 1;
        }
    for (std::size_t k = 0; k < x.size(); ++k) {
        body_id const id = ids[k];
        // the body's path in this substep: its pieces, or one path from its start
        body_path whole;
        if (h == 0.0)
            whole = {x[k], vec3::Zero(), vec3::Zero(), 0.0};
        else if (discrete)
            whole = {sensor_x0_[k], (x[k] - sensor_x0_[k]) / h, vec3::Zero(), 0.0};
        else
            whole = {sensor_x0_[k], sensor_v0_[k], (v[k] - sensor_v0_[k]) / h, 0.0};
        std::uint32_t const piece_begin = continuous ? first[k] : 0, piece_end = continuous ? first[k + 1] : 0;
        aabb reach = piece_begin == piece_end ? merged(whole.swept_box(h, 0.0), {x[k], x[k]})
                                              : aabb{x[k], x[k]};
        for (std::uint32_t p = piece_begin; p < piece_end; ++p) {
            auto const& piece = ws.segments[order[p]];
            reach = merged(reach, piece.path.swept_box(piece.until, 0.0));
        }
        if (!overlap(reach, all) && (id.index >= held_.size() || held_[id.index] == 0))
            continue; // near no sensor, and in none
        for (std::uint32_t si = 0; si < sensors_.size(); ++si) {
            auto const& was = inside_[si];
            bool in = std::binary_search(was.begin(), was.end(), id, by_id);
            if (!in && !overlap(reach, bounds[si]))
                continue; // never near it
            if (piece_begin == piece_end) {
                in = follow_sensor(sensors_[si], si, id, whole, 0.0, h, in, start, sensor_events_, x[k]);
            } else {
                for (std::uint32_t p = piece_begin; p < piece_end; ++p) {
                    auto const& piece = ws.segments[order[p]];
                    std::optional<vec3> const end = p + 1 == piece_end ? std::optional<vec3>(x[k]) : std::nullopt;
                    in = follow_sensor(sensors_[si], si, id, piece.path, piece.path.t, piece.until, in, start,
                                       sensor_events_, end);
                }
            }
            if (in)
                now_inside[si].push_back(id);
        }
    }
    for (std::size_t si = 0; si < sensors_.size(); ++si) {
        std::sort(now_inside[si].begin(), now_inside[si].end(), by_id);
        inside_[si] = std::move(now_inside[si]);
    }
}

} // namespace kugel::physics
