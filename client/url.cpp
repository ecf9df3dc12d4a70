#include "url.hpp"

#include <charconv>

namespace kugel::client {

websocket_url parse_websocket_url(std::string_view url)
{
    constexpr std::string_view scheme = "ws://";
    if (url.substr(0, scheme.size()) != scheme)
        throw url_error("'" + std::string(url) + "' is not a ws:// URL" +
                        (url.substr(0, 6) == "wss://" ? " (wss:// is not supported)" : ""));
    std::string_view rest = url.substr(scheme.size());
    auto const slash = rest.find('/');
    std::string_view authority = rest.substr(0, slash);
    websocket_url result;
    result.target = slash == std::string_view::npos ? "/" : std::string(rest.substr(slash));

    std::string_view port_text;
    if (authority.substr(0, 1) == "[") { // [::1]:8080
        auto const close = authority.find(']');
        if (close == std::string_view::npos)
            throw url_error("'" + std::string(url) + "': unclosed '[' in the host");
        result.host = std::string(authority.substr(1, close - 1));
        std::string_view const after = authority.substr(close + 1);
        if (!after.empty() && after.front() != ':')
            throw url_error("'" + std::string(url) + "': unexpected text after ']'");
        port_text = after.empty() ? std::string_view{} : after.substr(1);
        if (!after.empty() && port_text.empty())
            throw url_error("'" + std::string(url) + "': empty port");
    } else {
        auto const colon = authority.find(':');
        result.host = std::string(authority.substr(0, colon));
        if (colon != std::string_view::npos) {
            port_text = authority.substr(colon + 1);
            if (port_text.empty())
                throw url_error("'" + std::string(url) + "': empty port");
        }
    }
    if (result.host.empty())
        throw url_error("'" + std::string(url) + "' names no host");
    if (!port_text.empty()) {
        unsigned port = 0;
        auto const [end, ec] =
            std::from_chars(port_text.data(), port_text.data() + port_text.size(), port);
        if (ec != std::errc{} || end != port_text.data() + port_text.size() || port == 0 ||
            port > 65535)
            throw url_error("'" + std::string(url) +
                            "': the port must be a number from 1 to 65535");
        result.port = static_cast<std::uint16_t>(port);
    }
    return result;
}

std::string to_string(websocket_url const& url)
{
    bool const ipv6 = url.host.find(':') != std::string::npos;
    return "ws://" + (ipv6 ? "[" + url.host + "]" : url.host) + ":" + std::to_string(url.port) +
           url.target;
}

} // namespace kugel::client
