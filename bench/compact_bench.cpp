// The compact snapshot form (protocol/compact.hpp): what both of its forms of a 10^4-body
// snapshot cost to make, and what it puts on the wire per body on real scenes. The scenes
// run as a room runs them (two 60 Hz ticks per 30 Hz snapshot), with the room's default
// quanta and keyframes every 10 s; bytes are those of the stream an in-sync client gets.
#include "protocol/codec.hpp"
#include "protocol/compact.hpp"
#include "scene/scene.hpp"

#include <benchmark/benchmark.h>

#include <cmath>
#include <random>

namespace kugel::protocol {
namespace {

/// A world's state as the room copies it for the encoder.
snapshot copy(physics::world const& w, std::uint64_t tick)
{
    auto const& b = w.bodies();
    snapshot s{.tick = tick, .time = w.time(), .bodies = {}};
    s.bodies.mass.emplace(b.masses().begin(), b.masses().end());
    s.bodies.radius.assign(b.radii().begin(), b.radii().end());
    for (std::size_t i = 0; i < b.size(); ++i) {
        s.bodies.id.push_back(b.ids()[i].index + 1);
        for (int k = 0; k < 3; ++k) {
            s.bodies.position.push_back(b.positions()[i][k]);
            s.bodies.velocity.push_back(b.velocities()[i][k]);
        }
    }
    return s;
}

/// The room's quanta for a scene without server options (server/room.cpp, quanta_for): the
/// scene's, else chosen from its size and the 30 Hz snapshot rate.
quanta default_quanta(scene::scene const& s, physics::world const& w)
{
    double const size = std::max(scene::scene_bounds(s, w).radius, 1e-3);
    double const position = s.snapshots.position_quantum > 0.0
                                ? s.snapshots.position_quantum
                                : std::pow(10.0, std::ceil(std::log10(size))) * 1e-4;
    double const velocity = s.snapshots.velocity_quantum > 0.0
                                ? s.snapshots.velocity_quantum
                                : std::pow(10.0, std::round(std::log10(position * 30.0)));
    return {position, velocity};
}

/// Both compact forms of one snapshot of the 10,000-body gas, from the copy: quantizing,
/// the delta against the snapshot before, and the keyframe.
void encode_compact_forms(benchmark::State& state)
{
    scene::scene const s = scene::load_scene(KUGEL_SCENES_DIR "/gas.json");
    physics::world w = scene::build_world(s);
    quanta const q = default_quanta(s, w);
    w.step(s.dt);
    w.step(s.dt);
    compact_state const before = quantize(copy(w, 2), {}, q);
    w.step(s.dt);
    w.step(s.dt);
    snapshot const now = copy(w, 4);
    std::size_t delta_bytes = 0, key_bytes = 0;
    for (auto _ : state) {
        compact_state const after = quantize(now, {}, q);
        std::string d = encode(*delta(before, after));
        std::string k = encode_keyframe(after);
        delta_bytes = d.size();
        key_bytes = k.size();
        benchmark::DoNotOptimize(d.data());
        benchmark::DoNotOptimize(k.data());
    }
    state.counters["bodies"] = static_cast<double>(now.bodies.size());
    state.counters["delta_bytes"] = static_cast<double>(delta_bytes);
    state.counters["key_bytes"] = static_cast<double>(key_bytes);
    state.counters["full_bytes"] = static_cast<double>(encode(now).size());
}
BENCHMARK(encode_compact_forms)->Unit(benchmark::kMillisecond);

/// Bytes per body per snapshot of a scene's compact stream over `seconds` after `settle`
/// seconds, keyframes included; bodies counted as moving when their quantized state changed
/// since the last snapshot.
void compact_stream(benchmark::State& state, char const* file, double settle, double seconds)
{
    scene::scene const s = scene::load_scene(std::string(KUGEL_SCENES_DIR "/") + file);
    for (auto _ : state) {
        physics::world w = scene::build_world(s);
        quanta const q = default_quanta(s, w);
        std::uint64_t tick = 0;
        auto const advance = [&] {
            w.step(s.dt);
            w.step(s.dt);
            tick += 2;
        };
        for (int i = 0; i < static_cast<int>(settle * 30); ++i)
            advance();
        compact_state last = quantize(copy(w, tick), {}, q);
        double bytes = 0.0, moving = 0.0, resting = 0.0, full = 0.0;
        int const snapshots = static_cast<int>(seconds * 30);
        for (int n = 1; n <= snapshots; ++n) {
            advance();
            snapshot const full_form = copy(w, tick);
            compact_state const now = quantize(full_form, {}, q);
            auto const d = delta(last, now);
            bool const keyframe_due = n % 300 == 0; // every 10 s
            bytes += static_cast<double>(keyframe_due || !d ? encode(keyframe(now)).size() : encode(*d).size());
            full += static_cast<double>(encode(full_form).size());
            std::size_t const moved = d && d->moved ? d->moved->position.size() / 3 : 0;
            moving += static_cast<double>(moved);
            resting += static_cast<double>(now.bodies.size() - moved);
            last = now;
        }
        double const bodies = static_cast<double>(last.bodies.size());
        state.counters["bodies"] = bodies;
        state.counters["moving_share"] = moving / (moving + resting);
        state.counters["bytes_per_body"] = bytes / snapshots / bodies;
        state.counters["full_bytes_per_body"] = full / snapshots / bodies;
        state.counters["bytes_per_second"] = bytes / seconds;
    }
}
BENCHMARK_CAPTURE(compact_stream, arena, "arena.json", 1.0, 10.0)->Unit(benchmark::kSecond)->Iterations(1);
BENCHMARK_CAPTURE(compact_stream, gas, "gas.json", 1.0, 10.0)->Unit(benchmark::kSecond)->Iterations(1);
BENCHMARK_CAPTURE(compact_stream, pile_settled, "pile.json", 20.0, 20.0)->Unit(benchmark::kSecond)->Iterations(1);

} // namespace
} // namespace kugel::protocol
