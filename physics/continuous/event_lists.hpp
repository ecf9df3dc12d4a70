#pragma once

// Unsorted lists of events that share one pool of fixed blocks: the calendar's slices of a
// step (calendar.hpp). A list grows a block at a time and gives its blocks back when it is
// taken, so the lists together hold the events waiting plus at most one part-filled block
// each. A vector per list kept the most it had ever held: at 10⁶ spheres 4.3 million places
// for 1.4 to 2.3 million events (bench/README.md).

#include "physics/continuous/event.hpp"

#include <array>
#include <cstdint>
#include <deque>

namespace kugel::physics::continuous {

class event_lists
{
public:
    /// A list: its newest block, or `empty`.
    using list = std::uint32_t;
    static constexpr list empty = 0xffffffffU;

    void push(list& l, event const& e)
    {
        if (l == empty || blocks_[l].count == block_size) {
            list const fresh = take_block();
            blocks_[fresh].next = l;
            l = fresh;
        }
        block& b = blocks_[l];
        b.events[b.count++] = e;
    }

    /// Offers each event of `l` to f, and empties it. f may push to any list, `l` included:
    /// a block is given back only once it has been read.
    template <class F>
    void take(list& l, F f)
    {
        list at = l;
        l = empty;
        while (at != empty) {
            for (std::uint32_t k = 0; k < blocks_[at].count; ++k)
                f(event(blocks_[at].events[k])); // a copy: f may move the pool's blocks
            list const next = blocks_[at].next;
            give_back(at);
            at = next;
        }
    }

    /// Blocks taken from the system so far: the most the lists ever held at once, in blocks.
    std::size_t blocks() const { return blocks_.size(); }

    /// Every list is empty after this (their handles must be reset to `empty`).
    void clear()
    {
        blocks_.clear();
        free_ = empty;
    }

private:
    /// 512 bytes: 21 events and the block's link and count.
    static constexpr std::uint32_t block_size = 21;
    struct block
    {
        std::array<event, block_size> events;
        list next;
        std::uint32_t count;
    };

    list take_block()
    {
        list b = free_;
        if (b != empty) {
            free_ = blocks_[b].next;
        } else {
            b = static_cast<list>(blocks_.size());
            blocks_.emplace_back(); // a deque: the others stay where they are, no copy of all
        }
        blocks_[b].count = 0;
        return b;
    }
    void give_back(list b)
    {
        blocks_[b].next = free_;
        free_ = b;
    }

    std::deque<block> blocks_;
    list free_ = empty;
};

} // namespace kugel::physics::continuous
