// Barnes–Hut against the direct sum on a Plummer sphere (G = 1, ε = 0.01, as the gravity
// benchmark): the tree's relative RMS force error against its opening angle θ, and the
// cost of one force evaluation against N for the direct sum and the tree.
#include "problems.hpp"

#include "physics/barnes_hut.hpp"
#include "physics/plummer_sphere.hpp"
#include "physics/world.hpp"

#include <cmath>
#include <memory>
#include <random>

namespace kugel::tradeoff {

using namespace physics;

namespace {

constexpr double softening = 0.01;
constexpr std::size_t sample_size = 500;

world plummer_world(std::size_t n, std::unique_ptr<force_model> gravity)
{
    world w;
    w.add_force(std::move(gravity));
    for (auto const& b : plummer_sphere({.count = n, .seed = 1}))
        w.add_body(b);
    return w;
}

std::unique_ptr<force_model> gravity_model(double theta)
{
    if (theta == 0.0)
        return std::make_unique<newtonian_gravity>(1.0, softening);
    return std::make_unique<tree_gravity>(1.0, softening, theta);
}

/// The exact accelerations of a seeded sample of bodies (all of them when N is small):
/// the engine's θ = 0 tree, which opens every cell and is the direct sum in another order,
/// at O(N) per sampled body.
struct reference_sample
{
    std::vector<std::size_t> bodies;
    std::vector<vec3> accelerations;

    explicit reference_sample(world const& w)
    {
        std::size_t const n = w.bodies().size();
        std::mt19937_64 rng(3);
        for (std::size_t i = 0; i < n; ++i)
            if (n <= sample_size || std::uniform_int_distribution<std::size_t>(0, n - 1)(rng) < sample_size)
                bodies.push_back(i);
        source_tree tree;
        tree.build(w.bodies().positions(), w.bodies().masses(), 0.0);
        for (std::size_t const i : bodies)
            accelerations.push_back(tree.field_at(w.bodies().positions()[i], i, softening, false).field);
    }

