// kugel-server: hosts rooms, each a scene's world stepped at a fixed tick, and serves them
// over WebSocket (and the page over HTTP) on one port. With --headless it runs one scene a
// fixed number of steps without networking and prints one JSON summary on stdout. Logs go
// to stderr.

#include "checkpoint.hpp"
#include "headless.hpp"
#include "scene/scene.hpp"
#include "protocol/messages.hpp"
#include "server.hpp"
#include "static_files.hpp"

#include <CLI/CLI.hpp>
#include <boost/system/system_error.hpp>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

namespace {

int run_headless_command(std::string const& scene_file, std::vector<std::string> const& overrides,
                         std::uint64_t steps, std::size_t physics_threads)
{
    using namespace kugel;
    scene::scene s;
    try {
        s = scene::load_scene(scene_file, overrides);
    } catch (scene::scene_error const& e) {
        spdlog::error("{}", e.what());
        return 2;
    }
    spdlog::info("scene '{}': {} bodies, dt {} s, integrator {}, {} steps", s.name, s.body_count(),
                 s.dt, physics::info(s.integrator).name, steps);
    nlohmann::ordered_json summary;
    try {
        summary = server::run_headless(s, steps, physics_threads);
    } catch (physics::singular_force_error const& e) {
        spdlog::error("the scene's initial state is singular: {}", e.what());
        return 1;
    } catch (server::unmeasurable_scene const& e) {
        spdlog::error("{}: {}", scene_file, e.what());
        return 2;
    }
    std::cout << summary.dump() << '\n';
    if (summary.contains("error")) {
        spdlog::error("{}", summary["error"].get<std::string>());
        return 1;
    }
    spdlog::info("{} steps in {:.1f} ms, energy drift {}", steps, summary["wall_ms"].get<double>(),
                 summary["energy_rel_drift"].dump());
    return 0;
}

/// The page a server run without --web-root serves: the first of server::page_places() that
/// holds one, said in the log with where it was found, or none, said with where it looked.
std::filesystem::path default_web_root(char const* argv0)
{
    std::error_code ec;
    std::filesystem::path executable = std::filesystem::read_symlink("/proc/self/exe", ec);
    if (ec)
        executable = std::filesystem::absolute(argv0, ec);
    auto const places = kugel::server::page_places(executable, KUGEL_SOURCE_DIR);
    if (auto const found = kugel::server::find_page(places)) {
        spdlog::info("the page: {} ({}; --web-root DIR serves another)", found->root.string(), found->where);
        return found->root;
    }
    std::string looked;
    for (auto const& place : places)
        looked += (looked.empty() ? "" : ", ") + place.root.string();
    spdlog::info("no page to serve: no index.html in {}; --web-root DIR serves one", looked);
    return {};
}

/// "NAME=SCENE" into a room_spec.
kugel::server::room_spec parse_room(std::string const& text)
{
    auto const equals = text.find('=');
    if (equals == std::string::npos || equals == 0 || equals + 1 == text.size())
        throw CLI::ValidationError("--room", "expected NAME=SCENE, got '" + text + "'");
    return {text.substr(0, equals), text.substr(equals + 1)};
}

/// Gives each served room its `--set ROOM:PATH=VALUE` overrides, in the order given; the
/// rooms are those of --room, or the built-in 'default' without any. A room name has no
/// '=' and a scene path no ':', so the room is what stands before the last ':' ahead of
/// the first '=' (a room may be called "lab:2"), and VALUE may hold either. Throws
/// CLI::ValidationError naming the --set for one without a room or of a room not served.
void add_overrides(std::vector<kugel::server::room_spec>& rooms,
                   std::vector<std::string> const& overrides)
{
    if (rooms.empty() && !overrides.empty())
        rooms.push_back({"default", {}}); // the built-in arena scene
    for (std::string const& text : overrides) {
        std::string const target = text.substr(0, text.find('='));
        auto const colon = target.rfind(':');
        if (colon == std::string::npos)
            throw CLI::ValidationError("--set " + text,
                                       "a served room's override names its room, ROOM:PATH=VALUE "
                                       "(such as --set " + rooms.front().name + ":" + text +
                                           "); PATH=VALUE alone goes with --headless");
        std::string const name = text.substr(0, colon);
        auto const room = std::ranges::find(rooms, name, &kugel::server::room_spec::name);
        if (room == rooms.end()) {
            std::string served;
            for (auto const& r : rooms)
                served += (served.empty() ? "" : ", ") + r.name;
            throw CLI::ValidationError("--set " + text,
                                       "no room '" + name + "' is served (rooms: " + served + ")");
        }
        room->overrides.push_back(text.substr(colon + 1));
    }
}

int serve(kugel::server::server_options const& options)
{
    using namespace kugel;
    try {
        server::server s(options);
        s.stop_on_signals();
        s.start();
        spdlog::info("serving on http://{}:{}/ (WebSocket /ws, /ws/ROOM; probes /healthz, /readyz; /metrics){}",
                     options.host, s.port(),
                     options.web_root.empty() ? " without a web root"
                                              : ", page from " + options.web_root.string());
        s.wait();
        spdlog::info("stopped");
        return 0;
    } catch (scene::scene_error const& e) {
        spdlog::error("{}", e.what());
        return 2;
    } catch (server::checkpoint_error const& e) {
        spdlog::error("{}", e.what());
        return 2;
    } catch (std::invalid_argument const& e) {
        spdlog::error("{}", e.what());
        return 2;
    } catch (boost::system::system_error const& e) {
        spdlog::error("cannot listen on {}:{}: {}", options.host, options.port, e.code().message());
        return 1;
    } catch (physics::singular_force_error const& e) {
        spdlog::error("a room's scene is singular at the start: {}", e.what());
        return 1;
    }
}

} // namespace

