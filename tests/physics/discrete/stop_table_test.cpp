// The table of last step's support stops (discrete/stop_table.hpp): found by the ids of their
// two bodies, summed when a step adds a stop twice, emptied by clear, and whole after growing.

#include "physics/discrete/stop_table.hpp"

#include <gtest/gtest.h>

namespace kugel::physics::discrete {
namespace {

TEST(StopTable, FindsWhatWasAddedByBothBodies)
{
    stop_table table;
    table.clear(4);
    std::uint64_t const a = std::uint64_t{1} << 32U | 7U, b = std::uint64_t{1} << 32U | 9U;
    table.add({a, b, 0.25, vec3(0.1, 0, 0)});
    table.add({a, 3, 0.5, vec3::Zero()}); // a on wall 3
    ASSERT_NE(table.find(a, b), nullptr);
    EXPECT_EQ(table.find(a, b)->pushed, 0.25);
    EXPECT_EQ(table.find(a, 3)->pushed, 0.5);
    EXPECT_EQ(table.find(b, a), nullptr) << "a stop has an upper and a lower body";
    EXPECT_EQ(table.find(a, 4), nullptr);
}

// A step solves a stop before and after exchanging momentum: the table keeps the sum.
TEST(StopTable, AddingAStopAgainSumsIt)
{
    stop_table table;
    table.clear(1);
    std::uint64_t const a = std::uint64_t{2} << 32U | 1U, b = std::uint64_t{1} << 32U | 2U;
    table.add({a, b, 0.25, vec3(0.125, 0, 0)});
    table.add({a, b, 0.5, vec3(0, 0.25, 0)});
    EXPECT_EQ(table.size(), 1U);
    EXPECT_EQ(table.find(a, b)->pushed, 0.75);
    EXPECT_EQ(table.find(a, b)->friction, vec3(0.125, 0.25, 0));
    table.clear(1);
    EXPECT_EQ(table.size(), 0U);
    EXPECT_EQ(table.find(a, b), nullptr);
}

// More stops than it was cleared for: it grows and keeps every one.
TEST(StopTable, GrowsAndKeepsEveryStop)
{
    stop_table table;
    table.clear(2);
    for (std::uint32_t i = 0; i < 1000; ++i)
        table.add({std::uint64_t{1} << 32U | i, i + 1, static_cast<double>(i), vec3::Zero()});
    EXPECT_EQ(table.size(), 1000U);
    for (std::uint32_t i = 0; i < 1000; ++i) {
        kept_stop const* kept = table.find(std::uint64_t{1} << 32U | i, i + 1);
        ASSERT_NE(kept, nullptr) << i;
        EXPECT_EQ(kept->pushed, static_cast<double>(i));
    }
}

} // namespace
} // namespace kugel::physics::discrete
