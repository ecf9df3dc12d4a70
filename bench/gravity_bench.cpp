// One gravity force evaluation on a Plummer sphere (G = 1, total mass 1, a = 1, ε = 0.01):
// direct summation (O(N²), up to N = 10^4) against the Barnes–Hut tree (O(N log N), up to
// 10^6) at opening angles 0.5 and 1. Beside the time, the tree reports what one evaluation
// did (interactions per body, cells) and, where the direct sum is affordable, its error.
#include "physics/barnes_hut.hpp"
#include "physics/forces.hpp"
#include "physics/plummer_sphere.hpp"

#include <benchmark/benchmark.h>

#include <cmath>
#include <map>
#include <vector>

namespace kugel::physics {
namespace {

constexpr double softening = 0.01;

/// The sphere of N bodies, built once per N so that set-up is not timed.
body_storage const& sphere(std::size_t count)
{
    static std::map<std::size_t, body_storage> spheres;
    auto [it, inserted] = spheres.try_emplace(count);
    if (inserted)
        for (auto const& b : plummer_sphere({.count = count, .seed = 1}))
            it->second.add(b);
    return it->second;
}

void evaluate(force_model const& model, body_storage const& bodies, std::vector<vec3>& f)
{
    f.assign(bodies.size(), vec3::Zero());
    model.add_forces(bodies, bodies.positions(), f);
}

/// The direct forces of a sphere, once per N (only where the direct sum is affordable).
std::vector<vec3> const& direct_forces(std::size_t count)
{
    static std::map<std::size_t, std::vector<vec3>> forces;
    auto [it, inserted] = forces.try_emplace(count);
    if (inserted)
        evaluate(newtonian_gravity(1.0, softening), sphere(count), it->second);
    return it->second;
}

void gravity_direct(benchmark::State& state)
{
    auto const& bodies = sphere(static_cast<std::size_t>(state.range(0)));
    newtonian_gravity const model(1.0, softening);
    std::vector<vec3> f;
    for (auto _ : state) {
        evaluate(model, bodies, f);
        benchmark::DoNotOptimize(f.data());
    }
    state.SetItemsProcessed(state.iterations() * state.range(0)); // bodies per second
}

/// range(0): θ in tenths; range(1): N.
void gravity_tree(benchmark::State& state)
{
    double const theta = static_cast<double>(state.range(0)) / 10.0;
    auto const count = static_cast<std::size_t>(state.range(1));
    auto const& bodies = sphere(count);
    tree_gravity const model(1.0, softening, theta);
    std::vector<vec3> f;
    for (auto _ : state) {
        evaluate(model, bodies, f);
        benchmark::DoNotOptimize(f.data());
    }
    state.SetItemsProcessed(state.iterations() * state.range(1));

    // What one evaluation does, and (N <= 10^4) its relative RMS error against the direct sum.
    std::vector<double> const masses(bodies.masses().begin(), bodies.masses().end());
    source_tree tree;
    tree.build(bodies.positions(), masses, theta);
    double interactions = 0.0;
    for (std::size_t const i : tree.bodies())
        interactions += static_cast<double>(tree.field_at(bodies.positions()[i], i, softening, false).interactions);
    state.counters["interactions_per_body"] = interactions / static_cast<double>(count);
    state.counters["cells"] = static_cast<double>(tree.cell_count());
    if (count <= 10'000) {
        auto const& exact = direct_forces(count);
        double error2 = 0.0;
        double norm2 = 0.0;
        for (std::size_t i = 0; i < count; ++i) {
            error2 += (f[i] - exact[i]).squaredNorm();
            norm2 += exact[i].squaredNorm();
        }
        state.counters["rms_error"] = std::sqrt(error2 / norm2);
    }
}

BENCHMARK(gravity_direct)->RangeMultiplier(10)->Range(100, 10'000)->Unit(benchmark::kMillisecond);
BENCHMARK(gravity_tree)
    ->ArgsProduct({{5, 10}, {100, 1'000, 10'000, 100'000, 1'000'000}})
    ->ArgNames({"theta10", "N"})
    ->Unit(benchmark::kMillisecond);

} // namespace
} // namespace kugel::physics
