#pragma once

#include <span>
#include <string>
#include <string_view>

namespace kugel::server {

/// An origin as `--allow-origin` takes it and as origins are compared: "*" (every origin),
/// "null" (the opaque origin of file:// pages and sandboxed frames), or
/// scheme://host[:port] in lower case without a trailing slash. Throws std::invalid_argument,
/// saying what is wrong, for anything else (a path, a missing scheme, a bad port).
std::string normalized_origin(std::string_view origin);

/// Whether a WebSocket upgrade whose `Origin` header is `origin` may proceed: no header
/// (empty: a program, not a browser), the server's own origin (scheme://host:port naming
/// the `Host` the request was sent to: the page the server serves), or one of `allowed`
/// (normalized_origin's form; "*" allows every origin).
bool origin_allowed(std::string_view origin, std::string_view host,
                    std::span<std::string const> allowed);

/// Whether a `Host` header names this machine's loopback interface, with or without a port:
/// localhost or a name under .localhost (RFC 6761), an IPv4 address in 127.0.0.0/8, or [::1].
bool is_loopback_host(std::string_view host);

/// A host name as `--allow-host` takes it and as hosts are compared: "*" (every host), or a
/// host name or address in lower case, IPv6 in brackets, without a port. Throws
/// std::invalid_argument, saying what is wrong, for anything else.
std::string normalized_host(std::string_view host);

/// Whether a request whose `Host` header is `host` may be served by a server that checks
/// hosts (one listening on loopback): no header (an HTTP/1.0 program; a browser always sends
/// one), a loopback host (is_loopback_host), or a host in `allowed` (normalized_host's form,
/// compared without the port; "*" allows every host). This is what keeps a page whose name
/// was rebound to 127.0.0.1 (DNS rebinding) from reaching the server: its requests name the
/// page's host.
bool host_allowed(std::string_view host, std::span<std::string const> allowed);

} // namespace kugel::server
