#include "script.hpp"

#include "variables.hpp"

#include <algorithm>
#include <fstream>
#include <set>
#include <sstream>

namespace kugel::client {

namespace {

using json = nlohmann::json;

/// Where in the script we are, for messages: "step 3 (expect): /expect/code".
struct place
{
    std::string prefix;  ///< "step 3 (expect)" or "script"
    std::string pointer; ///< JSON pointer inside it

    place operator/(std::string const& key) const { return {prefix, pointer + "/" + key}; }
    place operator/(std::size_t index) const
    {
        return {prefix, pointer + "/" + std::to_string(index)};
    }

    [[noreturn]] void fail(std::string const& why) const
    {
        throw script_error(prefix + ": " + (pointer.empty() ? "" : pointer + ": ") + why);
    }
};

/// Refuses keys not in `known`, naming the first unknown one and the known ones.
void only_keys(json const& object, std::set<std::string> const& known, place const& at)
{
    for (auto const& [key, value] : object.items()) {
        if (known.contains(key))
            continue;
        std::string list;
        for (auto const& k : known)
            list += (list.empty() ? "" : ", ") + k;
        at.fail("unknown field \"" + key + "\" (known here: " + list + ")");
    }
}

json const& object_at(json const& value, place const& at)
{
    if (!value.is_object())
        at.fail("must be an object, got " + describe(value));
    return value;
}

std::string string_at(json const& value, place const& at)
{
    if (!value.is_string())
        at.fail("must be a string, got " + describe(value));
    return value.get<std::string>();
}

std::uint64_t whole_at(json const& value, place const& at, std::uint64_t low, std::uint64_t high)
{
    // nlohmann reads a whole number >= 0 as unsigned; anything else is refused here.
    if (!value.is_number_unsigned() || value.get<std::uint64_t>() < low ||
        value.get<std::uint64_t>() > high)
        at.fail("must be a whole number from " + std::to_string(low) + " to " +
                std::to_string(high) + ", got " + describe(value));
    return value.get<std::uint64_t>();
}

/// A number, or a string that a variable or expression will make one at run time.
json number_or_substituted(json const& value, place const& at)
{
    if (value.is_number() || is_substituted(value))
        return value;
    at.fail("must be a number, \"$variable\" or \"= expression\", got " + describe(value));
}

keep_map keep_at(json const& value, place const& at)
{
    keep_map keep;
    for (auto const& [name, where] : object_at(value, at).items()) {
        if (name.empty() || !std::all_of(name.begin(), name.end(), [](char c) {
                return std::isalnum(static_cast<unsigned char>(c)) || c == '_';
            }))
            (at / name).fail("a variable name is letters, digits and '_'");
        keep[name] = string_at(where, at / name);
    }
    return keep;
}

std::array<json, 3> vector_at(json const& value, place const& at)
{
    if (!value.is_array() || value.size() != 3)
        at.fail("must be [x, y, z] (null for a component not checked), got " + describe(value));
    std::array<json, 3> v;
    for (std::size_t k = 0; k < 3; ++k)
        v[k] = value[k].is_null() ? json() : number_or_substituted(value[k], at / k);
    return v;
}

body_expectation body_at(json const& value, place const& at, bool with_max_ticks, json* max_ticks)
{
    std::set<std::string> known{"id", "exists", "position", "velocity", "tolerance", "tag", "keep"};
    if (with_max_ticks)
        known.insert("max_ticks");
    json const& object = object_at(value, at);
    only_keys(object, known, at);
    body_expectation body;
    if (!object.contains("id"))
        at.fail("\"id\" is required: the body's id, usually \"$name\" kept from a spawn's ack");
    body.id = number_or_substituted(object["id"], at / "id");
    if (object.contains("exists")) {
        if (!object["exists"].is_boolean())
            (at / "exists").fail("must be true or false");
        body.exists = object["exists"].get<bool>();
    }
    if (object.contains("position"))
        body.position = vector_at(object["position"], at / "position");
    if (object.contains("velocity"))
        body.velocity = vector_at(object["velocity"], at / "velocity");
    if ((body.position || body.velocity) && !object.contains("tolerance"))
        at.fail("\"tolerance\" is required with position or velocity (0 asks for exact values)");
    if (object.contains("tolerance"))
        body.tolerance = number_or_substituted(object["tolerance"], at / "tolerance");
    if (!body.exists && (body.position || body.velocity || object.contains("keep")))
        at.fail("a body expected not to exist has no position, velocity or keep");
    if (object.contains("tag")) {
        if (!object["tag"].is_string() && !object["tag"].is_null())
            (at / "tag").fail("must be a string (the body's tag) or null (no tag), got " + describe(object["tag"]));
        if (!body.exists)
            (at / "tag").fail("a body expected not to exist has no tag");
        body.tag = object["tag"];
    }
    if (object.contains("keep"))
        body.keep = keep_at(object["keep"], at / "keep");
    if (with_max_ticks) {
        if (!object.contains("max_ticks"))
            at.fail("\"max_ticks\" is required: how many ticks to wait at most");
        *max_ticks = number_or_substituted(object["max_ticks"], at / "max_ticks");
    }
    return body;
}

expect_step expect_at(json const& value, place const& at)
{
    json const& object = object_at(value, at);
    only_keys(object, {"to", "which", "type", "code", "fields", "message_contains", "keep"}, at);
    expect_step e;
    if (object.contains("to"))
        e.to = string_at(object["to"], at / "to");
    if (object.contains("which")) {
        std::string const which = string_at(object["which"], at / "which");
        if (which == "last")
            e.of = expect_step::which::last;
        else if (which == "any")
            e.of = expect_step::which::any;
        else if (which == "all")
            e.of = expect_step::which::all;
        else
            (at / "which").fail("must be \"last\", \"any\" or \"all\", got \"" + which + "\"");
    }
    if (object.contains("type")) {
        e.type = string_at(object["type"], at / "type");
        if (*e.type != "ack" && *e.type != "error" && *e.type != "pong")
            (at / "type").fail("must be \"ack\", \"error\" or \"pong\", got \"" + *e.type + "\"");
    }
    if (object.contains("code")) {
        e.code = string_at(object["code"], at / "code");
        if (e.type && *e.type != "error")
            (at / "code").fail("a code belongs to an error, and type says \"" + *e.type + "\"");
        e.type = "error";
    }
    if (!e.type)
        at.fail("say what answer is expected: \"type\" (ack, error, pong) or an error \"code\"");
    if (object.contains("fields"))
        e.fields = object_at(object["fields"], at / "fields");
    if (object.contains("message_contains"))
        e.message_contains = string_at(object["message_contains"], at / "message_contains");
    if (object.contains("keep"))
        e.keep = keep_at(object["keep"], at / "keep");
    return e;
}

step step_at(json const& value, std::size_t number)
{
    place at{"step " + std::to_string(number), ""};
    json const& object = object_at(value, at);
    static std::set<std::string> const actions{"send",          "send_text",       "expect",
                                               "wait_ticks",    "wait_until_tick", "expect_body",
                                               "wait_for_body", "close",           "expect_close",
                                               "expect_player", "expect_event"};
    std::vector<std::string> found;
    for (auto const& [key, item] : object.items())
        if (actions.contains(key))
            found.push_back(key);
    if (found.size() != 1) {
        std::string list;
        for (auto const& a : actions)
            list += (list.empty() ? "" : ", ") + a;
        at.fail(found.empty() ? "no action: a step has one of " + list
                              : "more than one action (\"" + found[0] + "\" and \"" + found[1] +
                                    "\"): one per step");
    }
    step s;
    s.number = number;
    s.kind = found[0];
    s.source = value;
    at.prefix += " (" + s.kind + ")";
    std::set<std::string> known{"name", "client", s.kind};
    if (s.kind == "send")
        known.insert({"as", "repeat"});
    if (s.kind == "send_text")
        known.insert({"as", "pad_to_bytes"});
    only_keys(object, known, at);
    if (object.contains("name"))
        s.name = string_at(object["name"], at / "name");
    if (object.contains("client")) {
        s.client = string_at(object["client"], at / "client");
        if (s.client.empty())
            (at / "client").fail("must not be empty");
    }
    json const& body = object[s.kind];
    place const inner = at / s.kind;
    std::string const label = object.contains("as") ? string_at(object["as"], at / "as") : "";

    if (s.kind == "send") {
        send_step send;
        send.message = object_at(body, inner);
        if (!send.message.contains("type") || !send.message["type"].is_string())
            inner.fail("a message has a string \"type\" (spawn, impulse, set, remove, ping, interest, hello, or an "
                       "admin command: pause, resume, reset, load_scene)");
        if (send.message.contains("ref"))
            (inner / "ref")
                .fail("refs are chosen by the connection; leave \"ref\" out "
                      "(send_text sends a message exactly as written)");
        if (object.contains("repeat"))
            send.repeat = whole_at(object["repeat"], at / "repeat", 1, 100'000);
        send.label = label;
        s.action = std::move(send);
    } else if (s.kind == "send_text") {
        send_text_step send;
        send.text = string_at(body, inner);
        if (object.contains("pad_to_bytes"))
            send.pad_to_bytes = whole_at(object["pad_to_bytes"], at / "pad_to_bytes", 0, 64 << 20);
        send.label = label;
        s.action = std::move(send);
    } else if (s.kind == "expect") {
        s.action = expect_at(body, inner);
    } else if (s.kind == "wait_ticks") {
        s.action = wait_ticks_step{number_or_substituted(body, inner)};
    } else if (s.kind == "wait_until_tick") {
        s.action = wait_until_tick_step{number_or_substituted(body, inner)};
    } else if (s.kind == "expect_body") {
        s.action = expect_body_step{body_at(body, inner, false, nullptr)};
    } else if (s.kind == "wait_for_body") {
        wait_for_body_step w;
        w.body = body_at(body, inner, true, &w.max_ticks);
        s.action = std::move(w);
    } else if (s.kind == "close") {
        if (body != true && !(body.is_object() && body.empty()))
            inner.fail("write \"close\": true");
        s.action = close_step{};
    } else if (s.kind == "expect_player") {
        expect_player_step e;
        json const& wanted = object_at(body, inner);
        only_keys(wanted, {"change", "id", "name", "keep"}, inner);
        if (wanted.contains("change")) {
            json const& change = wanted["change"];
            if (!is_substituted(change) && change != "joined" && change != "renamed" && change != "left")
                (inner / "change").fail("must be \"joined\", \"renamed\" or \"left\", got " + describe(change));
            e.fields["change"] = change;
        }
        if (wanted.contains("id"))
            e.fields["id"] = number_or_substituted(wanted["id"], inner / "id");
        if (wanted.contains("name")) {
            if (!wanted["name"].is_string() && !wanted["name"].is_null())
                (inner / "name").fail("must be a string, or null for a player without a name");
            e.fields["name"] = wanted["name"];
        }
        if (wanted.contains("keep"))
            e.keep = keep_at(wanted["keep"], inner / "keep");
        s.action = std::move(e);
    } else if (s.kind == "expect_event") {
        expect_event_step e;
        json const& wanted = object_at(body, inner);
        only_keys(wanted, {"kind", "sensor", "body", "tag", "owner", "bodies", "tags", "tick", "keep"}, inner);
        if (wanted.contains("kind")) {
            json const& kind = wanted["kind"];
            if (!is_substituted(kind) && kind != "entered" && kind != "left" && kind != "contact")
                (inner / "kind").fail("must be \"entered\", \"left\" or \"contact\", got " + describe(kind));
            e.fields["kind"] = kind;
        }
        if (wanted.contains("owner"))
            e.fields["owner"] = number_or_substituted(wanted["owner"], inner / "owner");
        if (wanted.contains("bodies")) { // a contact's two bodies, ascending
            json const& bodies = wanted["bodies"];
            if (!bodies.is_array() || bodies.size() != 2)
                (inner / "bodies").fail("must be a contact's two body ids, [a, b], got " + describe(bodies));
            e.fields["bodies"] = json::array({number_or_substituted(bodies[0], inner / "bodies" / 0U),
                                              number_or_substituted(bodies[1], inner / "bodies" / 1U)});
        }
        if (wanted.contains("tags")) { // and their tags, in that order
            json const& tags = wanted["tags"];
            if (!tags.is_array() || tags.size() != 2)
                (inner / "tags").fail("must be a contact's two tags, [\"ball\", \"post\"], got " + describe(tags));
            e.fields["tags"] = json::array({string_at(tags[0], inner / "tags" / 0U), string_at(tags[1], inner / "tags" / 1U)});
        }
        if (wanted.contains("sensor"))
            e.fields["sensor"] = string_at(wanted["sensor"], inner / "sensor");
        if (wanted.contains("body"))
            e.fields["body"] = number_or_substituted(wanted["body"], inner / "body");
        if (wanted.contains("tick"))
            e.fields["tick"] = number_or_substituted(wanted["tick"], inner / "tick");
        if (wanted.contains("tag")) {
            if (!wanted["tag"].is_string() && !wanted["tag"].is_null())
                (inner / "tag").fail("must be a string, or null for a body without a tag");
            e.fields["tag"] = wanted["tag"];
        }
        if (wanted.contains("keep"))
            e.keep = keep_at(wanted["keep"], inner / "keep");
        s.action = std::move(e);
    } else if (s.kind == "expect_close") {
        expect_close_step e;
        only_keys(object_at(body, inner), {"code"}, inner);
        if (body.contains("code"))
            e.code = static_cast<std::uint16_t>(whole_at(body["code"], inner / "code", 1000, 4999));
        s.action = e;
    }
    return s;
}

} // namespace

script parse_script(std::string_view text)
{
    json document;
    try {
        document = json::parse(text);
    } catch (json::parse_error const& e) {
        throw script_error(std::string("not valid JSON: ") + e.what());
    }
    place const at{"script", ""};
    object_at(document, at);
    only_keys(document, {"description", "server", "variables", "steps", "cleanup"}, at);
    script result;
    if (document.contains("cleanup")) {
        if (!document["cleanup"].is_boolean())
            (at / "cleanup").fail("must be true or false, got " + describe(document["cleanup"]));
        result.cleanup = document["cleanup"].get<bool>();
    }
    if (document.contains("description"))
        result.description = string_at(document["description"], at / "description");
    if (document.contains("server")) {
        json const& server = document["server"];
        if (!server.is_array())
            (at / "server").fail("must be a list of kugel-server arguments");
        for (std::size_t i = 0; i < server.size(); ++i)
            result.server.push_back(string_at(server[i], at / "server" / i));
    }
    if (document.contains("variables"))
        for (auto const& [name, value] : object_at(document["variables"], at / "variables").items())
            result.variables[name] = value;
    if (!document.contains("steps") || !document["steps"].is_array() || document["steps"].empty())
        (at / "steps").fail("a script has a non-empty list of \"steps\"");
    std::size_t number = 1;
    for (json const& item : document["steps"])
        result.steps.push_back(step_at(item, number++));
    return result;
}

script load_script(std::filesystem::path const& file)
{
    std::ifstream in(file);
    if (!in)
        throw script_error(file.string() + ": cannot be read");
    std::stringstream text;
    text << in.rdbuf();
    try {
        return parse_script(text.str());
    } catch (script_error const& e) {
        throw script_error(file.string() + ": " + e.what());
    }
}

std::string label_of(step const& s)
{
    std::string label = "step " + std::to_string(s.number);
    if (!s.name.empty())
        label += " \"" + s.name + "\"";
    return label + " (" + s.kind + ", client " + s.client + ")";
}

} // namespace kugel::client
