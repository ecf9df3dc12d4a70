#pragma once

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
    std::uint64_t seed = 1;           ///< where spawns go and which way impulses push
    /// Polled while the load runs; true ends it early (Ctrl-C).
    std::function<bool()> stop_requested;
};

inline constexpr std::size_t max_load_clients = 500;
inline constexpr double max_load_duration = 3600.0;       ///< s
inline constexpr double max_commands_per_second = 1000.0; ///< per client

/// What one connection saw.
struct load_client_report
{
    std::size_t number = 0;      ///< 1..clients, in the order they connected
    std::string connect_error;   ///< empty when it connected
    std::uint64_t client_id = 0; ///< the server's id for it (welcome.client)
    double seconds = 0.0;        ///< from its welcome to the end of the run
    connection_stats stats;
    std::optional<close_info> disconnected; ///< set when it ended before the run did

    bool connected() const { return connect_error.empty(); }
    double snapshots_per_second() const;
};

struct load_report
{
    load_options options;
    double seconds = 0.0;       ///< the run's length, from the last connect to the end
    bool stopped_early = false; ///< by stop_requested
    double tick_rate = 0.0;     ///< Hz, from the welcome
    double snapshot_rate = 0.0; ///< Hz
    std::vector<load_client_report> clients;

    /// Every client connected and none was disconnected.
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
