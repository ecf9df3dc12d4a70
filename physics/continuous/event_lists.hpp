#pragma once

// Unsorted lists of events that share one pool of fixed blocks: the calendar's slices of a
// step (calendar.hpp). A list grows a block at a time and gives its blocks back when it is
// taken, so the lists together hold the events waiting plus at most one part-filled block
// each. A vector per list kept the most it had ever held: at 10⁶ spheres 4.3 million places
// for 1.4 to 2.3 million events (bench/README.md).

#include "physics/continuous/event.hpp"

#include <array>
#include <cstdint>
#include <memory>
#include <vector>

namespace kugel::physics::continuous {

class event_lists
{
public:
    /// A list: its newest block, or `empty`.
    using list = std::uint32_t;
    static constexpr list empty = 0xffffffffU;

    void push(list& l, event const& e)
    {
        if (l == empty || at(l).count == block_size) {
            list const fresh = take_block();
            at(fresh).next = l;
            l = fresh;
        }
        block& b = at(l);
        b.events[b.count++] = e;
    }

    /// Offers each event of `l` to f, and empties it. f may push to any list, `l` included:
    /// a block is given back only once it has been read.
    template <class F>
    void take(list& l, F f)
    {
        list from = l;
        l = empty;
        while (from != empty) {
            block const& b = at(from);
            for (std::uint32_t k = 0; k < b.count; ++k)
                f(b.events[k]);
            list const next = b.next;
            give_back(from);
            from = next;
        }
    }

    /// Blocks taken from the system so far: the most the lists ever held at once, in blocks.
    std::size_t blocks() const { return blocks_; }

    /// Every list is empty after this (their handles must be reset to `empty`).
    void clear()
    {
        chunks_.clear();
        blocks_ = 0;
        free_ = empty;
    }

    /// Events a block holds: 25, and the block's link and count, in 508 bytes.
    static constexpr std::uint32_t block_size = 25;

private:
    struct block
    {
        std::array<event, block_size> events;
        list next;
        std::uint32_t count;
    };
    static_assert(sizeof(block) <= 512);
    /// Blocks come in chunks of this many (32 KB): a block apiece would cost an allocation's
    /// header each, 4 % more.
    static constexpr std::uint32_t chunk_blocks = 64;

    block& at(list b) { return chunks_[b / chunk_blocks][b % chunk_blocks]; }

    list take_block()
    {
        list b = free_;
        if (b != empty) {
            free_ = at(b).next;
        } else {
            if (blocks_ % chunk_blocks == 0) // a chunk more: the others stay where they are
                chunks_.push_back(std::make_unique_for_overwrite<block[]>(chunk_blocks));
            b = blocks_++;
        }
        at(b).count = 0;
        return b;
    }
    void give_back(list b)
    {
        at(b).next = free_;
        free_ = b;
    }

    std::vector<std::unique_ptr<block[]>> chunks_;
    std::uint32_t blocks_ = 0;
    list free_ = empty;
};

} // namespace kugel::physics::continuous
