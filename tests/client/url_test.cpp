#include "client/url.hpp"

#include <gtest/gtest.h>

namespace kugel::client {
namespace {

TEST(Url, SplitsHostPortAndTarget)
{
    websocket_url const u = parse_websocket_url("ws://127.0.0.1:9000/ws/lab");
    EXPECT_EQ(u.host, "127.0.0.1");
    EXPECT_EQ(u.port, 9000);
    EXPECT_EQ(u.target, "/ws/lab");
}

TEST(Url, DefaultsToPort80AndTheRoot)
{
    websocket_url const u = parse_websocket_url("ws://localhost");
    EXPECT_EQ(u.host, "localhost");
    EXPECT_EQ(u.port, 80);
    EXPECT_EQ(u.target, "/");
}

TEST(Url, ReadsBracketedIpv6)
{
    websocket_url const u = parse_websocket_url("ws://[::1]:8080/ws");
    EXPECT_EQ(u.host, "::1");
    EXPECT_EQ(u.port, 8080);
    EXPECT_EQ(to_string(u), "ws://[::1]:8080/ws");
}

TEST(Url, RefusesWhatIsNotAWsUrl)
{
    EXPECT_THROW(parse_websocket_url("http://127.0.0.1:8080/ws"), url_error);
    EXPECT_THROW(parse_websocket_url("wss://example.org/ws"), url_error);
    EXPECT_THROW(parse_websocket_url("ws://:8080/ws"), url_error);
    EXPECT_THROW(parse_websocket_url("ws://host:/ws"), url_error);
    EXPECT_THROW(parse_websocket_url("ws://host:0/ws"), url_error);
    EXPECT_THROW(parse_websocket_url("ws://host:65536/ws"), url_error);
    EXPECT_THROW(parse_websocket_url("ws://host:80x/ws"), url_error);
    EXPECT_THROW(parse_websocket_url("ws://[::1/ws"), url_error);
}

} // namespace
} // namespace kugel::client
