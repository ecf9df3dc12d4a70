#include "websocket_session.hpp"

#include "admin_token.hpp"
#include "encoded_snapshot.hpp"
#include "room.hpp"

#include "protocol/codec.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>

namespace kugel::server {

namespace {

/// Player messages unsent before they are replaced by one roster.
constexpr std::size_t most_player_messages = 16;

std::optional<std::uint64_t> ref_of(protocol::client_message const& message)
{
    return std::visit(
        [](auto const& m) -> std::optional<std::uint64_t> {
            if constexpr (requires { m.ref; })
                return m.ref;
            else
                return std::nullopt;
        },
        message);
}

/// A client's text for a log line: at most 64 bytes, control characters (a newline that
/// would start a fake log line) shown as '?'.
std::string printable(std::string_view text)
{
    std::string out(text.substr(0, 64));
    for (char& c : out)
        if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f)
            c = '?';
    return text.size() > 64 ? out + "..." : out;
}

/// Whether the n-th refusal of one kind gets a log line: the first ten, then one per hundred,
/// so that a client cannot flood the log by sending what is refused.
bool worth_logging(std::uint64_t n)
{
    return n <= 10 || n % 100 == 0;
}

/// The type of an admin command, or nothing for a command everyone may send.
std::optional<std::string_view> admin_command(protocol::client_message const& message)
{
    return std::visit(
        []<class M>(M const&) -> std::optional<std::string_view> {
            if constexpr (std::is_same_v<M, protocol::pause> || std::is_same_v<M, protocol::resume> ||
                          std::is_same_v<M, protocol::reset> || std::is_same_v<M, protocol::load_scene>)
                return M::type;
            else
                return std::nullopt;
        },
        message);
}

std::shared_ptr<std::string const> encoded(protocol::error const& e)
{
    return std::make_shared<std::string const>(protocol::encode(e));
}

} // namespace

websocket_session::websocket_session(tcp::socket&& socket, std::shared_ptr<room> joined,
                                     client_limits limits, std::uint64_t client_id,
                                     std::string admin_token)
    : ws_(std::move(socket)), room_(std::move(joined)), limits_(limits), client_id_(client_id),
      player_id_(client_id), admin_token_(std::move(admin_token)), tokens_(limits.command_burst),
      refilled_(clock::now())
{
    beast::error_code ec;
    // Small replies must not wait behind a snapshot for the client's delayed ACK (Nagle):
    // without this a ping's round trip alternated between 0.2 ms and 40 ms.
    beast::get_lowest_layer(ws_).socket().set_option(tcp::no_delay(true), ec);
    if (limits_.send_buffer_bytes > 0)
        beast::get_lowest_layer(ws_).socket().set_option(
            net::socket_base::send_buffer_size(static_cast<int>(limits_.send_buffer_bytes)), ec);
    auto const remote = beast::get_lowest_layer(ws_).socket().remote_endpoint(ec);
    peer_ = ec ? std::string("?") : remote.address().to_string() + ":" + std::to_string(remote.port());
}

websocket_session::~websocket_session()
{
    if (accepted_) {
        spdlog::info("client {} ({}) left room '{}'", client_id_, peer_, room_->name());
        room_->leave(client_id_);
    }
}

void websocket_session::run(http::request<http::string_body> request)
{
    // Beast's suggested server timeouts (handshake 30 s, idle 300 s), plus our frame limit:
    // a larger frame fails the read and Beast closes with 1009 (too big).
    ws_.set_option(websocket::stream_base::timeout::suggested(beast::role_type::server));
    ws_.set_option(websocket::stream_base::decorator([](websocket::response_type& response) {
        response.set(http::field::server, "kugel-server");
    }));
    // The frame limit is kept here (on_read), not by Beast: Beast fails the connection on a
    // frame over its limit, and its teardown (Boost 1.74) drains only one read before it
    // closes, so the rest of a large frame in flight reset the connection and the client
    // saw 1006. A close handshake drains what is left and the client sees 1009.
    ws_.read_message_max(0); // no limit of Beast's
    ws_.text(true);
    ws_.async_accept(request, beast::bind_front_handler(&websocket_session::on_accept,
                                                        shared_from_this()));
}

void websocket_session::on_accept(beast::error_code ec)
{
    if (ec)
        return fail(ec, "websocket accept");
    accepted_ = true;
    spdlog::info("client {} ({}) joined room '{}'", client_id_, peer_, room_->name());
    room_->join(shared_from_this()); // the room sends welcome first, then snapshots
    do_read();
}

