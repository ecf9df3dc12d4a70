#pragma once

// A connection to one room of a Kugel server, for programs on the user's thread: connect,
// send commands (each gets a ref), await the answer to a ref, take snapshots as they come
// or wait until one satisfies a predicate, close. protocol/PROTOCOL.md is the conversation;
// every message goes through kugel_protocol's codec.

#include "client/latency_histogram.hpp"
#include "protocol/messages.hpp"

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <variant>
#include <vector>

namespace kugel::client {

/// A command: what the server answers with an ack (or pong) or an error carrying its ref.
/// The admin commands are answered `forbidden` unless the connection's hello made it an admin.
/// A `set` (a body's new position and/or velocity) is allowed by the room's push rule
/// (welcome().permissions), as an impulse is; a spawn's body may carry a tag, and an admin's a
/// `static` flag. An `interest` narrows the snapshots to a region and tags from the tick its ack
/// names (one without region or tags clears it).
using command = std::variant<protocol::spawn, protocol::impulse, protocol::remove, protocol::ping,
                             protocol::pause, protocol::resume, protocol::reset,
                             protocol::load_scene, protocol::set, protocol::interest>;

/// The server's answer to a command.
using reply = std::variant<protocol::ack, protocol::error, protocol::pong>;

/// The ref a reply carries, if any (an error for unreadable text may have none).
std::optional<std::uint64_t> ref_of(reply const& r);

/// The connection could not be made, or was lost where an answer was needed.
class connection_error : public std::runtime_error
{
public:
    using std::runtime_error::runtime_error;
};

struct connection_options
{
    /// Sent in a `hello` right after the welcome (the server logs it); empty (and no
    /// `snapshots`) sends no hello.
    std::string name = "kugel-client";
    /// The snapshots to ask for in the hello; nullopt asks for nothing (the full form, exact
    /// doubles: what scripts that compare values need). The compact form is decoded into the
    /// full form's columns, positions and velocities to the quanta the welcome announces
    /// (PROTOCOL.md); `kugel-client watch` and `load` ask for it.
    std::optional<protocol::snapshot_request> snapshots;
    /// A welcome's resume_token (resume_token() of an earlier connection): sent in the hello,
    /// so that this connection becomes that player again (its id, name and bodies) while the
    /// room still keeps it (PROTOCOL.md, resuming). The constructor waits for the answer:
    /// resumed() says whether it took; when it did not, resume_refusal() says why and the
    /// connection goes on as the fresh player its first welcome named.
    std::optional<std::string> resume_token;
    /// The sensor events to ask for in the hello (PROTOCOL.md, hello.events); nullopt asks
    /// for none. They are read with next_event.
    std::optional<protocol::event_request> events;
    /// What of the world to be sent, stated in the hello (PROTOCOL.md, interest): the bodies
    /// touching a box or a ball around a body, with one of some tags. nullopt asks for every
    /// body. A refusal (an unknown body to follow) comes as an error without a ref
    /// (next_unmatched_reply); the interest command changes it later.
    std::optional<protocol::interest_filter> interest;
    /// Sensor events received and not yet taken; a full queue drops its oldest.
    std::size_t kept_events = 4096;
    /// How long connecting (resolve, TCP, upgrade) and the welcome may take.
    std::chrono::milliseconds connect_timeout{10'000};
    /// Snapshots received and not yet taken; a full queue drops its oldest.
    std::size_t snapshot_queue = 256;
    /// The longest message read; a longer one ends the connection. A snapshot takes about
    /// 170 bytes per body.
    std::size_t max_message_bytes = 64 * 1024 * 1024;
    /// Messages given to send() and not yet written; a send beyond it throws.
    std::size_t max_unsent = 4096;
    /// Answers to this connection's refs kept for await_reply; beyond it the oldest go.
    std::size_t kept_replies = 4096;
    /// false: the hello asks the server for no player messages (players() stays as the roster
    /// after the welcome; no notices come): for load generators, whose thousand clients would
    /// otherwise each be told of every other's coming and going.
    bool players = true;
    /// Player notices (joined, renamed, left) kept for next_player_notice; beyond it the
    /// oldest go.
    std::size_t kept_player_notices = 256;
    /// Answers that match none of this connection's refs (to send_text, mostly) kept for
    /// next_unmatched_reply; beyond it the oldest go.
    std::size_t kept_unmatched_replies = 256;
    /// Snapshots are only counted (stats: snapshots, ticks, gaps): the tick is found in the
    /// text by a search and the snapshot is neither decoded nor kept, so next_snapshot,
    /// wait_for_snapshot and on_snapshot get none. For load generators, whose clients
    /// would otherwise spend more on decoding a large snapshot than the server spends on
    /// encoding it once for all of them.
    bool snapshot_ticks_only = false;
    /// When set, called with every snapshot it can keep up with, on a thread of its own
    /// (never the I/O thread): a newer snapshot replaces one it has not reached yet. It may
    /// call the connection, but must not destroy it.
    std::function<void(std::shared_ptr<protocol::snapshot const> const&)> on_snapshot;
};

/// How a connection ended.
struct close_info
{
    std::uint16_t code = 0; ///< the close frame's code (1000, 1001, 1008, 1009); 0: none, the
                            ///< connection just ended
    std::string reason;     ///< the close frame's reason, or what went wrong
    bool by_server = false; ///< the server ended it (false: this side called close())
};

/// What a connection counted since it opened. Counted on the I/O thread as messages
/// arrive, so nothing here depends on how fast the user takes them.
struct connection_stats
{
    std::chrono::steady_clock::time_point opened; ///< when the welcome arrived
    std::uint64_t messages_received = 0;
    std::uint64_t bytes_received = 0; ///< payload bytes of every message read
    std::uint64_t messages_sent = 0;
    std::uint64_t bytes_sent = 0; ///< payload bytes of every message written

