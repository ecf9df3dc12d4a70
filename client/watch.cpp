#include "watch.hpp"

#include <algorithm>
#include <array>
#include <cstdio>
#include <string>

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

std::string event_line(protocol::event const& event)
{
    std::array<char, 96> head{};
    int const n = std::snprintf(head.data(), head.size(), "event tick %llu  time %.6g s  ",
                                static_cast<unsigned long long>(event.tick), event.time);
    std::string text(head.data(), std::min(static_cast<std::size_t>(std::max(n, 0)), head.size() - 1));
    text += event.kind;
    auto const body = [](std::uint64_t id, std::optional<std::string> const& tag) {
        std::string b = std::to_string(id);
        if (tag && !tag->empty())
            b += " (" + *tag + ")";
        return b;
    };
    if (event.sensor)
        text += " " + *event.sensor;
    if (event.body) {
        text += "  body " + body(*event.body, event.tag);
        if (event.owner)
            text += "  owner " + std::to_string(*event.owner);
    }
    if (event.bodies) {
        text += "  bodies";
        for (std::size_t k = 0; k < event.bodies->size(); ++k)
            text += " " + body((*event.bodies)[k], event.tags && k < event.tags->size()
                                                       ? std::optional<std::string>((*event.tags)[k])
                                                       : std::nullopt);
    }
    if (event.missed)
        text += "  missed " + std::to_string(*event.missed);
    return text;
}

} // namespace kugel::client