void websocket_session::do_read()
{
    // A message is read in pieces, never more than one byte past the limit in all.
    constexpr std::size_t piece = 16 * 1024;
    std::size_t const left = limits_.max_message_bytes + 1 - buffer_.size();
    ws_.async_read_some(buffer_.prepare(std::min(left, piece)),
                        beast::bind_front_handler(&websocket_session::on_read, shared_from_this()));
}

void websocket_session::on_read(beast::error_code ec, std::size_t bytes)
{
    if (ec)
        return fail(ec, "websocket read");
    buffer_.commit(bytes);
    if (buffer_.size() > limits_.max_message_bytes) {
        spdlog::warn("client {} ({}): frame over {} bytes, closed with 1009", client_id_, peer_,
                     limits_.max_message_bytes);
        bump(room_->traffic().messages_in);
        room_->traffic().count_rejected(protocol::error_code::message_too_large);
        buffer_.consume(buffer_.size());
        return drain_oversized(0);
    }
    if (!ws_.is_message_done())
        return do_read();
    bump(room_->traffic().messages_in);
    handle_message(beast::buffers_to_string(buffer_.data()));
    buffer_.consume(buffer_.size());
    read_if_room();
}

// The rest of a message over the limit is read away before the close is sent. A browser
// answers the close only after it has sent all of its message, then gives the server two
// seconds to end the connection before it calls the close unclean; the close handshake's
// own drain (Beast's, 4 KiB a read) took longer than that on a busy machine. Reading the rest
// first, in large pieces, leaves nothing between the client's close and the end. Past
// most_drained_bytes the close is sent at once, and Beast drains what is left.
void websocket_session::drain_oversized(std::size_t drained)
{
    constexpr std::size_t piece = 256 * 1024;
    constexpr std::size_t most_drained_bytes = 64 * 1024 * 1024;
    if (ws_.is_message_done() || drained > most_drained_bytes)
        return close_with(websocket::close_code::too_big, "message too big");
    ws_.async_read_some(buffer_.prepare(piece), [self = shared_from_this(), drained](beast::error_code ec,
                                                                                     std::size_t bytes) {
        if (ec)
            return fail(ec, "websocket read");
        self->buffer_.commit(bytes);
        self->buffer_.consume(self->buffer_.size());
        self->drain_oversized(drained + bytes);
    });
}

// Back-pressure on reading: every message read owes one answer, and a burst read from the
// socket's buffer can owe answers faster than they are written. Past half the reply queue
// the next read waits until writes have caught up, so a client that reads its answers is
// never closed for a burst, and one that stops reading stops being read (its stalled write
// then drops it).
void websocket_session::read_if_room()
{
    if (closing_)
        return;
    reading_paused_ = replies_.size() + awaiting_room_ >= limits_.max_queued_replies / 2;
    if (reading_paused_) {
        // No read is pending now, and the room holds its commands' senders weakly: without
        // this the session would end (and its socket close with a reset) before the answers
        // it owes come back.
        held_while_paused_ = shared_from_this();
        return;
    }
    held_while_paused_.reset();
    do_read();
}

