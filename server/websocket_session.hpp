#pragma once

#include "metrics.hpp"
#include "network.hpp"
#include "options.hpp"

#include "protocol/compact.hpp"
#include "protocol/messages.hpp"


#include <atomic>
#include <chrono>
#include <cstdint>
#include <deque>
#include <vector>
#include <memory>
#include <optional>
#include <string>
#include <utility>

namespace kugel::server {

class room;
class encoded_snapshot;

/// A sensor event for a session: the message (to re-encode with `missed`) and its bytes,
/// encoded once for every session it goes to.
struct queued_event
{
    std::shared_ptr<protocol::event const> message;
    std::shared_ptr<std::string const> bytes;
};

/// One WebSocket client of a room. Reads commands and hands them to the room; writes what
/// the room sends back. The outgoing side is bounded, so that nothing a client does or fails
/// to do can hold up the tick or another client:
///  - replies (welcome, ack, error, pong) wait in a small queue, sent before any snapshot;
///    when the queue is full the client is closed with 1008 (policy);
///  - snapshots take one slot: a newer one replaces one not yet sent (on the compact form it
///    is then sent as the delta from the state the client holds: never a delta the client
///    cannot apply, and no keyframe for falling behind);
///  - a send pending longer than client_limits::write_stall means the client is not
///    reading: the connection is dropped.
/// All members run on the session's strand; the public functions may be called from any
/// thread.
class websocket_session : public std::enable_shared_from_this<websocket_session>
{
public:
    /// `admin_token`: what a hello must carry to make this client an admin; empty: none can.
    websocket_session(tcp::socket&& socket, std::shared_ptr<room> joined, client_limits limits,
                      std::uint64_t client_id, std::string admin_token = {});
    ~websocket_session();

    /// Accepts the upgrade request, then joins the room and starts reading.
    void run(http::request<http::string_body> request);

    /// Queues a reply (bytes of one message), ahead of snapshots: the answer to a command.
    void send_reply(std::shared_ptr<std::string const> bytes);
    /// Queues a message that answers no command (a welcome sent again), like a reply.
    void send_notice(std::shared_ptr<std::string const> bytes);
    /// Queues the room's players (sent after the welcome), in place of any player message
    /// still unsent, like a reply.
    void send_players(std::shared_ptr<std::string const> roster);
    /// Queues a notice that a player joined, was renamed or left, like a reply. When many wait
    /// unsent (a crowd joining at once), they are dropped and the room is asked for the roster
    /// instead, so a crowd cannot fill the reply queue of a client that reads.
    void send_player_notice(std::shared_ptr<std::string const> notice);
    /// Queues a tick's sensor events for this client (they match its hello.events), after the
    /// replies and before any snapshot. At most client_limits::max_queued_events wait unsent;
    /// those beyond are dropped and counted, and the next one queued says how many in
    /// `missed`. Never closes the connection.
    void send_events(std::vector<queued_event> events);
    /// Offers a snapshot; replaces any snapshot not yet sent. Which of its forms is sent is
    /// chosen when it is written (encoded_snapshot).
    void send_snapshot(std::shared_ptr<encoded_snapshot const> snapshot);
    /// From the next snapshot on: the compact form or the full one, and every n-th of the
    /// room's snapshots (the room's answer to hello.snapshots), announced by `welcome`, which
    /// is queued in the same turn: no snapshot of the new form goes out before it.
    void use_snapshots(bool compact, std::uint64_t every, std::shared_ptr<std::string const> welcome);
    /// Closes with 1001 (going away): the server is shutting down.
    void shut_down();

    /// The player this connection is: the id its welcome gave, or the one a resume made it
    /// again. Any thread; it changes only on the room's strand (become).
    std::uint64_t client_id() const { return player_id_.load(); }
    /// The id the connection was given when it opened (its first welcome's client): it names
    /// the connection in the logs and to the room, and never changes.
    std::uint64_t connection_id() const { return client_id_; }
    /// The room resumed a player on this connection: from now on it is that player. Called on
    /// the room's strand.
    void become(std::uint64_t player_id) { player_id_.store(player_id); }
    /// Its player was resumed on another connection: closes with close_resumed_elsewhere. The
    /// room no longer counts it as a member, and applies no command from it any more.
    void replace();
    bool replaced() const { return replaced_.load(); }

