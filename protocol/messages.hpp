#pragma once

// The messages of the Kugel wire protocol as plain structs. PROTOCOL.md describes them for
// client authors; codec.hpp turns them into JSON text and back. Units are SI.

#include "protocol/error_code.hpp"

#include <array>
#include <cstddef>
#include <cstdint>
#include <numbers>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

namespace kugel::protocol {

/// The version this code speaks: `hello.protocol` and `welcome.protocol`.
inline constexpr int protocol_version = 1;

/// 2^53 − 1, the largest integer a double (and so JavaScript) holds exactly. Refs, body ids,
/// client ids and ticks never exceed it.
inline constexpr std::uint64_t max_safe_integer = (std::uint64_t{1} << 53) - 1;

/// m/s. No body may move this fast or faster: a spawn's velocity and the velocity an impulse
/// gives must be slower. A speed limit far above any scene's keeps every position finite
/// (a speed near the largest double would overflow a position within a few ticks).
inline constexpr double speed_of_light = 299'792'458.0;

using vec3 = std::array<double, 3>;

// Client -> server --------------------------------------------------------------------------

/// Optional first message: which protocol the client speaks, a name for logs, and the
/// admin token that makes this connection an admin.
/// What a client asks of the snapshots it is sent (hello.snapshots).
struct snapshot_request
{
    /// "full" (every body in full, the default) or "compact" (quantized keyframes and
    /// deltas, compact.hpp); absent keeps the form the connection has.
    std::optional<std::string> form;
    /// Hz, > 0: at most this many snapshots a second; absent or above the room's rate: the
    /// room's rate.
    std::optional<double> rate;

    bool operator==(snapshot_request const&) const = default;
};

/// The longest sensor name, in bytes of UTF-8 (a scene's sensors[].name).
inline constexpr std::size_t max_sensor_name_bytes = 32;
/// The most entries one list of an event subscription may hold.
inline constexpr std::size_t max_event_filter_entries = 64;

/// Which sensor events a connection wants (hello.events as an object): an event is sent
/// when it matches every list given; a list left out matches every event. A list given
/// holds 1 to max_event_filter_entries entries.
struct event_filter
{
    std::optional<std::vector<std::string>> sensors; ///< sensor names of the room's scene
    std::optional<std::vector<std::string>> tags;    ///< body tags; an untagged body matches none
    std::optional<std::vector<std::string>> kinds;   ///< "entered", "left", "contact"

    bool operator==(event_filter const&) const = default;
};

/// hello.events: `true` (every event), `false` (none, the start of every connection) or an
/// event_filter object (the events it matches). Each replaces the one before.
struct event_request
{
    bool on = true;      ///< false: no events
    event_filter filter; ///< when on; all lists absent: every event

    bool operator==(event_request const&) const = default;
};

/// m: the largest radius of an `around` interest. Far beyond any world a room steps, and
/// small enough that (radius + a body's radius)² stays a finite double.
inline constexpr double max_interest_radius = 1e15;
/// The most tags one interest may list.
inline constexpr std::size_t max_interest_tags = 64;

/// An axis-aligned box of an interest: the points with min <= x <= max on every axis.
struct interest_box
{
    vec3 min{}; ///< m
    vec3 max{}; ///< m, >= min on every axis

    bool operator==(interest_box const&) const = default;
};

/// A ball of an interest around a body it follows: its centre is the body's, wherever the
/// body moves; once the body is gone, where the room's last snapshot showed it.
struct interest_around
{
    std::uint64_t body = 0; ///< the body's id, as in snapshots
    double radius = 0.0;    ///< m, > 0 and <= max_interest_radius

    bool operator==(interest_around const&) const = default;
};

/// What of the world a connection is sent (hello.interest, the interest command): the bodies
/// that touch its region (a box, or a ball around a body) and carry one of its tags. A part
/// left out matches every body; none given is no interest: every body, as at the start.
/// At most one region.
struct interest_filter
{
    std::optional<interest_box> box;
    std::optional<interest_around> around;
    /// 1 to max_interest_tags body tags; an untagged body matches none
    std::optional<std::vector<std::string>> tags;

