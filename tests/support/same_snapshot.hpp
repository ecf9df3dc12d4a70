#pragma once

// A decoded compact snapshot held to the full form of the same tick (the server tests of
// compact snapshots and of interest regions).

#include "protocol/compact.hpp"
#include "protocol/messages.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <map>
#include <string>

namespace kugel::test_support {

/// Every body of `mine` is in `full`, at the same position and velocity to half a quantum
/// (the rounding of quantizing, and a billionth of it for the decoding's arithmetic), with
/// the same constants and tag. `mine` may hold fewer bodies (an interest region's view).
inline void expect_bodies_of(protocol::snapshot const& mine, protocol::snapshot const& full, protocol::quanta q)
{
    std::map<std::uint64_t, std::size_t> slot;
    for (std::size_t i = 0; i < full.bodies.size(); ++i)
        slot[full.bodies.id[i]] = i;
    for (std::size_t j = 0; j < mine.bodies.size(); ++j) {
        ASSERT_TRUE(slot.contains(mine.bodies.id[j])) << "body " << mine.bodies.id[j];
        std::size_t const i = slot[mine.bodies.id[j]];
        for (std::size_t k = 0; k < 3; ++k) {
            EXPECT_LE(std::abs(mine.bodies.position[3 * j + k] - full.bodies.position[3 * i + k]),
                      0.5 * q.position * (1 + 1e-9));
            EXPECT_LE(std::abs(mine.bodies.velocity[3 * j + k] - full.bodies.velocity[3 * i + k]),
                      0.5 * q.velocity * (1 + 1e-9));
        }
        EXPECT_EQ(mine.bodies.radius[j], full.bodies.radius[i]);
        EXPECT_EQ((*mine.bodies.mass)[j], (*full.bodies.mass)[i]);
        std::string const my_tag = mine.bodies.tag ? (*mine.bodies.tag)[j] : "";
        std::string const full_tag = full.bodies.tag ? (*full.bodies.tag)[i] : "";
        EXPECT_EQ(my_tag, full_tag) << "body " << mine.bodies.id[j];
    }
}

/// The same tick and every body of it, each as expect_bodies_of holds it.
inline void expect_same_to_the_quantum(protocol::snapshot const& compact, protocol::snapshot const& full,
                                       protocol::quanta q)
{
    ASSERT_EQ(compact.tick, full.tick);
    ASSERT_EQ(compact.bodies.size(), full.bodies.size());
    expect_bodies_of(compact, full, q);
}

} // namespace kugel::test_support
