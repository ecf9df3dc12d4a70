#pragma once

// The support stops of one discrete step, filed by their upper body, so that the next step
// starts each stop's solve from what it summed (warm starting, as Box2D and Jolt keep a
// contact's impulses from step to step): a pile at rest needs the same stops every step, and
// starting from them its solve is done in one sweep instead of running into the cap.
//
// A step solves each sphere's stops together, so they are filed together: one body's stops
// side by side, found again by its id with one lookup, then among its few by the lower body.
// (A table of single stops by both ids took one lookup a stop and one more to add it, in a
// table of several megabytes at 10^4 spheres: 7 % of a forming pile's step.)

#include "physics/vec.hpp"

#include <algorithm>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace kugel::physics::discrete {

/// A stop as the next step finds it again among its upper body's: the lower body's id number
/// (body_id's to_number) or for a wall its index (a number below 2^32, which no live body's
/// is), and what its solve summed.
struct kept_stop
{
    std::uint64_t lower = 0;
    double pushed = 0.0;           ///< m/s, the normal change, >= 0
    vec3 friction = vec3::Zero();  ///< m/s, the tangential change
};

/// The stop against `lower` among one body's, or nullptr.
template <class Stop>
Stop* find(std::span<Stop> stops, std::uint64_t lower)
{
    auto const at = std::find_if(stops.begin(), stops.end(), [&](Stop const& s) { return s.lower == lower; });
    return at == stops.end() ? nullptr : &*at;
}

/// Each upper body's stops, by its id number (never 0: a live body's generation is at least
/// 1): an open-addressing index (linear probing, at most half full) into one array of stops,
/// cleared and refilled every step; its memory is kept, so a steady pile allocates nothing.
class stop_table
{
public:
    /// Empties the table, with room for `uppers` bodies before its index grows.
    void clear(std::size_t uppers)
    {
        std::size_t const capacity = std::bit_ceil(std::max<std::size_t>(16, 2 * uppers));
        if (index_.size() < capacity || index_.size() > 4 * capacity)
            index_.assign(capacity, filed{});
        else
            std::fill(index_.begin(), index_.end(), filed{});
        bodies_ = 0;
        stops_.clear();
    }

    /// Files one body's stops; a body is filed once a step (filing it again adds nothing).
    void file(std::uint64_t upper, std::span<kept_stop const> stops)
    {
        if (stops.empty())
            return;
        if (2 * (bodies_ + 1) > index_.size())
            grow();
        filed& slot = index_[slot_of(upper)];
        if (slot.upper != 0)
            return;
        slot = {upper, static_cast<std::uint32_t>(stops_.size()), static_cast<std::uint32_t>(stops.size())};
        stops_.insert(stops_.end(), stops.begin(), stops.end());
        ++bodies_;
    }

    /// The stops filed for a body: empty when none.
    std::span<kept_stop const> of(std::uint64_t upper) const
    {
        if (bodies_ == 0)
            return {};
        filed const& slot = index_[slot_of(upper)];
        return slot.upper == 0 ? std::span<kept_stop const>{} : std::span<kept_stop const>(stops_).subspan(slot.first, slot.count);
    }

    std::size_t size() const { return stops_.size(); } ///< stops filed

private:
    struct filed
    {
        std::uint64_t upper = 0;
        std::uint32_t first = 0, count = 0;
    };

    /// The body's slot in the index, or the empty one where it would go.
    std::size_t slot_of(std::uint64_t upper) const
    {
        std::size_t const mask = index_.size() - 1;
        std::uint64_t h = upper * 0x9e3779b97f4a7c15ULL;
        h ^= h >> 32U;
        for (std::size_t at = static_cast<std::size_t>(h) & mask;; at = (at + 1) & mask)
            if (index_[at].upper == upper || index_[at].upper == 0)
                return at;
    }

    void grow()
    {
        std::vector<filed> old = std::move(index_);
        index_.assign(std::max<std::size_t>(16, 2 * old.size()), filed{});
        for (filed const& f : old)
            if (f.upper != 0)
                index_[slot_of(f.upper)] = f;
    }

    std::vector<filed> index_;
    std::vector<kept_stop> stops_;
    std::size_t bodies_ = 0;
};

} // namespace kugel::physics::discrete