void websocket_session::handle_message(std::string_view text)
{
    if (!ws_.got_text()) {
        room_->traffic().count_rejected(protocol::error_code::bad_json);
        queue_reply(std::make_shared<std::string const>(protocol::encode(protocol::error{
            std::nullopt, protocol::error_code::bad_json, "/: frames must be text (JSON), not binary"})));
        return;
    }
    auto decoded = protocol::decode(text);
    if (decoded.failure) {
        room_->traffic().count_rejected(decoded.failure->code);
        if (worth_logging(++refused_))
            spdlog::info("client {} ({}): refused message {}: {} ({})", client_id_, peer_,
                         refused_, protocol::name(decoded.failure->code), decoded.failure->message);
        queue_reply(std::make_shared<std::string const>(protocol::encode(*decoded.failure)));
        return;
    }
    auto& message = *decoded.message;
    if (auto const* hello = std::get_if<protocol::hello>(&message)) {
        if (hello->resume) // first: the hello's name, if any, then names the player resumed
            handle_resume(*hello->resume);
        if (hello->name && !named_) // a flood of hellos logs one line
            spdlog::info("client {} ({}) is '{}'", client_id_, peer_, printable(*hello->name));
        named_ = named_ || hello->name.has_value();
        if (hello->name) {
            // Told to every player in the room, so counted as a command: a flood of renames
            // is slowed, not multiplied by the room's size.
            if (!take_command_token())
                return refuse_rate_limited(std::nullopt);
            room_->rename(shared_from_this(), *hello->name);
        }
        if (hello->players)
            room_->hear_players(shared_from_this(), *hello->players);
        if (hello->admin_token)
            handle_admin_token(*hello->admin_token);
        if (hello->events) {
            // Checked against the room's sensors and answered only when refused; counted as a
            // command, as a hello with snapshots is.
            if (!take_command_token())
                return refuse_rate_limited(std::nullopt);
            room_->subscribe_events(shared_from_this(), *hello->events);
        }
        if (hello->snapshots) {
            // Answered by a welcome, so counted as a command: a flood of them is slowed.
            if (!take_command_token())
                return refuse_rate_limited(std::nullopt);
            room_->request_snapshots(shared_from_this(), *hello->snapshots);
        }
        if (hello->interest) {
            // Checked and applied at the next tick, answered only when refused; counted as a
            // command, as the interest command is.
            if (!take_command_token())
                return refuse_rate_limited(std::nullopt);
            room_->set_interest(shared_from_this(), *hello->interest);
        }
        return;
    }
    if (!take_command_token())
        return refuse_rate_limited(ref_of(message));
    if (auto const type = admin_command(message); type && !admin_) {
        room_->traffic().count_rejected(protocol::error_code::forbidden);
        if (worth_logging(++forbidden_))
            spdlog::info("client {} ({}): refused admin command {} from a non-admin ({} refusals "
                         "so far)", client_id_, peer_, *type, forbidden_);
        queue_reply(encoded({ref_of(message), protocol::error_code::forbidden,
                             fmt::format("/type: {} is an admin command, and this connection is "
                                         "not an admin (a hello with the server's admin_token "
                                         "makes it one)", *type)}));
        return;
    }
    ++awaiting_room_;
    room_->submit(shared_from_this(), std::move(message), admin_);
}

// A token is a password: guessing one takes a command token each try (so a guesser is held
// to the rate limit), and neither the token nor a guess is ever written to the log.
void websocket_session::handle_admin_token(std::string_view token)
{
    if (!take_command_token())
        return refuse_rate_limited(std::nullopt);
    std::string why;
    if (admin_token_.empty())
        why = "/admin_token: this server has no admin token, so nobody is an admin";
    else if (!is_admin_token(token, admin_token_))
        why = "/admin_token: not the server's admin token; this connection stays an ordinary client";
    if (!why.empty()) {
        room_->traffic().count_rejected(protocol::error_code::forbidden);
        if (worth_logging(++forbidden_))
            spdlog::warn("client {} ({}): refused a wrong admin token ({} refusals so far)",
                         client_id_, peer_, forbidden_);
        queue_reply(encoded({std::nullopt, protocol::error_code::forbidden, std::move(why)}));
        return;
    }
    if (admin_)
        return;
    admin_ = true;
    spdlog::info("client {} ({}) is an admin", client_id_, peer_);
    room_->grant_admin(shared_from_this()); // answered by a welcome saying so
}

// A resume token is a password too: each try takes a command token, and the room compares
// it in constant time and never logs it. The room answers: a new welcome, or bad_resume.
void websocket_session::handle_resume(std::string token)
{
    if (!take_command_token())
        return refuse_rate_limited(std::nullopt);
    room_->resume(shared_from_this(), std::move(token));
}

void websocket_session::replace()
{
    replaced_ = true;
    net::post(ws_.get_executor(), [self = shared_from_this()] {
        spdlog::info("client {} ({}): its player {} resumed on another connection; closed",
                     self->client_id_, self->peer_, self->client_id());
        self->close_with(static_cast<websocket::close_code>(close_resumed_elsewhere),
                         "resumed on another connection");
    });
}

void websocket_session::refuse_rate_limited(std::optional<std::uint64_t> ref)
{
    room_->traffic().count_rejected(protocol::error_code::rate_limited);
    if (worth_logging(++rate_limited_))
        spdlog::info("client {} ({}): refused {} commands over the rate limit so far",
                     client_id_, peer_, rate_limited_);
    queue_reply(encoded({ref, protocol::error_code::rate_limited,
                         fmt::format("more than {} commands per second; this one was dropped",
                                     limits_.commands_per_second)}));
}

bool websocket_session::take_command_token()
{
    auto const now = clock::now();
    double const elapsed = std::chrono::duration<double>(now - refilled_).count();
    refilled_ = now;
    tokens_ = std::min(limits_.command_burst, tokens_ + elapsed * limits_.commands_per_second);
    if (tokens_ < 1.0)
        return false;
    tokens_ -= 1.0;
    return true;
}

