#pragma once

// The discrete collision mode: overlaps at the end of the step are answered, then separated.

#include "physics/collisions.hpp"
#include "physics/discrete/workspace.hpp"
#include "physics/parallel_for.hpp"
#include "physics/step_timings.hpp"

#include <span>

namespace kugel::physics {

/// Resolves the contacts of one discrete step of length h: the phases of discrete_step.cpp,
/// each timed into `timings`. Its loops over bodies and slabs run through `loops` when given
/// one; the result is the same bits with or without it.
void resolve_discrete(collision_settings const& settings, std::span<wall const> walls,
                      std::span<obstacle const> obstacles, collision_bodies const& bodies, double h,
                      discrete_workspace& workspace, collision_stats& stats, step_timings& timings,
                      parallel_for* loops = nullptr);

} // namespace kugel::physics
