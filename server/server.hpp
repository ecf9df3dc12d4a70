#pragma once

#include "options.hpp"

#include <cstdint>
#include <memory>
#include <string_view>
#include <thread>
#include <vector>

namespace kugel::server {

class room;

/// The whole network server: rooms, the listener, and the threads that run them (one
/// io_context with a thread per core for the sessions; each room on a thread of its own).
class server
{
public:
    /// Loads every room's scene and binds the port. Throws scene::scene_error for a bad
    /// scene, std::invalid_argument for bad options, boost::system::system_error when the
    /// port cannot be bound.
    explicit server(server_options options);
    ~server();
    server(server const&) = delete;
    server& operator=(server const&) = delete;

    /// The port listened on (the chosen one when options.port was 0).
    std::uint16_t port() const;

    /// Starts the rooms' ticks and the worker threads; returns at once.
    void start();
    /// Also stops on SIGINT and SIGTERM (what kugel-server's main wants).
    void stop_on_signals();
    /// Stops accepting, closes every WebSocket with 1001 (going away), and lets the threads
    /// finish; callable from any thread, more than once.
    void stop();
    /// Blocks until the worker threads have finished.
    void wait();

    /// A hosted room, or nullptr.
    std::shared_ptr<room> find_room(std::string_view name) const;

private:
    struct state;
    std::unique_ptr<state> state_;
};

/// The built-in scene of the default room (scenes/arena.json, compiled in).
std::string_view default_scene_text();

} // namespace kugel::server