void websocket_session::send_reply(std::shared_ptr<std::string const> bytes)
{
    net::post(ws_.get_executor(), [self = shared_from_this(), bytes = std::move(bytes)]() mutable {
        // An answer to a command, or the welcome (which answers none: hence no underflow).
        self->awaiting_room_ -= self->awaiting_room_ > 0 ? 1 : 0;
        self->queue_reply(std::move(bytes));
    });
}

void websocket_session::send_notice(std::shared_ptr<std::string const> bytes)
{
    net::post(ws_.get_executor(), [self = shared_from_this(), bytes = std::move(bytes)]() mutable {
        self->queue_reply(std::move(bytes)); // owes no answer: awaiting_room_ stays
    });
}

void websocket_session::send_players(std::shared_ptr<std::string const> roster)
{
    net::post(ws_.get_executor(), [self = shared_from_this(), roster = std::move(roster)]() mutable {
        if (self->closing_)
            return;
        self->drop_queued_player_messages(); // the roster says what they added up to
        self->roster_asked_ = false;
        self->queued_player_messages_.push_back(roster.get());
        self->queue_reply(std::move(roster));
    });
}

// Player notices wait with the replies. Past most_player_messages unsent, they are dropped and
// the room is asked for its roster, which comes after every notice it sent before (the room
// posts both from its strand, in order) and says what they added up to; notices that come
// while it is on its way are in it or come after it. A client that reads gets the same
// picture, and a crowd joining at once costs each client one message, not one per player.
void websocket_session::send_player_notice(std::shared_ptr<std::string const> notice)
{
    net::post(ws_.get_executor(), [self = shared_from_this(), notice = std::move(notice)]() mutable {
        if (self->closing_ || self->roster_asked_)
            return;
        if (self->queued_player_messages_.size() >= most_player_messages) {
            self->drop_queued_player_messages();
            self->roster_asked_ = true;
            self->room_->send_roster(self);
            bump(self->room_->traffic().player_messages_merged);
            return;
        }
        self->queued_player_messages_.push_back(notice.get());
        self->queue_reply(std::move(notice));
    });
}

void websocket_session::drop_queued_player_messages()
{
    std::erase_if(replies_, [&](std::shared_ptr<std::string const> const& r) {
        return std::find(queued_player_messages_.begin(), queued_player_messages_.end(), r.get()) !=
               queued_player_messages_.end();
    });
    queued_player_messages_.clear();
}

void websocket_session::send_events(std::vector<queued_event> events)
{
    net::post(ws_.get_executor(), [self = shared_from_this(), events = std::move(events)]() mutable {
        if (self->closing_)
            return;
        for (queued_event& e : events) {
            if (self->events_.size() >= self->limits_.max_queued_events) {
                ++self->events_missed_;
                bump(self->room_->traffic().events_dropped);
                continue;
            }
            if (self->events_missed_ > 0) {
                protocol::event told = *e.message;
                told.missed = std::exchange(self->events_missed_, 0);
                e.bytes = std::make_shared<std::string const>(protocol::encode(told));
            }
            self->events_.push_back(std::move(e.bytes));
        }
        self->write_next();
    });
}

void websocket_session::send_snapshot(std::shared_ptr<encoded_snapshot const> snapshot)
{
    net::post(ws_.get_executor(), [self = shared_from_this(), snapshot = std::move(snapshot)]() mutable {
        self->queue_snapshot(std::move(snapshot));
    });
}

void websocket_session::use_snapshots(bool compact, std::uint64_t every, std::shared_ptr<std::string const> welcome)
{
    net::post(ws_.get_executor(), [self = shared_from_this(), compact, every, welcome = std::move(welcome)]() mutable {
        if (compact != self->compact_)
            self->compact_held_.reset(); // the first compact snapshot is a keyframe
        self->compact_ = compact;
        self->every_ = every;
        self->queue_reply(std::move(welcome)); // owes no answer, as send_notice
    });
}

void websocket_session::shut_down()
{
    net::post(ws_.get_executor(), [self = shared_from_this()] {
        self->close_with(websocket::close_code::going_away, "server shutting down");
    });
}

void websocket_session::queue_reply(std::shared_ptr<std::string const> bytes)
{
    if (closing_)
        return;
    if (replies_.size() >= limits_.max_queued_replies) {
        spdlog::warn("client {} ({}): {} replies unsent, closing with 1008", client_id_, peer_,
                     replies_.size());
        return close_with(websocket::close_code::policy_error, "not reading its replies");
    }
    replies_.push_back(std::move(bytes));
    write_next();
}

