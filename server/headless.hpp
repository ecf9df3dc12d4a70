#pragma once

#include "scene/scene.hpp"

#include <nlohmann/json.hpp>

#include <cstdint>

namespace kugel::server {

/// Steps a scene's world `steps` times without networking and returns the summary that
/// `kugel-server --headless` prints: what was run, what it cost, and how well energy and
/// momentum were kept. If a step fails (a singular force), the summary says so in `error`
/// and counts the steps that completed; it never holds NaN or Inf. Throws
/// physics::singular_force_error when the initial state itself is singular.
nlohmann::ordered_json run_headless(scene::scene const& s, std::uint64_t steps);

} // namespace kugel::server
