#pragma once

// The continuous mode's predicted events, shared by the step-by-step loop and the calendar.

#include <cstdint>

namespace kugel::physics::continuous {

/// What an event is: a contact (of two spheres, a sphere and a wall, a sphere and a box), or
/// the calendar's crossing of a cell's face (continuous/calendar.hpp), which changes no path.
enum class event_kind : std::uint8_t { pair, wall, obstacle, crossing };

/// A predicted event: valid while neither body's path has changed since (their versions).
struct event
{
    double time;
    event_kind kind;
    std::uint32_t body;
    std::uint32_t other; ///< body, wall or obstacle index
    std::uint32_t body_version;
    std::uint32_t other_version; ///< for pairs

    /// Earliest first; ties broken by kind and indices so the order never depends on the heap.
    friend bool operator>(event const& l, event const& r)
    {
        if (l.time != r.time)
            return l.time > r.time;
        if (l.kind != r.kind)
            return l.kind > r.kind;
        if (l.body != r.body)
            return l.body > r.body;
        return l.other > r.other;
    }
};

} // namespace kugel::physics::continuous
