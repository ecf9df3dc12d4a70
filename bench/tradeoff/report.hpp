#pragma once

// What a run writes: a CSV per study, gnuplot data and commands per plot (script/tradeoff
// hands them to gnuplot), and the Markdown report with its tables.

#include "study.hpp"

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace kugel::tradeoff {

/// The cheapest row meeting the target (per value of target.per_knob when set, in the order
/// the values first appear), as (group knob value or "", row index or nothing).
std::vector<std::pair<std::string, std::optional<std::size_t>>> cheapest_meeting(study const& s, target const& t);

/// <dir>/<study>.csv for each study; for each plot <dir>/<plot>.dat (one block per line,
/// headed by its name, for gnuplot's `index`) and <dir>/<plot>.gp, the gnuplot commands that
/// draw it after bench/tradeoff.gp has set the terminal, the style and the output.
void write_data(std::vector<study> const& studies, std::filesystem::path const& dir);

struct report_header
{
    std::string command;   ///< how the report was made
    std::string machine;   ///< the machine class the costs were taken on
    std::string date;
    std::string plots_dir; ///< where the SVGs are, relative to the report
};

void write_markdown(std::vector<study> const& studies, report_header const& header,
                    std::filesystem::path const& file);

} // namespace kugel::tradeoff
