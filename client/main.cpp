// kugel-client: talks to a running kugel-server. `watch` prints its snapshots, `run` plays
// a script and checks every expectation in it (exit 0 when all hold), `load` puts the
// server under a measured load. client/README.md describes each, and the script format.

#include "connection.hpp"
#include "load.hpp"
#include "protocol/codec.hpp"
#include "protocol/messages.hpp"
#include "script.hpp"
#include "script_runner.hpp"
#include "url.hpp"
#include "watch.hpp"

#include <CLI/CLI.hpp>
#include <atomic>
#include <chrono>
#include <csignal>
#include <iostream>
#include <sstream>

namespace {

using namespace kugel::client;

/// Set by SIGINT or SIGTERM: watch and load end and report, rather than die.
std::atomic<bool> stop_requested{false};

extern "C" void on_stop_signal(int)
{
    stop_requested = true;
}

void stop_on_signals()
{
    std::signal(SIGINT, on_stop_signal);
    std::signal(SIGTERM, on_stop_signal);
}

std::chrono::milliseconds to_ms(double seconds)
{
    return std::chrono::milliseconds(static_cast<std::int64_t>(seconds * 1000.0));
}

/// What --snapshots and --snapshot-rate ask for: nothing for "full" at the room's rate.
std::optional<kugel::protocol::snapshot_request> snapshot_request(std::string const& form, double rate)
{
    if (form == "full" && rate <= 0.0)
        return std::nullopt; // protocol 1 as it always was: no request at all
    kugel::protocol::snapshot_request r{.form = form, .rate = std::nullopt};
    if (rate > 0.0)
        r.rate = rate;
    return r;
}

int watch(std::string const& url, bool as_json, std::uint64_t count, double timeout,
          std::optional<kugel::protocol::snapshot_request> snapshots, bool events)
{
    connection_options options;
    options.name = "kugel-client watch";
    options.snapshots = std::move(snapshots);
    if (events)
        options.events = kugel::protocol::event_request{}; // every event
    options.connect_timeout = to_ms(timeout);
    connection link(url, options);
    auto const w = link.welcome();
    std::cerr << "room '" << w.room << "', scene '" << w.scene.name << "': " << w.tick_rate
              << " ticks/s, " << w.snapshot_rate << " snapshots/s, dt " << w.dt << " s\n";
    stop_on_signals();
    std::uint64_t printed = 0;
    // A tick's events come before its snapshot: those received are printed first.
    auto const print_events = [&] {
        while (auto const e = link.next_event(std::chrono::milliseconds(0)))
            std::cout << (as_json ? kugel::protocol::encode(*e) : event_line(*e)) << '\n';
    };
    while (!stop_requested && (count == 0 || printed < count)) {
        auto const snapshot = link.next_snapshot(std::chrono::milliseconds(200));
        print_events();
        if (!snapshot) {
            if (auto const ended = link.closed_with()) {
                std::cerr << "connection closed"
                          << (ended->code ? " with " + std::to_string(ended->code) : "")
                          << (ended->reason.empty() ? "" : ": " + ended->reason) << '\n';
                return ended->code == 1000 || ended->code == 1001 ? 0 : 1;
            }
            continue;
        }
        std::cout << (as_json ? kugel::protocol::encode(*snapshot) : summary_line(*snapshot))
                  << '\n'
                  << std::flush;
        ++printed;
    }
    link.close();
    auto const stats = link.stats();
    if (stats.late_snapshots > 0)
        std::cerr << stats.late_snapshots << " snapshots came later than the server sends them "
                  << "(it skipped some: this client read too slowly)\n";
    return 0;
}

int run(std::string const& file, std::string const& url, double timeout, bool quiet, bool cleanup,
        std::optional<kugel::protocol::snapshot_request> snapshots)
{
    parse_websocket_url(url); // a bad URL is a usage error (2), not a failed step
    script s;
    try {
        s = load_script(file);
    } catch (script_error const& e) {
        std::cerr << e.what() << '\n';
        return 2;
    }
    run_options options;
    options.url = url;
    options.timeout = to_ms(timeout);
    options.cleanup = cleanup;
    options.snapshots = std::move(snapshots);
    std::ostringstream discarded;
    run_result const result = run_script(s, options, quiet ? discarded : std::cout);
    if (quiet && !result.passed)
        std::cout << result.failure << '\n';
    return result.passed ? 0 : 1;
}

int load(load_options options, bool as_json)
{
    stop_on_signals();
    options.stop_requested = [] { return stop_requested.load(); };
    load_report const report = run_load(options);
    if (as_json)
        std::cout << report_json(report).dump(2) << '\n';
    else
        print_report(report, std::cout);
    return report.ok() ? 0 : 1;
}

} // namespace

