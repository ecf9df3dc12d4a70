#include "error_code.hpp"

#include <cstddef>

namespace kugel::protocol {

namespace {

/// The one table of wire names, indexed by the enum's value.
constexpr std::array<std::string_view, all_error_codes.size()> wire_names{
    "bad_json",      "bad_message", "unknown_type",         "missing_field",     "wrong_type",
    "not_finite",    "bad_value",   "unsupported_protocol", "unknown_body",      "outside_world",
    "overlaps_wall", "room_full",   "rate_limited",         "message_too_large",
    "forbidden",     "too_many_bodies", "overlaps_body",       "singular_force",
    "bad_resume",
};

constexpr bool table_follows_the_enum()
{
    for (std::size_t i = 0; i < all_error_codes.size(); ++i)
        if (static_cast<std::size_t>(all_error_codes[i]) != i)
            return false;
    return true;
}
static_assert(table_follows_the_enum(), "all_error_codes must list the codes in order");

} // namespace

std::string_view name(error_code code)
{
    return wire_names.at(static_cast<std::size_t>(code));
}

std::optional<error_code> error_code_named(std::string_view wire_name)
{
    for (auto const code : all_error_codes)
        if (name(code) == wire_name)
            return code;
    return std::nullopt;
}

} // namespace kugel::protocol
