#pragma once

// JSON text <-> messages. Decoding validates every field and throws for no input: text it
// cannot accept gives an `error` naming the field (a JSON pointer) and what was wrong, ready
// to be sent back. Encoding writes doubles so that they parse back to the same bits.

#include "protocol/compact.hpp"
#include "protocol/messages.hpp"

#include <optional>
#include <string>
#include <string_view>

namespace kugel::protocol {

/// What decoding gives: exactly one of `message` and `failure` is set.
template <class Message> struct decode_result
{
    std::optional<Message> message;
    std::optional<error> failure; ///< with the ref when the text had a readable one
};

/// A message from a client (what the server reads).
decode_result<client_message> decode(std::string_view text);

/// A message from the server (what a client reads).
decode_result<server_message> decode_server_message(std::string_view text);

std::string encode(hello const& message);
std::string encode(spawn const& message);
std::string encode(impulse const& message);
std::string encode(remove const& message);
std::string encode(ping const& message);
std::string encode(pause const& message);
std::string encode(resume const& message);
std::string encode(reset const& message);
std::string encode(load_scene const& message);
std::string encode(set const& message);
std::string encode(interest const& message);
std::string encode(client_message const& message);

std::string encode(welcome const& message);
std::string encode(ack const& message);
std::string encode(error const& message);
std::string encode(snapshot const& message);
std::string encode(pong const& message);
std::string encode(compact_snapshot const& message);
std::string encode(roster const& message);
std::string encode(player_notice const& message);
std::string encode(event const& message);
/// encode(keyframe(state)), without copying the state's bodies into a message first.
std::string encode_keyframe(compact_state const& state);
std::string encode(server_message const& message);

} // namespace kugel::protocol
