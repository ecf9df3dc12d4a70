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

} // namespace kugel::server
