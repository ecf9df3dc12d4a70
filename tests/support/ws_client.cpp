#include "support/ws_client.hpp"

#include <boost/asio/connect.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>

#include <stdexcept>

namespace kugel::test_support {

struct ws_client::connection
{
    boost::asio::io_context io;
    boost::beast::websocket::stream<boost::asio::ip::tcp::socket> ws{io};
    boost::beast::flat_buffer buffer;
    bool reading = false;
    bool done = false;
    bool closed = false;
    boost::beast::error_code error;
};

ws_client::ws_client(std::uint16_t port, std::string const& target, std::string const& origin)
    : c_(std::make_unique<connection>())
{
    namespace net = boost::asio;
    net::ip::tcp::resolver resolver(c_->io);
    net::connect(c_->ws.next_layer(), resolver.resolve("127.0.0.1", std::to_string(port)));
    if (!origin.empty())
        c_->ws.set_option(boost::beast::websocket::stream_base::decorator(
            [origin](boost::beast::websocket::request_type& request) {
                request.set(boost::beast::http::field::origin, origin);
            }));
    c_->ws.handshake("127.0.0.1:" + std::to_string(port), target);
    c_->ws.text(true);
}

ws_client::~ws_client() = default;

void ws_client::set_receive_buffer(int bytes)
{
    c_->ws.next_layer().set_option(boost::asio::socket_base::receive_buffer_size(bytes));
}

void ws_client::send(std::string const& text) { c_->ws.write(boost::asio::buffer(text)); }

void ws_client::send_binary(std::string const& bytes)
{
    c_->ws.binary(true);
    c_->ws.write(boost::asio::buffer(bytes));
    c_->ws.text(true);
}

std::optional<std::string> ws_client::read(std::chrono::milliseconds timeout)
{
    auto const deadline = clock::now() + timeout;
    for (;;) {
        auto const left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - clock::now());
        auto text = read_any(std::max(left, std::chrono::milliseconds(0)));
        if (!text || hears_players_ || !(text->starts_with(R"({"type":"players",)") ||
                                         text->starts_with(R"({"type":"player",)")))
            return text;
    }
}

std::optional<std::string> ws_client::read_any(std::chrono::milliseconds timeout)
{
    connection& c = *c_;
    if (c.closed)
        return std::nullopt;
    if (!c.reading) {
        c.reading = true;
        c.done = false;
        c.ws.async_read(c.buffer, [&c](boost::beast::error_code ec, std::size_t) {
            c.done = true;
            c.error = ec;
        });
    }
    auto const deadline = clock::now() + timeout;
    c.io.restart();
    while (!c.done && c.io.run_one_until(deadline) > 0) {
    }
    if (!c.done)
        return std::nullopt;
    c.reading = false;
    if (c.error) {
        c.closed = true;
        return std::nullopt;
    }
    std::string text = boost::beast::buffers_to_string(c.buffer.data());
    c.buffer.consume(c.buffer.size());
    return text;
}

nlohmann::json ws_client::read_json(std::chrono::milliseconds timeout)
{
    auto text = read(timeout);
    if (!text)
        throw std::runtime_error(c_->closed ? "connection closed: " + c_->error.message()
                                            : std::string("no message in time"));
    return nlohmann::json::parse(*text);
}

nlohmann::json ws_client::next(std::string const& type, std::chrono::milliseconds timeout)
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

bool ws_client::closed() const { return c_->closed; }

std::uint16_t ws_client::close_code() const { return c_->ws.reason().code; }

} // namespace kugel::test_support
