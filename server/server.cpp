#include "server.hpp"

#include "checkpoint.hpp"
#include "listener.hpp"
#include "origin_check.hpp"
#include "room.hpp"
#include "websocket_session.hpp"

#include "scene/scene.hpp"

#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <boost/asio/signal_set.hpp>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>

#include <sys/resource.h>
#include <unistd.h>

namespace kugel::server {

struct server::state
{
    explicit state(std::size_t workers) : io(static_cast<int>(workers)), thread_count(workers) {}

    /// One context and thread per room, for its strand alone: a tick never waits behind the
    /// sessions' handlers (a snapshot's fan-out to 1,000 clients is 1,000 writes). Declared
    /// before `io`, so destroyed after it: a session left in io's queue may hold the last
    /// reference to a room, whose timers need their context. The other way round, a room's
    /// handler holding a session, cannot happen: wait() runs the rooms' contexts until their
    /// queues are empty, after io's threads have ended.
    std::vector<std::unique_ptr<net::io_context>> room_contexts;
    net::io_context io; ///< the sessions, the listener, checkpoint writes
    std::map<std::string, std::shared_ptr<room>, std::less<>> rooms;
    std::vector<net::executor_work_guard<net::io_context::executor_type>> room_work;
    std::shared_ptr<listener> acceptor;
    std::vector<std::thread> threads;      ///< io's
    std::vector<std::thread> room_threads; ///< one per room context
    std::size_t thread_count;
    int io_niceness = 0; ///< of io's threads
    std::optional<net::signal_set> signals;
    std::optional<net::steady_timer> grace; ///< ends what is left after a stop
    std::chrono::milliseconds shutdown_grace{1000};
    std::atomic<bool> stopping{false};
    std::atomic<std::uint64_t> next_client_id{1};
    bool final_checkpoints_written = false;
};

namespace {

static_assert(server_options::default_physics_threads_from == physics::world::bodies_worth_sharing);

void check(server_options const& o)
{
    if (!(o.tick_rate > 0.0 && o.tick_rate <= 10'000.0))
        throw std::invalid_argument("--tick-rate must be in (0, 10000] Hz");
    if (!(o.snapshot_rate > 0.0 && o.snapshot_rate <= o.tick_rate))
        throw std::invalid_argument("--snapshot-rate must be > 0 and <= the tick rate");
    for (room_spec const& r : o.rooms)
        if (r.name.empty() || r.name.find_first_of("/?#% ") != std::string::npos)
            throw std::invalid_argument("room name '" + r.name +
                                        "' must be non-empty, without / ? # % or spaces");
    if (!o.state_dir.empty() && o.checkpoint_interval <= std::chrono::milliseconds::zero())
        throw std::invalid_argument("--checkpoint-interval must be > 0");
    if (!(o.position_quantum >= 0.0 && o.velocity_quantum >= 0.0 && std::isfinite(o.position_quantum) &&
          std::isfinite(o.velocity_quantum)))
        throw std::invalid_argument("--position-quantum and --velocity-quantum must be >= 0 (0: from the scene)");
    if (!(o.keyframe_interval > 0.0 && o.keyframe_interval <= 3600.0))
        throw std::invalid_argument("--keyframe-interval must be in (0, 3600] s");
    if (o.io_niceness < 0 || o.io_niceness > 19)
        throw std::invalid_argument("--io-niceness must be in [0, 19]");
    if (o.physics_threads < 1 || o.physics_threads > 256)
        throw std::invalid_argument("--physics-threads must be in [1, 256]");
}

} // namespace

namespace {

std::size_t worker_count(server_options const& o)
{
    check(o);
    return std::max<std::size_t>(o.threads ? o.threads : std::thread::hardware_concurrency(), 1);
}

/// The scene file's bytes, for its fingerprint (load_scene has read and checked it).
std::string read_text(std::filesystem::path const& file)
{
    std::ifstream in(file, std::ios::binary);
    std::stringstream text;
    text << in.rdbuf();
    return text.str();
}

/// A room's own scene, its overrides applied, and the fingerprint of both.
struct room_scene
{
    scene::scene scene;
    std::string fingerprint;
};

/// Loads the scene of `r` with its overrides. A scene_error names the room besides the
/// file, the field and what is wrong with it.
room_scene load_room_scene(room_spec const& r)
{
    try {
        if (r.scene_file.empty())
            return {scene::parse_scene(default_scene_text(), "built-in arena scene", r.overrides),
                    scene_fingerprint(default_scene_text(), r.overrides)};
        scene::scene s = scene::load_scene(r.scene_file, r.overrides);
        return {std::move(s), scene_fingerprint(read_text(r.scene_file), r.overrides)};
    } catch (scene::scene_error const& e) {
        throw scene::scene_error("room '" + r.name + "': " + e.what());
    }
}

/// The room's checkpoint when there is a usable one. One that cannot be used stops the
/// server (checkpoint_error), or with discard_bad_state is moved aside for a fresh start.
std::optional<checkpoint> restore_or_discard(server_options const& options, room_spec const& r,
                                             scene::scene const& s, std::string const& fingerprint)
{
    std::string const& room = r.name;
    std::filesystem::path const file = checkpoint_path(options.state_dir, room);
    try {
        std::optional<checkpoint> c = read_checkpoint(file, room, s.name, fingerprint, r.overrides);
        if (c && c->bodies.size() > options.max_bodies)
            throw checkpoint_error(fmt::format("checkpoint {}: it holds {} bodies, more than --max-bodies {}",
                                               file.string(), c->bodies.size(), options.max_bodies));
        if (c) {
            // A loaded scene the loader refuses and bodies the world refuses are found here
            // too, before anything is started.
            scene::scene const runs = restored_scene(s, *c, file.string());
            (void)restored_world(runs, *c, file.string());
            spdlog::info("room '{}': restored from {}: scene '{}'{}, tick {}, time {} s, {} bodies, "
                         "next id {}",
                         room, file.string(), runs.name, c->loaded_scene ? " (loaded by an admin)" : "",
                         c->tick, c->time, c->bodies.size(), c->next_wire_id);
        } else {
            spdlog::info("room '{}': no checkpoint at {}, starting from the scene", room,
                         file.string());
        }
        return c;
    } catch (checkpoint_error const& e) {
        if (!options.discard_bad_state)
            throw checkpoint_error(std::string(e.what()) +
                                   " (the file is left as it is; --discard-bad-state moves it "
                                   "aside and starts the room from its scene)");
        std::filesystem::path const aside = move_aside(file);
        spdlog::warn("{}; moved it to {} and starting room '{}' from its scene", e.what(),
                     aside.string(), room);
        return std::nullopt;
    }
}

} // namespace

server::server(server_options options) : state_(std::make_unique<state>(worker_count(options)))
{
    state_->shutdown_grace = options.shutdown_grace;
    state_->io_niceness = options.io_niceness;
    room::settings const config{options.tick_rate, options.snapshot_rate, options.max_bodies,
                                options.client, options.state_dir, options.checkpoint_interval,
                                options.physics_threads, options.physics_threads_from,
                                options.position_quantum, options.velocity_quantum,
                                options.keyframe_interval, options.resume_grace,
                                options.remove_bodies_on_leave};
    if (!options.state_dir.empty()) {
        std::error_code ec;
        std::filesystem::create_directories(options.state_dir, ec);
        if (ec || !std::filesystem::is_directory(options.state_dir))
            throw std::invalid_argument("--state " + options.state_dir.string() +
                                        ": not a directory that can be created (" + ec.message() + ")");
    }
    auto const add_room = [&](room_spec const& r) {
        std::string const& name = r.name;
        if (state_->rooms.contains(name))
            throw std::invalid_argument("room '" + name + "' is given twice");
        auto const [s, fingerprint] = load_room_scene(r);
        std::optional<checkpoint> restored;
        if (!options.state_dir.empty())
            restored = restore_or_discard(options, r, s, fingerprint);
        auto& ticks = *state_->room_contexts.emplace_back(std::make_unique<net::io_context>(1));
        state_->room_work.push_back(net::make_work_guard(ticks));
        state_->rooms.emplace(name, std::make_shared<room>(ticks, state_->io.get_executor(), name,
                                                           s, config, fingerprint, r.overrides,
                                                           std::move(restored)));
        std::string overridden;
        for (std::string const& o : r.overrides)
            overridden += (overridden.empty() ? " (with " : ", ") + o;
        spdlog::info("room '{}': scene '{}'{}, {} bodies, dt {} s", name, s.name,
                     overridden.empty() ? "" : overridden + ")", s.body_count(), s.dt);
        // Each tick advances the scene's dt: a tick rate other than 1/dt runs the world faster
        // or slower than the wall clock, which the user should hear about once.
        if (double const speed = options.tick_rate * s.dt; std::abs(speed - 1.0) > 1e-9)
            spdlog::warn("room '{}': {} ticks/s of dt {} s run the world at {:.3g} times real time "
                         "(for real time, give --tick-rate {:.6g} or set the scene's dt to {:.6g} s)",
                         name, options.tick_rate, s.dt, speed, 1.0 / s.dt, 1.0 / options.tick_rate);
    };
    if (options.rooms.empty())
        add_room({"default", {}});
    for (room_spec const& r : options.rooms)
        add_room(r);

    auto routes = std::make_shared<http_routes>();
    // Canonical, so that every file served can be checked to lie inside it (file_for).
    if (!options.web_root.empty())
        routes->web_root = std::filesystem::canonical(options.web_root);
    for (std::string const& origin : options.allowed_origins)
        routes->allowed_origins.push_back(normalized_origin(origin)); // throws for a bad one
    for (std::string const& host : options.allowed_hosts)
        routes->allowed_hosts.push_back(normalized_host(host)); // throws for a bad one
    state* const s = state_.get();
    for (auto const& [name, r] : s->rooms)
        routes->room_names.push_back(name);
    routes->find_room = [s](std::string_view name) -> std::shared_ptr<room> {
        auto const it = s->rooms.find(name);
        return it == s->rooms.end() ? nullptr : it->second;
    };
    client_limits const limits = options.client;
    routes->upgrade = [s, limits, admin_token = options.admin_token](
                          tcp::socket&& socket, std::shared_ptr<room> target,
                          http::request<http::string_body> request) {
        if (s->stopping)
            return; // dropping the socket closes it
        std::make_shared<websocket_session>(std::move(socket), std::move(target), limits,
                                            s->next_client_id++, admin_token)
            ->run(std::move(request));
    };
    routes->health = [s] {
        nlohmann::ordered_json health{{"status", s->stopping ? "stopping" : "ok"}};
        for (auto const& [name, r] : s->rooms) {
            health["rooms"][name] = {{"ticks", r->counters().ticks.load()},
                                     {"bodies", r->counters().bodies.load()},
                                     {"clients", r->counters().sessions.load()},
                                     {"players", r->counters().players.load()},
                                     {"late_ticks", r->counters().late_ticks.load()},
                                     {"step_faults", r->counters().step_faults.load()}};
            if (auto fault = r->last_fault(); !fault.empty())
                health["rooms"][name]["last_fault"] = std::move(fault);
        }
        return health.dump() + "\n";
    };
    routes->metrics = [s] {
        std::vector<std::shared_ptr<room const>> rooms;
        for (auto const& [name, r] : s->rooms)
            rooms.push_back(r);
        return prometheus_metrics(rooms);
    };
    routes->ready = [s] {
        // Every room's scene loaded when the server was made; a room is ready once it ticks.
        bool all_ready = !s->stopping;
        nlohmann::ordered_json rooms = nlohmann::ordered_json::object();
        for (auto const& [name, r] : s->rooms) {
            bool const ticking = r->counters().ticks.load() > 0;
            all_ready = all_ready && ticking;
            rooms[name] = {{"ready", ticking}};
        }
        nlohmann::ordered_json const body{
            {"status", s->stopping ? "stopping" : all_ready ? "ready" : "starting"},
            {"ready", all_ready},
            {"rooms", rooms}};
        return std::pair{all_ready, body.dump() + "\n"};
    };
    auto const address = net::ip::make_address(options.host);
    routes->check_host = (address.is_loopback() || !routes->allowed_hosts.empty()) &&
                         std::ranges::find(routes->allowed_hosts, "*") == routes->allowed_hosts.end();
    state_->acceptor = std::make_shared<listener>(state_->io, tcp::endpoint{address, options.port},
                                                  std::move(routes));
}

server::~server()
{
    stop();
    wait();
}

std::uint16_t server::port() const { return state_->acceptor->port(); }

void server::start()
{
    for (auto& [name, r] : state_->rooms)
        r->start();
    state_->acceptor->run();
    for (std::size_t i = 0; i < state_->thread_count; ++i)
        state_->threads.emplace_back([s = state_.get(), niceness = state_->io_niceness] {
            // Linux gives each thread its own niceness (setpriority on a thread id); raising
            // it needs no privilege.
            if (niceness > 0 && setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), niceness) != 0)
                spdlog::warn("--io-niceness {}: {}", niceness, std::strerror(errno));
            s->io.run();
        });
    for (auto& ticks : state_->room_contexts)
        state_->room_threads.emplace_back([&ticks = *ticks] { ticks.run(); });
}

void server::stop_on_signals()
{
    state_->signals.emplace(state_->io, SIGINT, SIGTERM);
    state_->signals->async_wait([this](beast::error_code ec, int signal) {
        if (ec)
            return;
        spdlog::info("signal {}: shutting down", signal);
        stop();
    });
}

void server::stop()
{
    if (state_->stopping.exchange(true))
        return;
    state* const s = state_.get();
    net::post(s->io, [s] {
        s->acceptor->stop();
        if (s->signals)
            s->signals->cancel();
        for (auto& [name, r] : s->rooms)
            r->stop();
        // Sessions get a moment to finish their close handshakes; idle HTTP keep-alive
        // connections and clients that never answer are then cut off.
        s->grace.emplace(s->io, s->shutdown_grace);
        s->grace->async_wait([s](beast::error_code) { s->io.stop(); });
    });
}

void server::wait()
{
    for (std::thread& t : state_->threads)
        if (t.joinable())
            t.join();
    state_->threads.clear();
    // Nothing posts to the rooms once the sessions' threads have ended; the rooms stopped
    // (their timers are cancelled), so each room's context ends when its queue is empty.
    state_->room_work.clear();
    for (std::thread& t : state_->room_threads)
        if (t.joinable())
            t.join();
    state_->room_threads.clear();
    // The last checkpoint, after every thread ended (the rooms' too): nothing else touches the rooms now,
    // and the joins order their last ticks before this.
    if (state_->stopping && !state_->final_checkpoints_written) {
        state_->final_checkpoints_written = true;
        for (auto& [name, r] : state_->rooms)
            if (r->write_checkpoint())
                spdlog::info("room '{}': final checkpoint at tick {}", name, r->counters().ticks.load());
    }
}

std::shared_ptr<room> server::find_room(std::string_view name) const
{
    auto const it = state_->rooms.find(name);
    return it == state_->rooms.end() ? nullptr : it->second;
}

} // namespace kugel::server
