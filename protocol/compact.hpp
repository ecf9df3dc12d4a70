#pragma once

// The compact snapshot form (PROTOCOL.md, "Compact snapshots"): every body's position and
// velocity as integers of announced quanta, its constants sent once, and deltas that carry
// only the bodies whose quantized state changed since a base. What the server encodes and
// what a client decodes are the same integers, so a client holds exactly the server's
// quantized state and nothing drifts. The server and every C++ client share this code.

#include "protocol/messages.hpp"

#include <cstdint>
#include <optional>
#include <span>
#include <string>

namespace kugel::protocol {

/// The steps positions and velocities are quantized to.
struct quanta
{
    double position = 1e-3; ///< m, > 0
    double velocity = 1e-2; ///< m/s, > 0

    bool operator==(quanta const&) const = default;
};

/// Quantized coordinates stay within ±2^50 (a body beyond is shown at that distance):
/// a delta's differences then stay below 2^53, exact in a double and in JavaScript.
inline constexpr std::int64_t max_quantized = std::int64_t{1} << 50;

/// The state a compact stream carries at one tick: what a keyframe holds, and what a client
/// holds after applying a keyframe and the deltas after it.
struct compact_state
{
    std::uint64_t tick = 0;
    double time = 0.0;
    bool paused = false;
    std::uint64_t faults = 0;
    quanta q;
    compact_bodies bodies; ///< sorted by id

    bool operator==(compact_state const&) const = default;
};

/// x / quantum rounded to the nearest integer (halves up), clamped to ±max_quantized.
std::int64_t quantize(double x, double quantum);

/// A body's id and the client that spawned it.
struct body_owner
{
    std::uint64_t id = 0;
    std::uint64_t client = 0;
};

/// The full-form snapshot `full` quantized: bodies sorted by id. `owners`, sorted by id,
/// names the client that spawned each body it lists; the others are the scene's (owner 0).
compact_state quantize(snapshot const& full, std::span<body_owner const> owners, quanta q);

/// Where a delta predicts a coordinate: the base's plus the mean of the base's velocity and
/// the new one over the time between them, in quanta (PROTOCOL.md gives the formula; both
/// sides compute it in the same IEEE double operations, so they agree to the bit).
std::int64_t predicted_position(std::int64_t base_position, std::int64_t base_velocity,
                                std::int64_t velocity, double half_steps);
/// (time − base_time) · velocity quantum / position quantum / 2: the factor of the prediction.
double prediction_factor(double base_time, double time, quanta q);

/// The keyframe of a state.
compact_snapshot keyframe(compact_state const& state);
/// The keyframe without its bodies: what encode_keyframe writes ahead of the state's own.
compact_snapshot keyframe_head(compact_state const& state);
/// The delta that takes `base` to `now`, or nothing when a keyframe serves better: the
/// quanta differ, or more bodies appeared and vanished than stayed.
std::optional<compact_snapshot> delta(compact_state const& base, compact_state const& now);

/// What applying a compact snapshot gives: the new state, or why it cannot apply.
struct apply_result
{
    std::optional<compact_state> state;
    std::string failure; ///< when no state: a delta whose base is not `held`, or one that contradicts it
};

/// Applies a keyframe (`held` is not needed) or a delta against `held`, the state of its
/// base tick. Checks everything: a delta for another base, runs beyond the base's bodies, a
/// vanished id it does not hold, an appeared id it holds, a coordinate beyond 2^53.
apply_result apply_compact(compact_snapshot const& message, compact_state const* held);

/// The state in the full form's columns: positions and velocities as quanta · integer.
snapshot to_snapshot(compact_state const& state);

} // namespace kugel::protocol