int main(int argc, char** argv)
{
    spdlog::set_default_logger(spdlog::stderr_color_mt("kugel"));

    CLI::App app{"kugel-server: an authoritative physics server for point masses and spheres.\n"
                 "Steps a scene's world at a fixed dt; --headless runs it without networking and "
                 "prints one JSON summary on stdout (logs go to stderr)."};
    std::string scene_file;
    bool headless = false;
    std::uint64_t steps = 1000;
    std::vector<std::string> overrides;
    std::string log_level = "info";
    std::vector<std::string> rooms;
    kugel::server::server_options options;
    std::string web_root;
    app.add_option("--scene", scene_file, "Scene file (JSON), see scenes/README.md")
        ->check(CLI::ExistingFile);
    app.add_flag("--headless", headless,
                 "Step the scene without networking and print a JSON summary on stdout");
    app.add_option("--steps", steps, "Steps to run with --headless")
        ->check(CLI::Range(std::uint64_t{0}, std::uint64_t{1'000'000'000}))
        ->capture_default_str();
    app.add_option("--set", overrides,
                   "Override a scene field before validation (repeatable). With --headless\n"
                   "PATH=VALUE, e.g. --set integrator=rk4 --set dt=0.001\n"
                   "--set generators.0.count=100000 --set forces.gravity.softening=0.01.\n"
                   "Serving, ROOM:PATH=VALUE overrides a field of room ROOM's scene, e.g.\n"
                   "--room pile=scenes/pile.json --set pile:collisions.restitution=0.2\n"
                   "(the built-in room is 'default'); with --state a room restores only from a\n"
                   "checkpoint made with the same overrides. VALUE is JSON, or a plain string.")
        ->take_all();
    app.add_option("--log-level", log_level, "trace, debug, info, warn, error, critical or off")
        ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error", "critical", "off"}))
        ->capture_default_str();
    app.add_option("--room", rooms,
                   "Host a room NAME=SCENE (repeatable), reached at /ws/NAME; without any,\n"
                   "one room 'default' with the built-in arena scene at /ws. --set\n"
                   "NAME:PATH=VALUE changes a field of room NAME's scene");
    app.add_option("--host", options.host,
                   "Address to listen on. The default takes connections from this machine only;\n"
                   "0.0.0.0 (IPv4) or :: (IPv6) opens the server to the network: then give\n"
                   "--admin-token, and --allow-origin for pages served from elsewhere")
        ->capture_default_str();
    app.add_option("--port", options.port, "Port to listen on (0: any free port)")
        ->capture_default_str();
    app.add_option("--tick-rate", options.tick_rate,
                   "World steps per second of wall time (Hz). Each step advances the scene's dt, so\n"
                   "a rate other than 1/dt runs the world faster or slower than real time (the log says so)")
        ->check(CLI::Range(0.001, 10000.0))
        ->capture_default_str();
    app.add_option("--snapshot-rate", options.snapshot_rate,
                   "Snapshots per second (Hz), at most the tick rate")
        ->check(CLI::Range(0.001, 10000.0))
        ->capture_default_str();
    app.add_option("--position-quantum", options.position_quantum,
                   "m: compact snapshots write positions as integers of this, in every room\n"
                   "(0: the scene's snapshots.position_quantum, else 1/10,000 of its size,\n"
                   "to the decade above)")
        ->check(CLI::Range(0.0, 1e6))
        ->capture_default_str();
    app.add_option("--velocity-quantum", options.velocity_quantum,
                   "m/s: compact snapshots write velocities as integers of this, in every room\n"
                   "(0: the scene's snapshots.velocity_quantum, else about one position\n"
                   "quantum per snapshot interval)")
        ->check(CLI::Range(0.0, 1e9))
        ->capture_default_str();
    app.add_option("--keyframe-interval", options.keyframe_interval,
                   "s: compact snapshot streams get a keyframe at least this often")
        ->check(CLI::Range(0.001, 3600.0))
        ->capture_default_str();
    app.add_option("--web-root", web_root,
                   "Directory of the page's static files. Without it the server serves the page\n"
                   "it finds in web/ next to the executable, share/kugel/web of its install\n"
                   "prefix, or web/dist of the source tree it was built from (the log says which)")
        ->check(CLI::ExistingDirectory);
    app.add_option("--max-bodies", options.max_bodies, "Bodies per room before spawns are refused")
        ->capture_default_str();
    // Whole commands: welcome.limits announces the rate as an integer.
    std::uint64_t commands_per_second = 200;
    app.add_option("--commands-per-second", commands_per_second,
                   "Commands a client may send per second (a burst of one second's worth);\n"
                   "more are answered with rate_limited")
        ->check(CLI::Range(std::uint64_t{1}, std::uint64_t{1'000'000}))
        ->capture_default_str();
    app.add_option("--max-bodies-per-client", options.client.max_bodies_per_client,
                   "Bodies one connection spawned that may exist at once; more are answered with\n"
                   "too_many_bodies (0: no cap; admins are exempt)")
        ->capture_default_str();
    app.add_option("--allow-origin", options.allowed_origins,
                   "Let browser pages from this origin (scheme://host[:port]) open a WebSocket\n"
                   "(repeatable; '*' allows every origin). The server's own page is always let\n"
                   "in, and so are programs, which send no Origin; other pages get HTTP 403")
        ->take_all();
    app.add_option("--allow-host", options.allowed_hosts,
                   "A server listening on loopback answers only requests whose Host is loopback\n"
                   "(localhost, 127.0.0.1, [::1]): a web page whose name was rebound to\n"
                   "127.0.0.1 gets HTTP 403. Name another host to answer it too (repeatable,\n"
                   "without a port; '*' answers every host)")
        ->take_all();
    app.add_option("--admin-token", options.admin_token,
                   "A client whose hello carries this admin_token is an admin: it may pause,\n"
                   "resume, reset a room, load a scene into it and remove any body. Without\n"
                   "it nobody is an admin. Prefer the environment variable, which ps does not show")
        ->envname("KUGEL_ADMIN_TOKEN");
    app.add_option("--resume-grace", options.resume_grace,
                   "Seconds a room keeps a player whose connection ended: a new connection whose\n"
                   "hello carries its welcome's resume_token becomes it again, with its id, name\n"
                   "and bodies (0: the player leaves with its connection). A scene's\n"
                   "players.resume_grace wins in its room")
        ->check(CLI::Range(0.0, 86'400.0))
        ->capture_default_str();
    std::string bodies_on_leave = "stay";
    app.add_option("--bodies-on-leave", bodies_on_leave,
                   "What becomes of a player's bodies when it leaves for good (its grace ended):\n"
                   "stay, or remove at the next tick. A scene's players.bodies_on_leave wins in\n"
                   "its room")
        ->check(CLI::IsMember({"stay", "remove"}))
        ->capture_default_str();
    app.add_option("--max-message-bytes", options.client.max_message_bytes,
                   "Largest inbound WebSocket frame; a larger one closes the connection (1009)")
        ->check(CLI::Range(std::size_t{256}, std::size_t{64} << 20))
        ->capture_default_str();
    app.add_option("--max-queued-events", options.client.max_queued_events,
                   "Events (sensor crossings, contacts) a client may have unsent; more are\n"
                   "dropped, and the next sent says how many in `missed`")
        ->check(CLI::Range(std::size_t{1}, std::size_t{1} << 16))
        ->capture_default_str();
    double write_stall = 5.0;
    app.add_option("--write-stall", write_stall,
                   "Seconds a send to a client may stay pending before that client, which has\n"
                   "stopped reading, is disconnected (the others never wait for it)")
        ->check(CLI::Range(0.05, 3600.0))
        ->capture_default_str();
    app.add_option("--send-buffer", options.client.send_buffer_bytes,
                   "Bytes the kernel may hold unsent per client (SO_SNDBUF, doubled by Linux):\n"
                   "bounds the memory of a client that stopped reading, and how soon\n"
                   "--write-stall notices it (0: the kernel's own tuning, up to 4 MB)")
        ->check(CLI::Range(std::size_t{0}, std::size_t{64} << 20))
        ->capture_default_str();
    app.add_option("--threads", options.threads,
                   "Threads for connections, HTTP and checkpoint writes (0: one per core); each\n"
                   "room ticks on a thread of its own besides")
        ->capture_default_str();
    app.add_option("--io-niceness", options.io_niceness,
                   "Niceness (0-19) of the --threads threads: above 0 they yield the processor\n"
                   "to the rooms' ticks when both want it")
        ->check(CLI::Range(0, 19))
        ->capture_default_str();
    app.add_option("--physics-threads", options.physics_threads,
                   "Threads that step each room's world (and the --headless one), its own\n"
                   "counted: more split discrete collisions and the drift over threads. The\n"
                   "result is the same bit for bit; only the time a step takes changes")
        ->check(CLI::Range(std::size_t{1}, std::size_t{256}))
        ->capture_default_str();
    std::string state_dir;
    app.add_option("--state", state_dir,
                   "Keep each room's world in DIR/ROOM.json: restored at start, checkpointed\n"
                   "atomically every --checkpoint-interval and at SIGTERM/SIGINT. A checkpoint\n"
                   "of another scene (its file or --set overrides) or format, or a corrupt one,\n"
                   "stops the start (exit 2)");
    double checkpoint_interval = 5.0;
    app.add_option("--checkpoint-interval", checkpoint_interval,
                   "Seconds between checkpoints with --state (a kill -9 loses at most this)")
        ->check(CLI::Range(0.001, 86'400.0))
        ->capture_default_str();
    app.add_flag("--discard-bad-state", options.discard_bad_state,
                 "With --state: move an unusable checkpoint aside (ROOM.json.bad-TIME) and start\n"
                 "that room from its scene instead of refusing to start");
    app.set_version_flag("--version", std::string("kugel-server ") + KUGEL_VERSION + " (protocol " +
                                          std::to_string(kugel::protocol::protocol_version) + ")");
    try {
        app.parse(argc, argv);
    } catch (CLI::ParseError const& e) {
        // --help and --version exit 0; every mistake in the command line exits 2, the code of
        // bad input (README, exit codes), not the parser's own numbers.
        return app.exit(e) == 0 ? 0 : 2;
    }
    spdlog::set_level(spdlog::level::from_str(log_level));

    if (!headless) {
        if (!scene_file.empty()) {
            spdlog::error("--scene goes with --headless; to serve a scene use --room NAME=FILE");
            return 2;
        }
        try {
            for (std::string const& r : rooms)
                options.rooms.push_back(parse_room(r));
            add_overrides(options.rooms, overrides);
        } catch (CLI::ValidationError const& e) {
            spdlog::error("{}", e.what());
            return 2;
        }
        if (app.count("--admin-token") > 0 && options.admin_token.empty()) {
            spdlog::error("--admin-token (or KUGEL_ADMIN_TOKEN) is empty; give a token, or none "
                          "for a server without admins");
            return 2;
        }
        if (!options.admin_token.empty() && options.admin_token.size() < 16)
            spdlog::warn("the admin token has {} characters; one of 16 or more random characters "
                         "is much harder to guess", options.admin_token.size());
        options.web_root = web_root.empty() ? default_web_root(argv[0]) : std::filesystem::path(web_root);
        options.state_dir = state_dir;
        options.checkpoint_interval = std::chrono::duration_cast<std::chrono::milliseconds>(
            std::chrono::duration<double>(checkpoint_interval));
        options.client.write_stall = std::chrono::duration_cast<std::chrono::milliseconds>(
            std::chrono::duration<double>(write_stall));
        options.remove_bodies_on_leave = bodies_on_leave == "remove";
        options.client.commands_per_second = static_cast<double>(commands_per_second);
        options.client.command_burst = options.client.commands_per_second;
        return serve(options);
    }
    if (scene_file.empty()) {
        spdlog::error("--headless needs --scene FILE");
        return 2;
    }
    return run_headless_command(scene_file, overrides, steps, options.physics_threads);
}
