// Uses the installed client library as a program of one's own would: a URL, a message, and a
// connection that fails as documented.
#include "client/connection.hpp"
#include "client/url.hpp"
#include "protocol/codec.hpp"

#include <iostream>

int main()
{
    auto const url = kugel::client::parse_websocket_url("ws://127.0.0.1:1/ws/lab");
    std::cout << kugel::client::to_string(url) << '\n';
    std::cout << kugel::protocol::encode(kugel::protocol::ping{7}) << '\n';
    try {
        kugel::client::connection c("ws://127.0.0.1:1/ws/lab"); // nothing listens on port 1
        std::cout << "connected\n";
    } catch (kugel::client::connection_error const&) {
        std::cout << "no server\n";
    }
}
