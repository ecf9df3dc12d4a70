#include "http_session.hpp"

#include "metrics.hpp"
#include "origin_check.hpp"
#include "static_files.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cctype>
#include <chrono>

namespace kugel::server {

namespace {

constexpr std::size_t max_request_body = 8 * 1024; // bytes; GET requests carry none
constexpr auto request_timeout = std::chrono::seconds(30);

template <class Body>
void finish(http::response<Body>& response, http::request<http::string_body> const& request,
            std::string_view content_type)
{
    response.set(http::field::server, "kugel-server");
    response.set(http::field::content_type, content_type);
    response.keep_alive(request.keep_alive());
}

http::response<http::string_body> text_response(http::request<http::string_body> const& request,
                                                http::status status, std::string body,
                                                std::string_view content_type = "text/plain")
{
    http::response<http::string_body> response{status, request.version()};
    finish(response, request, content_type);
    response.body() = std::move(body);
    response.prepare_payload();
    if (request.method() == http::verb::head)
        response.body().clear(); // Content-Length stays that of the GET
    return response;
}

/// Whether a Sec-WebSocket-Key is what RFC 6455 §4.2.1 requires: the base64 of 16 bytes,
/// which is 22 characters of the base64 alphabet and "==".
bool valid_websocket_key(std::string_view key)
{
    auto const base64 = [](unsigned char c) { return std::isalnum(c) || c == '+' || c == '/'; };
    return key.size() == 24 && key.ends_with("==") &&
           std::all_of(key.begin(), key.begin() + 22, base64);
}

/// Client text for a log line or an answer: at most 100 bytes, control characters as '?'.
std::string printable(std::string_view text)
{
    std::string out(text.substr(0, 100));
    for (char& c : out)
        if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f)
            c = '?';
    return text.size() > 100 ? out + "..." : out;
}

} // namespace

std::optional<std::string> room_of_target(std::string_view target)
{
    std::string_view const path = path_of(target);
    if (path == "/ws" || path == "/ws/")
        return "default";
    if (path.starts_with("/ws/") && path.find('/', 4) == std::string_view::npos)
        return std::string(path.substr(4));
    return std::nullopt;
}

http_session::http_session(tcp::socket&& socket, std::shared_ptr<http_routes const> routes)
    : stream_(std::move(socket)), routes_(std::move(routes))
{
}

void http_session::run()
{
    net::dispatch(stream_.get_executor(),
                  beast::bind_front_handler(&http_session::do_read, shared_from_this()));
}

void http_session::do_read()
{
    parser_.emplace();
    parser_->body_limit(max_request_body);
    stream_.expires_after(request_timeout);
    http::async_read(stream_, buffer_, *parser_,
                     beast::bind_front_handler(&http_session::on_read, shared_from_this()));
}

