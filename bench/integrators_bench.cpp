// One step of each integrator on an N-body gravity problem: the cost side of the integrator
// trade (the accuracy side is in tests/physics/integrators_test.cpp and the trade-off report).

#include "physics/world.hpp"

#include <benchmark/benchmark.h>

#include <random>

namespace {

using namespace kugel::physics;

world gravity_world(integrator_kind kind, int n)
{
    world w({.integrator = kind, .substeps = 1});
    w.add_force(std::make_unique<newtonian_gravity>(1.0, 0.01));
    std::mt19937_64 rng(1);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (int i = 0; i < n; ++i)
        w.add_body({vec3(u(rng), u(rng), u(rng)), vec3(u(rng), u(rng), u(rng)) * 0.1, 1.0 / n, 0.0,
                    0.0, false});
    return w;
}

void integrator_step(benchmark::State& state)
{
    auto const kind = static_cast<integrator_kind>(state.range(0));
    int const n = static_cast<int>(state.range(1));
    world w = gravity_world(kind, n);
    w.step(1e-4); // start Verlet's cached forces
    for (auto _ : state)
        w.step(1e-4);
    state.SetLabel(std::string(info(kind).name));
    state.SetItemsProcessed(state.iterations() * n);
    state.counters["force_evals_per_step"] = info(kind).force_evaluations;
}

void all_integrators(benchmark::internal::Benchmark* b)
{
    for (auto const& entry : integrator_table())
        for (int n : {100, 1000})
            b->Args({static_cast<long>(entry.kind), n});
}

BENCHMARK(integrator_step)->Apply(all_integrators)->Unit(benchmark::kMicrosecond);

/// One step of a two-body orbit, the smallest world with a force: what a step costs beside
/// its physics, with the phase timings off (timed:0, the default) and on (timed:1, as in a
/// room or a headless run).
void two_body_step(benchmark::State& state)
{
    world w = gravity_world(integrator_kind::velocity_verlet, 2);
    w.time_phases(state.range(0) != 0);
    w.step(1e-4);
    for (auto _ : state)
        w.step(1e-4);
}

BENCHMARK(two_body_step)->ArgName("timed")->Arg(0)->Arg(1);

void drift_without_forces(benchmark::State& state)
{
    world w;
    int const n = static_cast<int>(state.range(0));
    for (int i = 0; i < n; ++i)
        w.add_body({vec3(i, 0, 0), vec3(1, 0, 0), 1.0, 0.0, 0.0, false});
    for (auto _ : state)
        w.step(1e-3);
    state.SetItemsProcessed(state.iterations() * n);
}

BENCHMARK(drift_without_forces)->Arg(100000)->Arg(1000000)->Unit(benchmark::kMicrosecond);

} // namespace
