#include "client/body_check.hpp"

#include <gtest/gtest.h>

namespace kugel::client {
namespace {

using json = nlohmann::json;

/// Two bodies at tick 100: 4 at rest at the origin, 17 at (1, 2, 3) moving at (0, 0, -1).
protocol::snapshot two_bodies()
{
    protocol::snapshot s;
    s.tick = 100;
    s.time = 1.5625;
    s.bodies.id = {4, 17};
    s.bodies.position = {0, 0, 0, 1, 2, 3};
    s.bodies.velocity = {0, 0, 0, 0, 0, -1};
    s.bodies.radius = {0.5, 0.25};
    s.bodies.mass = std::vector<double>{2, 1};
    return s;
}

body_expectation at(json id, std::array<json, 3> position, json tolerance)
{
    body_expectation e;
    e.id = std::move(id);
    e.position = std::move(position);
    e.tolerance = std::move(tolerance);
    return e;
}

TEST(BodyCheck, PositionWithinTheToleranceOnEveryCheckedComponent)
{
    variables vars;
    EXPECT_TRUE(check_body(at(17, {1, 2, 3}, 0), two_bodies(), vars).passed);
    EXPECT_TRUE(check_body(at(17, {1.05, 2, 3}, 0.1), two_bodies(), vars).passed);
    EXPECT_FALSE(check_body(at(17, {1.05, 2, 3}, 0.01), two_bodies(), vars).passed);
    EXPECT_TRUE(check_body(at(17, {json(), json(), 3}, 0), two_bodies(), vars).passed);
}

// A tag is a string (variables interpolated) or null for none; the body's JSON has it, so a
// script may keep it.
TEST(BodyCheck, TagsAreComparedAndKept)
{
    variables vars;
    vars.set("ball", "ann's ball");
    protocol::snapshot s = two_bodies();
    body_expectation e;
    e.id = 17;
    e.tag = json(nullptr);
    EXPECT_TRUE(check_body(e, s, vars).passed) << "no tag column: no tag";
    s.bodies.tag = std::vector<std::string>{"", "$ball"};
    EXPECT_FALSE(check_body(e, s, vars).passed);
    s.bodies.tag = std::vector<std::string>{"", "ann's ball"};
    e.tag = json("$ball");
    body_check const check = check_body(e, s, vars);
    EXPECT_TRUE(check.passed) << check.arrived;
    EXPECT_EQ(check.body.at("tag"), "ann's ball");
    e.id = 4;
    EXPECT_FALSE(check_body(e, s, vars).passed);
    EXPECT_EQ(check_body(e, s, vars).arrived, "body 4 at tick 100, tag null");
    EXPECT_EQ(check_body(e, s, vars).body.at("tag"), json());
}

TEST(BodyCheck, ExpressionsSeeTheSnapshotsTickAndTime)
{
    variables vars;
    vars.set("start", 97);
    EXPECT_TRUE(
        check_body(at(17, {"= $tick - $start - 2", 2, "= $time * 1.92"}, 1e-12), two_bodies(), vars)
            .passed);
}

TEST(BodyCheck, SaysWhatWasExpectedAndWhatArrived)
{
    variables vars;
    body_expectation e = at(17, {1, 2, 4}, 0);
    e.velocity = std::array<json, 3>{0, 0, -1};
    body_check const check = check_body(e, two_bodies(), vars);
    EXPECT_FALSE(check.passed);
    EXPECT_EQ(check.expected, "body 17, position [1.0, 2.0, 4.0], velocity [0.0, 0.0, -1.0] ± 0.0");
    EXPECT_EQ(check.arrived,
              "body 17 at tick 100, position [1.0, 2.0, 3.0], velocity [0.0, 0.0, -1.0]");
}

TEST(BodyCheck, AbsentBodies)
{
    variables vars;
    body_expectation gone;
    gone.id = 5;
    gone.exists = false;
    EXPECT_TRUE(check_body(gone, two_bodies(), vars).passed);
    gone.id = 4;
    EXPECT_FALSE(check_body(gone, two_bodies(), vars).passed);

    body_expectation there;
    there.id = 5;
    body_check const check = check_body(there, two_bodies(), vars);
    EXPECT_FALSE(check.passed);
    EXPECT_EQ(check.arrived, "no body 5 at tick 100 (2 bodies)");
}

TEST(BodyCheck, KeepsFieldsAndPointers)
{
    variables vars;
    body_expectation e;
    e.id = 17;
    e.keep = {{"z", "/position/2"}, {"m", "mass"}, {"when", "tick"}};
    body_check const check = check_body(e, two_bodies(), vars);
    ASSERT_TRUE(check.passed);
    keep_from_body(e, check, vars);
    EXPECT_EQ(*vars.find("z"), 3.0);
    EXPECT_EQ(*vars.find("m"), 1.0);
    EXPECT_EQ(*vars.find("when"), 100);
    e.keep = {{"q", "charge"}}; // the snapshot has no charges
    EXPECT_THROW(keep_from_body(e, check, vars), substitution_error);
}

} // namespace
} // namespace kugel::client
