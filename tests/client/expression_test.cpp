#include "client/expression.hpp"

#include <cmath>
#include <gtest/gtest.h>
#include <map>
#include <string>

namespace kugel::client {
namespace {

double eval(std::string_view text, std::map<std::string, double, std::less<>> const& vars = {})
{
    return evaluate(text, [&](std::string_view name) -> std::optional<double> {
        auto const it = vars.find(name);
        return it == vars.end() ? std::nullopt : std::optional<double>(it->second);
    });
}

TEST(Expression, ArithmeticWithTheUsualPrecedence)
{
    EXPECT_EQ(eval("1 + 2 * 3"), 7.0);
    EXPECT_EQ(eval("(1 + 2) * 3"), 9.0);
    EXPECT_EQ(eval("10 - 4 - 3"), 3.0); // left to right
    EXPECT_EQ(eval("12 / 3 / 2"), 2.0);
    EXPECT_EQ(eval("1.5e3 + .25"), 1500.25);
}

TEST(Expression, PowerIsRightAssociativeAndBindsTighterThanMinus)
{
    EXPECT_EQ(eval("2 ^ 3 ^ 2"), 512.0);
    EXPECT_EQ(eval("-2 ^ 2"), -4.0);
    EXPECT_EQ(eval("2 ^ -1"), 0.5);
    EXPECT_EQ(eval("--3"), 3.0);
}

TEST(Expression, VariablesAndFunctions)
{
    double const t = 21 * 0.015625;
    EXPECT_EQ(eval("$z0 - $g / 2 * $t^2", {{"z0", 10}, {"g", 9.81}, {"t", t}}),
              10 - 9.81 / 2 * std::pow(t, 2));
    EXPECT_EQ(eval("sqrt(16) + abs(-2) + min(1, 2) + max(1, 2)"), 4.0 + 2.0 + 1.0 + 2.0);
}

TEST(Expression, RefusesWhatItCannotRead)
{
    EXPECT_THROW(eval(""), expression_error);
    EXPECT_THROW(eval("1 +"), expression_error);
    EXPECT_THROW(eval("(1 + 2"), expression_error);
    EXPECT_THROW(eval("1 2"), expression_error);
    EXPECT_THROW(eval("$"), expression_error);
    EXPECT_THROW(eval("$missing + 1"), expression_error);
    EXPECT_THROW(eval("cos(1)"), expression_error);
    EXPECT_THROW(eval("sqrt(1, 2)"), expression_error);
    EXPECT_THROW(eval("1 / 0"), expression_error); // not finite
    EXPECT_THROW(eval("1e999"), expression_error);
}

TEST(Expression, ErrorsSayWhereAndWhat)
{
    try {
        eval("1 + $speed", {});
        FAIL() << "no error";
    } catch (expression_error const& e) {
        EXPECT_NE(std::string(e.what()).find("unknown variable $speed"), std::string::npos)
            << e.what();
    }
}

} // namespace
} // namespace kugel::client