    std::uint64_t snapshots = 0;
    std::uint64_t snapshots_dropped = 0; ///< fell out of the full snapshot queue untaken
    std::uint64_t first_tick = 0;        ///< of the first snapshot
    std::uint64_t last_tick = 0;         ///< of the latest snapshot
    std::uint64_t tick_gap_min = 0;      ///< ticks between consecutive snapshots
    std::uint64_t tick_gap_max = 0;
    std::uint64_t tick_gaps = 0; ///< consecutive pairs counted
    /// Gaps longer than the server's own (ceil(tick_rate / snapshot_rate)): snapshots the
    /// server replaced because this client had not taken the previous one yet.
    std::uint64_t late_snapshots = 0;

    std::uint64_t commands_sent = 0;
    std::uint64_t acks = 0;
    std::uint64_t pongs = 0;
    std::uint64_t events = 0;        ///< sensor events received
    std::uint64_t events_missed = 0; ///< events the server dropped for this connection (their `missed`)
    std::map<std::string, std::uint64_t> errors; ///< by wire code: "unknown_body": 2
    latency_histogram ack_latency;               ///< send to ack, per acked command
    latency_histogram pong_latency;              ///< send to pong

    std::uint64_t ignored = 0;     ///< messages of types this client does not know
    std::uint64_t undecodable = 0; ///< messages the codec refused
    std::string last_undecodable;  ///< the codec's reason for the latest
};

/// Why wait_for_snapshot returned.
enum class wait_outcome {
    matched,    ///< a snapshot satisfied the predicate
    past_limit, ///< a snapshot came after the tick limit and none had satisfied it
    timed_out,  ///< the wall-clock timeout passed first
    closed,     ///< the connection ended first
};

struct snapshot_wait
{
    wait_outcome outcome = wait_outcome::timed_out;
    /// The snapshot that satisfied the predicate, else the last one looked at (may be null).
    std::shared_ptr<protocol::snapshot const> snapshot;
};

/// A few I/O threads that many connections share, for a program that holds hundreds of
/// them (kugel-client load): a connection made with it runs on one of its threads (in turn)
/// instead of a thread of its own. Must outlive every connection made with it.
class io_threads
{
public:
    /// `count` threads, at least 1.
    explicit io_threads(std::size_t count);
    /// Stops and joins the threads.
    ~io_threads();
    io_threads(io_threads const&) = delete;
    io_threads& operator=(io_threads const&) = delete;

private:
    friend class connection;
    struct pool;
    std::unique_ptr<pool> pool_;
};

/// One WebSocket connection to a room, with an I/O thread of its own (or one of an
/// io_threads'). Every public function
/// may be called from any thread; none runs user code on the I/O thread, which only reads,
/// decodes, counts and hands over (snapshots through a bounded queue, answers by ref).
class connection
{
public:
    using clock = std::chrono::steady_clock;

    /// Connects to `url` (ws://host:port/ws/ROOM), waits for the welcome, and says hello.
    /// Throws url_error for a bad URL and connection_error when the server cannot be reached,
    /// refuses the upgrade (no such room), or sends no welcome in time.
    explicit connection(std::string const& url, connection_options options = {});
    /// The same, on one of `shared`'s threads.
    connection(std::string const& url, connection_options options, io_threads& shared);
    /// Closes (1000) if still open and waits for the I/O thread (its own).
    ~connection();
    connection(connection const&) = delete;
    connection& operator=(connection const&) = delete;

