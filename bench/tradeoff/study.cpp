#include "study.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>

namespace kugel::tradeoff {

void study::check(bool holds, std::string const& claim)
{
    if (!holds)
        failures.push_back(name + ": " + claim);
}

std::string number(double value, int significant)
{
    if (value == 0.0)
        return "0";
    if (!std::isfinite(value))
        return std::isnan(value) ? "–" : "∞";
    char text[32];
    double const magnitude = std::abs(value);
    if (magnitude >= 1.0 && magnitude < 1e6) {
        // plain digits, never 4e+03: as many decimals as the significant digits leave
        int const integer_digits = static_cast<int>(std::floor(std::log10(magnitude))) + 1;
        int const decimals = value == std::round(value) ? 0 : std::max(0, significant - integer_digits);
        std::snprintf(text, sizeof text, "%.*f", decimals, value);
        return text;
    }
    std::snprintf(text, sizeof text, "%.*g", significant, value);
    return text;
}

std::string seconds_fraction(double dt)
{
    double const per_second = 1.0 / dt;
    if (std::abs(per_second - std::round(per_second)) < 1e-9 * per_second && per_second >= 2.0)
        return "1/" + std::to_string(static_cast<long long>(std::round(per_second)));
    return number(dt);
}

double thread_cpu_seconds()
{
    timespec t{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

double median_cpu_seconds(timing_budget const& budget, std::function<double()> const& run)
{
    std::vector<double> times;
    double total = 0.0;
    while (static_cast<int>(times.size()) < budget.max_repeats) {
        double const t = run();
        times.push_back(t);
        total += t;
        if (times.size() == 1 && t >= budget.single_run_enough)
            break;
        if (static_cast<int>(times.size()) >= budget.min_repeats && total >= budget.min_total_seconds)
            break;
    }
    auto const middle = times.begin() + static_cast<std::ptrdiff_t>(times.size() / 2);
    std::nth_element(times.begin(), middle, times.end());
    return *middle;
}

std::vector<series> lines_of(study const& s, std::function<double(row const&)> const& x,
                             std::function<double(row const&)> const& y)
{
    std::vector<series> lines;
    for (auto const& r : s.rows) {
        auto it = std::find_if(lines.begin(), lines.end(), [&](series const& l) { return l.name == r.series; });
        if (it == lines.end()) {
            lines.push_back({r.series, {}});
            it = lines.end() - 1;
        }
        it->points.emplace_back(x(r), y(r));
    }
    return lines;
}

} // namespace kugel::tradeoff
