#include "websocket_session.hpp"

#include "room.hpp"

#include "protocol/codec.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>

namespace kugel::server {

namespace {

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

} // namespace

websocket_session::websocket_session(tcp::socket&& socket, std::shared_ptr<room> joined,
                                     client_limits limits, std::uint64_t client_id)
    : ws_(std::move(socket)), room_(std::move(joined)), limits_(limits), client_id_(client_id),
      tokens_(limits.command_burst), refilled_(clock::now())
{
    beast::error_code ec;
    // Small replies must not wait behind a snapshot for the client's delayed ACK (Nagle):
    // without this a ping's round trip alternated between 0.2 ms and 40 ms.
    beast::get_lowest_layer(ws_).socket().set_option(tcp::no_delay(true), ec);
    auto const remote = beast::get_lowest_layer(ws_).socket().remote_endpoint(ec);
    peer_ = ec ? std::string("?") : remote.address().to_string() + ":" + std::to_string(remote.port());
}

websocket_session::~websocket_session()
{
    if (accepted_)
        spdlog::info("client {} ({}) left room '{}'", client_id_, peer_, room_->name());
}

void websocket_session::run(http::request<http::string_body> request)
{
    // Beast's suggested server timeouts (handshake 30 s, idle 300 s), plus our frame limit:
    // a larger frame fails the read and Beast closes with 1009 (too big).
    ws_.set_option(websocket::stream_base::timeout::suggested(beast::role_type::server));
    ws_.set_option(websocket::stream_base::decorator([](websocket::response_type& response) {
        response.set(http::field::server, "kugel-server");
    }));
    ws_.read_message_max(limits_.max_message_bytes);
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
    ws_.async_read(buffer_, beast::bind_front_handler(&websocket_session::on_read,
                                                      shared_from_this()));
}

void websocket_session::on_read(beast::error_code ec, std::size_t)
{
    if (ec == websocket::error::message_too_big) {
        spdlog::warn("client {} ({}): frame over {} bytes, closed with 1009", client_id_, peer_,
                     limits_.max_message_bytes);
        closing_ = true;
        return;
    }
    if (ec)
        return fail(ec, "websocket read");
    handle_message(beast::buffers_to_string(buffer_.data()));
    buffer_.consume(buffer_.size());
    do_read();
}

void websocket_session::handle_message(std::string_view text)
{
    if (!ws_.got_text()) {
        queue_reply(std::make_shared<std::string const>(protocol::encode(protocol::error{
            std::nullopt, protocol::error_code::bad_json, "frames must be text (JSON), not binary"})));
        return;
    }
    auto decoded = protocol::decode(text);
    if (decoded.failure) {
        spdlog::info("client {} ({}): refused a message: {} ({})", client_id_, peer_,
                     protocol::name(decoded.failure->code), decoded.failure->message);
        queue_reply(std::make_shared<std::string const>(protocol::encode(*decoded.failure)));
        return;
    }
    auto& message = *decoded.message;
    if (auto const* hello = std::get_if<protocol::hello>(&message)) {
        if (hello->name)
            spdlog::info("client {} ({}) is '{}'", client_id_, peer_, *hello->name);
        return;
    }
    if (!take_command_token()) {
        if (++rate_limited_ == 1 || rate_limited_ % 100 == 0) // a flood logs a line per 100
            spdlog::info("client {} ({}): refused {} commands over the rate limit so far",
                         client_id_, peer_, rate_limited_);
        queue_reply(std::make_shared<std::string const>(protocol::encode(protocol::error{
            ref_of(message), protocol::error_code::rate_limited,
            fmt::format("more than {} commands per second; this one was dropped",
                        limits_.commands_per_second)})));
        return;
    }
    room_->submit(shared_from_this(), std::move(message));
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
        self->queue_reply(std::move(bytes));
    });
}

void websocket_session::send_snapshot(std::shared_ptr<std::string const> bytes)
{
    net::post(ws_.get_executor(), [self = shared_from_this(), bytes = std::move(bytes)]() mutable {
        self->queue_snapshot(std::move(bytes));
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

void websocket_session::queue_snapshot(std::shared_ptr<std::string const> bytes)
{
    if (closing_)
        return;
    if (in_flight_ && clock::now() - write_started_ > limits_.write_stall)
        return drop_connection("not reading: a send has been pending too long");
    latest_snapshot_ = std::move(bytes); // a newer snapshot replaces an unsent one
    write_next();
}

void websocket_session::write_next()
{
    if (in_flight_ || closing_ || !accepted_)
        return;
    if (!replies_.empty()) {
        in_flight_ = std::move(replies_.front());
        replies_.pop_front();
    } else if (latest_snapshot_) {
        in_flight_ = std::move(latest_snapshot_);
    } else {
        return;
    }
    write_started_ = clock::now();
    ws_.async_write(net::buffer(*in_flight_),
                    beast::bind_front_handler(&websocket_session::on_write, shared_from_this()));
}

void websocket_session::on_write(beast::error_code ec, std::size_t)
{
    in_flight_.reset();
    if (ec)
        return fail(ec, "websocket write");
    write_next();
}

void websocket_session::close_with(websocket::close_code code, std::string_view reason)
{
    if (closing_)
        return;
    closing_ = true;
    replies_.clear();
    latest_snapshot_.reset();
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
    latest_snapshot_.reset();
    beast::error_code ignored;
    beast::get_lowest_layer(ws_).socket().shutdown(tcp::socket::shutdown_both, ignored);
    beast::get_lowest_layer(ws_).close();
}

} // namespace kugel::server