void http_session::on_read(beast::error_code ec, std::size_t)
{
    if (ec == http::error::end_of_stream)
        return do_close();
    if (ec)
        return fail(ec, "http read");

    http::request<http::string_body> request = parser_->release();
    // A page whose name an attacker rebound to 127.0.0.1 sends its own name as Host: a
    // server on loopback serves only loopback names and those it was told of.
    if (routes_->check_host && !host_allowed(request[http::field::host], routes_->allowed_hosts)) {
        std::string const shown = printable(request[http::field::host]);
        auto const n = ++routes_->host_refusals;
        if (n <= 10 || n % 100 == 0)
            spdlog::info("refused a request for host {} ({} so far); --allow-host {} would allow it",
                         shown, n, shown);
        return send(text_response(request, http::status::forbidden,
                                  "host " + shown + " is not served here: this server listens on "
                                  "loopback and answers localhost, 127.0.0.1 and [::1]; start "
                                  "kugel-server with --allow-host to name another\n"));
    }
    if (websocket::is_upgrade(request)) {
        if (!valid_websocket_key(request[http::field::sec_websocket_key]))
            return send(text_response(request, http::status::bad_request,
                                      "Sec-WebSocket-Key must be the base64 encoding of 16 bytes "
                                      "(RFC 6455, section 4.2.1)\n"));
        // A browser lets any page open a WebSocket to any server, and says which page did in
        // Origin: only the server's own page and the origins it was told of are let in.
        std::string_view const origin = request[http::field::origin];
        if (!origin_allowed(origin, request[http::field::host], routes_->allowed_origins)) {
            std::string const shown = printable(origin);
            auto const n = ++routes_->origin_refusals;
            if (n <= 10 || n % 100 == 0) // a refused page retrying cannot flood the log
                spdlog::info("refused a WebSocket upgrade from origin {} ({} so far); "
                             "--allow-origin {} would allow it",
                             shown, n, shown);
            return send(text_response(request, http::status::forbidden,
                                      "origin " + shown + " may not open a WebSocket here; "
                                      "start kugel-server with --allow-origin " + shown +
                                      " to allow it\n"));
        }
        auto const room_name = room_of_target(request.target());
        auto target_room = room_name ? routes_->find_room(*room_name) : nullptr;
        if (!target_room) {
            spdlog::info("refused a WebSocket upgrade to {}: no such room", request.target());
            std::string rooms;
            for (std::string const& name : routes_->room_names)
                rooms += (rooms.empty() ? "" : ", ") + ("/ws/" + name);
            return send(text_response(request, http::status::not_found,
                                      "no room at " + printable(request.target()) + "; the rooms are " + rooms +
                                          (routes_->find_room("default") ? " (and /ws for default)" : "") + "\n"));
        }
        stream_.expires_never(); // the WebSocket session keeps its own timeouts
        routes_->upgrade(stream_.release_socket(), std::move(target_room), std::move(request));
        return;
    }
    if (request.method() != http::verb::get && request.method() != http::verb::head)
        return send(text_response(request, http::status::method_not_allowed,
                                  "only GET and HEAD are served\n"));
    std::string_view const target = request.target();
    std::string_view const path = path_of(target); // probes may carry a query string
    if (path == "/healthz")
        return send(text_response(request, http::status::ok, routes_->health(), "application/json"));
    if (path == "/readyz") {
        auto [ready, body] = routes_->ready();
        return send(text_response(request, ready ? http::status::ok : http::status::service_unavailable,
                                  std::move(body), "application/json"));
    }
    if (path == "/metrics")
        return send(text_response(request, http::status::ok, routes_->metrics(), metrics_content_type));

    auto const file = routes_->web_root.empty() ? std::nullopt : file_for(routes_->web_root, target);
    if (!file)
        return send(text_response(request, http::status::not_found, "not found\n"));
    beast::error_code open_ec;
    http::file_body::value_type body;
    body.open(file->c_str(), beast::file_mode::scan, open_ec);
    if (open_ec)
        return send(text_response(request, http::status::internal_server_error,
                                  "cannot read this file\n"));
    auto const size = body.size();
    if (request.method() == http::verb::head) {
        http::response<http::empty_body> response{http::status::ok, request.version()};
        finish(response, request, mime_type(file->string()));
        response.content_length(size);
        return send(std::move(response));
    }
    http::response<http::file_body> response{std::piecewise_construct, std::make_tuple(std::move(body)),
                                              std::make_tuple(http::status::ok, request.version())};
    finish(response, request, mime_type(file->string()));
    response.set(http::field::cache_control, "no-cache");
    response.content_length(size);
    send(std::move(response));
}

template <class Body>
void http_session::send(http::response<Body>&& response)
{
    auto message = std::make_shared<http::response<Body>>(std::move(response));
    response_ = message;
    http::async_write(stream_, *message,
                      beast::bind_front_handler(&http_session::on_write, shared_from_this(),
                                                message->keep_alive()));
}

void http_session::on_write(bool keep_alive, beast::error_code ec, std::size_t)
{
    if (ec)
        return fail(ec, "http write");
    response_.reset();
    if (!keep_alive)
        return do_close();
    do_read();
}

void http_session::do_close()
{
    beast::error_code ec;
    stream_.socket().shutdown(tcp::socket::shutdown_send, ec);
}

} // namespace kugel::server