    /// The close code of a connection whose player a resume took to another connection.
    static constexpr std::uint16_t close_resumed_elsewhere = 4000;

private:
    using clock = std::chrono::steady_clock;

    void on_accept(beast::error_code ec);
    void do_read();
    void read_if_room();
    void on_read(beast::error_code ec, std::size_t bytes);
    /// Reads away the rest of a message over the limit (`drained` bytes of it so far), then
    /// closes with 1009.
    void drain_oversized(std::size_t drained);
    void handle_message(std::string_view text);
    void handle_admin_token(std::string_view token);
    void handle_resume(std::string token);
    bool take_command_token();
    void refuse_rate_limited(std::optional<std::uint64_t> ref);

    void queue_reply(std::shared_ptr<std::string const> bytes);
    void drop_queued_player_messages();
    void queue_snapshot(std::shared_ptr<encoded_snapshot const> snapshot);
    /// The bytes to send of a snapshot: the full form, a delta against what the client
    /// holds, or the keyframe.
    std::pair<std::shared_ptr<std::string const>, snapshot_form> bytes_of(encoded_snapshot const& snapshot);
    void write_next();
    void on_write(beast::error_code ec, std::size_t bytes);
    void close_with(websocket::close_code code, std::string_view reason);
    void drop_connection(char const* why);

    websocket::stream<beast::tcp_stream, false> ws_; ///< false: no permessage-deflate, not compiled
    beast::flat_buffer buffer_;
    std::shared_ptr<room> room_;
    client_limits limits_;
    std::uint64_t client_id_;                ///< the connection's (connection_id)
    std::atomic<std::uint64_t> player_id_;   ///< the player's (client_id)
    std::atomic<bool> replaced_{false};      ///< its player was resumed elsewhere
    std::string admin_token_; ///< the server's; empty: nobody is an admin
    bool admin_ = false;      ///< a hello carried the admin token
    std::string peer_; ///< address:port, for logs

    std::deque<std::shared_ptr<std::string const>> replies_;
    /// Which of replies_ are player messages (at most most_player_messages; more are
    /// replaced by one roster), and whether the room was asked for that roster.
    std::vector<std::string const*> queued_player_messages_;
    bool roster_asked_ = false;
    /// Sensor events not yet sent (after replies, before snapshots), and how many were
    /// dropped since the last one queued.
    std::deque<std::shared_ptr<std::string const>> events_;
    std::uint64_t events_missed_ = 0;
    /// The snapshot not yet sent: the newest alone (on the compact form, whichever snapshots
    /// it replaced, it comes as the delta from the state the client holds).
    std::shared_ptr<encoded_snapshot const> pending_snapshot_;
    bool compact_ = false;          ///< the client asked for the compact form
    std::uint64_t every_ = 1;       ///< it takes the room's snapshots whose index is a multiple
    /// The last compact snapshot written: the state the client holds, the only base a delta
    /// it is sent may have.
    struct held_state
    {
        std::uint64_t view = 0; ///< the view of the world it shows (encoded_snapshot::view)
        std::uint64_t tick = 0;
        std::shared_ptr<protocol::compact_state const> state;
    };
    std::optional<held_state> compact_held_;
    std::shared_ptr<std::string const> in_flight_;       ///< being written
    clock::time_point write_started_;
    /// Commands handed to the room and not answered yet: each gets exactly one answer.
    std::size_t awaiting_room_ = 0;
    bool reading_paused_ = false; ///< too many answers owed: the next read waits for writes
    /// The session itself while reading is paused: what keeps it alive until its answers come.
    std::shared_ptr<websocket_session> held_while_paused_;
    bool accepted_ = false;
    bool closing_ = false; ///< a close was started or the connection dropped: write nothing more

    double tokens_;               ///< commands the client may send now (token bucket)
    clock::time_point refilled_; ///< when tokens_ was last topped up
    std::uint64_t rate_limited_ = 0; ///< commands refused for the rate, for the log
    std::uint64_t refused_ = 0;      ///< messages that did not decode, for the log
    std::uint64_t forbidden_ = 0;    ///< admin commands and wrong tokens refused, for the log
    bool named_ = false;             ///< a hello gave a name (logged once)
};

} // namespace kugel::server
