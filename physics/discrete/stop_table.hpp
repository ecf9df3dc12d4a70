#pragma once

// The support stops of one discrete step by the two bodies they join, so that the next step
// starts each stop's solve from what it summed (warm starting, as Box2D and Jolt keep a
// contact's impulses from step to step): a pile at rest needs the same stops every step, and
// starting from them its solve is done in one sweep instead of running into the cap.

#include "physics/vec.hpp"

#include <algorithm>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace kugel::physics::discrete {

/// A stop as the next step finds it again: the upper body's id number (body_id's to_number,
/// never 0: a live body's generation is at least 1), the lower body's, or for a wall its
/// index (a number below 2^32, which no live body's is), and what its solve summed.
struct kept_stop
{
    std::uint64_t upper = 0;
    std::uint64_t lower = 0;
    double pushed = 0.0;           ///< m/s, the normal change, >= 0
    vec3 friction = vec3::Zero();  ///< m/s, the tangential change
};

/// An open-addressing table of kept stops (linear probing, at most half full), cleared and
/// refilled every step; its slots are kept, so a steady pile allocates nothing.
class stop_table
{
public:
    /// Empties the table, with room for `expected` stops before it grows.
    void clear(std::size_t expected)
    {
        std::size_t const capacity = std::bit_ceil(std::max<std::size_t>(16, 2 * expected));
        if (slots_.size() < capacity || slots_.size() > 4 * capacity)
            slots_.assign(capacity, kept_stop{});
        else
            std::fill(slots_.begin(), slots_.end(), kept_stop{});
        size_ = 0;
    }

    /// The stop between these bodies, or nullptr.
    kept_stop const* find(std::uint64_t upper, std::uint64_t lower) const
    {
        if (size_ == 0)
            return nullptr;
        std::size_t const mask = slots_.size() - 1;
        for (std::size_t at = hash(upper, lower) & mask;; at = (at + 1) & mask) {
            kept_stop const& slot = slots_[at];
            if (slot.upper == 0)
                return nullptr;
            if (slot.upper == upper && slot.lower == lower)
                return &slot;
        }
    }

    /// Adds what a stop summed to what the table holds for its bodies (nothing yet: a new
    /// entry). A step solves a stop twice, before and after exchanging momentum: the table
    /// keeps the sum.
    void add(kept_stop const& stop)
    {
        if (2 * (size_ + 1) > slots_.size())
            grow();
        std::size_t const mask = slots_.size() - 1;
        for (std::size_t at = hash(stop.upper, stop.lower) & mask;; at = (at + 1) & mask) {
            kept_stop& slot = slots_[at];
            if (slot.upper == 0) {
                slot = stop;
                ++size_;
                return;
            }
            if (slot.upper == stop.upper && slot.lower == stop.lower) {
                slot.pushed += stop.pushed;
                slot.friction += stop.friction;
                return;
            }
        }
    }

    std::size_t size() const { return size_; }

private:
    static std::size_t hash(std::uint64_t upper, std::uint64_t lower)
    {
        std::uint64_t h = upper * 0x9e3779b97f4a7c15ULL ^ lower;
        h ^= h >> 32U;
        h *= 0xd6e8feb86659fd93ULL;
        h ^= h >> 32U;
        return static_cast<std::size_t>(h);
    }

    void grow()
    {
        std::vector<kept_stop> old = std::move(slots_);
        slots_.assign(std::max<std::size_t>(16, 2 * old.size()), kept_stop{});
        size_ = 0;
        for (kept_stop const& stop : old)
            if (stop.upper != 0)
                add(stop);
    }

    std::vector<kept_stop> slots_;
    std::size_t size_ = 0;
};

} // namespace kugel::physics::discrete
