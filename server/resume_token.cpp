#include "resume_token.hpp"

#include "admin_token.hpp"

#include <array>
#include <cerrno>
#include <cstddef>
#include <system_error>

#include <sys/random.h>

namespace kugel::server {

std::string new_resume_token()
{
    std::array<unsigned char, 16> bytes{};
    std::size_t got = 0;
    while (got < bytes.size()) {
        // Blocks only until the kernel's pool is first seeded, at boot; never returns bytes
        // from an unseeded pool (no GRND_NONBLOCK, no GRND_INSECURE).
        ssize_t const n = ::getrandom(bytes.data() + got, bytes.size() - got, 0);
        if (n < 0) {
            if (errno == EINTR)
                continue;
            throw std::system_error(errno, std::generic_category(), "getrandom");
        }
        got += static_cast<std::size_t>(n);
    }
    constexpr char const* digits = "0123456789abcdef";
    std::string token;
    token.reserve(2 * bytes.size());
    for (unsigned char const b : bytes) {
        token += digits[b >> 4U];
        token += digits[b & 0x0FU];
    }
    return token;
}

bool is_resume_token(std::string_view given, std::string_view issued)
{
    return is_admin_token(given, issued);
}

} // namespace kugel::server
