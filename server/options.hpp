#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace kugel::server {

/// A room to host: `--room NAME=SCENE`, with its `--set NAME:PATH=VALUE` overrides.
struct room_spec
{
    std::string name;                 ///< the room's name, as in /ws/NAME
    std::filesystem::path scene_file; ///< its scene (JSON); empty: the built-in arena scene
    /// PATH=VALUE, applied to the scene in order before it is validated, as the headless
    /// `--set` does (scene::parse_scene). They are part of the room's scene: its checkpoints
    /// record them, and restore only into a room started with the same ones.
    std::vector<std::string> overrides = {};
};

/// What one client may do. Every limit has a clear answer when reached (protocol/PROTOCOL.md).
struct client_limits
{
    std::size_t max_message_bytes = 64 * 1024; ///< inbound frame size; larger: close 1009
    double commands_per_second = 200.0;         ///< sustained; larger: error rate_limited
    double command_burst = 200.0;               ///< commands allowed at once after a pause
    std::size_t max_queued_replies = 256;       ///< acks and errors not yet sent; more: close 1008
    /// Sensor events not yet sent; more are dropped and counted (the next one sent says how
    /// many in `missed`). Never a reason to close.
    std::size_t max_queued_events = 256;
    /// Bodies one connection spawned that may exist at once; a spawn beyond it: error
    /// too_many_bodies. 0: no cap. Admins are exempt.
    std::size_t max_bodies_per_client = 1000;
    std::chrono::milliseconds write_stall{5000}; ///< a send pending this long: the client is
                                                 ///< not reading, and is disconnected
    /// The kernel's send buffer per connection (SO_SNDBUF; Linux doubles it). Bounds what a
    /// client that stopped reading holds in the kernel, and so how soon its send is pending
    /// and write_stall can see it: with the kernel's own tuning that is up to 4 MB, minutes
    /// of a small room's snapshots. 0: the kernel's tuning.
    std::size_t send_buffer_bytes = 256 * 1024;
};

struct server_options
{
    /// Only this machine can connect unless told otherwise (0.0.0.0 or :: opens the server).
    std::string host = "127.0.0.1";
    std::uint16_t port = 8080;   ///< 0 picks a free port (tests)
    double tick_rate = 60.0;     ///< Hz, world steps per second of wall time
    double snapshot_rate = 30.0; ///< Hz, <= tick_rate
    /// m and m/s: the compact snapshots' quanta in every room; 0 chooses them from each
    /// room's scene.
    double position_quantum = 0.0;
    double velocity_quantum = 0.0;
    double keyframe_interval = 10.0; ///< s: a compact stream's keyframes at least this often
    std::filesystem::path web_root; ///< static files served over HTTP; empty serves none
    std::vector<room_spec> rooms;   ///< empty: one room "default" with the built-in scene
    std::size_t max_bodies = 20'000; ///< per room; a spawn beyond it: error room_full
    std::size_t threads = 0;         ///< 0: one per core
    /// Niceness of those threads (0–19): above 0 they yield the processor to the rooms'
    /// ticks when both want it, so that fanning snapshots out never makes a tick late.
    int io_niceness = 0;
    /// Threads that step each room's world, its tick thread counted (room::settings).
    std::size_t physics_threads = 1;
    /// Bodies from which a room's world uses them; fewer are stepped on the room's thread
    /// alone (waking the others costs more than it saves). Default
    /// physics::world::bodies_worth_sharing (16,384; server.cpp checks they agree).
    static constexpr std::size_t default_physics_threads_from = 16 * 1024;
    std::size_t physics_threads_from = default_physics_threads_from;
    /// After a stop, how long closing handshakes may take before the rest is cut off.
    std::chrono::milliseconds shutdown_grace{1000};
    client_limits client;
    /// Where each room's checkpoint lives (DIR/ROOM.json); empty: no persistence.
    std::filesystem::path state_dir;
    std::chrono::milliseconds checkpoint_interval{5000}; ///< between checkpoints, > 0
    /// A checkpoint that cannot be used is moved aside (ROOM.json.bad-<time>) and the room
    /// starts fresh; without this the server refuses to start.
    bool discard_bad_state = false;
    /// Browser origins, besides the server's own, whose pages may open a WebSocket
    /// (scheme://host[:port], or "*" for every origin). Upgrades without Origin (programs,
    /// not browsers) are always let in.
    std::vector<std::string> allowed_origins;
    /// Host names, besides loopback ones, that a server listening on loopback answers
    /// (normalized_host's form, or "*" for every host); with any given, a server on another
    /// address checks hosts too. Other requests get HTTP 403 (DNS rebinding).
    std::vector<std::string> allowed_hosts;
    /// What a hello's admin_token must be for the connection to be an admin (pause, resume,
    /// reset, load_scene, remove any body); empty: nobody is an admin.
    std::string admin_token;
    /// Players, in every room whose scene does not set them (its `players`, which wins):
    /// seconds a player whose connection ended is kept for a hello.resume (0: none), and
    /// whether its bodies are removed when it leaves for good (else they stay).
    double resume_grace = 0.0;
    bool remove_bodies_on_leave = false;
};

} // namespace kugel::server