void websocket_session::queue_snapshot(std::shared_ptr<encoded_snapshot const> snapshot)
{
    if (closing_ || snapshot->index() % every_ != 0)
        return; // closing, or not one of the share of snapshots the client asked for
    if (in_flight_ && clock::now() - write_started_ > limits_.write_stall) {
        bump(room_->traffic().stalled_clients);
        return drop_connection("not reading: a send has been pending too long");
    }
    // A newer snapshot replaces an unsent one; on the compact form it then comes as the delta
    // from the state the client holds (bytes_of).
    if (pending_snapshot_)
        bump(room_->traffic().snapshots_dropped);
    pending_snapshot_ = std::move(snapshot);
    write_next();
}

std::pair<std::shared_ptr<std::string const>, snapshot_form>
websocket_session::bytes_of(encoded_snapshot const& snapshot)
{
    if (!compact_)
        return {snapshot.full(), snapshot_form::full};
    // A delta only against the state the client holds (the encoder's, or a catch-up delta
    // when it skipped snapshots); otherwise (it just joined, its keyframe is due) the keyframe.
    std::optional<held_state> const held =
        std::exchange(compact_held_, held_state{snapshot.view(), snapshot.tick(), snapshot.compact()});
    if (held && held->view == snapshot.view()) {
        if (auto bytes = snapshot.delta_for(*held->state, every_))
            return {std::move(bytes), snapshot_form::delta};
    } else if (held) {
        // Its interest changed: the bodies that left it vanish and those that came appear, as
        // in any delta, in one encoded for this client alone (once per change), unless a
        // keyframe is smaller.
        if (auto const d = protocol::delta(*held->state, *snapshot.compact())) {
            auto bytes = std::make_shared<std::string const>(protocol::encode(*d));
            snapshot.count_encoded(snapshot_form::delta, bytes->size());
            return {std::move(bytes), snapshot_form::delta};
        }
    }
    return {snapshot.keyframe(), snapshot_form::keyframe};
}

void websocket_session::write_next()
{
    if (in_flight_ || closing_ || !accepted_)
        return;
    traffic_counters& traffic = room_->traffic();
    if (!replies_.empty()) {
        in_flight_ = std::move(replies_.front());
        replies_.pop_front();
        std::erase(queued_player_messages_, in_flight_.get());
        bump(traffic.replies_out);
    } else if (!events_.empty()) {
        in_flight_ = std::move(events_.front());
        events_.pop_front();
        bump(traffic.events_out);
    } else if (pending_snapshot_) {
        auto [bytes, form] = bytes_of(*pending_snapshot_);
        in_flight_ = std::move(bytes);
        pending_snapshot_.reset();
        bump(traffic.snapshots_out);
        traffic.sent.count(form, in_flight_->size());
    } else {
        return;
    }
    // Counted when handed to the socket, so a client that has read a message always finds
    // it counted.
    bump(traffic.bytes_out, in_flight_->size());
    write_started_ = clock::now();
    ws_.async_write(net::buffer(*in_flight_),
                    beast::bind_front_handler(&websocket_session::on_write, shared_from_this()));
}

void websocket_session::on_write(beast::error_code ec, std::size_t)
{
    in_flight_.reset();
    if (ec) {
        held_while_paused_.reset(); // nothing more can be written: the answers have nowhere to go
        return fail(ec, "websocket write");
    }
    write_next();
    if (reading_paused_)
        read_if_room();
}

void websocket_session::close_with(websocket::close_code code, std::string_view reason)
{
    if (closing_)
        return;
    closing_ = true;
    replies_.clear();
    events_.clear();
    pending_snapshot_.reset();
    held_while_paused_.reset(); // the caller holds the session
    if (!accepted_)
        return drop_connection("closed before the handshake finished");
    // Beast runs a close after a pending write; if that write never finishes (the client
    // does not read), the handshake timeout ends the connection.
    ws_.async_close(websocket::close_reason(code, reason),
                    [self = shared_from_this()](beast::error_code close_ec) {
                        if (close_ec)
                            fail(close_ec, "websocket close");
                    });
}

void websocket_session::drop_connection(char const* why)
{
    spdlog::warn("client {} ({}): {}; disconnected", client_id_, peer_, why);
    closing_ = true;
    replies_.clear();
    events_.clear();
    pending_snapshot_.reset();
    held_while_paused_.reset(); // the caller holds the session
    beast::error_code ignored;
    beast::get_lowest_layer(ws_).socket().shutdown(tcp::socket::shutdown_both, ignored);
    beast::get_lowest_layer(ws_).close();
}

} // namespace kugel::server
