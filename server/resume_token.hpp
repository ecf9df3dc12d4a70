#pragma once

#include <string>
#include <string_view>

namespace kugel::server {

/// A new resume token (welcome.resume_token): 128 bits from the kernel's cryptographic
/// source (getrandom(2)), as 32 lowercase hex digits. Throws std::system_error should the
/// kernel give none.
std::string new_resume_token();

/// Whether `given` (a hello.resume) is the token `issued`. Compared as the admin token is
/// (is_admin_token): every byte, in the same time whatever they are. False for an empty
/// `issued`.
bool is_resume_token(std::string_view given, std::string_view issued);

} // namespace kugel::server
