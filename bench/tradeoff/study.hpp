#pragma once

// A study: one reference problem with a known answer, run at many settings of the knobs
// a scene exposes, each row an error against the answer and a cost. The problems fill
// studies; report.cpp turns them into CSV, plot data and the Markdown report.

#include <cstddef>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace kugel::tradeoff {

/// One setting, measured.
struct row
{
    std::string series;              ///< the plot line it belongs to ("rk4", "continuous")
    std::vector<std::string> knobs;  ///< one value per study::knob_names, as the table shows it
    std::vector<double> values;      ///< one per study::value_names: errors, then the costs
};

/// A bound on one of a study's values; the report names the cheapest row that meets it.
struct target
{
    /// Met when every listed value (index into study::value_names) is <= its bound.
    std::vector<std::pair<std::size_t, double>> bounds;
    std::string description; ///< "phase error ≤ 1e-3 rad after 10 orbits"
    /// When set, the cheapest row is named separately for each value of this knob (the
    /// striker's speed: each speed asks for its own setting).
    std::optional<std::size_t> per_knob;
};

/// A line on a plot: (x, y) points in order.
struct series
{
    std::string name;
    std::vector<std::pair<double, double>> points;
};

struct plot
{
    std::string file; ///< file stem: plots/<file>.svg, data <file>.dat
    std::string title;
    std::string x_label;
    std::string y_label;
    bool x_log = true;
    bool y_log = true;
    std::vector<series> lines;
};

struct study
{
    std::string name;      ///< file stem: "kepler"
    std::string title;     ///< "Kepler orbit, eccentricity 0.5"
    std::string reference; ///< Markdown: the answer, the error measure, the setup
    std::vector<std::string> knob_names;
    std::vector<std::string> value_names;
    std::size_t cost = 0; ///< which value is the cost the targets minimise
    std::vector<target> targets;
    std::vector<row> rows;
    std::vector<plot> plots;
    std::string notes; ///< Markdown after the table: what the numbers show
    /// Claims about the results that must hold whatever the machine (the exact integrator
    /// at rounding, measured orders, ...), each broken one as a sentence: the run fails.
    std::vector<std::string> failures;

    /// Records a failure when `holds` is false.
    void check(bool holds, std::string const& claim);
};

/// How long to repeat one setting to take the median of its cost.
struct timing_budget
{
    int min_repeats = 3;
    int max_repeats = 31;
    double min_total_seconds = 0.05; ///< repeat until at least this much CPU time is spent
    double single_run_enough = 0.5;  ///< one run this long is measured once only
};

/// A number as the tables show it: `significant` digits, exponent form when large or small.
std::string number(double value, int significant = 3);

/// A time step as a fraction of a second when it is one ("1/60"), else as a number.
std::string seconds_fraction(double dt);

/// CPU time of the calling thread, in seconds (immune to other processes' load, not to
/// their effect on caches and turbo clocks).
double thread_cpu_seconds();

/// Runs `run` (which returns the CPU seconds of its own timed part, and keeps its outcome
/// itself) until the budget is spent; returns the median of the timed parts.
double median_cpu_seconds(timing_budget const& budget, std::function<double()> const& run);

/// The study's series as plot lines, one point per row, in row order.
std::vector<series> lines_of(study const& s, std::function<double(row const&)> const& x,
                             std::function<double(row const&)> const& y);

} // namespace kugel::tradeoff
