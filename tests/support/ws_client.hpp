#pragma once

// A small synchronous-looking WebSocket client for the server tests: connect, send text,
// read with a timeout. Each client has its own io_context, run only inside its calls, so a
// test controls exactly when a client reads (or, to test back-pressure, never does).

#include <boost/asio/connect.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>
#include <nlohmann/json.hpp>

#include <chrono>
#include <optional>
#include <stdexcept>
#include <string>

namespace kugel::test_support {

class ws_client
{
public:
    using clock = std::chrono::steady_clock;

    /// Connects to 127.0.0.1:port and upgrades on `target`, as a page of `origin` when one
    /// is given (an Origin header, as a browser sends); throws on failure.
    explicit ws_client(std::uint16_t port, std::string const& target = "/ws",
                       std::string const& origin = {})
        : ws_(io_)
    {
        namespace net = boost::asio;
        net::ip::tcp::resolver resolver(io_);
        net::connect(ws_.next_layer(), resolver.resolve("127.0.0.1", std::to_string(port)));
        if (!origin.empty())
            ws_.set_option(boost::beast::websocket::stream_base::decorator(
                [origin](boost::beast::websocket::request_type& request) {
                    request.set(boost::beast::http::field::origin, origin);
                }));
        ws_.handshake("127.0.0.1:" + std::to_string(port), target);
        ws_.text(true);
    }

    void send(std::string const& text) { ws_.write(boost::asio::buffer(text)); }
    void send(nlohmann::json const& message) { send(message.dump()); }
    /// A binary frame (the protocol speaks text only).
    void send_binary(std::string const& bytes)
    {
        ws_.binary(true);
        ws_.write(boost::asio::buffer(bytes));
        ws_.text(true);
    }

    /// The next message, or nullopt when none came within `timeout` or the connection
    /// ended (then closed() is true). A read still pending at the timeout stays pending
    /// for the next call, so no message is lost.
    std::optional<std::string> read(std::chrono::milliseconds timeout = std::chrono::seconds(10))
    {
        if (closed_)
            return std::nullopt;
        if (!reading_) {
            reading_ = true;
            done_ = false;
            ws_.async_read(buffer_, [this](boost::beast::error_code ec, std::size_t) {
                done_ = true;
                error_ = ec;
            });
        }
        auto const deadline = clock::now() + timeout;
        io_.restart();
        while (!done_ && io_.run_one_until(deadline) > 0) {
        }
        if (!done_)
            return std::nullopt;
        reading_ = false;
        if (error_) {
            closed_ = true;
            return std::nullopt;
        }
        std::string text = boost::beast::buffers_to_string(buffer_.data());
        buffer_.consume(buffer_.size());
        return text;
    }

    /// The next message parsed; throws when none comes in time.
    nlohmann::json read_json(std::chrono::milliseconds timeout = std::chrono::seconds(10))
    {
        auto text = read(timeout);
        if (!text)
            throw std::runtime_error(closed_ ? "connection closed: " + error_.message()
                                             : std::string("no message in time"));
        return nlohmann::json::parse(*text);
    }

    /// The next message of this type, skipping others (snapshots, mostly); throws when none
    /// comes in time.
    nlohmann::json next(std::string const& type,
                        std::chrono::milliseconds timeout = std::chrono::seconds(10))
    {
        auto const deadline = clock::now() + timeout;
        while (clock::now() < deadline) {
            auto const left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - clock::now());
            nlohmann::json message = read_json(left);
            if (message.at("type") == type)
                return message;
        }
        throw std::runtime_error("no " + type + " in time");
    }

    bool closed() const { return closed_; }
    boost::beast::error_code const& error() const { return error_; }
    /// The close frame's code (1000, 1001, 1008, 1009, ...) once the server closed.
    std::uint16_t close_code() const { return ws_.reason().code; }

private:
    boost::asio::io_context io_;
    boost::beast::websocket::stream<boost::asio::ip::tcp::socket> ws_;
    boost::beast::flat_buffer buffer_;
    bool reading_ = false;
    bool done_ = false;
    bool closed_ = false;
    boost::beast::error_code error_;
};

} // namespace kugel::test_support