    /// The server's newest welcome (a new one comes after a hello that makes this connection
    /// an admin, and after an admin loads another scene): room, tick rate, dt, the scene's
    /// geometry, the limits. A copy, since the connection's thread may replace it.
    protocol::welcome welcome() const;
    /// The newest welcome's resume_token: what a later connection gives as
    /// connection_options::resume_token to become this player again. Nothing when the room
    /// keeps no player for a resume (its resume_grace is 0). A secret: do not log it.
    std::optional<std::string> resume_token() const;
    /// Whether the resume this connection was opened with took: welcome().client is then the
    /// player resumed.
    bool resumed() const;
    /// The error that refused this connection's resume (bad_resume, mostly); nothing when it
    /// took or none was asked.
    std::optional<protocol::error> resume_refusal() const;

    /// Sends a command with a fresh ref (1, 2, 3, ...: whatever ref it carries is replaced)
    /// and returns that ref. Throws connection_error once the connection has ended.
    std::uint64_t send(command c);
    /// Sends a hello (it has no ref and is answered only when refused).
    void send(protocol::hello const& h);
    /// Sends text as it is: for testing how the server answers what it cannot read. Its
    /// answer, if any, is read with next_unmatched_reply (give it a ref far from this
    /// connection's own, or none, so that it cannot be taken for the answer to a send).
    void send_text(std::string text);

    /// The answer to `ref`, once it arrives; nullopt when none comes within `timeout` or the
    /// connection ends first. Each answer is handed out once.
    std::optional<reply> await_reply(std::uint64_t ref, std::chrono::milliseconds timeout);
    /// The ids of the bodies this connection's spawns made (from their acks), in that order,
    /// less those remove_spawned() has seen gone.
    std::vector<std::uint64_t> spawned() const;
    /// Removes every body of spawned(): a `remove` for each, and waits up to `timeout` in all
    /// for the answers. Returns how many it removed; a body removed before (by this
    /// connection, an admin or a reset) is answered unknown_body and dropped from the list.
    std::size_t remove_spawned(std::chrono::milliseconds timeout);
    /// The oldest answer that matches no ref this connection sent (for send_text), waiting up
    /// to `timeout` for one.
    std::optional<reply> next_unmatched_reply(std::chrono::milliseconds timeout);

    /// The room's players as this connection last heard (the roster sent after its welcome,
    /// then each notice), this connection's own among them, by id.
    std::vector<protocol::player> players() const;
    /// The oldest player notice (another player joined, renamed or left; this one renamed)
    /// not yet taken, waiting up to `timeout` for one.
    std::optional<protocol::player_notice> next_player_notice(std::chrono::milliseconds timeout);

    /// The oldest sensor event (an `event` message: the hello asked for them) not yet taken,
    /// waiting up to `timeout` for one.
    std::optional<protocol::event> next_event(std::chrono::milliseconds timeout);

    /// The oldest snapshot not yet taken, waiting up to `timeout`; null when none came.
    std::shared_ptr<protocol::snapshot const> next_snapshot(std::chrono::milliseconds timeout);
    /// Takes every queued snapshot and returns the newest received; when none has ever been
    /// received, waits up to `timeout` for one (null when none came).
    std::shared_ptr<protocol::snapshot const>
    take_latest_snapshot(std::chrono::milliseconds timeout);
    /// Takes snapshots in the order they came until one satisfies `predicate`. Gives up at a
    /// snapshot later than `max_ticks` ticks after the newest tick received when called,
    /// after `timeout`, or when the connection ends. The predicate runs on the calling thread.
    snapshot_wait wait_for_snapshot(std::function<bool(protocol::snapshot const&)> const& predicate,
                                    std::uint64_t max_ticks, std::chrono::milliseconds timeout);
    /// The tick of the newest snapshot received (0 before the first).
    std::uint64_t latest_tick() const;

    /// Closes with 1000 (normal) and waits, up to a second, for the server's close frame.
    /// Does nothing when already closed.
    void close();
    /// Waits until the connection has ended (the server closed it, or it failed); nullopt
    /// when it is still open after `timeout`.
    std::optional<close_info> wait_closed(std::chrono::milliseconds timeout);
    bool is_open() const;
    /// How it ended; nullopt while open.
    std::optional<close_info> closed_with() const;

    connection_stats stats() const;

private:
    class session;
    struct state;
    connection(std::string const& url, connection_options options, io_threads* shared);
    std::unique_ptr<state> state_;
};

} // namespace kugel::client