    /// No part given: the connection is sent every body.
    bool everything() const { return !box && !around && !tags; }
    bool operator==(interest_filter const&) const = default;
};

/// The longest player name, in bytes of UTF-8.
inline constexpr std::size_t max_player_name_bytes = 64;
/// The longest hello.resume read, in bytes: a server's tokens are far shorter (kugel-server's
/// are 32 hex digits), and a longer one is refused before any token is compared.
inline constexpr std::size_t max_resume_token_bytes = 128;

/// Optional first message: which protocol the client speaks, the player's name (shown to
/// the room's other players; a later hello renames), the admin token that makes this
/// connection an admin, and the snapshots it wants.
struct hello
{
    static constexpr std::string_view type = "hello";
    std::optional<int> protocol; ///< must be protocol_version when given
    /// 1 to max_player_name_bytes bytes, no control characters
    std::optional<std::string> name;
    std::optional<std::string> admin_token; ///< the server's --admin-token; never logged
    std::optional<snapshot_request> snapshots;
    /// false: send this connection no player messages (a load generator, a bot that needs no
    /// presence); true: send them again, starting with the roster. Absent keeps what it was
    /// (every connection starts hearing them).
    std::optional<bool> players;
    /// A welcome's resume_token: this connection becomes that player again (its id, name and
    /// bodies), answered by a new welcome; 1 to max_resume_token_bytes bytes. Never logged.
    std::optional<std::string> resume;
    /// The sensor events this connection is sent (`event` messages); absent keeps what it
    /// was (a connection starts with none). Answered by nothing, or a bad_value error.
    std::optional<event_request> events;
    /// What of the world this connection is sent, from the next tick on (the interest
    /// command's region and tags); absent keeps it, `{}` clears it. Answered by nothing, or
    /// an error.
    std::optional<interest_filter> interest;

    bool operator==(hello const&) const = default;
};

/// The longest body tag, in bytes of UTF-8.
inline constexpr std::size_t max_body_tag_bytes = 32;

/// A body to create. Decoding guarantees exactly one of mass and density is set.
struct body_spec
{
    vec3 position{};               ///< m
    vec3 velocity{};               ///< m/s, speed below speed_of_light
    double radius = 0.0;           ///< m, >= 0; 0 is a point mass, which never collides
    std::optional<double> mass;    ///< kg, > 0
    std::optional<double> density; ///< kg/m³, > 0; needs radius > 0; mass = density·4/3·π·r³
    double charge = 0.0;           ///< C
    /// A short label shown with the body: 1 to max_body_tag_bytes bytes, no control characters
    std::optional<std::string> tag;
    /// Never moves (inverse mass 0): an obstacle. Only an admin may spawn one; velocity zero.
    bool is_static = false;

    bool operator==(body_spec const&) const = default;
};

/// The mass a spawn's body has: its mass, or density · 4/3 · π · radius³ (the engine's
/// formula, to the bit).
inline double mass_of(body_spec const& body)
{
    if (body.mass)
        return *body.mass;
    double const r = body.radius;
    return body.density.value_or(0.0) * 4.0 / 3.0 * std::numbers::pi * r * r * r;
}

struct spawn
{
    static constexpr std::string_view type = "spawn";
    std::uint64_t ref = 0; ///< chosen by the client, <= max_safe_integer; echoed in the reply
    body_spec body;

    bool operator==(spawn const&) const = default;
};

/// Change a body's velocity by impulse / mass.
struct impulse
{
    static constexpr std::string_view type = "impulse";
    std::uint64_t ref = 0;
    std::uint64_t id = 0; ///< the body, as in snapshot ids
    vec3 impulse{};       ///< N·s (kg·m/s)

    bool operator==(struct impulse const&) const = default;
};

/// Set a body's position and/or velocity (at least one) at the start of the next tick.
struct set
{
    static constexpr std::string_view type = "set";
    std::uint64_t ref = 0;
    std::uint64_t id = 0;
    std::optional<vec3> position; ///< m
    std::optional<vec3> velocity; ///< m/s, speed below speed_of_light

    bool operator==(set const&) const = default;
};

struct remove
{
    static constexpr std::string_view type = "remove";
    std::uint64_t ref = 0;
    std::uint64_t id = 0;

    bool operator==(remove const&) const = default;
};

struct ping
{
    static constexpr std::string_view type = "ping";
    std::uint64_t ref = 0;

    bool operator==(ping const&) const = default;
};

// Admin commands: only a connection whose hello carried the server's admin token may send
// them; anyone else gets `forbidden`.

/// Stop stepping the world: ticks go on (commands still apply), simulated time stands still.
struct pause
{
    static constexpr std::string_view type = "pause";
    std::uint64_t ref = 0;

