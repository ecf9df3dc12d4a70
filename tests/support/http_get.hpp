#pragma once

// One HTTP request on a fresh connection to 127.0.0.1, for the server tests (compiled once,
// in kugel_test_support, like ws_client).

#include <cstdint>
#include <string>

namespace kugel::test_support {

struct http_reply
{
    unsigned status = 0;
    std::string content_type;
    std::string body;
};

/// GET `target`; the reply's status, content type and body.
http_reply http_get(std::uint16_t port, std::string const& target);

/// A WebSocket upgrade request on a fresh connection, with `origin` as its Origin header
/// (none when empty) and `host` as its Host; the answer's status (101: accepted) and body.
http_reply websocket_upgrade(std::uint16_t port, std::string const& target,
                             std::string const& origin, std::string const& host);

/// A WebSocket upgrade request on a fresh connection, with `origin` as its Origin header
/// (none when empty) and `host` as its Host; the answer's status (101: accepted) and body.
inline http_reply websocket_upgrade(std::uint16_t port, std::string const& target,
                                    std::string const& origin, std::string const& host)
{
    namespace beast = boost::beast;
    namespace http = beast::http;
    boost::asio::io_context io;
    boost::asio::ip::tcp::socket socket(io);
    boost::asio::ip::tcp::resolver resolver(io);
    boost::asio::connect(socket, resolver.resolve("127.0.0.1", std::to_string(port)));
    http::request<http::empty_body> request{http::verb::get, target, 11};
    request.set(http::field::host, host);
    request.set(http::field::upgrade, "websocket");
    request.set(http::field::connection, "Upgrade");
    request.set(http::field::sec_websocket_key, "dGhlIHNhbXBsZSBub25jZQ==");
    request.set(http::field::sec_websocket_version, "13");
    if (!origin.empty())
        request.set(http::field::origin, origin);
    http::write(socket, request);
    beast::flat_buffer buffer;
    http::response<http::string_body> response;
    http::read(socket, buffer, response);
    return {response.result_int(), std::string(response[http::field::content_type]), response.body()};
}

} // namespace kugel::test_support
