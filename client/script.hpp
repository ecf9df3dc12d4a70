#pragma once

// A script: a conversation with a running server, written by hand as JSON, with the
// expectations that make it a test. client/README.md describes the format for users; this
// is its reader. Reading checks the script's shape, so a typo is reported before anything is
// sent; values that use variables are checked when the step runs.

#include <array>
#include <cstdint>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <variant>
#include <vector>

namespace kugel::client {

/// A script that cannot be read: what() names the step and the field.
class script_error : public std::runtime_error
{
public:
    using std::runtime_error::runtime_error;
};

/// "keep": variable name -> where to read it ("id", or a JSON pointer such as "/position/2").
using keep_map = std::map<std::string, std::string>;

/// Send a command; its ref is chosen by the connection.
struct send_step
{
    nlohmann::json message;   ///< a client message without "ref"; values may use variables
    std::uint64_t repeat = 1; ///< sent this many times in a row
    std::string label;        ///< "as": a name for expect's "to"
};

/// Send text as it is (with $name interpolated): for answers to malformed input.
struct send_text_step
{
    std::string text;
    std::uint64_t pad_to_bytes = 0; ///< spaces appended until the text is this long
    std::string label;
};

/// Wait for the answer to an earlier send and check it.
struct expect_step
{
    enum class which { last, any, all };
    std::string to;                  ///< a label; empty: the client's latest send
    which of = which::last;          ///< for a repeated send: whose answers must match
    std::optional<std::string> type; ///< "ack", "error" or "pong"
    std::optional<std::string> code; ///< an error code: implies type error
    nlohmann::json fields = nlohmann::json::object(); ///< field or /pointer -> value
    std::optional<std::string> message_contains;      ///< a part of an error's message
    keep_map keep;
};

/// Wait until the world is `ticks` ticks further than the newest snapshot received.
struct wait_ticks_step
{
    nlohmann::json ticks;
};

/// Wait for a snapshot of tick `tick` or later.
struct wait_until_tick_step
{
    nlohmann::json tick;
};

/// What a body should be like in a snapshot.
struct body_expectation
{
    nlohmann::json id;
    bool exists = true;
    std::optional<std::array<nlohmann::json, 3>> position; ///< m; null components are not checked
    std::optional<std::array<nlohmann::json, 3>> velocity; ///< m/s
    nlohmann::json tolerance; ///< m or m/s, absolute, per component: |got - expected| <= it
    /// The body's tag: a string ("$name" for a kept one), or null for a body without one
    std::optional<nlohmann::json> tag;
    keep_map keep;            ///< from id, position, velocity, radius, mass, charge, tag, tick, time
};

/// Check a body in the newest snapshot received.
struct expect_body_step
{
    body_expectation body;
};

/// Wait for a snapshot in which the body is as expected, for at most max_ticks ticks.
struct wait_for_body_step
{
    body_expectation body;
    nlohmann::json max_ticks;
};

/// Close the connection (1000, normal).
struct close_step
{
};

/// Wait for the server to close the connection, optionally with a given close code.
struct expect_close_step
{
    std::optional<std::uint16_t> code;
};

/// Wait for the client's next player notice (another player joined, was renamed or left;
/// this one renamed) not yet taken, and check it.
struct expect_player_step
{
    /// "change", "id", "name" -> the value wanted (variables allowed); a null name: none
    nlohmann::json fields = nlohmann::json::object();
    keep_map keep; ///< from "id", "name", "change"
};

/// Wait for the client's next sensor event (its hello asked for events) not yet taken, and
/// check it.
struct expect_event_step
{
    /// "kind", "sensor", "body", "tag", "owner", "bodies", "tags", "tick" -> the value wanted
    /// (variables allowed); a null tag: a body without one
    nlohmann::json fields = nlohmann::json::object();
    keep_map keep; ///< from any field of the event ("body", "tick", "time", "bodies", ...)
};

using step_action =
    std::variant<send_step, send_text_step, expect_step, wait_ticks_step, wait_until_tick_step,
                 expect_body_step, wait_for_body_step, close_step, expect_close_step, expect_player_step,
                 expect_event_step>;

struct step
{
    std::size_t number = 0;      ///< 1-based, as messages name it
    std::string kind;            ///< the action's key: "send", "expect", ...
    std::string name;            ///< the script's own description of the step, if any
    std::string client = "main"; ///< which connection
    step_action action;
    nlohmann::json source; ///< the step as written, for messages
};

struct script
{
    std::string description;
    std::vector<std::string> server;                 ///< kugel-server arguments it was written for
    std::map<std::string, nlohmann::json> variables; ///< set before the first step
    std::vector<step> steps;
    /// At the end, passed or failed, each client removes the bodies it spawned (so that a
    /// script run again and again against a long-lived room leaves nothing behind).
    bool cleanup = false;
};

/// Reads a script from JSON text; throws script_error naming the step and field at fault.
script parse_script(std::string_view text);
/// Reads a script file; throws script_error (with the file name) when it cannot.
script load_script(std::filesystem::path const& file);

/// "step 4 \"name\" (expect_body, client main)": how messages name a step.
std::string label_of(step const& s);

} // namespace kugel::client
