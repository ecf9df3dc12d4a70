#pragma once

// The reference problems of the trade-off report, each a study of one known answer across
// the knobs a scene exposes (integrator, dt and substeps, collision mode, gravity method).
// Every problem runs through physics::world, as the server does.

#include "study.hpp"

namespace kugel::tradeoff {

struct problem_options
{
    bool quick = false; ///< tiny sizes and few settings: a smoke run, not a report
    timing_budget budget;
};

study projectile(problem_options const& options);
study kepler(problem_options const& options);
study kepler_eccentric(problem_options const& options);
study close_encounter(problem_options const& options);
study coulomb_scattering(problem_options const& options);
study bounce(problem_options const& options);
study cradle(problem_options const& options);
study gas(problem_options const& options);
study pile(problem_options const& options);
study tree_error(problem_options const& options);
study tree_scaling(problem_options const& options);

} // namespace kugel::tradeoff
