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

/// Writes `request` (raw bytes: a request line, headers, the blank line) to a fresh
/// connection and reads one response; status 0 when the server closed without one.
http_reply http_raw(std::uint16_t port, std::string const& request);

} // namespace kugel::test_support
