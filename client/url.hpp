#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>

namespace kugel::client {

/// A `ws://` address split into what a connection needs.
struct websocket_url
{
    std::string host;         ///< a name or an address; IPv6 without the brackets
    std::uint16_t port = 80;  ///< 80 when the URL names none
    std::string target = "/"; ///< path and query: "/ws/lab"
};

/// A URL that is not a usable `ws://` address.
class url_error : public std::invalid_argument
{
public:
    using std::invalid_argument::invalid_argument;
};

/// Splits "ws://host[:port][/path]". Throws url_error for anything else (including wss://,
/// which this client does not speak).
websocket_url parse_websocket_url(std::string_view url);

/// "ws://host:port/target", the form parse_websocket_url reads.
std::string to_string(websocket_url const& url);

} // namespace kugel::client
