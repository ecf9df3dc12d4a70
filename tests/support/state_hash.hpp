#pragma once

// Test support: a fingerprint of a world's state, for determinism (golden hash) tests.

#include "physics/world.hpp"

#include <cstdint>
#include <cstring>

namespace kugel::test_support {

/// FNV-1a over the bytes of every position and velocity, in slot order.
inline std::uint64_t state_hash(physics::world const& w)
{
    std::uint64_t h = 14695981039346656037ULL;
    auto mix = [&](physics::vec3 const& v) {
        unsigned char bytes[sizeof(double) * 3];
        std::memcpy(bytes, v.data(), sizeof bytes);
        for (unsigned char b : bytes)
            h = (h ^ b) * 1099511628211ULL;
    };
    for (std::size_t i = 0; i < w.bodies().size(); ++i) {
        mix(w.bodies().positions()[i]);
        mix(w.bodies().velocities()[i]);
    }
    return h;
}

} // namespace kugel::test_support
