#include "support/http_get.hpp"

#include <boost/asio/connect.hpp>
#include <boost/asio/write.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>

namespace kugel::test_support {

namespace {

namespace beast = boost::beast;
namespace http = beast::http;

http_reply round_trip(std::uint16_t port, http::request<http::empty_body> const& request)
{
    boost::asio::io_context io;
    boost::asio::ip::tcp::socket socket(io);
    boost::asio::ip::tcp::resolver resolver(io);
    boost::asio::connect(socket, resolver.resolve("127.0.0.1", std::to_string(port)));
    http::write(socket, request);
    beast::flat_buffer buffer;
    http::response<http::string_body> response;
    http::read(socket, buffer, response);
    return {response.result_int(), std::string(response[http::field::content_type]), response.body()};
}

} // namespace

http_reply http_raw(std::uint16_t port, std::string const& request)
{
    boost::asio::io_context io;
    boost::asio::ip::tcp::socket socket(io);
    boost::asio::ip::tcp::resolver resolver(io);
    boost::asio::connect(socket, resolver.resolve("127.0.0.1", std::to_string(port)));
    boost::asio::write(socket, boost::asio::buffer(request));
    beast::flat_buffer buffer;
    http::response<http::string_body> response;
    beast::error_code ec;
    http::read(socket, buffer, response, ec);
    if (ec)
        return {};
    return {response.result_int(), std::string(response[http::field::content_type]), response.body()};
}

http_reply http_get(std::uint16_t port, std::string const& target)
{
    http::request<http::empty_body> request{http::verb::get, target, 11};
    request.set(http::field::host, "127.0.0.1");
    request.keep_alive(false);
    return round_trip(port, request);
}

http_reply websocket_upgrade(std::uint16_t port, std::string const& target,
                             std::string const& origin, std::string const& host)
{
    http::request<http::empty_body> request{http::verb::get, target, 11};
    request.set(http::field::host, host);
    request.set(http::field::upgrade, "websocket");
    request.set(http::field::connection, "Upgrade");
    request.set(http::field::sec_websocket_key, "dGhlIHNhbXBsZSBub25jZQ==");
    request.set(http::field::sec_websocket_version, "13");
    if (!origin.empty())
        request.set(http::field::origin, origin);
    return round_trip(port, request);
}

} // namespace kugel::test_support
