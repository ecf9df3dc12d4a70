#pragma once

// A small synchronous-looking WebSocket client for the server tests: connect, send text,
// read with a timeout. Each client has its own io_context, run only inside its calls, so a
// test controls exactly when a client reads (or, to test back-pressure, never does).
//
// Compiled once (ws_client.cpp, in kugel_test_support) rather than in every test file:
// Beast's WebSocket stream was half the compile time of each server test file.

#include <nlohmann/json.hpp>

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

namespace kugel::test_support {

class ws_client
{
public:
    using clock = std::chrono::steady_clock;

    /// Connects to 127.0.0.1:port and upgrades on `target`, as a page of `origin` when one
    /// is given (an Origin header, as a browser sends); throws on failure.
    explicit ws_client(std::uint16_t port, std::string const& target = "/ws",
                       std::string const& origin = {});
    ~ws_client();
    ws_client(ws_client const&) = delete;
    ws_client& operator=(ws_client const&) = delete;

    /// Sets the socket's receive buffer (SO_RCVBUF; the kernel doubles it, and no longer
    /// grows it): a client that stops reading is then soon behind, whatever the machine's
    /// defaults.
    void set_receive_buffer(int bytes);

    void send(std::string const& text);
    void send(nlohmann::json const& message) { send(message.dump()); }
    /// A binary frame (the protocol speaks text only).
    void send_binary(std::string const& bytes);

    /// The next message, or nullopt when none came within `timeout` or the connection
    /// ended (then closed() is true). A read still pending at the timeout stays pending
    /// for the next call, so no message is lost. The room's player messages (`players`,
    /// `player`) are passed over unless hear_players() was called: most tests are about
    /// other things, and a player joining would interleave with what they read.
    std::optional<std::string> read(std::chrono::milliseconds timeout = std::chrono::seconds(10));

    /// From now on read() returns the player messages too.
    void hear_players() { hears_players_ = true; }

    /// The next message parsed; throws when none comes in time.
    nlohmann::json read_json(std::chrono::milliseconds timeout = std::chrono::seconds(10));

    /// The next message of this type, skipping others (snapshots, mostly); throws when none
    /// comes in time.
    nlohmann::json next(std::string const& type,
                        std::chrono::milliseconds timeout = std::chrono::seconds(10));

    bool closed() const;
    /// The close frame's code (1000, 1001, 1008, 1009, ...) once the server closed.
    std::uint16_t close_code() const;

private:
    std::optional<std::string> read_any(std::chrono::milliseconds timeout);

    struct connection;
    std::unique_ptr<connection> c_;
    bool hears_players_ = false;
};

/// Index of body `id` in a full snapshot's columns, or -1 when it is not there.
inline std::ptrdiff_t index_of(nlohmann::json const& snapshot, std::uint64_t id)
{
    auto const& ids = snapshot.at("bodies").at("id");
    for (std::size_t i = 0; i < ids.size(); ++i)
        if (ids[i].get<std::uint64_t>() == id)
            return static_cast<std::ptrdiff_t>(i);
    return -1;
}

} // namespace kugel::test_support
