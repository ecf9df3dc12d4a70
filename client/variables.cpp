#include "variables.hpp"

#include "expression.hpp"

#include <cctype>
#include <cmath>

namespace kugel::client {

namespace {

bool is_name_char(char c)
{
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_';
}

/// "name" when `text` is exactly "$name", else nullopt.
std::optional<std::string_view> whole_variable(std::string_view text)
{
    if (text.size() < 2 || text.front() != '$')
        return std::nullopt;
    for (char const c : text.substr(1))
        if (!is_name_char(c))
            return std::nullopt;
    return text.substr(1);
}

} // namespace

void variables::set(std::string const& name, nlohmann::json value)
{
    values_.insert_or_assign(name, std::move(value));
}

nlohmann::json const* variables::find(std::string_view name) const
{
    auto const it = values_.find(name);
    return it == values_.end() ? nullptr : &it->second;
}

nlohmann::json const* variables::lookup(std::string_view name, variables const* overlay) const
{
    if (overlay)
        if (auto const* value = overlay->find(name))
            return value;
    return find(name);
}

nlohmann::json variables::resolve(nlohmann::json const& value, variables const* overlay) const
{
    if (value.is_object()) {
        nlohmann::json out = nlohmann::json::object();
        for (auto const& [key, item] : value.items())
            out[key] = resolve(item, overlay);
        return out;
    }
    if (value.is_array()) {
        nlohmann::json out = nlohmann::json::array();
        for (auto const& item : value)
            out.push_back(resolve(item, overlay));
        return out;
    }
    if (!value.is_string())
        return value;
    auto const& text = value.get_ref<std::string const&>();
    if (auto const name = whole_variable(text)) {
        auto const* found = lookup(*name, overlay);
        if (!found)
            throw substitution_error("$" + std::string(*name) + " is not set");
        return *found;
    }
    if (!text.empty() && text.front() == '=') {
        try {
            return evaluate(std::string_view(text).substr(1), [&](std::string_view name) {
                auto const* found = lookup(name, overlay);
                if (!found)
                    return std::optional<double>{};
                if (!found->is_number())
                    throw substitution_error("$" + std::string(name) + " is " + describe(*found) +
                                             ", not a number, in \"" + text + "\"");
                return std::optional<double>{found->get<double>()};
            });
        } catch (expression_error const& e) {
            throw substitution_error(e.what());
        }
    }
    return value;
}

double variables::number(nlohmann::json const& value, std::string_view what,
                         variables const* overlay) const
{
    nlohmann::json const resolved = resolve(value, overlay);
    if (!resolved.is_number())
        throw substitution_error(std::string(what) + " must be a number, got " +
                                 describe(resolved));
    return resolved.get<double>();
}

std::uint64_t variables::whole_number(nlohmann::json const& value, std::string_view what,
                                      variables const* overlay) const
{
    double const x = number(value, what, overlay);
    if (!(x >= 0.0) || std::floor(x) != x || x > 9007199254740991.0)
        throw substitution_error(std::string(what) + " must be a whole number >= 0, got " +
                                 describe(nlohmann::json(x)));
    return static_cast<std::uint64_t>(x);
}

std::string variables::interpolate(std::string_view text) const
{
    std::string out;
    for (std::size_t i = 0; i < text.size(); ++i) {
        if (text[i] != '$') {
            out += text[i];
            continue;
        }
        if (i + 1 < text.size() && text[i + 1] == '$') {
            out += '$';
            ++i;
            continue;
        }
        std::size_t end = i + 1;
        while (end < text.size() && is_name_char(text[end]))
            ++end;
        std::string_view const name = text.substr(i + 1, end - i - 1);
        if (name.empty()) {
            out += '$';
            continue;
        }
        auto const* found = find(name);
        if (!found)
            throw substitution_error("$" + std::string(name) + " is not set");
        out += found->dump();
        i = end - 1;
    }
    return out;
}

bool is_substituted(nlohmann::json const& value)
{
    if (!value.is_string())
        return false;
    auto const& text = value.get_ref<std::string const&>();
    return whole_variable(text).has_value() || (!text.empty() && text.front() == '=');
}

std::string describe(nlohmann::json const& value)
{
    std::string text = value.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
    constexpr std::size_t limit = 400;
    if (text.size() > limit)
        text = text.substr(0, limit - 3) + "...";
    return text;
}

} // namespace kugel::client
