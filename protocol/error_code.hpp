#pragma once

#include <array>
#include <optional>
#include <string_view>

namespace kugel::protocol {

/// Why a message was refused: the `code` of an `error` message. The wire names (name()) are
/// stable; a client may switch on them. PROTOCOL.md says when each one happens.
enum class error_code {
    // Found by decode(): the message itself is wrong.
    bad_json,             ///< not valid JSON (including invalid UTF-8)
    bad_message,          ///< not an object, or no string `type`
    unknown_type,         ///< `type` names no message
    missing_field,        ///< a required field is absent
    wrong_type,           ///< a field has the wrong JSON type
    not_finite,           ///< a number is out of double range (1e999)
    bad_value,            ///< the right type, but a value out of its range
    unsupported_protocol, ///< hello asks for a protocol version this side does not speak
    // Found by the server: the message is well formed but cannot apply.
    unknown_body,      ///< impulse or remove names an id that is not in the world
    outside_world,     ///< spawn puts a body's centre behind a wall
    overlaps_wall,     ///< spawn puts a sphere across a wall or into an obstacle
    room_full,         ///< spawn while the room holds limits.max_bodies bodies
    rate_limited,      ///< more than limits.commands_per_second commands
    message_too_large, ///< a frame longer than limits.max_message_bytes
    forbidden,         ///< an admin command (or a wrong admin token) from a non-admin
    too_many_bodies,   ///< spawn while the client has limits.max_bodies_per_client bodies
    overlaps_body,     ///< spawn puts a sphere into another sphere, in a room with collisions
    singular_force,    ///< spawn gives a force beyond what the room can step (none holds it)
    bad_resume,        ///< hello.resume names no player this connection can become again
};

/// Every code, in declaration order.
inline constexpr std::array all_error_codes{
    error_code::bad_json,      error_code::bad_message,          error_code::unknown_type,
    error_code::missing_field, error_code::wrong_type,           error_code::not_finite,
    error_code::bad_value,     error_code::unsupported_protocol, error_code::unknown_body,
    error_code::outside_world, error_code::overlaps_wall,        error_code::room_full,
    error_code::rate_limited,  error_code::message_too_large,    error_code::forbidden,
    error_code::too_many_bodies, error_code::overlaps_body,      error_code::singular_force,
    error_code::bad_resume,
};

/// The wire name of a code: "bad_json", "unknown_body", ...
std::string_view name(error_code code);

/// The code with this wire name, if there is one.
std::optional<error_code> error_code_named(std::string_view wire_name);

} // namespace kugel::protocol
