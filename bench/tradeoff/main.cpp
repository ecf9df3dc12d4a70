// kugel_tradeoff: runs the reference problems across the knobs, writes their results (CSV,
// plot data) and, when asked, the Markdown report. script/tradeoff runs it and draws the
// plots; `--quick` is the smoke run that keeps it from rotting (ctest -R tradeoff).
// Exits 1 when a claim the report rests on fails (the exact integrator off the parabola,
// a measured order of accuracy off its declared one, ...).
#include "problems.hpp"
#include "report.hpp"

#include <CLI/CLI.hpp>

#include <functional>
#include <iostream>
#include <map>

int main(int argc, char** argv)
{
    using namespace kugel::tradeoff;

    CLI::App app{"kugel_tradeoff: error against cost for Kugel's speed/accuracy knobs on reference problems"};
    std::filesystem::path out = "tradeoff";
    std::filesystem::path markdown;
    report_header header{"script/tradeoff", "an unnamed machine", "an unrecorded date", "tradeoff"};
    bool quick = false;
    std::vector<std::string> only;
    app.add_option("--out", out, "directory for the CSV results and plot data")->capture_default_str();
    app.add_option("--markdown", markdown, "write the report to this file");
    app.add_option("--plots-dir", header.plots_dir, "the SVGs' directory, relative to the report")
        ->capture_default_str();
    app.add_option("--machine", header.machine, "the machine class named in the report");
    app.add_option("--date", header.date, "the date named in the report");
    app.add_option("--command", header.command, "the command named in the report")->capture_default_str();
    app.add_flag("--quick", quick, "tiny sizes and few settings: a smoke run, seconds");
    app.add_option("--only", only, "run only these problems (projectile, kepler, kepler_eccentric, close_encounter, "
                                   "coulomb, bounce, cradle, gas, pile, tree_error, tree_scaling)");
    CLI11_PARSE(app, argc, argv);

    problem_options options;
    options.quick = quick;
    if (quick)
        options.budget = {.min_repeats = 1, .max_repeats = 1, .min_total_seconds = 0.0, .single_run_enough = 0.0};

    std::vector<std::pair<std::string, std::function<study(problem_options const&)>>> const problems{
        {"projectile", projectile}, {"kepler", kepler}, {"kepler_eccentric", kepler_eccentric},
        {"close_encounter", close_encounter}, {"coulomb", coulomb_scattering},
        {"bounce", bounce},         {"cradle", cradle}, {"gas", gas},         {"pile", pile},
        {"tree_error", tree_error}, {"tree_scaling", tree_scaling}};
    for (auto const& name : only)
        if (std::none_of(problems.begin(), problems.end(), [&](auto const& p) { return p.first == name; })) {
            std::cerr << "kugel_tradeoff: no problem named " << name << '\n';
            return 2;
        }

    std::vector<study> studies;
    std::vector<std::string> failures;
    for (auto const& [name, run] : problems) {
        if (!only.empty() && std::find(only.begin(), only.end(), name) == only.end())
            continue;
        double const started = thread_cpu_seconds();
        studies.push_back(run(options));
        study const& s = studies.back();
        std::cout << s.name << ": " << s.rows.size() << " settings, " << number(thread_cpu_seconds() - started, 2)
                  << " s CPU\n";
        for (auto const& t : s.targets)
            for (auto const& [group, index] : cheapest_meeting(s, t)) {
                std::cout << "  " << t.description << (group.empty() ? "" : " at " + group) << ": ";
                if (!index) {
                    std::cout << "none meets it\n";
                    continue;
                }
                auto const& r = s.rows[*index];
                for (std::size_t k = 0; k < r.knobs.size(); ++k)
                    std::cout << (k ? ", " : "") << r.knobs[k];
                std::cout << " (" << number(r.values[s.cost], 3) << ' ' << s.value_names[s.cost] << ")\n";
            }
        failures.insert(failures.end(), s.failures.begin(), s.failures.end());
    }

    write_data(studies, out);
    if (!markdown.empty())
        write_markdown(studies, header, markdown);
    for (auto const& f : failures)
        std::cerr << "FAILED: " << f << '\n';
    std::cout << (failures.empty() ? "all claims hold\n" : std::to_string(failures.size()) + " claims failed\n");
    return failures.empty() ? 0 : 1;
}
