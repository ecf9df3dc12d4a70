#include "body_check.hpp"

#include <cmath>
#include <optional>

namespace kugel::client {

namespace {

using json = nlohmann::json;

std::optional<std::size_t> index_of(protocol::snapshot const& snapshot, std::uint64_t id)
{
    auto const& ids = snapshot.bodies.id;
    for (std::size_t i = 0; i < ids.size(); ++i)
        if (ids[i] == id)
            return i;
    return std::nullopt;
}

json column3(std::vector<double> const& column, std::size_t i)
{
    return json::array({column[3 * i], column[3 * i + 1], column[3 * i + 2]});
}

json body_json(protocol::snapshot const& snapshot, std::size_t i)
{
    auto const& b = snapshot.bodies;
    json body = {{"id", b.id[i]},
                 {"position", column3(b.position, i)},
                 {"velocity", column3(b.velocity, i)},
                 {"radius", b.radius[i]}};
    if (b.mass)
        body["mass"] = (*b.mass)[i];
    if (b.charge)
        body["charge"] = (*b.charge)[i];
    body["tag"] = b.tag && !(*b.tag)[i].empty() ? json((*b.tag)[i]) : json(); // null: none
    body["tick"] = snapshot.tick;
    body["time"] = snapshot.time;
    return body;
}

/// "[1.0, any, 2.5]": components in full precision, "any" for one not checked.
std::string vector_text(std::array<json, 3> const& v)
{
    std::string text = "[";
    for (std::size_t k = 0; k < 3; ++k)
        text += (k ? ", " : "") + (v[k].is_null() ? std::string("any") : describe(v[k]));
    return text + "]";
}

std::string vector_text(json const& v)
{
    return vector_text(std::array<json, 3>{v[0], v[1], v[2]});
}

} // namespace

json const& value_at(json const& value, std::string const& where)
{
    try {
        json::json_pointer const pointer(where.starts_with('/') ? where : "/" + where);
        return value.at(pointer);
    } catch (json::exception const&) {
        throw substitution_error("nothing at \"" + where + "\" in " + describe(value));
    }
}

body_check check_body(body_expectation const& expectation, protocol::snapshot const& snapshot,
                      variables const& vars)
{
    variables here; // this snapshot's $tick and $time
    here.set("tick", snapshot.tick);
    here.set("time", snapshot.time);
    std::uint64_t const id = vars.whole_number(expectation.id, "id", &here);
    auto const i = index_of(snapshot, id);
    std::string const at_tick = " at tick " + std::to_string(snapshot.tick);

    body_check check;
    check.body = i ? body_json(snapshot, *i) : json();
    if (!expectation.exists) {
        check.expected = "no body " + std::to_string(id);
        check.passed = !i;
        check.arrived = i ? "body " + std::to_string(id) + " at " +
                                vector_text(check.body["position"]) + at_tick
                          : "no body " + std::to_string(id) + at_tick;
        return check;
    }

    check.expected = "body " + std::to_string(id);
    if (!i) {
        check.arrived = "no body " + std::to_string(id) + at_tick + " (" +
                        std::to_string(snapshot.bodies.size()) + " bodies)";
        return check;
    }
    check.passed = true;
    check.arrived = "body " + std::to_string(id) + at_tick;
    double const tolerance = expectation.position || expectation.velocity
                                 ? vars.number(expectation.tolerance, "tolerance", &here)
                                 : 0.0;
    auto const compare = [&](char const* what, std::optional<std::array<json, 3>> const& wanted) {
        if (!wanted)
            return;
        std::array<json, 3> resolved;
        for (std::size_t k = 0; k < 3; ++k) {
            if ((*wanted)[k].is_null())
                continue;
            resolved[k] =
                vars.number((*wanted)[k], std::string(what) + "/" + std::to_string(k), &here);
            double const got = check.body[what][k].get<double>();
            if (!(std::abs(got - resolved[k].get<double>()) <= tolerance))
                check.passed = false;
        }
        check.expected += std::string(", ") + what + " " + vector_text(resolved);
        check.arrived += std::string(", ") + what + " " + vector_text(check.body[what]);
    };
    compare("position", expectation.position);
    compare("velocity", expectation.velocity);
    if (expectation.position || expectation.velocity)
        check.expected += " ± " + describe(json(tolerance));
    if (expectation.tag) {
        json const wanted = vars.resolve(*expectation.tag, &here); // "$name": a kept tag
        if (check.body["tag"] != wanted)
            check.passed = false;
        check.expected += ", tag " + describe(wanted);
        check.arrived += ", tag " + describe(check.body["tag"]);
    }
    return check;
}

void keep_from_body(body_expectation const& expectation, body_check const& check, variables& vars)
{
    for (auto const& [name, where] : expectation.keep)
        vars.set(name, value_at(check.body, where));
}

} // namespace kugel::client
