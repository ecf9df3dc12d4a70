// Broadphase cost: find_overlapping_pairs for each kind on N random spheres of radius
// 0.05 m filling 10 % of a cube, N = 10^3 … 10^6 (brute force only up to 10^4).
#include "physics/broadphase.hpp"

#include <benchmark/benchmark.h>

#include <cmath>
#include <map>
#include <numbers>
#include <random>
#include <vector>

namespace kugel::physics {
namespace {

constexpr double radius = 0.05;       // m
constexpr double fill_fraction = 0.1; // sphere volume / cube volume

/// N spheres, centres uniform in a cube sized so that their volume is 10 % of it. Built
/// once per N and kept, so that set-up is not timed.
std::vector<aabb> const& scene(std::size_t count)
{
    static std::map<std::size_t, std::vector<aabb>> scenes;
    auto [it, inserted] = scenes.try_emplace(count);
    if (inserted) {
        double const sphere_volume = 4.0 / 3.0 * std::numbers::pi * radius * radius * radius;
        double const side = std::cbrt(static_cast<double>(count) * sphere_volume / fill_fraction);
        std::mt19937_64 rng(count);
        std::uniform_real_distribution<double> coordinate(0.0, side);
        it->second.reserve(count);
        for (std::size_t i = 0; i < count; ++i)
            it->second.push_back(
                aabb_of_sphere(vec3(coordinate(rng), coordinate(rng), coordinate(rng)), radius));
    }
    return it->second;
}

void find_pairs(benchmark::State& state, broadphase_kind kind)
{
    auto const& boxes = scene(static_cast<std::size_t>(state.range(0)));
    broadphase_workspace workspace;
    std::vector<box_pair> pairs;
    find_overlapping_pairs(kind, boxes, pairs, workspace); // warm up the buffers
    for (auto _ : state) {
        find_overlapping_pairs(kind, boxes, pairs, workspace);
        benchmark::DoNotOptimize(pairs.data());
        benchmark::ClobberMemory();
    }
    state.SetItemsProcessed(state.iterations() * state.range(0)); // boxes per second
    state.counters["boxes"] = static_cast<double>(boxes.size());
    state.counters["pairs"] = static_cast<double>(pairs.size());
    state.counters["pairs_per_second"] = benchmark::Counter(
        static_cast<double>(pairs.size()) * static_cast<double>(state.iterations()),
        benchmark::Counter::kIsRate);
}

void brute_force(benchmark::State& state) { find_pairs(state, broadphase_kind::brute_force); }
void sweep_and_prune(benchmark::State& state)
{
    find_pairs(state, broadphase_kind::sweep_and_prune);
}
void uniform_grid(benchmark::State& state) { find_pairs(state, broadphase_kind::uniform_grid); }

BENCHMARK(brute_force)->RangeMultiplier(10)->Range(1'000, 10'000)->Unit(benchmark::kMillisecond);
BENCHMARK(sweep_and_prune)
    ->RangeMultiplier(10)
    ->Range(1'000, 1'000'000)
    ->Unit(benchmark::kMillisecond);
BENCHMARK(uniform_grid)
    ->RangeMultiplier(10)
    ->Range(1'000, 1'000'000)
    ->Unit(benchmark::kMillisecond);

} // namespace
} // namespace kugel::physics
