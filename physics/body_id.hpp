#pragma once

#include <cstdint>
#include <string>

namespace kugel::physics {

/// A stable handle to a body: a slot index and the generation of that slot. Removing a body
/// bumps its slot's generation, so an id kept by a client never refers to a later body that
/// reuses the slot. Generation 0 never names a live body: `body_id{}` is the null id.
struct body_id
{
    std::uint32_t index = 0;
    std::uint32_t generation = 0;

    friend bool operator==(body_id, body_id) = default;
};

inline bool is_null(body_id id) { return id.generation == 0; }

/// An order of ids (slot, then generation): for sorted lists of bodies and pairs.
inline bool by_id(body_id a, body_id b)
{
    return a.index != b.index ? a.index < b.index : a.generation < b.generation;
}

/// One number for the outside world (protocol, logs): generation in the high 32 bits.
inline std::uint64_t to_number(body_id id)
{
    return (std::uint64_t{id.generation} << 32U) | id.index;
}

inline body_id from_number(std::uint64_t n)
{
    return {static_cast<std::uint32_t>(n & 0xffffffffU), static_cast<std::uint32_t>(n >> 32U)};
}

inline std::string to_string(body_id id)
{
    return std::to_string(id.index) + ":" + std::to_string(id.generation);
}

} // namespace kugel::physics
