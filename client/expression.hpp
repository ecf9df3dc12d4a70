#pragma once

// The arithmetic a script may write where it expects a number: "= 10 - 0.5 * 9.81 * $t^2".

#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

namespace kugel::client {

/// An expression that cannot be read or evaluated; what() names the place and the reason.
class expression_error : public std::runtime_error
{
public:
    using std::runtime_error::runtime_error;
};

/// The value of a variable by name (without the '$'), or nullopt when it has none.
using variable_lookup = std::function<std::optional<double>(std::string_view name)>;

/// Evaluates `text`: numbers, $variables, + - * / ^ (power, right-associative, binding
/// tighter than a leading minus: -2^2 = -4), parentheses, and the functions sqrt, abs, min,
/// max. Throws expression_error for text it cannot read, an unknown variable or function,
/// or a result that is not finite.
double evaluate(std::string_view text, variable_lookup const& variables);

} // namespace kugel::client