    bool operator==(pause const&) const = default;
};

/// Step the world again after a pause.
struct resume
{
    static constexpr std::string_view type = "resume";
    std::uint64_t ref = 0;

    bool operator==(resume const&) const = default;
};

/// Put the room's scene back as it was loaded: its bodies (under new ids), every spawned
/// body gone. Simulated time and ticks go on.
struct reset
{
    static constexpr std::string_view type = "reset";
    std::uint64_t ref = 0;

    bool operator==(reset const&) const = default;
};

/// A JSON object carried as its text. The protocol does not look inside: a scene is read by
/// the server's scene loader, which names what is wrong with it.
struct json_object
{
    std::string text; ///< one JSON object, as decode() gives it

    bool operator==(json_object const&) const = default;
};

/// Replace the room's world by a scene (the format of a scene file, inline).
struct load_scene
{
    static constexpr std::string_view type = "load_scene";
    std::uint64_t ref = 0;
    json_object scene;

    bool operator==(load_scene const&) const = default;
};

/// Narrow (or widen) what of the world this connection is sent, from the snapshot of the
/// tick it is applied in: the bodies inside a region (`box` or `around`, not both) and with
/// one of `tags`. None of the three clears the interest: every body again.
struct interest
{
    static constexpr std::string_view type = "interest";
    std::uint64_t ref = 0;
    std::optional<interest_box> box;
    std::optional<interest_around> around;
    std::optional<std::vector<std::string>> tags;

    interest_filter filter() const { return {box, around, tags}; }
    bool operator==(interest const&) const = default;
};

using client_message =
    std::variant<hello, spawn, impulse, remove, ping, pause, resume, reset, load_scene, set, interest>;

// Server -> client --------------------------------------------------------------------------

/// The plane normal · x = offset; the normal points to where bodies may be.
struct wall
{
    vec3 normal{};         ///< unit vector
    double offset = 0.0;   ///< m
    double damping = 0.0;  ///< 0..1, normal speed lost in a bounce
    double friction = 0.0; ///< 0..1, tangential speed lost in a bounce

    bool operator==(wall const&) const = default;
};

/// A static box: centre + Σ s_i·half_extents[i]·axes[i] for s_i in [−1, 1].
struct obstacle
{
    vec3 centre{};              ///< m
    vec3 half_extents{};        ///< m, >= 0
    std::array<vec3, 3> axes{}; ///< unit vectors, the columns of the box's rotation

    bool operator==(obstacle const&) const = default;
};

/// The sphere holding the scene's bodies (as they start), obstacles and box: what a client
/// frames its camera on.
struct world_bounds
{
    vec3 centre{};       ///< m
    double radius = 0.0; ///< m

    bool operator==(world_bounds const&) const = default;
};

/// The static geometry of the room's scene.
struct scene_geometry
{
    std::string name;
    std::vector<wall> walls;
    std::vector<obstacle> obstacles;
    world_bounds bounds;

    bool operator==(scene_geometry const&) const = default;
};

struct session_limits
{
    std::uint64_t max_message_bytes = 0;   ///< longer frames close the connection (1009)
    std::uint64_t max_bodies = 0;          ///< a spawn beyond it gets room_full
    std::uint64_t commands_per_second = 0; ///< more get rate_limited
    /// Bodies this connection spawned that may exist at once (more: too_many_bodies);
    /// absent when no such cap applies to it (none is set, or the client is an admin).
    std::optional<std::uint64_t> max_bodies_per_client;
    /// Events a connection may have unsent; more are dropped and counted (event.missed).
    std::uint64_t max_queued_events = 0;

    bool operator==(session_limits const&) const = default;
};

/// Who may act on whose bodies in a room (its scene's `permissions`). An admin always may.
struct room_permissions
{
    /// impulse and set: "anyone", "owner" (the client that spawned the body) or "admins"
    std::string push = "anyone";
    /// remove: "owner" or "admins"
    std::string remove = "owner";

    bool operator==(room_permissions const&) const = default;
};

/// The snapshots a connection is sent: the answer to hello.snapshots.
struct snapshot_stream
{
    std::string form;              ///< "full" or "compact"
    double rate = 0.0;             ///< Hz: the room's snapshot rate, or an integer part of it
    double position_quantum = 0.0; ///< m, > 0: a compact position is an integer times this
    double velocity_quantum = 0.0; ///< m/s, > 0
    double keyframe_interval = 0.0; ///< s, > 0: a compact stream has a keyframe at least this often

