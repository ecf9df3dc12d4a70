#pragma once

// A connection that takes its welcome and then stops reading: how a hung client looks to a
// server. For load tests: the server must drop it after its write-stall bound while every
// other client carries on.

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>

namespace kugel::client {

class stalled_connection
{
public:
    /// Connects to `url` (ws://host:port/ws/ROOM) with a small receive buffer, so that the
    /// server's sends back up within a few messages, and reads the welcome; after that it
    /// reads nothing until dropped() is called. Throws url_error for a bad URL and
    /// connection_error when it cannot connect or no welcome comes within `timeout`.
    stalled_connection(std::string const& url, std::chrono::milliseconds timeout);
    ~stalled_connection();
    stalled_connection(stalled_connection const&) = delete;
    stalled_connection& operator=(stalled_connection const&) = delete;

    /// The server's id for it (welcome.client).
    std::uint64_t client_id() const;

    /// Reads again, for at most `patience`: true when the server had ended the connection
    /// (what it had buffered is read, then the connection ends), false when messages still
    /// come. Closes the connection either way.
    bool dropped(std::chrono::milliseconds patience);

private:
    struct state;
    std::unique_ptr<state> state_;
};

} // namespace kugel::client
