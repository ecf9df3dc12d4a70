#include "client/variables.hpp"

#include <gtest/gtest.h>

namespace kugel::client {
namespace {

using json = nlohmann::json;

TEST(Variables, ResolveReplacesWholeVariablesAndExpressionsAtAnyDepth)
{
    variables v;
    v.set("ball", 17);
    v.set("where", json::array({1, 2, 3}));
    v.set("m", 2);
    json const resolved =
        v.resolve({{"id", "$ball"}, {"at", "$where"}, {"impulse", {"= 3 * $m", 0, "plain text"}}});
    EXPECT_EQ(resolved["id"], 17);
    EXPECT_EQ(resolved["at"], json::array({1, 2, 3}));
    EXPECT_EQ(resolved["impulse"][0], 6.0);
    EXPECT_EQ(resolved["impulse"][2], "plain text");
}

TEST(Variables, AnOverlayTakesPrecedence)
{
    variables v;
    v.set("tick", 1);
    variables here;
    here.set("tick", 42);
    EXPECT_EQ(v.number("= $tick + 1", "x", &here), 43.0);
    EXPECT_EQ(v.number("= $tick + 1", "x"), 2.0);
}

TEST(Variables, UnsetOrWrongTypeIsAnError)
{
    variables v;
    v.set("name", "bob");
    EXPECT_THROW(v.resolve("$nobody"), substitution_error);
    EXPECT_THROW(v.resolve("= $name + 1"), substitution_error);
    EXPECT_THROW(v.number("$name", "x"), substitution_error);
    EXPECT_THROW(v.whole_number(1.5, "x"), substitution_error);
    EXPECT_THROW(v.whole_number(-1, "x"), substitution_error);
    EXPECT_EQ(v.whole_number("= 2 * 3", "x"), 6U);
}

TEST(Variables, InterpolatePutsJsonTextIntoText)
{
    variables v;
    v.set("id", 17);
    v.set("name", "bob");
    EXPECT_EQ(v.interpolate(R"({"id": $id, "name": $name, "price": "$$5"})"),
              R"({"id": 17, "name": "bob", "price": "$5"})");
    EXPECT_THROW(v.interpolate("$nobody"), substitution_error);
}

TEST(Variables, IsSubstitutedKnowsWhatResolveReplaces)
{
    EXPECT_TRUE(is_substituted("$x"));
    EXPECT_TRUE(is_substituted("= 1 + 1"));
    EXPECT_FALSE(is_substituted("x"));
    EXPECT_FALSE(is_substituted("$x y"));
    EXPECT_FALSE(is_substituted(3));
}

} // namespace
} // namespace kugel::client