    /// √(Σ|Δa|² / Σ|a|²) over the sample.
    double rms_error(std::span<vec3 const> a) const
    {
        double error2 = 0.0, norm2 = 0.0;
        for (std::size_t k = 0; k < bodies.size(); ++k) {
            error2 += (a[bodies[k]] - accelerations[k]).squaredNorm();
            norm2 += accelerations[k].squaredNorm();
        }
        return std::sqrt(error2 / norm2);
    }
};

struct evaluation
{
    double error;
    double ms;
};

evaluation evaluate(std::size_t n, double theta, problem_options const& options)
{
    world const w = plummer_world(n, gravity_model(theta));
    reference_sample const reference(w);
    std::vector<vec3> a(n);
    double const seconds = median_cpu_seconds(options.budget, [&] {
        double const start = thread_cpu_seconds();
        w.accelerations(w.bodies().positions(), a);
        return thread_cpu_seconds() - start;
    });
    return {reference.rms_error(a), 1e3 * seconds};
}

std::string method_name(double theta) { return theta == 0.0 ? "direct" : "tree θ = " + number(theta); }

} // namespace

study tree_error(problem_options const& options)
{
    std::size_t const n = options.quick ? 300 : 10'000;
    study s;
    s.name = "tree_error";
    s.title = "Barnes–Hut: force error against θ";
    s.reference = "One gravity evaluation on a Plummer sphere of " + std::to_string(n) +
                  " bodies (G = 1, softening 0.01, as the `gravity_tree` benchmark), through the world's "
                  "force models: the direct pair sum (`\"method\": \"direct\"`) or the tree at opening "
                  "angle θ (`\"method\": \"tree\"`). The answer is the direct sum; the engine's θ = 0 tree "
                  "(every cell opened) gives it for a seeded sample of " + std::to_string(sample_size) +
                  " bodies. **Error**: the relative RMS acceleration error √(Σ|Δa|²/Σ|a|²) over the "
                  "sample. Cost: CPU ms per force evaluation (a step of velocity Verlet costs one).";
    s.knob_names = {"method", "θ"};
    s.value_names = {"force error (RMS, relative)", "ms per evaluation"};
    s.cost = 1;
    s.targets = {{{{0, 1e-2}}, "force error ≤ 1%", std::nullopt},
                 {{{0, 1e-3}}, "force error ≤ 0.1%", std::nullopt}};

    std::vector<double> const thetas =
        options.quick ? std::vector<double>{0.0, 0.3, 1.0} : std::vector<double>{0.0, 0.1, 0.2, 0.3, 0.5, 0.7, 1.0};
    double previous = 0.0;
    for (double const theta : thetas) {
        auto const e = evaluate(n, theta, options);
        s.rows.push_back({theta == 0.0 ? "direct" : "tree", {theta == 0.0 ? "direct" : "tree", number(theta)},
                          {e.error, e.ms}});
        if (theta == 0.0)
            s.check(e.error <= 1e-13, "the direct sum differs from the θ = 0 tree by " + number(e.error));
        else
            s.check(e.error >= 0.5 * previous && e.error <= 0.05,
                    "tree error " + number(e.error) + " at θ = " + number(theta) + " after " + number(previous));
        previous = e.error;
    }
    s.notes = "The error grows steeply with θ (between θ² and θ³ here: what the monopole leaves out), and the tree's cost falls "
              "as θ grows; at θ ≤ 0.2 the tree opens so many cells that it costs more than the direct sum.";
    study only_tree = s;
    std::erase_if(only_tree.rows, [](row const& r) { return r.series != "tree"; });
    s.plots.push_back({"tree_error", "Barnes–Hut (N = " + std::to_string(n) + "): force error against θ",
                       "opening angle θ", "force error (RMS, relative)", false, true,
                       lines_of(only_tree, [](row const& r) { return std::stod(r.knobs[1]); },
                                [](row const& r) { return r.values[0]; })});
    return s;
}

study tree_scaling(problem_options const& options)
{
    study s;
    s.name = "tree_scaling";
    s.title = "Barnes–Hut: time against N";
    s.reference = "The same Plummer sphere and force evaluation at growing N: the direct sum (up to 10⁴ "
                  "bodies) against the tree at θ = 0.5 and 1. The error is measured as above on a sample "
                  "of " + std::to_string(sample_size) + " bodies at every N.";
    s.knob_names = {"method", "N"};
    s.value_names = {"force error (RMS, relative)", "ms per evaluation"};
    s.cost = 1;
    s.targets = {{{{0, 1e-2}}, "force error ≤ 1%", 1}};

    std::vector<std::size_t> const sizes = options.quick ? std::vector<std::size_t>{100, 1000}
                                                         : std::vector<std::size_t>{300, 1'000, 3'000, 10'000, 30'000, 100'000};
    std::size_t const direct_limit = 10'000;
    for (double const theta : {0.0, 0.5, 1.0}) {
        for (std::size_t const n : sizes) {
            if (theta == 0.0 && n > direct_limit)
                continue;
            auto const e = evaluate(n, theta, options);
            s.rows.push_back({method_name(theta), {method_name(theta), std::to_string(n)}, {e.error, e.ms}});
        }
    }
    s.notes = "The direct sum grows as N², the tree as N log N; the tree wins from a few thousand "
              "bodies (θ = 0.5) or about a thousand (θ = 1), and its error does not grow with N.";
    s.plots.push_back({"tree_scaling", "Barnes–Hut: one force evaluation against N", "bodies N",
                       "CPU ms per evaluation", true, true,
                       lines_of(s, [](row const& r) { return std::stod(r.knobs[1]); },
                                [](row const& r) { return r.values[1]; })});
    return s;
}

} // namespace kugel::tradeoff
