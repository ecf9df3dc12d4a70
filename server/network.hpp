#pragma once

// The network names every server file uses, in Beast's own spelling.

#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/strand.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>

namespace kugel::server {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace net = boost::asio;
using tcp = net::ip::tcp;

/// Logs a failed network operation at debug level; quiet for the errors that only mean the
/// peer went away or we are shutting down (Beast's examples do the same).
void fail(beast::error_code ec, char const* what);

} // namespace kugel::server
