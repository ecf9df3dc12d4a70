// The calendar's lists of events from one pool of blocks: every event pushed comes out of
// its own list once, a list taken can be pushed to while it is read, and blocks given back
// are used again (the pool holds what waits, not what ever waited).

#include "physics/continuous/event_lists.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <vector>

namespace kugel::physics::continuous {
namespace {

event numbered(std::uint32_t n) { return {static_cast<double>(n), event_kind::crossing, n, n % 6U, n, 0}; }

std::vector<std::uint32_t> taken(event_lists& lists, event_lists::list& l)
{
    std::vector<std::uint32_t> out;
    lists.take(l, [&](event const& e) { out.push_back(e.body); });
    std::sort(out.begin(), out.end());
    return out;
}

TEST(EventLists, EveryEventComesOutOfItsOwnListOnce)
{
    event_lists lists;
    std::array<event_lists::list, 3> l{event_lists::empty, event_lists::empty, event_lists::empty};
    std::array<std::vector<std::uint32_t>, 3> expected;
    for (std::uint32_t n = 0; n < 1000; ++n) { // interleaved, across many blocks each
        lists.push(l[n % 3U], numbered(n));
        expected[n % 3U].push_back(n);
    }
    for (std::size_t k = 0; k < 3; ++k) {
        EXPECT_EQ(taken(lists, l[k]), expected[k]);
        EXPECT_EQ(l[k], event_lists::empty);
        EXPECT_TRUE(taken(lists, l[k]).empty()) << "a list taken is empty";
    }
    // The whole event is kept, not only its body.
    lists.push(l[0], numbered(7));
    lists.take(l[0], [](event const& e) {
        EXPECT_EQ(e.time, 7.0);
        EXPECT_EQ(e.kind(), event_kind::crossing);
        EXPECT_EQ(e.other(), 1U);
        EXPECT_EQ(e.versions, 7U);
    });
}

TEST(EventLists, AListTakenCanBeFilledAgainWhileItIsRead)
{
    // The calendar's ring turn: the latest events are read and the later ones filed back.
    event_lists lists;
    event_lists::list latest = event_lists::empty, due = event_lists::empty;
    for (std::uint32_t n = 0; n < 500; ++n)
        lists.push(latest, numbered(n));
    lists.take(latest, [&](event const& e) { lists.push(e.body % 2U == 0U ? due : latest, e); });
    std::vector<std::uint32_t> evens, odds;
    for (std::uint32_t n = 0; n < 500; ++n)
        (n % 2U == 0U ? evens : odds).push_back(n);
    EXPECT_EQ(taken(lists, due), evens);
    EXPECT_EQ(taken(lists, latest), odds);
}

TEST(EventLists, BlocksGivenBackAreUsedAgain)
{
    // Filling and taking the same number again and again must not grow the pool: the events
    // read back after many rounds are still exactly the last round's.
    event_lists lists;
    event_lists::list l = event_lists::empty;
    for (int round = 0; round < 100; ++round) {
        for (std::uint32_t n = 0; n < 300; ++n)
            lists.push(l, numbered(n + 1000U * static_cast<std::uint32_t>(round)));
        auto const out = taken(lists, l);
        ASSERT_EQ(out.size(), 300U);
        EXPECT_EQ(out.front(), 1000U * static_cast<std::uint32_t>(round));
    }
    EXPECT_LE(lists.blocks(), (300U + event_lists::block_size - 1U) / event_lists::block_size);
}

} // namespace
} // namespace kugel::physics::continuous
