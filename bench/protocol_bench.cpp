// Protocol cost: encoding one snapshot of N bodies (what a room pays per snapshot, once for
// all its clients) and decoding one command (what a session pays per message). The snapshot
// is also built and dumped as a plain nlohmann::json document, the obvious way to write it,
// so the direct writer's advantage stays measured rather than remembered.
#include "protocol/codec.hpp"

#include <benchmark/benchmark.h>
#include <nlohmann/json.hpp>

#include <random>

namespace kugel::protocol {
namespace {

snapshot random_snapshot(std::size_t n)
{
    std::mt19937_64 rng(n);
    std::uniform_real_distribution<double> u(-10.0, 10.0);
    snapshot s;
    s.tick = 123456;
    s.time = 2057.6;
    for (std::size_t i = 0; i < n; ++i) {
        s.bodies.id.push_back(i + 1);
        for (int k = 0; k < 3; ++k) {
            s.bodies.position.push_back(u(rng));
            s.bodies.velocity.push_back(u(rng));
        }
        s.bodies.radius.push_back(0.05);
    }
    return s;
}

void encode_snapshot(benchmark::State& state)
{
    snapshot const s = random_snapshot(static_cast<std::size_t>(state.range(0)));
    std::size_t bytes = 0;
    for (auto _ : state) {
        std::string text = encode(s);
        bytes = text.size();
        benchmark::DoNotOptimize(text.data());
    }
    state.SetItemsProcessed(state.iterations() * state.range(0)); // bodies per second
    state.counters["bytes"] = static_cast<double>(bytes);
    state.counters["bytes_per_body"] = static_cast<double>(bytes) / static_cast<double>(state.range(0));
}
BENCHMARK(encode_snapshot)->RangeMultiplier(10)->Range(1000, 100000)->Unit(benchmark::kMillisecond);

/// The same snapshot as encode_snapshot, built as a JSON document and dumped: what the codec
/// did before its snapshot writer, and what every other message still does.
void encode_snapshot_via_json_document(benchmark::State& state)
{
    snapshot const s = random_snapshot(static_cast<std::size_t>(state.range(0)));
    std::size_t bytes = 0;
    for (auto _ : state) {
        nlohmann::json const document = {
            {"type", snapshot::type},
            {"tick", s.tick},
            {"time", s.time},
            {"bodies",
             {{"id", s.bodies.id},
              {"position", s.bodies.position},
              {"velocity", s.bodies.velocity},
              {"radius", s.bodies.radius}}},
        };
        std::string text = document.dump();
        bytes = text.size();
        benchmark::DoNotOptimize(text.data());
    }
    state.SetItemsProcessed(state.iterations() * state.range(0)); // bodies per second
    state.counters["bytes"] = static_cast<double>(bytes);
    state.counters["bytes_per_body"] = static_cast<double>(bytes) / static_cast<double>(state.range(0));
}
BENCHMARK(encode_snapshot_via_json_document)
    ->RangeMultiplier(10)
    ->Range(1000, 100000)
    ->Unit(benchmark::kMillisecond);

void decode_spawn(benchmark::State& state)
{
    std::string const text = R"({"type":"spawn","ref":42,"body":{"position":[1.5,-2.25,3],)"
                             R"("velocity":[0,0,0],"radius":0.25,"density":1000}})";
    for (auto _ : state) {
        auto result = decode(text);
        benchmark::DoNotOptimize(result);
    }
    state.SetItemsProcessed(state.iterations());
}
BENCHMARK(decode_spawn);

} // namespace
} // namespace kugel::protocol
