#pragma once

// Runs a script against a server: each step in order, on the connection it names, until a
// step fails or all have passed.

#include "client/script.hpp"
#include "protocol/messages.hpp"

#include <chrono>
#include <optional>
#include <ostream>
#include <string>

namespace kugel::client {

struct run_options
{
    std::string url; ///< ws://host:port/ws/ROOM: every client of the script connects here
    /// How long to wait for an answer, a close or a first snapshot. Waits counted in ticks
    /// get twice their ticks' worth of wall-clock time on top (see client/README.md).
    std::chrono::milliseconds timeout{10'000};
    /// Remove what each client spawned at the end, passed or failed (also when the script
    /// says "cleanup": true).
    bool cleanup = false;
    /// The snapshots every client of the script asks for in its hello; nullopt asks for
    /// nothing: the full form, exact doubles (what a check with tolerance 0 needs). On the
    /// compact form the variables position_quantum and velocity_quantum hold the quanta the
    /// welcome announced, for tolerances.
    std::optional<protocol::snapshot_request> snapshots;
};

struct run_result
{
    bool passed = false;
    std::size_t failed_step = 0; ///< its number; 0 when every step passed
    std::string failure;         ///< names the step, what was expected and what arrived
};

/// Runs every step; writes one line per step to `log` ("ok   step 3 ...") and, when a step
/// fails, the failure (the same text as run_result::failure).
run_result run_script(script const& s, run_options const& options, std::ostream& log);

} // namespace kugel::client
