#pragma once

// The continuous mode's predicted events, shared by the step-by-step loop and the calendar.

#include <cassert>
#include <cstdint>

namespace kugel::physics::continuous {

/// What an event is: a contact (of two spheres, a sphere and a wall, a sphere and a box), or
/// the calendar's crossing of a cell's face (continuous/calendar.hpp), which changes no path.
enum class event_kind : std::uint8_t { pair, wall, obstacle, crossing };

/// A predicted event: valid while neither body's path has changed since (their versions).
///
/// 20 bytes: the kind shares a word with `other`, so a sphere, a wall or a box is named in 30
/// bits (a world holds fewer bodies than that, body_storage::most_bodies); the two bodies'
/// versions are kept as their sum, which a version only ever raises, so it changes when
/// either does; and the struct is packed to 4 bytes (its time is read and written by value,
/// never by address). A gas of 10⁶ spheres keeps two to three million events waiting; at 32
/// bytes they were the largest thing the calendar held.
#pragma pack(push, 4)
struct event
{
    /// Sphere, wall, box and face indices stay below this.
    static constexpr std::uint32_t most_indexed = 1U << 30U;

    double time;
    std::uint32_t body;
    /// The body's path version plus the other's (pairs; 0 else), modulo 2³²: an event is
    /// current while the sum of the versions now is the same.
    std::uint32_t versions;

    event() = default;
    event(double at, event_kind kind, std::uint32_t b, std::uint32_t other_index, std::uint32_t b_version,
          std::uint32_t o_version)
        : time(at), body(b), versions(b_version + o_version),
          kind_and_other_((static_cast<std::uint32_t>(kind) << 30U) | other_index)
    {
        assert(other_index < most_indexed);
    }

    event_kind kind() const { return static_cast<event_kind>(kind_and_other_ >> 30U); }
    /// The other body (pairs), the wall, the box, or the face crossed.
    std::uint32_t other() const { return kind_and_other_ & (most_indexed - 1U); }

    /// Earliest first; ties broken by kind and indices so the order never depends on the heap.
    friend bool operator>(event const& l, event const& r)
    {
        if (l.time != r.time)
            return l.time > r.time;
        if (l.kind() != r.kind())
            return l.kind() > r.kind();
        if (l.body != r.body)
            return l.body > r.body;
        return l.other() > r.other();
    }

private:
    std::uint32_t kind_and_other_;
};
#pragma pack(pop)

static_assert(sizeof(event) == 20);

} // namespace kugel::physics::continuous
