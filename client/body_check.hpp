#pragma once

// A script's expectation of one body, held against one snapshot.

#include "client/script.hpp"
#include "client/variables.hpp"
#include "protocol/messages.hpp"

#include <string>

namespace kugel::client {

/// The outcome of holding a body_expectation against a snapshot.
struct body_check
{
    bool passed = false;
    std::string expected; ///< what the expectation asked, values resolved
    std::string arrived;  ///< what the snapshot showed
    nlohmann::json body;  ///< the body as JSON (id, position, velocity, radius, mass, charge,
                          ///< tag (null: none), tick, time), null when it is not in the snapshot
};

/// Checks `expectation` against `snapshot`. Its values may use `vars` and, for this snapshot,
/// $tick and $time. Throws substitution_error when a value cannot be resolved.
body_check check_body(body_expectation const& expectation, protocol::snapshot const& snapshot,
                      variables const& vars);

/// Sets the expectation's "keep" variables from a body that passed.
void keep_from_body(body_expectation const& expectation, body_check const& check, variables& vars);

/// The value at `where` in `value`: a field name ("id") or a JSON pointer ("/position/2").
/// Throws substitution_error when there is nothing there.
nlohmann::json const& value_at(nlohmann::json const& value, std::string const& where);

} // namespace kugel::client
