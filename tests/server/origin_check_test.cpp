// Which browser origins may open a WebSocket, and the admin token's comparison: the pure
// functions behind the server's access checks (the server tests drive them over the wire).

#include "admin_token.hpp"
#include "origin_check.hpp"

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>
#include <vector>

namespace kugel::server {
namespace {

bool allowed(std::string_view origin, std::string_view host, std::vector<std::string> const& list = {})
{
    return origin_allowed(origin, host, list);
}

TEST(OriginCheck, NoOriginIsAProgramAndIsLetIn)
{
    EXPECT_TRUE(allowed("", "127.0.0.1:8080"));
    EXPECT_TRUE(allowed("", ""));
}

TEST(OriginCheck, TheServersOwnPageIsLetInWhateverTheCaseAndDefaultPort)
{
    EXPECT_TRUE(allowed("http://127.0.0.1:8080", "127.0.0.1:8080"));
    EXPECT_TRUE(allowed("http://LocalHost:8080", "localhost:8080"));
    EXPECT_TRUE(allowed("http://example.org", "example.org:80"));
    EXPECT_TRUE(allowed("https://example.org", "example.org"));
    EXPECT_TRUE(allowed("https://example.org:443", "example.org"));
    EXPECT_TRUE(allowed("http://[::1]:8080", "[::1]:8080"));
    EXPECT_TRUE(allowed("http://127.0.0.1:8080/", "127.0.0.1:8080"));
}

TEST(OriginCheck, AnotherHostOrPortIsRefused)
{
    EXPECT_FALSE(allowed("http://evil.example", "127.0.0.1:8080"));
    EXPECT_FALSE(allowed("http://127.0.0.1:9090", "127.0.0.1:8080"));
    EXPECT_FALSE(allowed("http://localhost:8080", "127.0.0.1:8080")); // same machine, other name
    EXPECT_FALSE(allowed("https://example.org", "example.org:80"));   // https implies 443
    EXPECT_FALSE(allowed("http://127.0.0.1.evil.example:8080", "127.0.0.1:8080"));
    EXPECT_FALSE(allowed("null", "127.0.0.1:8080"));
    EXPECT_FALSE(allowed("not an origin", "127.0.0.1:8080"));
    EXPECT_FALSE(allowed("http://127.0.0.1:8080", "")); // no Host: nothing to be the same as
}

TEST(OriginCheck, TheAllowListAndStarLetIn)
{
    std::vector<std::string> const list{normalized_origin("https://Viewer.Example.org/"),
                                        normalized_origin("null")};
    EXPECT_TRUE(allowed("https://viewer.example.org", "127.0.0.1:8080", list));
    EXPECT_TRUE(allowed("null", "127.0.0.1:8080", list));
    EXPECT_FALSE(allowed("http://viewer.example.org", "127.0.0.1:8080", list)); // other scheme
    EXPECT_FALSE(allowed("https://viewer.example.org:8443", "127.0.0.1:8080", list));
    EXPECT_TRUE(allowed("http://anything.example", "127.0.0.1:8080", {"*"}));
    EXPECT_TRUE(allowed("not an origin", "127.0.0.1:8080", {"*"}));
}

TEST(OriginCheck, NormalizedOriginRefusesWhatIsNoOriginAndSaysWhy)
{
    EXPECT_EQ(normalized_origin("HTTPS://Example.ORG:8443/"), "https://example.org:8443");
    EXPECT_EQ(normalized_origin("*"), "*");
    for (std::string const bad : {"example.org", "https://example.org/page", "https://",
                                  "https://example.org:80a", "https://user@example.org", "://x",
                                  "https://example.org:1234567", ""}) {
        SCOPED_TRACE(bad);
        try {
            (void)normalized_origin(bad);
            ADD_FAILURE() << "accepted";
        } catch (std::invalid_argument const& e) {
            EXPECT_NE(std::string(e.what()).find("scheme://host[:port]"), std::string::npos) << e.what();
        }
    }
}

TEST(AdminToken, OnlyTheExactTokenIsAdmin)
{
    std::string const token = "correct-horse-battery-staple";
    EXPECT_TRUE(is_admin_token(token, token));
    EXPECT_FALSE(is_admin_token("correct-horse-battery-stapl", token));   // a prefix
    EXPECT_FALSE(is_admin_token("correct-horse-battery-staple!", token)); // longer
    EXPECT_FALSE(is_admin_token("Correct-horse-battery-staple", token));
    EXPECT_FALSE(is_admin_token("", token));
    EXPECT_FALSE(is_admin_token(std::string("correct-horse-battery-staple\0", 29), token));
}

TEST(AdminToken, WithoutAConfiguredTokenNobodyIsAdmin)
{
    EXPECT_FALSE(is_admin_token("", ""));
    EXPECT_FALSE(is_admin_token("anything", ""));
}

} // namespace
} // namespace kugel::server
