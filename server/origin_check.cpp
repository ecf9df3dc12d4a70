#include "origin_check.hpp"

#include <arpa/inet.h>

#include <algorithm>
#include <cctype>
#include <optional>
#include <stdexcept>

namespace kugel::server {

namespace {

std::string lower(std::string_view text)
{
    std::string out(text);
    std::ranges::transform(out, out.begin(),
                           [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return out;
}

/// The port a scheme implies when the origin names none.
std::string_view default_port(std::string_view scheme)
{
    return scheme == "https" || scheme == "wss" ? "443" : "80";
}

struct authority
{
    std::string host; ///< lower case; an IPv6 address keeps its brackets
    std::string port; ///< digits; empty when not given
};

/// "host", "host:port", "[v6]" or "[v6]:port"; nullopt when it is none of these.
std::optional<authority> split_authority(std::string_view text)
{
    std::size_t host_end = 0;
    if (text.starts_with('[')) {
        host_end = text.find(']');
        if (host_end == std::string_view::npos)
            return std::nullopt;
        ++host_end;
    } else {
        host_end = std::min(text.find(':'), text.size());
    }
    authority out{lower(text.substr(0, host_end)), {}};
    std::string_view rest = text.substr(host_end);
    if (!rest.empty()) {
        if (rest.front() != ':' || rest.size() == 1 || rest.size() > 6)
            return std::nullopt;
        out.port = std::string(rest.substr(1));
    }
    bool const host_ok =
        !out.host.empty() && std::ranges::none_of(out.host, [](unsigned char c) {
            return c <= 0x20 || c >= 0x7f || c == '/' || c == '?' || c == '#' || c == '@';
        });
    bool const port_ok = std::ranges::all_of(out.port, [](unsigned char c) { return std::isdigit(c); });
    if (!host_ok || !port_ok)
        return std::nullopt;
    return out;
}

} // namespace

std::string normalized_origin(std::string_view origin)
{
    if (origin == "*" || origin == "null")
        return std::string(origin);
    std::string text = lower(origin);
    if (text.ends_with('/'))
        text.pop_back();
    auto const separator = text.find("://");
    std::string_view const scheme = std::string_view(text).substr(0, std::min(separator, text.size()));
    if (separator == std::string::npos || scheme.empty() ||
        !std::ranges::all_of(scheme, [](unsigned char c) { return std::isalpha(c) || c == '+' || c == '-' || c == '.'; }))
        throw std::invalid_argument("origin '" + std::string(origin) +
                                    "' must be scheme://host[:port], such as https://example.org "
                                    "or http://localhost:8080 (or * for every origin)");
    if (!split_authority(std::string_view(text).substr(separator + 3)))
        throw std::invalid_argument("origin '" + std::string(origin) +
                                    "' must be scheme://host[:port] with no path, user or query, "
                                    "such as https://example.org");
    return text;
}

bool origin_allowed(std::string_view origin, std::string_view host,
                    std::span<std::string const> allowed)
{
    if (origin.empty())
        return true; // not a browser: nothing to protect a page from
    std::string normal;
    try {
        normal = normalized_origin(origin);
    } catch (std::invalid_argument const&) {
        normal = std::string(origin); // matched only by "*"
    }
    for (std::string const& a : allowed)
        if (a == "*" || a == normal)
            return true;
    // The server's own page: an origin that names the host and port the request went to.
    auto const separator = normal.find("://");
    if (separator == std::string::npos)
        return false;
    std::string_view const scheme = std::string_view(normal).substr(0, separator);
    auto const from = split_authority(std::string_view(normal).substr(separator + 3));
    auto const to = split_authority(host);
    if (!from || !to)
        return false;
    std::string_view const implied = default_port(scheme);
    return from->host == to->host &&
           (from->port.empty() ? implied : std::string_view(from->port)) ==
               (to->port.empty() ? implied : std::string_view(to->port));
}

bool is_loopback_host(std::string_view host)
{
    auto const a = split_authority(host);
    if (!a)
        return false;
    std::string const& name = a->host;
    if (name == "localhost" || name.ends_with(".localhost") || name == "[::1]")
        return true;
    in_addr v4{};
    return inet_pton(AF_INET, name.c_str(), &v4) == 1 &&
           (ntohl(v4.s_addr) >> 24) == 127; // 127.0.0.0/8
}

std::string normalized_host(std::string_view host)
{
    if (host == "*")
        return "*";
    auto const a = split_authority(host);
    if (!a || !a->port.empty())
        throw std::invalid_argument("host '" + std::string(host) +
                                    "' must be a host name or address without a port, such as "
                                    "kugel.example.org or 192.0.2.7 (or * for every host)");
    return a->host;
}

bool host_allowed(std::string_view host, std::span<std::string const> allowed)
{
    if (host.empty() || is_loopback_host(host))
        return true;
    auto const a = split_authority(host);
    if (!a)
        return false;
    return std::ranges::any_of(allowed, [&](std::string const& h) { return h == "*" || h == a->host; });
}

} // namespace kugel::server