int main(int argc, char** argv)
{
    CLI::App app{"kugel-client: watch a Kugel room, run a scripted test against it, or put it "
                 "under load.\nURLs are ws://HOST:PORT/ws/ROOM (kugel-server prints its port). "
                 "See client/README.md."};
    app.require_subcommand(0, 1); // none is refused below, after unknown arguments are named
    app.set_version_flag("--version", std::string("kugel-client ") + KUGEL_VERSION + " (protocol " +
                                          std::to_string(kugel::protocol::protocol_version) + ")");

    CLI::App* watch_command = app.add_subcommand(
        "watch", "Print one line per snapshot: tick, time, bodies, and the kinetic energy when the "
                 "snapshots carry masses. Ends at Ctrl-C, after --count snapshots, or when the "
                 "server closes.");
    std::string watch_url;
    bool watch_json = false;
    std::uint64_t watch_count = 0;
    double watch_timeout = 10.0;
    watch_command->add_option("URL", watch_url, "ws://HOST:PORT/ws/ROOM")->required();
    watch_command->add_flag("--json", watch_json,
                            "Print each snapshot as its JSON message instead");
    watch_command->add_option("--count", watch_count, "Stop after this many snapshots (0: never)")
        ->capture_default_str();
    watch_command->add_option("--timeout", watch_timeout, "Seconds to wait for the connection")
        ->check(CLI::Range(0.1, 600.0))
        ->capture_default_str();
    bool watch_events = false;
    watch_command->add_flag("--events", watch_events,
                            "Also print every event (sensor crossings, contacts), a line each "
                            "(its JSON message with --json), before the snapshot of its tick");

    CLI::App* run_command = app.add_subcommand(
        "run", "Run a script of steps (send, expect, wait, check bodies) against a server. Prints "
               "each step; exits 0 when every expectation holds, 1 naming the step that failed "
               "(what was expected, what arrived), 2 when the script cannot be read.");
    std::string script_file;
    std::string run_url;
    double run_timeout = 10.0;
    bool quiet = false;
    bool cleanup = false;
    run_command->add_option("SCRIPT", script_file, "The script (JSON), see client/README.md")
        ->required()
        ->check(CLI::ExistingFile);
    run_command->add_option("--url", run_url, "ws://HOST:PORT/ws/ROOM: where every client connects")
        ->required();
    run_command
        ->add_option("--timeout", run_timeout,
                     "Seconds to wait for an answer, a close, or a first snapshot; waits "
                     "in ticks get twice their ticks' worth on top")
        ->check(CLI::Range(0.1, 600.0))
        ->capture_default_str();
    run_command->add_flag("--quiet", quiet, "Print only a failure");
    run_command->add_flag("--cleanup", cleanup,
                          "At the end, passed or failed, each client removes the bodies it spawned "
                          "(as the script's \"cleanup\": true)");

    CLI::App* load_command = app.add_subcommand(
        "load", "Open N connections to one room for S seconds, optionally sending commands (spawn, "
                "impulse, remove) at a rate, and report per client: snapshot rate, tick gaps, ack "
                "latency (p50, p99, max), bytes per second, errors, disconnects. Connects only to "
                "--url. Exits 0 when every client connected and stayed connected.");
    load_options load_opts;
    bool load_json = false;
    load_command->add_option("--url", load_opts.url, "ws://HOST:PORT/ws/ROOM")->required();
    load_command->add_option("--clients", load_opts.clients, "Connections to open")
        ->required()
        ->check(CLI::Range(std::size_t{1}, max_load_clients));
    load_command->add_option("--duration", load_opts.duration, "Seconds to run, after connecting")
        ->required()
        ->check(CLI::Range(0.1, max_load_duration));
    load_command
        ->add_option("--commands-per-second", load_opts.commands_per_second,
                     "Commands each client sends per second (0: none, only watch). The "
                     "server refuses more than its limit (welcome.limits) with rate_limited")
        ->check(CLI::Range(0.0, max_commands_per_second))
        ->capture_default_str();
    load_command
        ->add_option("--reconnects-per-second", load_opts.reconnects_per_second,
                     "Churn: connections closed and opened again per second over all clients, "
                     "clients in turn (each once it has had a snapshot; its body removed first)")
        ->check(CLI::Range(0.0, max_reconnects_per_second))
        ->capture_default_str();
    load_command
        ->add_option("--stalled", load_opts.stalled,
                     "Extra connections that stop reading after their welcome (a hung client); "
                     "the report says whether the server dropped them")
        ->check(CLI::Range(std::size_t{0}, max_stalled_clients))
        ->capture_default_str();
    load_command->add_option("--seed", load_opts.seed, "Seed for where spawns go and impulses push")
        ->capture_default_str();
    load_command->add_flag("--players", load_opts.players,
                           "Each client hears who joins and leaves, as a game's players do (off: each asks for none)");
    load_command->add_flag("--events", load_opts.events,
                           "Each client subscribes to every event (sensor crossings, contacts) and counts them");
    load_command->add_flag("--json", load_json, "Print the report as JSON");
    std::string snapshot_form = "compact";
    std::string run_snapshot_form = "full"; // scripts that check with tolerance 0 need exact doubles
    double snapshot_rate = 0.0;
    for (CLI::App* command : {watch_command, load_command, run_command}) {
        command
            ->add_option("--snapshots", command == run_command ? run_snapshot_form : snapshot_form,
                         command == run_command
                             ? "Snapshot form every client of the script asks for: full (exact "
                               "doubles) or compact (quantized; $position_quantum and "
                               "$velocity_quantum then hold the quanta, for tolerances)"
                             : "Snapshot form to ask for: compact (quantized keyframes and deltas, "
                               "decoded here; protocol/PROTOCOL.md) or full")
            ->check(CLI::IsMember({"compact", "full"}))
            ->capture_default_str();
        command->add_option("--snapshot-rate", snapshot_rate,
                            "Snapshots per second to ask for (0: the room's rate)")
            ->check(CLI::Range(0.0, 10000.0))
            ->capture_default_str();
    }

    try {
        app.parse(argc, argv);
    } catch (CLI::ParseError const& e) {
        // --help and --version exit 0; every mistake in the command line exits 2, the code of
        // bad input (client/README.md, exit codes), not the parser's own numbers.
        return app.exit(e) == 0 ? 0 : 2;
    }
    if (!*watch_command && !*run_command && !*load_command) {
        std::cerr << "kugel-client: name a command: watch, run or load (kugel-client --help)\n";
        return 2;
    }

    try {
        if (*watch_command)
            return watch(watch_url, watch_json, watch_count, watch_timeout,
                         snapshot_request(snapshot_form, snapshot_rate), watch_events);
        if (*run_command)
            return run(script_file, run_url, run_timeout, quiet, cleanup,
                       snapshot_request(run_snapshot_form, snapshot_rate));
        load_opts.snapshots = snapshot_request(snapshot_form, snapshot_rate);
        return load(load_opts, load_json);
    } catch (url_error const& e) {
        std::cerr << e.what() << '\n';
        return 2;
    } catch (connection_error const& e) {
        std::cerr << e.what() << '\n';
        return 1;
    } catch (std::invalid_argument const& e) {
        std::cerr << e.what() << '\n';
        return 2;
    }
}
