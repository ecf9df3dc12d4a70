#include "client/watch.hpp"

#include <gtest/gtest.h>

namespace kugel::client {
namespace {

protocol::snapshot moving_bodies()
{
    protocol::snapshot s;
    s.tick = 1204;
    s.time = 20.0625;
    s.bodies.id = {1, 2};
    s.bodies.position = {0, 0, 0, 1, 1, 1};
    s.bodies.velocity = {3, 4, 0, 0, 0, 1};
    s.bodies.radius = {0.1, 0.1};
    return s;
}

TEST(Watch, KineticEnergyOnlyWhenMassesAreSent)
{
    protocol::snapshot s = moving_bodies();
    EXPECT_EQ(kinetic_energy(s), std::nullopt);
    s.bodies.mass = std::vector<double>{2, 4};
    EXPECT_EQ(kinetic_energy(s), 0.5 * 2 * 25 + 0.5 * 4 * 1);
}

TEST(Watch, SummaryLineShowsTickTimeBodiesAndEnergyWhenKnown)
{
    protocol::snapshot s = moving_bodies();
    EXPECT_EQ(summary_line(s), "tick 1204  time 20.0625 s  bodies 2");
    s.bodies.mass = std::vector<double>{2, 4};
    EXPECT_EQ(summary_line(s), "tick 1204  time 20.0625 s  bodies 2  kinetic energy 27 J");
}

TEST(Watch, EventLineNamesWhatHappenedAndToWhom)
{
    protocol::event crossing{.tick = 1204, .time = 20.0583, .kind = "entered", .sensor = "goal", .body = 17,
                             .tag = "ball", .owner = 3};
    EXPECT_EQ(event_line(crossing), "event tick 1204  time 20.0583 s  entered goal  body 17 (ball)  owner 3");
    crossing.tag.reset();
    crossing.owner.reset();
    crossing.missed = 2;
    EXPECT_EQ(event_line(crossing), "event tick 1204  time 20.0583 s  entered goal  body 17  missed 2");
    protocol::event const contact{.tick = 88, .time = 1.46, .kind = "contact",
                                  .bodies = std::vector<std::uint64_t>{4, 9},
                                  .tags = std::vector<std::string>{"ball", ""}};
    EXPECT_EQ(event_line(contact), "event tick 88  time 1.46 s  contact  bodies 4 (ball) 9");
}

} // namespace
} // namespace kugel::client
