#pragma once

// A script's variables, and the substitution that puts them into the script's values:
//   "$name"            the variable's value, of any JSON type (a body id, a vector, ...)
//   "= expression"     a number computed from numbers and $variables (expression.hpp)
//   anything else      itself
// Inside send_text, "$name" anywhere in the text becomes the value's JSON text ("$$" is "$").

#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

namespace kugel::client {

/// A value that names a variable that is not set, or an expression that fails.
class substitution_error : public std::runtime_error
{
public:
    using std::runtime_error::runtime_error;
};

class variables
{
public:
    void set(std::string const& name, nlohmann::json value);
    /// The value, or nullptr when unset.
    nlohmann::json const* find(std::string_view name) const;
    std::map<std::string, nlohmann::json, std::less<>> const& all() const { return values_; }

    /// `value` with every "$name" and "= expression" string in it replaced, at any depth.
    /// `overlay` names variables that take precedence (a snapshot's tick and time).
    nlohmann::json resolve(nlohmann::json const& value, variables const* overlay = nullptr) const;
    /// resolve() that must give a number.
    double number(nlohmann::json const& value, std::string_view what,
                  variables const* overlay = nullptr) const;
    /// resolve() that must give a whole number >= 0.
    std::uint64_t whole_number(nlohmann::json const& value, std::string_view what,
                               variables const* overlay = nullptr) const;
    /// `text` with every "$name" replaced by the value's JSON text, and "$$" by "$".
    std::string interpolate(std::string_view text) const;

private:
    nlohmann::json const* lookup(std::string_view name, variables const* overlay) const;

    std::map<std::string, nlohmann::json, std::less<>> values_;
};

/// True for a string that resolve() would replace.
bool is_substituted(nlohmann::json const& value);

/// A short one-line form of a JSON value for messages; numbers keep every digit.
std::string describe(nlohmann::json const& value);

} // namespace kugel::client
