#include "admin_token.hpp"

#include <cstddef>

namespace kugel::server {

bool is_admin_token(std::string_view given, std::string_view configured)
{
    if (configured.empty())
        return false;
    // Every byte of the configured token is compared, against the given one's byte at the
    // same place (or a stand-in past its end), and differences are collected without a
    // branch on them; a length mismatch is folded in at the end.
    unsigned difference = given.size() == configured.size() ? 0U : 1U;
    for (std::size_t i = 0; i < configured.size(); ++i) {
        unsigned char const a = i < given.size() ? static_cast<unsigned char>(given[i]) : 0U;
        difference |= static_cast<unsigned>(a ^ static_cast<unsigned char>(configured[i]));
    }
    return difference == 0;
}

} // namespace kugel::server
