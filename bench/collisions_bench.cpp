// One step of an elastic gas (radius 0.05 m, 10% of the box filled, speeds up to 1 m/s,
// dt = 1/60 s) in each collision mode: the cost side of the discrete/continuous trade.
// The accuracy side is in tests/physics/collisions_test.cpp.

#include "physics/thread_pool.hpp"
#include "physics/world.hpp"

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>
#include <random>
#include <vector>

namespace {

using namespace kugel::physics;

/// The gas, its spheres added on the lattice row by row, so that neighbours start in
/// neighbouring slots; or, `mixed`, in a shuffled order, as the slots of a gas that has run
/// for a while are (it mixes, and bodies come and go).
world gas(collision_mode mode, std::int64_t n, bool mixed = false, bool calendar = true)
{
    world_settings settings;
    settings.collisions.mode = mode;
    settings.collisions.event_calendar = calendar;
    world w(settings);
    double const r = 0.05;
    double const side = std::cbrt(static_cast<double>(n) * 4.0 / 3.0 * std::numbers::pi * r * r * r / 0.1);
    for (wall const& boundary : box_walls({vec3::Constant(-side / 2), vec3::Constant(side / 2)}, 0.0, 0.0))
        w.add_wall(boundary);
    auto const per_axis = static_cast<std::int64_t>(std::ceil(std::cbrt(static_cast<double>(n))));
    double const spacing = side / static_cast<double>(per_axis);
    std::mt19937_64 rng(1);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    std::vector<std::int64_t> order(static_cast<std::size_t>(n));
    std::iota(order.begin(), order.end(), 0);
    if (mixed)
        std::shuffle(order.begin(), order.end(), std::mt19937_64(2));
    for (std::int64_t const i : order) {
        vec3 const cell(static_cast<double>(i % per_axis), static_cast<double>((i / per_axis) % per_axis),
                        static_cast<double>(i / (per_axis * per_axis)));
        vec3 v(u(rng), u(rng), u(rng));
        if (v.norm() > 1.0)
            v.normalize();
        w.add_body({(cell.array() + 0.5).matrix() * spacing - vec3::Constant(side / 2), v, 0.5, r, 0.0,
                    false});
    }
    return w;
}

/// Times steps of `w` (a gas of `bodies` spheres), after one untimed step.
void time_gas_steps(benchmark::State& state, world& w, std::int64_t bodies)
{
    w.step(1.0 / 60.0);
    auto const contacts_before = w.collisions().contacts();
    for (auto _ : state)
        w.step(1.0 / 60.0);
    state.SetItemsProcessed(state.iterations() * bodies);
    state.counters["contacts_per_step"] = benchmark::Counter(
        static_cast<double>(w.collisions().contacts() - contacts_before) / static_cast<double>(state.iterations()));
}

void gas_step(benchmark::State& state, collision_mode mode)
{
    world w = gas(mode, state.range(0));
    time_gas_steps(state, w, state.range(0));
}

// The continuous step by the step-by-step loop, which predicts every pair afresh each step
// (the calendar off): what the calendar saves.
void gas_step_stepwise(benchmark::State& state)
{
    world w = gas(collision_mode::continuous, state.range(0), false, false);
    time_gas_steps(state, w, state.range(0));
}

// The same step with the world lent a pool of T threads (arguments T, N); wall time, since
// the work is spread over threads.
void gas_step_threads(benchmark::State& state, collision_mode mode)
{
    kugel::physics::thread_pool pool(static_cast<std::size_t>(state.range(0)));
    world w = gas(mode, state.range(1));
    w.set_parallel_for(&pool);
    time_gas_steps(state, w, state.range(1));
}

// The discrete step of a mixed gas (arguments T, N: T = 1 lends no pool). A large world keeps
// its bodies in cell order (world::bodies_worth_sorting): this is where that shows.
void gas_step_mixed(benchmark::State& state)
{
    kugel::physics::thread_pool pool(static_cast<std::size_t>(state.range(0)));
    world w = gas(collision_mode::discrete, state.range(1), true);
    if (state.range(0) > 1)
        w.set_parallel_for(&pool);
    time_gas_steps(state, w, state.range(1));
}

BENCHMARK_CAPTURE(gas_step, discrete, collision_mode::discrete)
    ->RangeMultiplier(10)->Range(1000, 1000000)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(gas_step, continuous, collision_mode::continuous)
    ->RangeMultiplier(10)->Range(1000, 100000)->Unit(benchmark::kMillisecond);

BENCHMARK(gas_step_stepwise)->RangeMultiplier(10)->Range(1000, 100000)->Unit(benchmark::kMillisecond);

BENCHMARK_CAPTURE(gas_step_threads, discrete, collision_mode::discrete)
    ->ArgsProduct({{2}, {1000, 10000, 100000, 1000000}})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(gas_step_threads, continuous, collision_mode::continuous)
    ->ArgsProduct({{2}, {1000, 10000, 100000}})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(gas_step_mixed)->ArgsProduct({{1, 2}, {100000, 1000000}})->Unit(benchmark::kMillisecond)->UseRealTime();

} // namespace