    bool operator==(snapshot_stream const&) const = default;
};

/// The server's first message on every connection, and again whenever what it says changes
/// (the client became an admin, an admin loaded another scene).
struct welcome
{
    static constexpr std::string_view type = "welcome";
    int protocol = protocol_version;
    std::uint64_t client = 0; ///< this connection's id in the room
    std::string room;
    double tick_rate = 0.0;     ///< Hz
    double dt = 0.0;            ///< s of simulated time per tick
    double snapshot_rate = 0.0; ///< Hz
    scene_geometry scene;
    session_limits limits;
    bool admin = false; ///< this connection may send admin commands
    room_permissions permissions; ///< who may push and remove whose bodies here
    /// What this connection's snapshots are; only in a welcome answering hello.snapshots.
    std::optional<snapshot_stream> snapshots;
    /// s: how long the room keeps a player whose connection ended, for a hello.resume to
    /// take up; 0: not at all (the player leaves with its connection).
    double resume_grace = 0.0;
    /// What becomes of a player's bodies when it leaves for good: "stay" or "remove".
    std::string bodies_on_leave = "stay";
    /// This player's secret for hello.resume, only while resume_grace > 0; a new one after
    /// each resume. Never logged.
    std::optional<std::string> resume_token;

    bool operator==(welcome const&) const = default;
};

/// A command took effect.
struct ack
{
    static constexpr std::string_view type = "ack";
    std::uint64_t ref = 0;
    std::uint64_t tick = 0;          ///< the tick at whose start it was applied
    std::optional<std::uint64_t> id; ///< the new body, for a spawn

    bool operator==(ack const&) const = default;
};

/// A message was refused. Also what decode() gives for text it cannot accept.
struct error
{
    static constexpr std::string_view type = "error";
    std::optional<std::uint64_t> ref; ///< the command's ref, when it could be read
    error_code code = error_code::bad_message;
    std::string message; ///< for people: the field (a JSON pointer) and what was wrong

    bool operator==(error const&) const = default;
};

/// Every body at one tick, as columns: entry i of each column belongs to body i.
struct body_columns
{
    std::vector<std::uint64_t> id;
    std::vector<double> position;              ///< m, 3 per body: x0 y0 z0 x1 y1 z1 ...
    std::vector<double> velocity;              ///< m/s, 3 per body
    std::vector<double> radius;                ///< m
    std::optional<std::vector<double>> mass;   ///< kg, when the scene has masses to show
    std::optional<std::vector<double>> charge; ///< C, when the scene has charges
    /// Each body's tag, "" for none; only when some body has one
    std::optional<std::vector<std::string>> tag;

    std::size_t size() const { return id.size(); }
    bool operator==(body_columns const&) const = default;
};

struct snapshot
{
    static constexpr std::string_view type = "snapshot";
    std::uint64_t tick = 0; ///< ticks completed
    double time = 0.0;      ///< s of simulated time
    bool paused = false;    ///< an admin paused the room: ticks go on, time stands still
    /// Steps the room could not take, and recovered from by removing the bodies that made
    /// them impossible, since it started; written only when > 0.
    std::uint64_t faults = 0;
    body_columns bodies;

    bool operator==(snapshot const&) const = default;
};

struct pong
{
    static constexpr std::string_view type = "pong";
    std::uint64_t ref = 0;
    std::uint64_t tick = 0; ///< the tick the server was at when it answered
    /// ms the room's last tick took (its commands, its step, a snapshot's copy); absent
    /// before the first tick
    std::optional<double> tick_ms;

    bool operator==(pong const&) const = default;
};

/// The bodies of a compact snapshot (PROTOCOL.md, compact snapshots): sorted by id, each
/// position and velocity an integer number of quanta. On the wire `id` is gap-coded (the
/// first id, then each id less the one before); here it holds the ids themselves.
struct compact_bodies
{
    std::vector<std::uint64_t> id;      ///< strictly increasing
    std::vector<std::int64_t> position; ///< position quanta, 3 per body
    std::vector<std::int64_t> velocity; ///< velocity quanta, 3 per body
    std::vector<double> radius;         ///< m
    std::vector<double> mass;           ///< kg
    std::optional<std::vector<double>> charge; ///< C, when the scene has charges
    std::vector<std::uint64_t> owner;   ///< the client that spawned it; 0: the scene's
    /// Each body's tag, "" for none; only when some body here has one
    std::optional<std::vector<std::string>> tag;

