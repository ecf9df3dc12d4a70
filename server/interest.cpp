#include "interest.hpp"

#include <algorithm>
#include <cmath>

namespace kugel::server {

protocol::interest_filter normalized(protocol::interest_filter filter)
{
    if (filter.tags) {
        std::vector<std::string>& tags = *filter.tags;
        std::sort(tags.begin(), tags.end());
        tags.erase(std::unique(tags.begin(), tags.end()), tags.end());
    }
    return filter;
}

namespace {

/// Whether three distances along the axes (each >= 0, or infinite) lie within `radius`: a
/// far axis decides at once, and hypot neither overflows nor underflows on the rest.
bool within(double dx, double dy, double dz, double radius)
{
    if (dx > radius || dy > radius || dz > radius)
        return false;
    return std::hypot(dx, dy, dz) <= radius;
}

} // namespace

bool touches(protocol::interest_box const& box, protocol::vec3 const& centre, double radius)
{
    protocol::vec3 gap{};
    for (std::size_t k = 0; k < 3; ++k)
        gap[k] = std::max({box.min[k] - centre[k], centre[k] - box.max[k], 0.0});
    return within(gap[0], gap[1], gap[2], radius);
}

bool touches(interest_ball const& ball, protocol::vec3 const& centre, double radius)
{
    return within(std::abs(centre[0] - ball.centre[0]), std::abs(centre[1] - ball.centre[1]),
                  std::abs(centre[2] - ball.centre[2]), ball.radius + radius);
}

protocol::snapshot inside(protocol::snapshot const& all, resolved_interest const& interest)
{
    protocol::body_columns const& from = all.bodies;
    protocol::snapshot out{.tick = all.tick, .time = all.time, .paused = all.paused,
                           .faults = all.faults, .bodies = {}};
    if (interest.nothing)
        return out;
    std::string const none;
    auto const holds = [&](std::size_t i) {
        if (interest.tags) {
            std::string const& tag = from.tag ? (*from.tag)[i] : none;
            if (tag.empty() || !std::binary_search(interest.tags->begin(), interest.tags->end(), tag))
                return false; // an untagged body matches no list
        }
        protocol::vec3 const centre{from.position[3 * i], from.position[3 * i + 1],
                                    from.position[3 * i + 2]};
        if (interest.box)
            return touches(*interest.box, centre, from.radius[i]);
        if (interest.ball)
            return touches(*interest.ball, centre, from.radius[i]);
        return true;
    };
    std::vector<std::size_t> kept;
    for (std::size_t i = 0; i < from.size(); ++i)
        if (holds(i))
            kept.push_back(i);

    protocol::body_columns& to = out.bodies;
    std::size_t const n = kept.size();
    to.id.reserve(n);
    to.position.reserve(3 * n);
    to.velocity.reserve(3 * n);
    to.radius.reserve(n);
    if (from.mass)
        to.mass.emplace().reserve(n);
    if (from.charge)
        to.charge.emplace().reserve(n);
    bool const tagged = from.tag && std::any_of(kept.begin(), kept.end(), [&](std::size_t i) {
                            return !(*from.tag)[i].empty();
                        });
    if (tagged)
        to.tag.emplace().reserve(n);
    for (std::size_t const i : kept) {
        to.id.push_back(from.id[i]);
        for (std::size_t k = 0; k < 3; ++k) {
            to.position.push_back(from.position[3 * i + k]);
            to.velocity.push_back(from.velocity[3 * i + k]);
        }
        to.radius.push_back(from.radius[i]);
        if (from.mass)
            to.mass->push_back((*from.mass)[i]);
        if (from.charge)
            to.charge->push_back((*from.charge)[i]);
        if (tagged)
            to.tag->push_back((*from.tag)[i]);
    }
    return out;
}

} // namespace kugel::server
