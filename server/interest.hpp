#pragma once

// Interest (PROTOCOL.md, interest): what of the world a connection is sent. A client names a
// region (a box, or a ball around a body it follows) and tags; the room resolves the region
// at each snapshot (where the followed body is now) and sends the client the bodies that
// touch it. Clients with the same interest share one view of each snapshot, encoded once.

#include "protocol/messages.hpp"

#include <optional>
#include <string>
#include <vector>

namespace kugel::server {

/// A ball of the world: its centre and radius.
struct interest_ball
{
    protocol::vec3 centre{}; ///< m
    double radius = 0.0;     ///< m, > 0
};

/// An interest as the room resolved it for one snapshot: the region where it stands then and
/// the tags. A body is inside when its sphere touches the region (its centre in it, for a
/// point mass; touching counts) and, when tags are given, it carries one of them.
struct resolved_interest
{
    std::optional<protocol::interest_box> box;
    std::optional<interest_ball> ball;
    std::optional<std::vector<std::string>> tags; ///< sorted, each once
    bool nothing = false; ///< a region that holds no body (a followed body never seen)
};

/// The interest as rooms keep and compare it: tags sorted, each once, so that clients that
/// list the same tags in another order share a view.
protocol::interest_filter normalized(protocol::interest_filter filter);

/// Whether a sphere at `centre` of `radius` (m, >= 0) touches the box: its distance from the
/// box is at most its radius.
bool touches(protocol::interest_box const& box, protocol::vec3 const& centre, double radius);
/// Whether a sphere at `centre` of `radius` touches the ball: the distance of their centres
/// is at most the sum of their radii.
bool touches(interest_ball const& ball, protocol::vec3 const& centre, double radius);

/// The bodies of `all` inside the interest, in the order `all` lists them, with every column
/// `all` has (the tag column only while some body kept has a tag, as the room writes it).
protocol::snapshot inside(protocol::snapshot const& all, resolved_interest const& interest);

} // namespace kugel::server