    std::size_t size() const { return id.size(); }
    bool operator==(compact_bodies const&) const = default;
};

/// The bodies of a delta's base whose quantized state changed: `runs` alternates how many
/// of the base's bodies (in id order) to skip and how many moved, and `position` holds each
/// moved body's position less its prediction, `velocity` its velocity less the base's.
struct compact_moves
{
    std::vector<std::uint64_t> runs;
    std::vector<std::int64_t> position; ///< 3 per moved body
    std::vector<std::int64_t> velocity; ///< 3 per moved body

    bool operator==(compact_moves const&) const = default;
};

/// A snapshot in the compact form: a keyframe (`form` "key": every body, its constants and
/// the quanta) or a delta against the snapshot of tick `base` (`form` "delta": the bodies
/// that moved, appeared and vanished since). A client applies it with apply_compact().
struct compact_snapshot
{
    static constexpr std::string_view type = "snapshot";
    std::uint64_t tick = 0;
    std::string form;       ///< "key" or "delta"
    std::optional<std::uint64_t> base; ///< delta: the tick it applies to (< tick)
    double time = 0.0;      ///< s
    bool paused = false;
    std::uint64_t faults = 0;
    /// key: [position quantum (m), velocity quantum (m/s)]; a delta has its base's
    std::optional<std::array<double, 2>> q;
    std::optional<compact_bodies> bodies;   ///< key: every body
    std::optional<compact_moves> moved;     ///< delta
    std::optional<compact_bodies> appeared; ///< delta: bodies not in the base
    std::optional<std::vector<std::uint64_t>> vanished; ///< delta: base ids gone (gap-coded on the wire)

    bool operator==(compact_snapshot const&) const = default;
};

/// A player of a room: one connection, known by its welcome.client id and the name its
/// hello gave.
struct player
{
    std::uint64_t id = 0;
    std::optional<std::string> name; ///< absent until a hello names it
    /// true: its connection ended and the room keeps it for a resume (its grace); absent: it
    /// is connected.
    std::optional<bool> away;

    bool operator==(player const&) const = default;
};

/// Who is in the room, the receiver too: sent after a client's first welcome.
struct roster
{
    static constexpr std::string_view type = "players";
    std::vector<player> players; ///< by id

    bool operator==(roster const&) const = default;
};

/// A player joined, was renamed (a hello with a name), went away (its connection ended, and
/// the room keeps it for a resume), came back (a resume) or left: sent to every other client
/// of the room, and a rename to the renamed one too.
struct player_notice
{
    static constexpr std::string_view type = "player";
    std::string change; ///< "joined", "renamed", "away", "back" or "left"
    std::uint64_t id = 0;
    std::optional<std::string> name;

    bool operator==(player_notice const&) const = default;
};

/// A body's centre entered or left one of the scene's sensors during a tick's step: sent to
/// the connections whose hello.events it matches, ahead of that tick's snapshot.
struct event
{
    static constexpr std::string_view type = "event";
    std::uint64_t tick = 0;  ///< the tick whose step it happened in (its snapshot's tick)
    double time = 0.0;       ///< s: the world time it happened, inside that step
    /// "entered" or "left" (a body crossed a sensor's boundary), or "contact" (two bodies
    /// began to touch)
    std::string kind;
    std::optional<std::string> sensor;   ///< entered, left: the sensor's name
    std::optional<std::uint64_t> body;   ///< entered, left: the body's id, as in snapshots
    std::optional<std::string> tag;      ///< entered, left: the body's tag, when it has one
    /// entered, left: the client that spawned the body, when one did (its welcome.client)
    std::optional<std::uint64_t> owner;
    std::optional<std::vector<std::uint64_t>> bodies; ///< contact: the two bodies' ids, ascending
    std::optional<std::vector<std::string>> tags;     ///< contact: their tags, in that order
    /// Events this connection was not sent since the last one it was (its queue of unsent
    /// events was full); absent when none.
    std::optional<std::uint64_t> missed;

    bool operator==(event const&) const = default;
};

using server_message =
    std::variant<welcome, ack, error, snapshot, pong, compact_snapshot, roster, player_notice, event>;

} // namespace kugel::protocol
