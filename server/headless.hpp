#pragma once

#include "scene/scene.hpp"

#include <nlohmann/json.hpp>

#include <cstddef>
#include <cstdint>

namespace kugel::server {

/// Steps a scene's world `steps` times without networking and returns the summary that
/// `kugel-server --headless` prints: what was run, what it cost, and how well energy and
/// momentum were kept. If a step fails (a singular force), the summary says so in `error`
/// and counts the steps that completed; it never holds NaN or Inf. Throws
/// physics::singular_force_error when the initial state itself is singular. With
/// physics_threads > 1 the world is lent a thread_pool of that many threads (this one
/// counted); the result is the same bit for bit, only wall_ms changes.
nlohmann::ordered_json run_headless(scene::scene const& s, std::uint64_t steps,
                                    std::size_t physics_threads = 1);

} // namespace kugel::server
