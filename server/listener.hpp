#pragma once

#include "http_session.hpp"
#include "network.hpp"

#include <memory>

namespace kugel::server {

/// Accepts TCP connections and starts an http_session on each, on a strand of its own.
class listener : public std::enable_shared_from_this<listener>
{
public:
    /// Binds and listens; throws boost::system::system_error when the address is taken.
    listener(net::io_context& io, tcp::endpoint endpoint, std::shared_ptr<http_routes const> routes);

    void run();
    void stop();
    std::uint16_t port() const { return port_; }

private:
    void do_accept();
    void on_accept(beast::error_code ec, tcp::socket socket);

    net::io_context& io_;
    tcp::acceptor acceptor_;
    std::shared_ptr<http_routes const> routes_;
    std::uint16_t port_;
};

} // namespace kugel::server
