#pragma once

#include "network.hpp"

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace kugel::server {

class room;

/// What an HTTP connection needs from the server: where the page's files are, and which
/// room a WebSocket path names.
struct http_routes
{
    std::filesystem::path web_root; ///< canonical (file_for); empty: no static files
    /// Every request's Host must pass host_allowed (the server listens on loopback, or was
    /// given hosts to allow).
    bool check_host = false;
    std::vector<std::string> allowed_hosts; ///< normalized_host's form
    /// Requests refused for their Host, for rate-limiting the log.
    mutable std::atomic<std::uint64_t> host_refusals{0};
    /// Origins allowed to upgrade besides the server's own (normalized_origin's form).
    std::vector<std::string> allowed_origins;
    /// Upgrades refused for their Origin, for rate-limiting the log.
    mutable std::atomic<std::uint64_t> origin_refusals{0};
    std::function<std::shared_ptr<room>(std::string_view name)> find_room;
    std::vector<std::string> room_names; ///< every room, for the answer to an upgrade to no room
    std::function<void(tcp::socket&&, std::shared_ptr<room>, http::request<http::string_body>)>
        upgrade; ///< hands the socket to a new websocket_session
    std::function<std::string()> health;  ///< the body of /healthz (JSON): alive
    std::function<std::string()> metrics; ///< the body of /metrics (Prometheus text)
    /// /readyz: whether every room is ticking, and the body (JSON).
    std::function<std::pair<bool, std::string>()> ready;
};

/// One HTTP connection: GET and HEAD of the page's static files, /healthz, /readyz, /metrics,
/// and the upgrade
/// to WebSocket on /ws (the default room) or /ws/ROOM. Keep-alive, one request at a time.
class http_session : public std::enable_shared_from_this<http_session>
{
public:
    http_session(tcp::socket&& socket, std::shared_ptr<http_routes const> routes);
    void run();

private:
    void do_read();
    void on_read(beast::error_code ec, std::size_t bytes);
    template <class Body>
    void send(http::response<Body>&& response);
    void on_write(bool keep_alive, beast::error_code ec, std::size_t bytes);
    void do_close();

    beast::tcp_stream stream_;
    beast::flat_buffer buffer_;
    std::shared_ptr<http_routes const> routes_;
    std::optional<http::request_parser<http::string_body>> parser_;
    std::shared_ptr<void> response_; ///< kept alive until written
};

/// The room a request target names: "/ws" is "default", "/ws/NAME" is NAME; nullopt for a
/// path that is not a WebSocket path.
std::optional<std::string> room_of_target(std::string_view target);

} // namespace kugel::server
