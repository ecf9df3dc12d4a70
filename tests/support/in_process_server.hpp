#pragma once

// A kugel server running in the test's own process, on a free port of 127.0.0.1, with two
// worker threads and a short shutdown grace; stopped when it goes out of scope.

#include "room.hpp"
#include "server.hpp"

#include <chrono>
#include <cstdint>
#include <string>
#include <string_view>

namespace kugel::test_support {

class in_process_server
{
public:
    explicit in_process_server(server::server_options options)
        : server_(with_test_defaults(std::move(options)))
    {
        server_.start();
    }
    ~in_process_server() { stop(); }
    in_process_server(in_process_server const&) = delete;
    in_process_server& operator=(in_process_server const&) = delete;

    void stop()
    {
        server_.stop();
        server_.wait();
    }

    std::uint16_t port() const { return server_.port(); }
    std::string url(std::string const& room) const
    {
        return "ws://127.0.0.1:" + std::to_string(port()) + "/ws/" + room;
    }
    server::server& get() { return server_; }
    /// Ticks the room has completed so far.
    std::uint64_t bodies(std::string_view room) const
    {
        return server_.find_room(room)->counters().bodies.load();
    }
    std::uint64_t ticks(std::string_view room) const
    {
        return server_.find_room(room)->counters().ticks.load();
    }
    /// Snapshots the room skipped so far because the last one was still being encoded.
    std::uint64_t snapshots_skipped(std::string_view room) const
    {
        return server_.find_room(room)->counters().snapshots_skipped.load();
    }

private:
    static server::server_options with_test_defaults(server::server_options o)
    {
        o.port = 0;
        o.threads = 2;
        o.shutdown_grace = std::chrono::milliseconds(200);
        return o;
    }
    server::server server_;
};

} // namespace kugel::test_support
