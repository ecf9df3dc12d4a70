#include "stalled_connection.hpp"

#include "connection.hpp"
#include "protocol/codec.hpp"
#include "url.hpp"

#include <boost/asio/connect.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>

#include <variant>

namespace kugel::client {

namespace net = boost::asio;
namespace beast = boost::beast;
namespace websocket = beast::websocket;
using tcp = net::ip::tcp;

struct stalled_connection::state
{
    net::io_context io;
    websocket::stream<tcp::socket> ws{io};
    beast::flat_buffer buffer;
    std::uint64_t client_id = 0;

    /// One message, or an error; runs the io_context for at most `timeout` (then the read is
    /// cancelled by closing the socket, and `timed_out` is set).
    beast::error_code read_one(std::chrono::milliseconds timeout, bool& timed_out)
    {
        beast::error_code result;
        bool done = false;
        ws.async_read(buffer, [&](beast::error_code ec, std::size_t) {
            result = ec;
            done = true;
        });
        io.restart();
        io.run_for(timeout);
        timed_out = !done;
        if (!done) {
            beast::error_code ignored;
            ws.next_layer().close(ignored);
            io.restart();
            io.run(); // the cancelled read's handler
        }
        return result;
    }
};

stalled_connection::stalled_connection(std::string const& url, std::chrono::milliseconds timeout)
    : state_(std::make_unique<state>())
{
    websocket_url const where = parse_websocket_url(url);
    try {
        tcp::resolver resolver(state_->io);
        auto const endpoints = resolver.resolve(where.host, std::to_string(where.port));
        // A small receive buffer, set before connecting (it bounds the window offered).
        tcp::socket& socket = state_->ws.next_layer();
        socket.open(endpoints.begin()->endpoint().protocol());
        socket.set_option(net::socket_base::receive_buffer_size(4096));
        socket.connect(*endpoints.begin());
        state_->ws.handshake(where.host + ":" + std::to_string(where.port), where.target);
    } catch (boost::system::system_error const& e) {
        throw connection_error("cannot connect to " + url + ": " + e.code().message());
    }
    bool timed_out = false;
    if (auto const ec = state_->read_one(timeout, timed_out))
        throw connection_error("no welcome from " + url + ": " +
                               (timed_out ? std::string("timed out") : ec.message()));
    auto const decoded =
        protocol::decode_server_message(beast::buffers_to_string(state_->buffer.data()));
    state_->buffer.consume(state_->buffer.size());
    auto const* welcome = decoded.message ? std::get_if<protocol::welcome>(&*decoded.message) : nullptr;
    if (!welcome)
        throw connection_error("the first message from " + url + " is not a welcome");
    state_->client_id = welcome->client;
}

stalled_connection::~stalled_connection() = default;

std::uint64_t stalled_connection::client_id() const
{
    return state_->client_id;
}

bool stalled_connection::dropped(std::chrono::milliseconds patience)
{
    auto const deadline = std::chrono::steady_clock::now() + patience;
    for (;;) {
        auto const left = std::chrono::duration_cast<std::chrono::milliseconds>(
            deadline - std::chrono::steady_clock::now());
        if (left <= std::chrono::milliseconds::zero())
            break;
        bool timed_out = false;
        beast::error_code const ec = state_->read_one(left, timed_out);
        if (timed_out)
            return false;
        if (ec)
            return true; // ended: a close frame, end of stream or a reset
        state_->buffer.consume(state_->buffer.size());
    }
    beast::error_code ignored;
    state_->ws.next_layer().close(ignored);
    return false;
}

} // namespace kugel::client
