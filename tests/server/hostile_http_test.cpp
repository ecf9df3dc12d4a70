// Hostile HTTP, one case per row: the raw request a client writes to a real socket and the
// status the server must answer. The web root sits next to a secret file, and holds links
// that lead out of it; no row may ever get the secret's bytes back. Then the WebSocket
// upgrade's own hostile values (keys, hosts a rebound name would send) and the probes that
// monitoring calls with a query string.

#include "server.hpp"

#include "support/http_get.hpp"
#include "support/in_process_server.hpp"
#include "support/scene_files.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

namespace kugel::server {
namespace {

namespace fs = std::filesystem;
using test_support::http_raw;

constexpr char const* secret = "the secret outside the web root";

struct http_case
{
    std::string name;
    std::string target;    ///< the request line's target, as written on the wire
    unsigned status;       ///< what the server answers (0: it closes without an answer)
    std::string host = {}; ///< the Host header; empty: 127.0.0.1:PORT
};

/// The web root (an index, a script, a subfolder, a hidden file, links in and out) beside
/// a folder with a secret, under a fresh temporary folder.
struct web_tree
{
    // One tree per test: the suite's tests run at the same time, each in its own process.
    fs::path base = fs::path(testing::TempDir()) /
                    ("kugel_hostile_http_" + std::string(testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::path root = base / "root";
    fs::path outside = base / "outside";

    web_tree()
    {
        fs::remove_all(base);
        fs::create_directories(root / "sub");
        fs::create_directories(outside);
        std::ofstream(root / "index.html") << "<!doctype html><title>kugel</title>";
        std::ofstream(root / "app.js") << "console.log('kugel');";
        std::ofstream(root / "sub" / "page.html") << "<p>sub</p>";
        std::ofstream(root / ".env") << secret;
        std::ofstream(outside / "secret.txt") << secret;
        fs::create_symlink(outside / "secret.txt", root / "link_out");
        fs::create_symlink("../outside", root / "dir_out");
        fs::create_symlink("app.js", root / "link_in.js");
    }
};

std::vector<http_case> catalogue(fs::path const& outside)
{
    std::string const secret_file = (outside / "secret.txt").string();
    return {
        // What the page needs is served.
        {"the index", "/", 200},
        {"a file", "/app.js", 200},
        {"a file with a query string", "/app.js?v=1", 200},
        {"a file with a fragment", "/app.js#top", 200},
        {"a file in a folder", "/sub/page.html", 200},
        {"a folder's index", "/sub/", 404}, // it has none
        {"a doubled slash inside the root", "/sub//page.html", 200},
        {"a percent-encoded letter", "/%61pp.js", 200},
        {"a link that stays inside", "/link_in.js", 200},

        // Every way out of the root, and nothing it hides.
        {"a doubled slash before an absolute path", "//etc/passwd", 404},
        {"a doubled slash before the secret", "/" + secret_file, 404},
        {"three slashes", "///etc/passwd", 404},
        {"dot-dot", "/../outside/secret.txt", 404},
        {"dot-dot after a folder", "/sub/../../outside/secret.txt", 404},
        {"dot-dot that stays inside", "/sub/../app.js", 404},
        {"a dot segment", "/./app.js", 404},
        {"encoded dot-dot", "/%2e%2e/outside/secret.txt", 404},
        {"encoded dot-dot in capitals", "/%2E%2E/outside/secret.txt", 404},
        {"encoded slashes", "/..%2f..%2foutside%2fsecret.txt", 404},
        {"encoded slash before an absolute path", "/%2fetc%2fpasswd", 404},
        {"doubly encoded dot-dot", "/%252e%252e/outside/secret.txt", 404},
        {"backslashes", "/..\\outside\\secret.txt", 404},
        {"encoded backslashes", "/..%5coutside%5csecret.txt", 404},
        {"an encoded NUL", "/app.js%00.html", 404},
        {"a bad escape", "/app.js%", 404},
        {"a half escape", "/app.js%4", 404},
        {"a non-hex escape", "/app%zz.js", 404},
        {"a link to a file outside", "/link_out", 404},
        {"a link to a folder outside", "/dir_out/secret.txt", 404},
        {"a hidden file", "/.env", 404},
        {"an encoded hidden file", "/%2eenv", 404},
        {"the absolute form", "http://127.0.0.1/../outside/secret.txt", 404},
        {"an asterisk", "*", 404},
        {"a missing file", "/missing.js", 404},

        // Probes with a query string, as load balancers and monitoring send them.
        {"/healthz with a query", "/healthz?probe=1", 200},
        {"/readyz with a query", "/readyz?probe=1", 200},
        {"/metrics with a query", "/metrics?name[]=kugel", 200},

        // Hosts: a page whose name was rebound to 127.0.0.1 names itself.
        {"a foreign host", "/", 403, "evil.example"},
        {"a foreign host with the port", "/healthz", 403, "evil.example:PORT"},
        {"a host that only starts with localhost", "/", 403, "localhost.evil.example"},
        {"a host that ends in 127.0.0.1", "/", 403, "evil.127.0.0.1"},
        {"localhost", "/", 200, "localhost:PORT"},
        {"a name under .localhost", "/", 200, "kugel.localhost:PORT"},
        {"another loopback address", "/", 200, "127.1.2.3"},
        {"IPv6 loopback", "/", 200, "[::1]:PORT"},
        {"localhost in capitals", "/", 200, "LOCALHOST:PORT"},
    };
}

std::string with_port(std::string text, std::uint16_t port)
{
    auto const at = text.find("PORT");
    if (at != std::string::npos)
        text.replace(at, 4, std::to_string(port));
    return text;
}

server_options options_for(web_tree const& tree)
{
    server_options o;
    o.rooms.push_back({"still", test_support::write_scene(tree.base / "still.json",
                                                          test_support::still_scene())});
    o.web_root = tree.root;
    return o;
}

TEST(HostileHttp, EachRequestIsAnsweredAsDocumentedAndNothingOutsideTheRootIsServed)
{
    web_tree const tree;
    test_support::in_process_server s(options_for(tree));
    while (s.ticks("still") == 0) // /readyz answers 200 once the room ticks
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    for (http_case const& c : catalogue(tree.outside)) {
        SCOPED_TRACE(c.name + ": " + c.target);
        std::string const host = c.host.empty() ? "127.0.0.1:PORT" : c.host;
        auto const reply = http_raw(s.port(), "GET " + c.target + " HTTP/1.1\r\nHost: " +
                                                  with_port(host, s.port()) +
                                                  "\r\nConnection: close\r\n\r\n");
        EXPECT_EQ(reply.status, c.status) << reply.body;
        EXPECT_EQ(reply.body.find(secret), std::string::npos) << "the secret was served";
        EXPECT_EQ(reply.body.find("root:"), std::string::npos) << "/etc/passwd was served";
        if (c.status == 404) { // says nothing of why: no path, no file name
            EXPECT_EQ(reply.body, "not found\n");
        }
    }
    // The server still serves the page afterwards.
    EXPECT_EQ(test_support::http_get(s.port(), "/").status, 200U);
}

TEST(HostileHttp, ANulByteInTheRequestLineIsRefused)
{
    web_tree const tree;
    test_support::in_process_server s(options_for(tree));
    using namespace std::string_literals;
    auto const reply = http_raw(s.port(), "GET /app.js\0../../outside/secret.txt HTTP/1.1\r\n"
                                          "Host: 127.0.0.1\r\nConnection: close\r\n\r\n"s);
    EXPECT_NE(reply.status, 200U); // Beast refuses the request line: no answer at all
    EXPECT_EQ(reply.body.find(secret), std::string::npos);
}

TEST(HostileHttp, AllowedHostsAreAnsweredAndStarAnswersEveryHost)
{
    web_tree const tree;
    server_options o = options_for(tree);
    o.allowed_hosts = {"Kugel.Example.org"};
    test_support::in_process_server s(o);
    auto const get = [&](std::string const& host) {
        return http_raw(s.port(), "GET /healthz HTTP/1.1\r\nHost: " + host + "\r\nConnection: close\r\n\r\n").status;
    };
    EXPECT_EQ(get("kugel.example.org"), 200U);
    EXPECT_EQ(get("kugel.example.org:8080"), 200U);
    EXPECT_EQ(get("other.example.org"), 403U);
    EXPECT_EQ(get("localhost"), 200U);

    server_options every = options_for(tree);
    every.allowed_hosts = {"*"};
    test_support::in_process_server open(every);
    EXPECT_EQ(http_raw(open.port(), "GET /healthz HTTP/1.1\r\nHost: evil.example\r\nConnection: close\r\n\r\n").status,
              200U);

    server_options bad = options_for(tree);
    bad.allowed_hosts = {"kugel.example.org:8080"};
    EXPECT_THROW(test_support::in_process_server{bad}, std::invalid_argument);
}

/// An upgrade request with this key, Host and Origin (none when empty).
std::string upgrade(std::string const& key, std::string const& host, std::string const& origin = {},
                    std::string const& target = "/ws/still")
{
    std::string request = "GET " + target + " HTTP/1.1\r\nHost: " + host +
                          "\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Version: 13\r\n";
    if (key != "(none)")
        request += "Sec-WebSocket-Key: " + key + "\r\n";
    if (!origin.empty())
        request += "Origin: " + origin + "\r\n";
    return request + "\r\n";
}

TEST(HostileHttp, AnUpgradeNeedsAKeyOfSixteenBytesInBase64)
{
    web_tree const tree;
    test_support::in_process_server s(options_for(tree));
    std::string const host = "127.0.0.1:" + std::to_string(s.port());
    EXPECT_EQ(http_raw(s.port(), upgrade("dGhlIHNhbXBsZSBub25jZQ==", host)).status, 101U);
    for (std::string const key : {"", "AAAA", "(none)", "!!!!!!!!!!!!!!!!!!!!!!==", "dGhlIHNhbXBsZSBub25jZQ",
                                  "dGhlIHNhbXBsZSBub25jZQ==AAAA", "dGhlIHNhbXBsZSBub25jZQ=A", "dGhlIHNhbXBsZSBub25j"}) {
        SCOPED_TRACE("key '" + key + "'");
        auto const reply = http_raw(s.port(), upgrade(key, host));
        EXPECT_EQ(reply.status, 400U) << reply.body;
    }
}

TEST(HostileHttp, ARebindingPageCannotOpenAWebSocket)
{
    web_tree const tree;
    test_support::in_process_server s(options_for(tree));
    std::string const port = std::to_string(s.port());
    std::string const key = "dGhlIHNhbXBsZSBub25jZQ==";
    // The own-origin rule alone would let this in: Origin and Host name the same site.
    auto const rebound = http_raw(s.port(), upgrade(key, "evil.example:" + port, "http://evil.example:" + port));
    EXPECT_EQ(rebound.status, 403U);
    EXPECT_NE(rebound.body.find("--allow-host"), std::string::npos) << rebound.body;
    EXPECT_EQ(http_raw(s.port(), upgrade(key, "localhost:" + port, "http://localhost:" + port)).status, 101U);
}

// An upgrade to a room that does not exist is told which rooms do: a server with one room
// named "still" and no default answers /ws and /ws/nosuch with 404 naming /ws/still.
TEST(HostileHttp, AnUpgradeToNoRoomIsToldTheRooms)
{
    web_tree const tree;
    test_support::in_process_server s(options_for(tree));
    std::string const host = "127.0.0.1:" + std::to_string(s.port());
    std::string const key = "dGhlIHNhbXBsZSBub25jZQ==";
    for (std::string const target : {"/ws", "/ws/nosuch"}) {
        auto const reply = http_raw(s.port(), upgrade(key, host, {}, target));
        EXPECT_EQ(reply.status, 404U) << target;
        EXPECT_NE(reply.body.find("the rooms are /ws/still"), std::string::npos) << reply.body;
        EXPECT_EQ(reply.body.find("/ws for default"), std::string::npos) << reply.body;
    }
}

} // namespace
} // namespace kugel::server
