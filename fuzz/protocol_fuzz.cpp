// Fuzz target: protocol decoding. Any bytes a client (or a server) could send.
//
// Properties checked on every input:
//  - decode() never throws and gives exactly one of a message and an error;
//  - an error names a code and says what was wrong;
//  - a message encodes to text that decodes to the same message, and that text is stable
//    (encoding it again gives the same bytes);
//  - the same for decode_server_message(), which clients run on what the server sends.

#include "protocol/codec.hpp"

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

} // namespace

extern "C" int LLVMFuzzerTestOneInput(std::uint8_t const* data, std::size_t size)
{
    std::string_view const text(reinterpret_cast<char const*>(data), size);
    check<kugel::protocol::client_message>(text, [](std::string_view t) { return kugel::protocol::decode(t); });
    check<kugel::protocol::server_message>(
        text, [](std::string_view t) { return kugel::protocol::decode_server_message(t); });
    return 0;
}
