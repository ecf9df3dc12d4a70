#include "expression.hpp"

#include <cctype>
#include <charconv>
#include <cmath>
#include <vector>

namespace kugel::client {

namespace {

/// A recursive-descent reader over the grammar
///   sum     = product {("+" | "-") product}
///   product = signed {("*" | "/") signed}
///   signed  = ("-" | "+") signed | power
///   power   = atom ["^" signed]
///   atom    = number | "$" name | name "(" sum {"," sum} ")" | "(" sum ")"
class reader
{
public:
    reader(std::string_view text, variable_lookup const& variables)
        : text_(text), variables_(variables)
    {
    }

    double whole()
    {
        double const value = sum();
        skip_space();
        if (at_ < text_.size())
            fail("unexpected '" + std::string(1, text_[at_]) + "'");
        return value;
    }

private:
    double sum()
    {
        double value = product();
        for (;;) {
            if (take('+'))
                value += product();
            else if (take('-'))
                value -= product();
            else
                return value;
        }
    }

    double product()
    {
        double value = signed_value();
        for (;;) {
            if (take('*'))
                value *= signed_value();
            else if (take('/'))
                value /= signed_value();
            else
                return value;
        }
    }

    double signed_value()
    {
        if (take('-'))
            return -signed_value();
        if (take('+'))
            return signed_value();
        return power();
    }

    double power()
    {
        double const base = atom();
        if (take('^'))
            return std::pow(base, signed_value());
        return base;
    }

    double atom()
    {
        skip_space();
        if (at_ >= text_.size())
            fail("a number, $variable or '(' expected");
        char const c = text_[at_];
        if (take('(')) {
            double const value = sum();
            expect(')');
            return value;
        }
        if (c == '$') {
            ++at_;
            std::string const name = identifier();
            if (name.empty())
                fail("a variable name expected after '$'");
            auto const value = variables_(name);
            if (!value)
                fail("unknown variable $" + name);
            return *value;
        }
        if (std::isalpha(static_cast<unsigned char>(c)))
            return function_call(identifier());
        return number();
    }

    double function_call(std::string const& name)
    {
        expect('(');
        std::vector<double> args{sum()};
        while (take(','))
            args.push_back(sum());
        expect(')');
        auto const arity = [&](std::size_t n) {
            if (args.size() != n)
                fail(name + "() takes " + std::to_string(n) + " argument" + (n == 1 ? "" : "s"));
        };
        if (name == "sqrt") {
            arity(1);
            return std::sqrt(args[0]);
        }
        if (name == "abs") {
            arity(1);
            return std::abs(args[0]);
        }
        if (name == "min" || name == "max") {
            arity(2);
            return name == "min" ? std::min(args[0], args[1]) : std::max(args[0], args[1]);
        }
        fail("unknown function " + name + "() (known: sqrt, abs, min, max)");
    }

    double number()
    {
        double value = 0.0;
        char const* const begin = text_.data() + at_;
        auto const [end, ec] = std::from_chars(begin, text_.data() + text_.size(), value);
        if (ec != std::errc{} || end == begin)
            fail("a number, $variable or '(' expected");
        at_ += static_cast<std::size_t>(end - begin);
        return value;
    }

    std::string identifier()
    {
        std::size_t const start = at_;
        while (at_ < text_.size() &&
               (std::isalnum(static_cast<unsigned char>(text_[at_])) || text_[at_] == '_'))
            ++at_;
        return std::string(text_.substr(start, at_ - start));
    }

    void skip_space()
    {
        while (at_ < text_.size() && std::isspace(static_cast<unsigned char>(text_[at_])))
            ++at_;
    }

    bool take(char c)
    {
        skip_space();
        if (at_ < text_.size() && text_[at_] == c) {
            ++at_;
            return true;
        }
        return false;
    }

    void expect(char c)
    {
        if (!take(c))
            fail(std::string("'") + c + "' expected");
    }

    [[noreturn]] void fail(std::string const& why) const
    {
        throw expression_error("in \"" + std::string(text_) + "\" at " + std::to_string(at_ + 1) +
                               ": " + why);
    }

    std::string_view text_;
    variable_lookup const& variables_;
    std::size_t at_ = 0;
};

} // namespace

double evaluate(std::string_view text, variable_lookup const& variables)
{
    double const value = reader(text, variables).whole();
    if (!std::isfinite(value))
        throw expression_error("\"" + std::string(text) + "\" is not a finite number (" +
                               std::to_string(value) + ")");
    return value;
}

} // namespace kugel::client
