#pragma once

// What `kugel-client watch` prints for a snapshot.

#include "protocol/messages.hpp"

#include <optional>
#include <string>

namespace kugel::client {

/// Σ ½·m·|v|², in J, when the snapshot carries masses (the server sends them only when the
/// scene has gravity between bodies); nullopt otherwise.
std::optional<double> kinetic_energy(protocol::snapshot const& snapshot);

/// One line: "tick 1204  time 20.0667 s  bodies 400  kinetic energy 12.5 J" (the energy
/// only when known).
std::string summary_line(protocol::snapshot const& snapshot);

/// One line for an event: "event tick 1204  time 20.0583 s  entered goal  body 17 (ball,
/// owner 3)" or "event tick 88  time 1.46 s  contact  bodies 4 (ball) 9 (post)", with
/// "  missed 2" when the server dropped some before it.
std::string event_line(protocol::event const& event);

} // namespace kugel::client
