#include "watch.hpp"

#include <algorithm>
#include <array>
#include <cstdio>

namespace kugel::client {

std::optional<double> kinetic_energy(protocol::snapshot const& snapshot)
{
    auto const& b = snapshot.bodies;
    if (!b.mass || b.mass->size() != b.size() || b.velocity.size() != 3 * b.size())
        return std::nullopt;
    double energy = 0.0;
    for (std::size_t i = 0; i < b.size(); ++i) {
        double const vx = b.velocity[3 * i];
        double const vy = b.velocity[3 * i + 1];
        double const vz = b.velocity[3 * i + 2];
        energy += 0.5 * (*b.mass)[i] * (vx * vx + vy * vy + vz * vz);
    }
    return energy;
}

std::string summary_line(protocol::snapshot const& snapshot)
{
    std::array<char, 160> line{};
    int const n = std::snprintf(line.data(), line.size(), "tick %llu  time %.6g s  bodies %zu",
                                static_cast<unsigned long long>(snapshot.tick), snapshot.time,
                                snapshot.bodies.size());
    std::string text(line.data(),
                     std::min(static_cast<std::size_t>(std::max(n, 0)), line.size() - 1));
    if (auto const energy = kinetic_energy(snapshot)) {
        std::snprintf(line.data(), line.size(), "  kinetic energy %.9g J", *energy);
        text += line.data();
    }
    return text;
}

} // namespace kugel::client
