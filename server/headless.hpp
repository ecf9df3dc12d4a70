#pragma once

#include "scene/scene.hpp"

#include <nlohmann/json.hpp>

#include <cstddef>
#include <cstdint>
#include <stdexcept>

namespace kugel::server {

/// A scene whose initial state has no finite diagnostics (a mass times a speed squared
/// beyond the largest double, say): nothing could be measured of a run of it.
struct unmeasurable_scene : std::runtime_error
{
    using std::runtime_error::runtime_error;
};

/// Steps a scene's world `steps` times without networking and returns the summary that
/// `kugel-server --headless` prints: what was run, what it cost, and how well energy and
/// momentum were kept. If a step fails (a singular force), or leaves a body's position or
/// velocity not finite, or the energy at the end is not finite, the summary says so in
/// `error` (naming the step and the body) and counts the steps that completed; it never
/// holds NaN or Inf but as null. Throws physics::singular_force_error when the initial state
/// itself is singular, and unmeasurable_scene when its energy or momentum is not finite. With
/// physics_threads > 1 the world is lent a thread_pool of that many threads (this one
/// counted); the result is the same bit for bit, only wall_ms changes.
nlohmann::ordered_json run_headless(scene::scene const& s, std::uint64_t steps,
                                    std::size_t physics_threads = 1);

} // namespace kugel::server
