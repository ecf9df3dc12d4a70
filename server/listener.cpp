#include "listener.hpp"

#include <spdlog/spdlog.h>

namespace kugel::server {

listener::listener(net::io_context& io, tcp::endpoint endpoint,
                   std::shared_ptr<http_routes const> routes)
    : io_(io), acceptor_(net::make_strand(io)), routes_(std::move(routes))
{
    acceptor_.open(endpoint.protocol());
    acceptor_.set_option(net::socket_base::reuse_address(true));
    acceptor_.bind(endpoint);
    acceptor_.listen(net::socket_base::max_listen_connections);
    port_ = acceptor_.local_endpoint().port();
}

void listener::run()
{
    net::dispatch(acceptor_.get_executor(),
                  beast::bind_front_handler(&listener::do_accept, shared_from_this()));
}

void listener::stop()
{
    net::dispatch(acceptor_.get_executor(), [self = shared_from_this()] {
        beast::error_code ignored;
        self->acceptor_.close(ignored);
    });
}

void listener::do_accept()
{
    acceptor_.async_accept(net::make_strand(io_),
                           beast::bind_front_handler(&listener::on_accept, shared_from_this()));
}

void listener::on_accept(beast::error_code ec, tcp::socket socket)
{
    if (ec == net::error::operation_aborted || !acceptor_.is_open())
        return; // stopped
    if (ec)
        fail(ec, "accept");
    else
        std::make_shared<http_session>(std::move(socket), routes_)->run();
    do_accept();
}

void fail(beast::error_code ec, char const* what)
{
    // The peer went away or we closed the connection: normal, not worth a warning.
    if (ec == net::error::operation_aborted || ec == websocket::error::closed ||
        ec == beast::error::timeout || ec == net::error::eof ||
        ec == net::error::connection_reset || ec == net::error::broken_pipe ||
        ec == http::error::end_of_stream)
        spdlog::debug("{}: {}", what, ec.message());
    else
        spdlog::warn("{}: {}", what, ec.message());
}

} // namespace kugel::server
