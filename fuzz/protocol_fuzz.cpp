// Fuzz target: protocol decoding. Any bytes a client (or a server) could send.
//
// Properties checked on every input:
//  - decode() never throws and gives exactly one of a message and an error;
//  - an error names a code and says what was wrong;
//  - a message encodes to text that decodes to the same message, and that text is stable
//    (encoding it again gives the same bytes);
//  - the same for decode_server_message(), which clients run on what the server sends;
//  - a compact snapshot applies (apply_compact) to nothing and to a held state without
//    crashing, and what it gives, as a keyframe, applies again to the same state.

#include "protocol/codec.hpp"
#include "protocol/compact.hpp"

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

namespace {

void require(bool ok)
{
    if (!ok)
        std::abort(); // the fuzzer reports the input
}

template <class Message, class Decode>
void check(std::string_view text, Decode decode_fn)
{
    auto const decoded = decode_fn(text);
    require(decoded.message.has_value() != decoded.failure.has_value());
    if (decoded.failure) {
        require(!decoded.failure->message.empty());
        return;
    }
    std::string const once = kugel::protocol::encode(*decoded.message);
    auto const again = decode_fn(once);
    require(again.message.has_value());
    require(*again.message == *decoded.message);
    require(kugel::protocol::encode(*again.message) == once);
}

/// A state a delta from the fuzzer may name as its base (tick 10).
kugel::protocol::compact_state const& held_state()
{
    static kugel::protocol::compact_state const held = [] {
        kugel::protocol::compact_state s{.tick = 10, .time = 1.0, .q = {1e-3, 1e-2}, .bodies = {}};
        s.bodies = {.id = {1, 2, 5}, .position = {0, 0, 0, 1, 1, 1, -5, 9, 2},
                    .velocity = {0, 0, 0, 3, 0, -1, 0, 0, 0}, .radius = {0.1, 0.1, 0.0},
                    .mass = {1, 1, 2}, .owner = {0, 0, 3}};
        return s;
    }();
    return held;
}

void check_compact(std::string_view text)
{
    auto const decoded = kugel::protocol::decode_server_message(text);
    if (!decoded.message)
        return;
    auto const* compact = std::get_if<kugel::protocol::compact_snapshot>(&*decoded.message);
    if (!compact)
        return;
    for (auto const* held : {static_cast<kugel::protocol::compact_state const*>(nullptr), &held_state()}) {
        auto const applied = kugel::protocol::apply_compact(*compact, held);
        require(applied.state.has_value() != !applied.failure.empty());
        if (!applied.state)
            continue;
        auto const again = kugel::protocol::apply_compact(kugel::protocol::keyframe(*applied.state), nullptr);
        require(again.state && *again.state == *applied.state);
    }
}

} // namespace

extern "C" int LLVMFuzzerTestOneInput(std::uint8_t const* data, std::size_t size)
{
    std::string_view const text(reinterpret_cast<char const*>(data), size);
    check<kugel::protocol::client_message>(text, [](std::string_view t) { return kugel::protocol::decode(t); });
    check<kugel::protocol::server_message>(
        text, [](std::string_view t) { return kugel::protocol::decode_server_message(t); });
    check_compact(text);
    return 0;
}
