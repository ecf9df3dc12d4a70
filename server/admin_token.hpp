#pragma once

#include <string_view>

namespace kugel::server {

/// Whether a client's `hello.admin_token` is the server's admin token. Takes the same time
/// whatever the bytes are, so that the time of a refusal does not tell how many leading
/// bytes were right; only the lengths can show. False when no token is configured.
bool is_admin_token(std::string_view given, std::string_view configured);

} // namespace kugel::server
