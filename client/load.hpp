#pragma once

#include "protocol/messages.hpp"

// `kugel-client load`: N connections to one room for a fixed time, optionally sending
// commands at a fixed rate, and what each of them saw.

#include "client/connection.hpp"

#include <chrono>
#include <cstdint>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

namespace kugel::client {

struct load_options
{
    std::string url;                  ///< the one address connected to
    std::size_t clients = 1;          ///< connections, 1 to max_load_clients
    double duration = 5.0;            ///< s of wall-clock time, after every client connected
    double commands_per_second = 0.0; ///< per client; 0 sends nothing (watch only)
    /// Churn: connections closed and opened again per second, over the whole load. Clients
    /// take turns; a client leaves only once its connection has received a snapshot (and,
    /// when it holds a body, after the body's remove is answered). 0: no churn.
    double reconnects_per_second = 0.0;
    /// Extra connections that take their welcome and then never read again (a hung client);
    /// at the end each is read to see whether the server dropped it. Not in `clients`.
    std::size_t stalled = 0;
    std::uint64_t seed = 1;           ///< where spawns go and which way impulses push
    /// Each client hears the player messages (players, player), as a game's players do; off,
    /// each says in its hello that it wants none.
    bool players = false;
    /// Each client subscribes to every event (hello.events true), counted in its report.
    bool events = false;
    /// What each client asks for in its hello: the compact form by default; nullopt asks
    /// for nothing (the full form at the room's rate).
    std::optional<protocol::snapshot_request> snapshots = protocol::snapshot_request{.form = "compact"};
    /// Polled while the load runs; true ends it early (Ctrl-C).
    std::function<bool()> stop_requested;
};

/// The clients' connections share a few I/O threads (one per processor): a thread per
/// connection spent more of the machine switching between them than the server spent
/// sending. Each connection holds a socket, and a second for a while when it reconnects:
/// 2,000 need `ulimit -n` of about 4,100.
inline constexpr std::size_t max_load_clients = 2000;
inline constexpr std::size_t max_stalled_clients = 100;
inline constexpr double max_reconnects_per_second = 1000.0;
/// File descriptors one client needs (run_load checks RLIMIT_NOFILE against it).
inline constexpr std::size_t file_descriptors_per_client = 2;
inline constexpr double max_load_duration = 3600.0;       ///< s
inline constexpr double max_commands_per_second = 1000.0; ///< per client

/// What one connection saw.
struct load_client_report
{
    std::size_t number = 0;      ///< 1..clients, in the order they connected
    std::string connect_error;   ///< empty when it connected
    std::uint64_t client_id = 0; ///< the server's id for it (welcome.client; the last one)
    double seconds = 0.0;        ///< from its first welcome to the end of the run
    connection_stats stats;      ///< of all its connections together
    /// Set when the server ended one of its connections before the run did (or a reconnect
    /// failed: code 0 and the reason).
    std::optional<close_info> disconnected;
    std::size_t connections = 0;        ///< opened: 1 plus its reconnects
    std::size_t silent_connections = 0; ///< ended (or still open at the end, after waiting
                                        ///< for one) without a single snapshot

    bool connected() const { return connect_error.empty(); }
    double snapshots_per_second() const;
};

/// What one stalled connection came to.
struct stalled_client_report
{
    std::string connect_error;   ///< empty when it connected
    std::uint64_t client_id = 0; ///< the server's id for it
    bool dropped = false;        ///< the server had ended it by the end of the run

    bool connected() const { return connect_error.empty(); }
};

struct load_report
{
    load_options options;
    double seconds = 0.0;       ///< the run's length, from the last connect to the end
    bool stopped_early = false; ///< by stop_requested
    double tick_rate = 0.0;     ///< Hz, from the welcome
    double snapshot_rate = 0.0; ///< Hz
    std::vector<load_client_report> clients;
    std::vector<stalled_client_report> stalled;

    std::size_t connections() const;        ///< opened by all clients, reconnects included
    std::size_t silent_connections() const; ///< without a single snapshot
    /// Every client connected, none was disconnected, and every connection received at
    /// least one snapshot. (Whether the stalled ones were dropped is reported, not judged:
    /// that depends on the server's bound and the run's length.)
    bool ok() const;
};

/// Connects, runs for options.duration, closes every connection and reports. Throws
/// std::invalid_argument for options out of bounds and url_error for a bad URL.
load_report run_load(load_options options);

/// The report as a table, one row per client and a total.
void print_report(load_report const& report, std::ostream& out);
/// The report as JSON: {"url", "clients", "seconds", ..., "per_client": [...], "total": {...}}.
nlohmann::json report_json(load_report const& report);

} // namespace kugel::client
