// The table of last step's support stops (discrete/stop_table.hpp): each body's stops found by
// its id, then among them by the lower body's; emptied by clear, and whole after growing.

#include "physics/discrete/stop_table.hpp"

#include <gtest/gtest.h>

#include <vector>

namespace kugel::physics::discrete {
namespace {

TEST(StopTable, FindsEachBodysStopsByItsIdAndTheLowerOnes)
{
    stop_table table;
    table.clear(4);
    std::uint64_t const a = std::uint64_t{1} << 32U | 7U, b = std::uint64_t{1} << 32U | 9U;
    std::vector<kept_stop> const of_a{{b, 0.25, vec3(0.1, 0, 0)}, {3, 0.5, vec3::Zero()}}; // b, and wall 3
    table.file(a, of_a);
    ASSERT_EQ(table.of(a).size(), 2U);
    ASSERT_NE(find(table.of(a), b), nullptr);
    EXPECT_EQ(find(table.of(a), b)->pushed, 0.25);
    EXPECT_EQ(find(table.of(a), b)->friction, vec3(0.1, 0, 0));
    EXPECT_EQ(find(table.of(a), 3)->pushed, 0.5);
    EXPECT_EQ(find(table.of(a), 4), nullptr);
    EXPECT_TRUE(table.of(b).empty()) << "a stop has an upper and a lower body";
    EXPECT_EQ(table.size(), 2U);
}

// A body is filed once a step: a second filing adds nothing. Clearing empties the table.
TEST(StopTable, ABodyIsFiledOnceAndClearEmptiesIt)
{
    stop_table table;
    table.clear(1);
    std::uint64_t const a = std::uint64_t{2} << 32U | 1U, b = std::uint64_t{1} << 32U | 2U;
    std::vector<kept_stop> const first{{b, 0.25, vec3(0.125, 0, 0)}}, second{{b, 0.5, vec3::Zero()}};
    table.file(a, first);
    table.file(a, second);
    EXPECT_EQ(table.size(), 1U);
    EXPECT_EQ(find(table.of(a), b)->pushed, 0.25);
    table.clear(1);
    EXPECT_EQ(table.size(), 0U);
    EXPECT_TRUE(table.of(a).empty());
}

// More bodies than it was cleared for: its index grows and keeps every one's stops.
TEST(StopTable, GrowsAndKeepsEveryBodysStops)
{
    stop_table table;
    table.clear(2);
    for (std::uint32_t i = 0; i < 1000; ++i) {
        std::vector<kept_stop> const stops{{i + 1, static_cast<double>(i), vec3::Zero()},
                                           {i + 2, 0.5 * i, vec3::Zero()}};
        table.file(std::uint64_t{1} << 32U | i, stops);
    }
    EXPECT_EQ(table.size(), 2000U);
    for (std::uint32_t i = 0; i < 1000; ++i) {
        auto const stops = table.of(std::uint64_t{1} << 32U | i);
        ASSERT_EQ(stops.size(), 2U) << i;
        EXPECT_EQ(find(stops, i + 1)->pushed, static_cast<double>(i));
        EXPECT_EQ(find(stops, i + 2)->pushed, 0.5 * i);
    }
}

} // namespace
} // namespace kugel::physics::discrete
