#pragma once

// Contact events: two bodies that begin to touch, for a game that must know "the ball hit the
// post" (world::report_contacts names the bodies it asks about). A world that asks about no
// body does none of this work.
//
// A contact begins when the collisions answer two reported spheres in a substep and those two
// were not in contact; it goes on, unreported, while they are answered again or stay within
// half the smaller radius of touching (a ball resting on another, asleep, or hovering after a
// discrete stop), and ends when they part farther. When:
//  - in continuous mode (and the discrete mode's sweep of fast bodies), each response to the
//    pair is timed at its event: exact to rounding. Two spheres that bounce apart and meet
//    again after they parted are two contacts.
//  - in discrete mode, the pairs the step answered (overlapping at the end of free motion, or
//    within its contact margin) at the substep's end, where the discrete mode looks.
// A body removed ends its contacts without an event.

#include "body_id.hpp"

#include <cstdint>

namespace kugel::physics {

struct contact_event
{
    double time; ///< s, world time of the first touch
    body_id a;   ///< the pair, a before b by id (index, then generation)
    body_id b;
};

/// A response to a pair of spheres inside a step, as the collision modes note it for the
/// world: the two spheres by slot, and the time (s from the step's start).
struct pair_touch
{
    std::uint32_t a, b;
    double time;
};

} // namespace kugel::physics
