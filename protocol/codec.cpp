#include "codec.hpp"

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <memory>
#include <limits>
#include <nlohmann/json.hpp>
#include <tuple>
#include <type_traits>
#include <utility>
#include <vector>

namespace kugel::protocol {

// Keeps the order fields are written in, so `type` comes first on the wire.
using json = nlohmann::ordered_json;

namespace {

// Text ------------------------------------------------------------------------------------

/// The shortest text that reads back as the same double.
std::string format(double x)
{
    std::array<char, 32> buffer{};
    auto const [end, ec] = std::to_chars(buffer.data(), buffer.data() + buffer.size(), x);
    return std::string(buffer.data(), end);
}

/// Writes `value` as JSON text. Strings from a client (echoed in error messages) may hold
/// invalid UTF-8; it becomes U+FFFD rather than an exception.
std::string dump(json const& value)
{
    return value.dump(-1, ' ', false, json::error_handler_t::replace);
}

/// At most `limit` bytes of `text`, cut at a character boundary, "..." marking a cut.
std::string shortened(std::string text, std::size_t limit = 40)
{
    if (text.size() <= limit)
        return text;
    std::size_t end = limit - 3;
    auto const continues_a_character = [](char c) {
        return (static_cast<unsigned char>(c) & 0xC0U) == 0x80U;
    };
    while (end > 0 && continues_a_character(text[end]))
        --end;
    return text.substr(0, end) + "...";
}

/// A short description of a value for messages: "string \"0.1\"", "array of 2", "number -1".
/// Never dumps a whole container: a message could be deep or long.
std::string describe(json const& value)
{
    switch (value.type()) {
    case json::value_t::object:
        return "object";
    case json::value_t::array:
        return "array of " + std::to_string(value.size());
    case json::value_t::string:
        return "string " + dump(json(shortened(value.get_ref<std::string const&>())));
    case json::value_t::null:
        return "null";
    default:
        return std::string(value.type_name()) + " " + dump(value);
    }
}

/// A JSON pointer segment (RFC 6901): '~' becomes "~0", '/' becomes "~1".
std::string escaped(std::string_view key)
{
    std::string out;
    for (char const c : key) {
        if (c == '~')
            out += "~0";
        else if (c == '/')
            out += "~1";
        else
            out += c;
    }
    return out;
}

// Where a refusal happened ----------------------------------------------------------------

/// A message that cannot be accepted; decode turns it into an `error`.
struct refusal
{
    error_code code;
    std::string message;
};

/// Where we are in the message, as a JSON pointer, for messages.
struct location
{
    std::string pointer;

    location operator/(std::string_view key) const { return {pointer + "/" + escaped(key)}; }
    location operator/(std::size_t index) const { return {pointer + "/" + std::to_string(index)}; }

    [[noreturn]] void fail(error_code code, std::string_view reason) const
    {
        throw refusal{code, (pointer.empty() ? "/" : pointer) + ": " + std::string(reason)};
    }
};

// Field tables ----------------------------------------------------------------------------

template <class T> struct optional_traits
{
    using value_type = T;
    static constexpr bool is_optional = false;
};
template <class T> struct optional_traits<std::optional<T>>
{
    using value_type = T;
    static constexpr bool is_optional = true;
};

/// One member and its wire name. A std::optional member may be absent; another member must
/// be present unless `defaulted`. `check`, when set, refuses values out of range.
template <class T, class M> struct field
{
    using value_type = typename optional_traits<M>::value_type;

    std::string_view name;
    M T::*member;
    bool defaulted = false;
    void (*check)(value_type const&, location const&) = nullptr;
    bool written_only_when_set = false; ///< a defaulted member left off the wire at its default
};

template <class T, class M>
constexpr field<T, M> member(std::string_view name, M T::*pointer,
                             void (*check)(typename field<T, M>::value_type const&,
                                           location const&) = nullptr)
{
    return {name, pointer, false, check};
}

/// A member that may be absent on the wire; it keeps the default the struct gives it.
template <class T, class M> constexpr field<T, M> with_default(std::string_view name, M T::*pointer)
{
    return {name, pointer, true, nullptr};
}

/// A member that may be absent on the wire, and is written only when it is not M{}: a flag
/// added to a message that existing senders never set.
template <class T, class M> constexpr field<T, M> only_when_set(std::string_view name, M T::*pointer)
{
    return {name, pointer, true, nullptr, true};
}

void at_least_zero(double const& x, location const& at)
{
    if (!(x >= 0.0))
        at.fail(error_code::bad_value, "must be >= 0, got " + format(x));
}

void above_zero(double const& x, location const& at)
{
    if (!(x > 0.0))
        at.fail(error_code::bad_value, "must be > 0, got " + format(x));
}

void zero_to_one(double const& x, location const& at)
{
    if (!(x >= 0.0 && x <= 1.0))
        at.fail(error_code::bad_value, "must be between 0 and 1, got " + format(x));
}

void each_at_least_zero(vec3 const& v, location const& at)
{
    for (std::size_t i = 0; i < v.size(); ++i)
        at_least_zero(v[i], at / i);
}

void spoken_protocol(int const& version, location const& at)
{
    if (version != protocol_version)
        at.fail(error_code::unsupported_protocol, "protocol " + std::to_string(version) +
                                                      " is not spoken here (this side speaks " +
                                                      std::to_string(protocol_version) + ")");
}

// The one table of wire names: every struct's fields, in the order they are written.

constexpr auto fields(std::type_identity<snapshot_request>)
{
    return std::tuple{member("form", &snapshot_request::form),
                      member("rate", &snapshot_request::rate, above_zero)};
}

/// Text shown to other clients (a player's name, a body's tag): 1 to `most` bytes, free of
/// control characters (JSON has already refused invalid UTF-8).
void shown_text(std::string const& text, std::size_t most, location const& at)
{
    if (text.empty() || text.size() > most)
        at.fail(error_code::bad_value, "must be 1 to " + std::to_string(most) + " bytes of UTF-8, got " +
                                           std::to_string(text.size()));
    for (char const ch : text)
        if (auto const c = static_cast<unsigned char>(ch); c < 0x20 || c == 0x7f)
            at.fail(error_code::bad_value, "must not hold control characters (found the byte " +
                                               std::to_string(static_cast<unsigned>(c)) + ")");
}

/// A player's name: shown to the room's other players.
void player_name(std::string const& name, location const& at) { shown_text(name, max_player_name_bytes, at); }

/// A body's tag: shown with the body to every client.
void body_tag(std::string const& tag, location const& at) { shown_text(tag, max_body_tag_bytes, at); }

/// A snapshot's tag column: a tag, or "" for a body without one.
void tag_column(std::vector<std::string> const& tags, location const& at)
{
    for (std::size_t i = 0; i < tags.size(); ++i)
        if (!tags[i].empty())
            body_tag(tags[i], at / i);
}

/// A resume token: a secret, so its length is all a refusal says of it.
void resume_token_text(std::string const& token, location const& at)
{
    if (token.empty() || token.size() > max_resume_token_bytes)
        at.fail(error_code::bad_value, "must be 1 to " + std::to_string(max_resume_token_bytes) +
                                           " bytes (a welcome's resume_token), got " +
                                           std::to_string(token.size()));
}

/// A sensor's name, as a scene gives it.
void sensor_name(std::string const& name, location const& at) { shown_text(name, max_sensor_name_bytes, at); }

/// One list of an event subscription: 1 to max_event_filter_entries entries, each checked.
template <void (*Check)(std::string const&, location const&)>
void filter_list(std::vector<std::string> const& list, location const& at)
{
    if (list.empty())
        at.fail(error_code::bad_value, "must hold at least one entry (leave the list out to match every event)");
    if (list.size() > max_event_filter_entries)
        at.fail(error_code::bad_value, "must hold at most " + std::to_string(max_event_filter_entries) +
                                           " entries, got " + std::to_string(list.size()));
    for (std::size_t i = 0; i < list.size(); ++i)
        Check(list[i], at / i);
}

void event_kind(std::string const& kind, location const& at)
{
    if (kind != "entered" && kind != "left" && kind != "contact")
        at.fail(error_code::bad_value,
                "must be \"entered\", \"left\" or \"contact\", got " + dump(json(shortened(kind))));
}

/// A contact event's two bodies, or their two tags.
template <typename T>
void exactly_two(std::vector<T> const& pair, location const& at)
{
    if (pair.size() != 2)
        at.fail(error_code::bad_value, "must hold the contact's two bodies, got " + std::to_string(pair.size()));
}

void tag_pair(std::vector<std::string> const& tags, location const& at)
{
    exactly_two(tags, at);
    for (std::size_t i = 0; i < tags.size(); ++i)
        body_tag(tags[i], at / i);
}

constexpr auto fields(std::type_identity<event_filter>)
{
    return std::tuple{member("sensors", &event_filter::sensors, filter_list<sensor_name>),
                      member("tags", &event_filter::tags, filter_list<body_tag>),
                      member("kinds", &event_filter::kinds, filter_list<event_kind>)};
}

/// An interest's tags: 1 to max_interest_tags of them, each a body tag.
void interest_tags(std::vector<std::string> const& tags, location const& at)
{
    if (tags.empty())
        at.fail(error_code::bad_value, "must hold at least one tag (leave the list out to match "
                                       "bodies with any tag or none)");
    if (tags.size() > max_interest_tags)
        at.fail(error_code::bad_value, "must hold at most " + std::to_string(max_interest_tags) +
                                           " tags, got " + std::to_string(tags.size()));
    for (std::size_t i = 0; i < tags.size(); ++i)
        body_tag(tags[i], at / i);
}

void interest_radius(double const& r, location const& at)
{
    if (!(r > 0.0 && r <= max_interest_radius))
        at.fail(error_code::bad_value, "must be > 0 and at most " + format(max_interest_radius) +
                                           " m, got " + format(r));
}

constexpr auto fields(std::type_identity<interest_box>)
{
    return std::tuple{member("min", &interest_box::min), member("max", &interest_box::max)};
}

constexpr auto fields(std::type_identity<interest_around>)
{
    return std::tuple{member("body", &interest_around::body),
                      member("radius", &interest_around::radius, interest_radius)};
}

constexpr auto fields(std::type_identity<interest_filter>)
{
    return std::tuple{member("box", &interest_filter::box), member("around", &interest_filter::around),
                      member("tags", &interest_filter::tags, interest_tags)};
}

constexpr auto fields(std::type_identity<interest>)
{
    return std::tuple{member("ref", &interest::ref), member("box", &interest::box),
                      member("around", &interest::around), member("tags", &interest::tags, interest_tags)};
}

constexpr auto fields(std::type_identity<event>)
{
    return std::tuple{member("tick", &event::tick), member("time", &event::time),
                      member("kind", &event::kind, event_kind), member("sensor", &event::sensor, sensor_name),
                      member("body", &event::body), member("tag", &event::tag, body_tag),
                      member("owner", &event::owner), member("bodies", &event::bodies, exactly_two<std::uint64_t>),
                      member("tags", &event::tags, tag_pair), member("missed", &event::missed)};
}

constexpr auto fields(std::type_identity<hello>)
{
    return std::tuple{member("protocol", &hello::protocol, spoken_protocol),
                      member("name", &hello::name, player_name), member("admin_token", &hello::admin_token),
                      member("snapshots", &hello::snapshots), member("players", &hello::players),
                      member("resume", &hello::resume, resume_token_text),
                      member("events", &hello::events), member("interest", &hello::interest)};
}

constexpr auto fields(std::type_identity<body_spec>)
{
    return std::tuple{member("position", &body_spec::position),
                      with_default("velocity", &body_spec::velocity),
                      member("radius", &body_spec::radius, at_least_zero),
                      member("mass", &body_spec::mass, above_zero),
                      member("density", &body_spec::density, above_zero),
                      with_default("charge", &body_spec::charge),
                      member("tag", &body_spec::tag, body_tag),
                      only_when_set("static", &body_spec::is_static)};
}

constexpr auto fields(std::type_identity<spawn>)
{
    return std::tuple{member("ref", &spawn::ref), member("body", &spawn::body)};
}

constexpr auto fields(std::type_identity<impulse>)
{
    return std::tuple{member("ref", &impulse::ref), member("id", &impulse::id),
                      member("impulse", &impulse::impulse)};
}

constexpr auto fields(std::type_identity<set>)
{
    return std::tuple{member("ref", &set::ref), member("id", &set::id),
                      member("position", &set::position), member("velocity", &set::velocity)};
}

constexpr auto fields(std::type_identity<remove>)
{
    return std::tuple{member("ref", &remove::ref), member("id", &remove::id)};
}

constexpr auto fields(std::type_identity<ping>)
{
    return std::tuple{member("ref", &ping::ref)};
}

constexpr auto fields(std::type_identity<pause>)
{
    return std::tuple{member("ref", &pause::ref)};
}

constexpr auto fields(std::type_identity<resume>)
{
    return std::tuple{member("ref", &resume::ref)};
}

constexpr auto fields(std::type_identity<reset>)
{
    return std::tuple{member("ref", &reset::ref)};
}

constexpr auto fields(std::type_identity<load_scene>)
{
    return std::tuple{member("ref", &load_scene::ref), member("scene", &load_scene::scene)};
}

constexpr auto fields(std::type_identity<wall>)
{
    return std::tuple{member("normal", &wall::normal), member("offset", &wall::offset),
                      member("damping", &wall::damping, zero_to_one),
                      member("friction", &wall::friction, zero_to_one)};
}

constexpr auto fields(std::type_identity<obstacle>)
{
    return std::tuple{member("centre", &obstacle::centre),
                      member("half_extents", &obstacle::half_extents, each_at_least_zero),
                      member("axes", &obstacle::axes)};
}

constexpr auto fields(std::type_identity<world_bounds>)
{
    return std::tuple{member("centre", &world_bounds::centre),
                      member("radius", &world_bounds::radius, at_least_zero)};
}

constexpr auto fields(std::type_identity<scene_geometry>)
{
    return std::tuple{
        member("name", &scene_geometry::name), member("walls", &scene_geometry::walls),
        member("obstacles", &scene_geometry::obstacles), member("bounds", &scene_geometry::bounds)};
}

constexpr auto fields(std::type_identity<session_limits>)
{
    return std::tuple{member("max_message_bytes", &session_limits::max_message_bytes),
                      member("max_bodies", &session_limits::max_bodies),
                      member("commands_per_second", &session_limits::commands_per_second),
                      member("max_bodies_per_client", &session_limits::max_bodies_per_client),
                      only_when_set("max_queued_events", &session_limits::max_queued_events)};
}

constexpr auto fields(std::type_identity<room_permissions>)
{
    return std::tuple{member("push", &room_permissions::push),
                      member("remove", &room_permissions::remove)};
}

constexpr auto fields(std::type_identity<snapshot_stream>)
{
    return std::tuple{member("form", &snapshot_stream::form),
                      member("rate", &snapshot_stream::rate, above_zero),
                      member("position_quantum", &snapshot_stream::position_quantum, above_zero),
                      member("velocity_quantum", &snapshot_stream::velocity_quantum, above_zero),
                      member("keyframe_interval", &snapshot_stream::keyframe_interval, above_zero)};
}

constexpr auto fields(std::type_identity<welcome>)
{
    return std::tuple{member("protocol", &welcome::protocol, spoken_protocol),
                      member("client", &welcome::client),
                      member("room", &welcome::room),
                      member("tick_rate", &welcome::tick_rate, above_zero),
                      member("dt", &welcome::dt, above_zero),
                      member("snapshot_rate", &welcome::snapshot_rate, above_zero),
                      member("scene", &welcome::scene),
                      member("limits", &welcome::limits),
                      with_default("admin", &welcome::admin),
                      with_default("permissions", &welcome::permissions),
                      member("snapshots", &welcome::snapshots),
                      with_default("resume_grace", &welcome::resume_grace),
                      with_default("bodies_on_leave", &welcome::bodies_on_leave),
                      member("resume_token", &welcome::resume_token, resume_token_text)};
}

constexpr auto fields(std::type_identity<ack>)
{
    return std::tuple{member("ref", &ack::ref), member("tick", &ack::tick), member("id", &ack::id)};
}

constexpr auto fields(std::type_identity<error>)
{
    return std::tuple{member("ref", &error::ref), member("code", &error::code),
                      member("message", &error::message)};
}

constexpr auto fields(std::type_identity<body_columns>)
{
    return std::tuple{member("id", &body_columns::id),
                      member("position", &body_columns::position),
                      member("velocity", &body_columns::velocity),
                      member("radius", &body_columns::radius),
                      member("mass", &body_columns::mass),
                      member("charge", &body_columns::charge),
                      member("tag", &body_columns::tag, tag_column)};
}

constexpr auto fields(std::type_identity<snapshot>)
{
    return std::tuple{member("tick", &snapshot::tick), member("time", &snapshot::time),
                      with_default("paused", &snapshot::paused), with_default("faults", &snapshot::faults),
                      member("bodies", &snapshot::bodies)};
}

constexpr auto fields(std::type_identity<compact_bodies>)
{
    return std::tuple{member("id", &compact_bodies::id),
                      member("p", &compact_bodies::position),
                      member("v", &compact_bodies::velocity),
                      member("radius", &compact_bodies::radius),
                      member("mass", &compact_bodies::mass),
                      member("charge", &compact_bodies::charge),
                      member("owner", &compact_bodies::owner),
                      member("tag", &compact_bodies::tag, tag_column)};
}

constexpr auto fields(std::type_identity<compact_moves>)
{
    return std::tuple{member("runs", &compact_moves::runs),
                      member("p", &compact_moves::position),
                      member("v", &compact_moves::velocity)};
}

constexpr auto fields(std::type_identity<compact_snapshot>)
{
    return std::tuple{member("tick", &compact_snapshot::tick),
                      member("form", &compact_snapshot::form),
                      member("base", &compact_snapshot::base),
                      member("time", &compact_snapshot::time),
                      with_default("paused", &compact_snapshot::paused),
                      with_default("faults", &compact_snapshot::faults),
                      member("q", &compact_snapshot::q),
                      member("bodies", &compact_snapshot::bodies),
                      member("moved", &compact_snapshot::moved),
                      member("appeared", &compact_snapshot::appeared),
                      member("vanished", &compact_snapshot::vanished)};
}

constexpr auto fields(std::type_identity<player>)
{
    return std::tuple{member("id", &player::id), member("name", &player::name, player_name),
                      member("away", &player::away)};
}

constexpr auto fields(std::type_identity<roster>)
{
    return std::tuple{member("players", &roster::players)};
}

constexpr auto fields(std::type_identity<player_notice>)
{
    return std::tuple{member("change", &player_notice::change), member("id", &player_notice::id),
                      member("name", &player_notice::name, player_name)};
}

constexpr auto fields(std::type_identity<pong>)
{
    return std::tuple{member("ref", &pong::ref), member("tick", &pong::tick),
                      member("tick_ms", &pong::tick_ms, at_least_zero)};
}

template <class T>
concept has_fields = requires
{
    fields(std::type_identity<T>{});
};

// Rules that involve more than one field, checked once all of a struct's fields are read.

template <class T> void check_together(T const&, location const&) {}

/// A velocity (at `at`) must be slower than light.
void below_light(vec3 const& velocity, location const& at)
{
    double const speed = std::hypot(velocity[0], velocity[1], velocity[2]);
    if (!(speed < speed_of_light))
        at.fail(error_code::bad_value, "a speed " +
                                           (std::isfinite(speed) ? "of " + format(speed) + " m/s"
                                                                 : std::string("beyond the range of a double")) +
                                           " is not below the speed of light, " +
                                           format(speed_of_light) + " m/s");
}

void check_together(body_spec const& body, location const& at)
{
    if (body.mass && body.density)
        at.fail(error_code::bad_value, "give either mass or density, not both");
    if (!body.mass && !body.density)
        at.fail(error_code::missing_field, "needs a mass (kg) or a density (kg/m^3)");
    below_light(body.velocity, at / "velocity");
    if (body.is_static && body.velocity != vec3{})
        (at / "velocity").fail(error_code::bad_value, "a static body cannot move; leave out the velocity "
                                                      "or the static flag");
    if (body.density && !(body.radius > 0.0))
        (at / "density")
            .fail(error_code::bad_value, "needs a radius > 0 (a point mass has no volume; give "
                                         "mass)");
    double const mass = mass_of(body);
    if (!(mass > 0.0 && std::isfinite(mass) && std::isfinite(1.0 / mass)))
        at.fail(error_code::bad_value, "the mass this gives, " + format(mass) +
                                           " kg, is not a usable positive mass (it and its "
                                           "inverse must be finite and > 0)");
}

void check_together(set const& command, location const& at)
{
    if (!command.position && !command.velocity)
        at.fail(error_code::missing_field, "needs a position (m), a velocity (m/s) or both");
    if (command.velocity)
        below_light(*command.velocity, at / "velocity");
}

void check_together(interest_box const& box, location const& at)
{
    for (std::size_t k = 0; k < 3; ++k)
        if (!(box.min[k] <= box.max[k]))
            (at / "max" / k).fail(error_code::bad_value, "must be >= min[" + std::to_string(k) + "] = " +
                                                          format(box.min[k]) + ", got " + format(box.max[k]));
}

/// One region at a time: a box, or a ball around a body.
void one_region(interest_filter const& filter, location const& at)
{
    if (filter.box && filter.around)
        (at / "around").fail(error_code::bad_value, "give one region, a box or a ball around a body, "
                                                    "not both");
}

void check_together(interest_filter const& filter, location const& at) { one_region(filter, at); }

void check_together(interest const& command, location const& at) { one_region(command.filter(), at); }

void check_together(room_permissions const& p, location const& at)
{
    if (p.push != "anyone" && p.push != "owner" && p.push != "admins")
        (at / "push").fail(error_code::bad_value, "must be \"anyone\", \"owner\" or \"admins\", got " +
                                                      dump(json(shortened(p.push))));
    if (p.remove != "owner" && p.remove != "admins")
        (at / "remove").fail(error_code::bad_value, "must be \"owner\" or \"admins\", got " +
                                                        dump(json(shortened(p.remove))));
}

void check_together(body_columns const& bodies, location const& at)
{
    std::size_t const n = bodies.size();
    auto const expect = [&](std::size_t size, std::string_view column, std::size_t per_body) {
        if (size != per_body * n)
            (at / column)
                .fail(error_code::bad_value, "must hold " + std::to_string(per_body * n) +
                                                 " numbers (" + std::to_string(per_body) +
                                                 " for each of the " + std::to_string(n) +
                                                 " ids), got " + std::to_string(size));
    };
    expect(bodies.position.size(), "position", 3);
    expect(bodies.velocity.size(), "velocity", 3);
    expect(bodies.radius.size(), "radius", 1);
    if (bodies.mass)
        expect(bodies.mass->size(), "mass", 1);
    if (bodies.charge)
        expect(bodies.charge->size(), "charge", 1);
    if (bodies.tag)
        expect(bodies.tag->size(), "tag", 1);
}

void check_together(snapshot_request const& request, location const& at)
{
    if (request.form && *request.form != "full" && *request.form != "compact")
        (at / "form").fail(error_code::bad_value, "must be \"full\" or \"compact\", got " +
                                                      dump(json(shortened(*request.form))));
}

void check_together(player_notice const& notice, location const& at)
{
    if (notice.change != "joined" && notice.change != "renamed" && notice.change != "away" &&
        notice.change != "back" && notice.change != "left")
        (at / "change").fail(error_code::bad_value, "must be \"joined\", \"renamed\", \"away\", "
                                                    "\"back\" or \"left\", got " +
                                                        dump(json(shortened(notice.change))));
}

void check_together(welcome const& w, location const& at)
{
    if (!(w.resume_grace >= 0.0))
        (at / "resume_grace")
            .fail(error_code::bad_value, "must be >= 0, got " + format(w.resume_grace));
    if (w.bodies_on_leave != "stay" && w.bodies_on_leave != "remove")
        (at / "bodies_on_leave")
            .fail(error_code::bad_value, "must be \"stay\" or \"remove\", got " +
                                             dump(json(shortened(w.bodies_on_leave))));
}

void check_together(snapshot_stream const& stream, location const& at)
{
    if (stream.form != "full" && stream.form != "compact")
        (at / "form").fail(error_code::bad_value, "must be \"full\" or \"compact\", got " +
                                                      dump(json(shortened(stream.form))));
}

/// Gap-coded ids (the first id, then each less the one before) into the ids themselves:
/// strictly increasing, none beyond 2^53 − 1.
void ungap(std::vector<std::uint64_t>& ids, location const& at)
{
    std::uint64_t id = 0;
    for (std::size_t i = 0; i < ids.size(); ++i) {
        if (i > 0 && ids[i] == 0)
            (at / i).fail(error_code::bad_value, "must be >= 1: ids are gap-coded and strictly increasing");
        if (ids[i] > max_safe_integer - id)
            (at / i).fail(error_code::bad_value, "the id it gives is beyond 2^53 - 1");
        id += ids[i];
        ids[i] = id;
    }
}

void check_sizes(std::size_t size, std::size_t wanted, location const& at)
{
    if (size != wanted)
        at.fail(error_code::bad_value, "must hold " + std::to_string(wanted) + " numbers, got " +
                                           std::to_string(size));
}

void check_together(compact_bodies& bodies, location const& at)
{
    ungap(bodies.id, at / "id");
    std::size_t const n = bodies.size();
    check_sizes(bodies.position.size(), 3 * n, at / "p");
    check_sizes(bodies.velocity.size(), 3 * n, at / "v");
    check_sizes(bodies.radius.size(), n, at / "radius");
    check_sizes(bodies.mass.size(), n, at / "mass");
    check_sizes(bodies.owner.size(), n, at / "owner");
    if (bodies.charge)
        check_sizes(bodies.charge->size(), n, at / "charge");
    if (bodies.tag)
        check_sizes(bodies.tag->size(), n, at / "tag");
    for (std::size_t i = 0; i < n; ++i) {
        at_least_zero(bodies.radius[i], at / "radius" / i);
        at_least_zero(bodies.mass[i], at / "mass" / i);
    }
}

void check_together(compact_moves const& moves, location const& at)
{
    std::uint64_t moved = 0;
    for (std::size_t i = 1; i < moves.runs.size(); i += 2) {
        moved += moves.runs[i]; // each at most 2^53 − 1: the sum cannot wrap before the check
        if (moved > max_safe_integer / 3)
            (at / "runs" / i).fail(error_code::bad_value, "more moved bodies than a message holds");
    }
    check_sizes(moves.position.size(), static_cast<std::size_t>(3 * moved), at / "p");
    check_sizes(moves.velocity.size(), static_cast<std::size_t>(3 * moved), at / "v");
}

void check_together(compact_snapshot& s, location const& at)
{
    if (s.form == "key") {
        if (!s.bodies)
            (at / "bodies").fail(error_code::missing_field, "missing (required in a keyframe)");
        if (!s.q)
            (at / "q").fail(error_code::missing_field, "missing (required in a keyframe)");
        if (s.base || s.moved || s.appeared || s.vanished)
            at.fail(error_code::bad_value, "a keyframe has no base, moved, appeared or vanished");
        for (std::size_t k = 0; k < 2; ++k)
            if (!((*s.q)[k] > 0.0))
                (at / "q" / k).fail(error_code::bad_value, "must be > 0, got " + format((*s.q)[k]));
    } else if (s.form == "delta") {
        if (!s.base)
            (at / "base").fail(error_code::missing_field, "missing (required in a delta)");
        if (!(*s.base < s.tick))
            (at / "base").fail(error_code::bad_value, "must be below the tick");
        if (s.bodies || s.q)
            at.fail(error_code::bad_value, "a delta has no bodies or q (its base's hold)");
        if (s.vanished)
            ungap(*s.vanished, at / "vanished");
    } else {
        (at / "form").fail(error_code::bad_value, "must be \"key\" or \"delta\", got " +
                                                      dump(json(shortened(s.form))));
    }
}

// Reading ---------------------------------------------------------------------------------

double number(json const& value, location const& at)
{
    if (!value.is_number())
        at.fail(error_code::wrong_type, "must be a number, got " + describe(value));
    double const x = value.get<double>();
    if (!std::isfinite(x))
        at.fail(error_code::not_finite, "must be finite, got " + format(x));
    return x;
}

/// A whole number that a double holds exactly: 0 ... 2^53 − 1. 7.0 counts as 7.
std::uint64_t safe_integer(json const& value, location const& at)
{
    if (!value.is_number())
        at.fail(error_code::wrong_type, "must be a whole number, got " + describe(value));
    auto const refuse = [&] {
        at.fail(error_code::bad_value, "must be a whole number from 0 to " +
                                           std::to_string(max_safe_integer) + ", got " +
                                           dump(value));
    };
    if (value.is_number_unsigned()) {
        auto const n = value.get<std::uint64_t>();
        if (n > max_safe_integer)
            refuse();
        return n;
    }
    if (value.is_number_integer()) { // negative: non-negative integers are parsed as unsigned
        if (value.get<std::int64_t>() == 0)
            return 0; // -0, which the parser reads as a signed zero
        refuse();
    }
    double const x = value.get<double>();
    if (!(x >= 0.0 && x <= static_cast<double>(max_safe_integer) && x == std::floor(x)))
        refuse();
    return static_cast<std::uint64_t>(x);
}

void read_value(json const& value, location const& at, double& out)
{
    out = number(value, at);
}

void read_value(json const& value, location const& at, std::uint64_t& out)
{
    out = safe_integer(value, at);
}

/// A whole number from −(2^53 − 1) to 2^53 − 1 (a quantized coordinate).
void read_value(json const& value, location const& at, std::int64_t& out)
{
    if (!value.is_number())
        at.fail(error_code::wrong_type, "must be a whole number, got " + describe(value));
    auto const limit = static_cast<std::int64_t>(max_safe_integer);
    auto const refuse = [&] {
        at.fail(error_code::bad_value, "must be a whole number from -" + std::to_string(limit) +
                                           " to " + std::to_string(limit) + ", got " + dump(value));
    };
    if (value.is_number_unsigned()) {
        auto const n = value.get<std::uint64_t>();
        if (n > max_safe_integer)
            refuse();
        out = static_cast<std::int64_t>(n);
        return;
    }
    if (value.is_number_integer()) {
        auto const n = value.get<std::int64_t>();
        if (n < -limit)
            refuse();
        out = n;
        return;
    }
    double const x = value.get<double>();
    if (!(std::abs(x) <= static_cast<double>(max_safe_integer) && x == std::floor(x)))
        refuse();
    out = static_cast<std::int64_t>(x);
}

void read_value(json const& value, location const& at, int& out)
{
    std::uint64_t const n = safe_integer(value, at);
    if (n > static_cast<std::uint64_t>(std::numeric_limits<int>::max()))
        at.fail(error_code::bad_value, "must be at most " +
                                           std::to_string(std::numeric_limits<int>::max()) +
                                           ", got " + std::to_string(n));
    out = static_cast<int>(n);
}

void read_value(json const& value, location const& at, std::string& out)
{
    if (!value.is_string())
        at.fail(error_code::wrong_type, "must be a string, got " + describe(value));
    out = value.get<std::string>();
}

void read_value(json const& value, location const& at, bool& out)
{
    if (!value.is_boolean())
        at.fail(error_code::wrong_type, "must be true or false, got " + describe(value));
    out = value.get<bool>();
}

void read_value(json const& value, location const& at, json_object& out)
{
    if (!value.is_object())
        at.fail(error_code::wrong_type, "must be an object, got " + describe(value));
    out.text = dump(value);
}

void read_value(json const& value, location const& at, error_code& out)
{
    if (!value.is_string())
        at.fail(error_code::wrong_type, "must be a string, got " + describe(value));
    auto const code = error_code_named(value.get_ref<std::string const&>());
    if (!code)
        at.fail(error_code::bad_value, "unknown error code " + describe(value));
    out = *code;
}

void read_value(json const& value, location const& at, event_request& out);
template <class E, std::size_t N>
void read_value(json const& value, location const& at, std::array<E, N>& out);
template <class E> void read_value(json const& value, location const& at, std::vector<E>& out);
template <class T>
requires has_fields<T>
void read_value(json const& value, location const& at, T& out);

template <class E> constexpr std::string_view items_called()
{
    return std::is_arithmetic_v<E> ? "numbers" : "arrays";
}

template <class E, std::size_t N>
void read_value(json const& value, location const& at, std::array<E, N>& out)
{
    std::string const shape = "an array of " + std::to_string(N) + " " +
                              std::string(items_called<E>()) +
                              (std::is_arithmetic_v<E> && N == 3 ? " [x, y, z]" : "");
    if (!value.is_array())
        at.fail(error_code::wrong_type, "must be " + shape + ", got " + describe(value));
    if (value.size() != N)
        at.fail(error_code::bad_value, "must be " + shape + ", got " + describe(value));
    for (std::size_t i = 0; i < N; ++i)
        read_value(value[i], at / i, out[i]);
}

template <class E> void read_value(json const& value, location const& at, std::vector<E>& out)
{
    if (!value.is_array())
        at.fail(error_code::wrong_type, "must be an array, got " + describe(value));
    out.resize(value.size());
    for (std::size_t i = 0; i < out.size(); ++i)
        read_value(value[i], at / i, out[i]);
}

template <class T, class M>
void read_field(json const& object, location const& at, T& out, field<T, M> const& f)
{
    location const here = at / f.name;
    auto const found = object.find(f.name);
    if (found == object.end()) {
        if (!optional_traits<M>::is_optional && !f.defaulted)
            here.fail(error_code::missing_field, "missing (required)");
        return;
    }
    typename field<T, M>::value_type value{};
    read_value(*found, here, value);
    if (f.check)
        f.check(value, here);
    out.*f.member = std::move(value);
}

template <class T>
requires has_fields<T>
void read_value(json const& value, location const& at, T& out)
{
    if (!value.is_object())
        at.fail(error_code::wrong_type, "must be an object, got " + describe(value));
    std::apply([&](auto const&... f) { (read_field(value, at, out, f), ...); },
               fields(std::type_identity<T>{}));
    check_together(out, at);
}

/// hello.events: true, false or an event_filter object.
void read_value(json const& value, location const& at, event_request& out)
{
    if (value.is_boolean()) {
        out = {value.get<bool>(), {}};
        return;
    }
    if (!value.is_object())
        at.fail(error_code::wrong_type, "must be true, false or an object {sensors, tags, kinds}, got " +
                                            describe(value));
    out.on = true;
    read_value(value, at, out.filter);
}

/// The message named by `type`, one of the Variant's alternatives.
template <class... Types>
std::variant<Types...> read_message(json const& doc, std::type_identity<std::variant<Types...>>)
{
    location const root;
    if (!doc.is_object())
        root.fail(error_code::bad_message, "a message must be a JSON object, got " + describe(doc));
    auto const type = doc.find("type");
    if (type == doc.end())
        (root / "type").fail(error_code::bad_message, "missing: every message names its type");
    if (!type->is_string())
        (root / "type").fail(error_code::bad_message, "must be a string, got " + describe(*type));
    std::string const& name = type->get_ref<std::string const&>();

    std::optional<std::variant<Types...>> message;
    // Both snapshot forms are "snapshot": a compact one says its `form`.
    bool const has_form = doc.contains("form");
    auto const read_if_named = [&]<class T>(std::type_identity<T>) {
        if constexpr (std::is_same_v<T, snapshot>)
            if (has_form)
                return;
        if constexpr (std::is_same_v<T, compact_snapshot>)
            if (!has_form)
                return;
        if (!message && name == T::type) {
            T out;
            read_value(doc, root, out);
            message = std::move(out);
        }
    };
    (read_if_named(std::type_identity<Types>{}), ...);
    if (!message) {
        std::vector<std::string_view> names; // each once: "snapshot" names two types
        auto const add_known = [&](std::string_view t) {
            if (std::find(names.begin(), names.end(), t) == names.end())
                names.push_back(t);
        };
        (add_known(Types::type), ...);
        std::string known;
        for (std::string_view const t : names)
            known += (known.empty() ? "" : ", ") + std::string(t);
        (root / "type")
            .fail(error_code::unknown_type, "unknown message type " + dump(json(shortened(name))) +
                                                " (known: " + known + ")");
    }
    return *std::move(message);
}

/// The message's top-level `ref`, when it is there and valid: errors echo it.
std::optional<std::uint64_t> readable_ref(json const& doc)
{
    if (!doc.is_object())
        return std::nullopt;
    auto const ref = doc.find("ref");
    if (ref == doc.end())
        return std::nullopt;
    try {
        return safe_integer(*ref, location{});
    } catch (refusal const&) {
        return std::nullopt;
    }
}

/// Objects and arrays may nest this deep in a message; no message needs more than about six
/// levels (a load_scene's generator region). Deeper text is refused before it becomes a
/// document: copying or printing a document recurses once per level, and 20,000 levels in
/// a 64 kB frame overflowed a server thread's stack.
constexpr std::size_t max_nesting = 32;

/// True when objects and arrays in `text` nest deeper than max_nesting (brackets inside
/// strings do not count). A scan of the bytes, much cheaper than a parse.
bool nests_too_deep(std::string_view text)
{
    std::size_t depth = 0;
    bool in_string = false, escaped = false;
    for (char const c : text) {
        if (in_string) {
            if (escaped)
                escaped = false;
            else if (c == '\\')
                escaped = true;
            else if (c == '"')
                in_string = false;
        } else if (c == '"') {
            in_string = true;
        } else if (c == '[' || c == '{') {
            if (++depth > max_nesting)
                return true;
        } else if ((c == ']' || c == '}') && depth > 0) {
            --depth;
        }
    }
    return false;
}

/// A second look at text that did not parse, or nests too deep: where it failed (a JSON
/// pointer), whether the failure was a number beyond double range, and the top-level `ref`
/// if it came first.
class failure_locator final : public nlohmann::json_sax<json>
{
  public:
    error failure() const { return {ref_, code_, message_}; }

    bool null() override { return scalar(); }
    bool boolean(bool) override { return scalar(); }
    bool number_integer(number_integer_t) override { return scalar(); }
    bool number_unsigned(number_unsigned_t n) override
    {
        if (at_top_level_ref() && n <= max_safe_integer)
            ref_ = n;
        return scalar();
    }
    bool number_float(number_float_t x, string_t const&) override
    {
        if (at_top_level_ref() && x >= 0.0 && x <= static_cast<double>(max_safe_integer) &&
            x == std::floor(x))
            ref_ = static_cast<std::uint64_t>(x);
        return scalar();
    }
    bool string(string_t&) override { return scalar(); }
    bool binary(binary_t&) override { return scalar(); }

    bool start_object(std::size_t) override { return open(false); }
    bool key(string_t& name) override
    {
        frames_.back().segment = escaped(name);
        frames_.back().inside_child = true;
        return true;
    }
    bool end_object() override { return close(); }
    bool start_array(std::size_t) override { return open(true); }
    bool end_array() override { return close(); }

    bool parse_error(std::size_t, std::string const& token, json::exception const& ex) override
    {
        constexpr int number_overflow = 406;              // nlohmann's out_of_range.406
        std::string const at = shortened(pointer(), 200); // text may nest deeper than any message
        if (ex.id == number_overflow) {
            code_ = error_code::not_finite;
            message_ = at + ": " + shortened(token) + " is beyond the range of a double";
        } else {
            code_ = error_code::bad_json;
            std::string what = ex.what();
            // "[json.exception.parse_error.101] parse error at line 1, column 9: ..."
            if (auto const end = what.find("] "); end != std::string::npos)
                what.erase(0, end + 2);
            message_ = at + ": not valid JSON: " + shortened(what, 200);
        }
        return false;
    }

  private:
    struct frame
    {
        bool is_array = false;
        std::size_t next_index = 0; ///< arrays: the index of the next element
        std::string segment;        ///< the child being read
        bool inside_child = false;
    };

    bool at_top_level_ref() const
    {
        return frames_.size() == 1 && !frames_[0].is_array && frames_[0].inside_child &&
               frames_[0].segment == "ref";
    }

    void begin_value()
    {
        if (!frames_.empty() && frames_.back().is_array) {
            frames_.back().segment = std::to_string(frames_.back().next_index);
            frames_.back().inside_child = true;
        }
    }

    void end_value()
    {
        if (frames_.empty())
            return;
        frames_.back().inside_child = false;
        if (frames_.back().is_array)
            ++frames_.back().next_index;
    }

    bool scalar()
    {
        begin_value();
        end_value();
        return true;
    }

    bool open(bool is_array)
    {
        begin_value();
        if (frames_.size() == max_nesting) {
            code_ = error_code::bad_message;
            message_ = shortened(pointer(), 200) + ": nested deeper than " +
                       std::to_string(max_nesting) + " levels";
            return false;
        }
        frames_.push_back({.is_array = is_array});
        return true;
    }

    bool close()
    {
        frames_.pop_back();
        end_value();
        return true;
    }

    /// The value being read when parsing stopped; an array's next element if between two.
    std::string pointer() const
    {
        std::string out;
        for (auto const& f : frames_) {
            if (f.inside_child)
                out += "/" + f.segment;
            else if (f.is_array && &f == &frames_.back())
                out += "/" + std::to_string(f.next_index);
        }
        return out.empty() ? "/" : out;
    }

    std::vector<frame> frames_;
    std::optional<std::uint64_t> ref_;
    error_code code_ = error_code::bad_json;
    std::string message_ = "/: not valid JSON";
};

template <class Variant> decode_result<Variant> decode_as(std::string_view text)
{
    if (nests_too_deep(text)) {
        failure_locator locator;
        json::sax_parse(text.begin(), text.end(), &locator);
        return {.failure = locator.failure()};
    }
    json const doc = json::parse(text.begin(), text.end(), nullptr, /*allow_exceptions=*/false);
    if (doc.is_discarded()) {
        failure_locator locator;
        json::sax_parse(text.begin(), text.end(), &locator);
        return {.failure = locator.failure()};
    }
    try {
        return {.message = read_message(doc, std::type_identity<Variant>{})};
    } catch (refusal& r) {
        return {.failure = error{readable_ref(doc), r.code, std::move(r.message)}};
    }
}

// Writing ---------------------------------------------------------------------------------

json to_value(double x)
{
    return x;
}
json to_value(std::uint64_t n)
{
    return n;
}
json to_value(int n)
{
    return n;
}
json to_value(std::string const& s)
{
    return s;
}
json to_value(bool b)
{
    return b;
}
json to_value(json_object const& object)
{
    // Text that decode() gave is one object; anything else is written as null, not thrown.
    json value = json::parse(object.text, nullptr, /*allow_exceptions=*/false);
    return value.is_object() ? value : json(nullptr);
}
json to_value(error_code code)
{
    return name(code);
}

json to_value(event_request const& request);
template <class E, std::size_t N> json to_value(std::array<E, N> const& items);
template <class E> json to_value(std::vector<E> const& items);
template <class T>
requires has_fields<T> json to_value(T const& value);

template <class E, std::size_t N> json to_value(std::array<E, N> const& items)
{
    json out = json::array();
    for (auto const& item : items)
        out.push_back(to_value(item));
    return out;
}

template <class E> json to_value(std::vector<E> const& items)
{
    json out = json::array();
    out.get_ref<json::array_t&>().reserve(items.size());
    for (auto const& item : items)
        out.push_back(to_value(item));
    return out;
}

template <class T>
requires has_fields<T>
void write_fields(json& out, T const& value)
{
    auto const write = [&]<class M>(field<T, M> const& f) {
        auto const& member = value.*f.member;
        if constexpr (optional_traits<M>::is_optional) {
            if (member)
                out[std::string(f.name)] = to_value(*member);
        } else if (f.written_only_when_set && member == M{}) {
            return;
        } else {
            out[std::string(f.name)] = to_value(member);
        }
    };
    std::apply([&](auto const&... f) { (write(f), ...); }, fields(std::type_identity<T>{}));
}

template <class T>
requires has_fields<T> json to_value(T const& value)
{
    json out = json::object();
    write_fields(out, value);
    return out;
}

json to_value(event_request const& request)
{
    if (!request.on)
        return false;
    if (request.filter == event_filter{})
        return true;
    return to_value(request.filter);
}

template <class T> std::string encode_message(T const& message)
{
    json out = json::object();
    out["type"] = T::type;
    write_fields(out, message);
    return dump(out);
}

} // namespace

decode_result<client_message> decode(std::string_view text)
{
    return decode_as<client_message>(text);
}

decode_result<server_message> decode_server_message(std::string_view text)
{
    return decode_as<server_message>(text);
}

std::string encode(hello const& message)
{
    return encode_message(message);
}
std::string encode(spawn const& message)
{
    return encode_message(message);
}
std::string encode(impulse const& message)
{
    return encode_message(message);
}
std::string encode(remove const& message)
{
    return encode_message(message);
}
std::string encode(ping const& message)
{
    return encode_message(message);
}
std::string encode(pause const& message)
{
    return encode_message(message);
}
std::string encode(resume const& message)
{
    return encode_message(message);
}
std::string encode(reset const& message)
{
    return encode_message(message);
}
std::string encode(load_scene const& message)
{
    return encode_message(message);
}
std::string encode(set const& message)
{
    return encode_message(message);
}
std::string encode(interest const& message)
{
    return encode_message(message);
}
std::string encode(welcome const& message)
{
    return encode_message(message);
}
std::string encode(ack const& message)
{
    return encode_message(message);
}
std::string encode(error const& message)
{
    return encode_message(message);
}
std::string encode(roster const& message)
{
    return encode_message(message);
}
std::string encode(player_notice const& message)
{
    return encode_message(message);
}
std::string encode(event const& message)
{
    return encode_message(message);
}
// A snapshot is most of the traffic and grows with the bodies, so it is written straight
// into one buffer with std::to_chars rather than built as a JSON document first: the same
// text in two thirds to four fifths of the time (bench/protocol_bench.cpp, encode_snapshot
// against encode_snapshot_via_json_document). The buffer is never zero-filled and each
// number is written in place, one capacity check each (bench/README.md, compact snapshots).
namespace {

class snapshot_writer
{
public:
    explicit snapshot_writer(std::size_t expected_bytes) { grow(expected_bytes + 256); }

    void raw(std::string_view text)
    {
        make_room(text.size());
        std::memcpy(end_, text.data(), text.size());
        end_ += text.size();
    }

    void raw(char c)
    {
        make_room(1);
        *end_++ = c;
    }

    template <class Number>
    void number(Number x)
    {
        make_room(max_number_chars);
        write_number(x);
    }

    template <class Number>
    void column(std::string_view name, std::vector<Number> const& values)
    {
        open_column(name);
        if constexpr (std::is_integral_v<Number>) {
            // Room for the whole column at once: one check, then integers written in place.
            make_room(values.size() * (max_integer_chars + 1) + 1);
            // Locals: a char written through a pointer may alias anything, and the compiler
            // would reload the end and the vector's bounds after every one.
            char* out = end_;
            Number const* const first = values.data();
            std::size_t const count = values.size();
            for (std::size_t i = 0; i < count; ++i) {
                *out = ',';
                out += i > 0 ? 1 : 0;
                out = write_integer(out, first[i]);
            }
            end_ = out;
        } else {
            for (std::size_t i = 0; i < values.size(); ++i) {
                make_room(max_number_chars + 1);
                if (i > 0)
                    *end_++ = ',';
                write_number(values[i]);
            }
        }
        raw(']');
    }

    /// Ids as the first, then each less the one before.
    void gap_column(std::string_view name, std::vector<std::uint64_t> const& ids)
    {
        open_column(name);
        make_room(ids.size() * (max_integer_chars + 1) + 1);
        char* out = end_;
        std::uint64_t const* const first = ids.data();
        std::size_t const count = ids.size();
        std::uint64_t last = 0;
        for (std::size_t i = 0; i < count; ++i) {
            *out = ',';
            out += i > 0 ? 1 : 0;
            out = write_integer(out, first[i] - last);
            last = first[i];
        }
        end_ = out;
        raw(']');
    }

    /// Doubles, a run of equal ones written by copying the first's text (a scene's bodies
    /// mostly share radius and mass: shortest-form conversion is the costly part).
    void constant_column(std::string_view name, std::vector<double> const& values)
    {
        open_column(name);
        std::size_t text_start = 0, text_size = 0;
        for (std::size_t i = 0; i < values.size(); ++i) {
            make_room(max_number_chars + 1);
            if (i > 0)
                *end_++ = ',';
            if (i > 0 && std::bit_cast<std::uint64_t>(values[i]) ==
                             std::bit_cast<std::uint64_t>(values[i - 1])) {
                std::memcpy(end_, buffer_.get() + text_start, text_size);
                end_ += text_size;
                continue;
            }
            text_start = static_cast<std::size_t>(end_ - buffer_.get());
            write_number(values[i]);
            text_size = static_cast<std::size_t>(end_ - buffer_.get()) - text_start;
        }
        raw(']');
    }

    /// Strings (tags: short, without control characters), escaped as JSON wants; "" for none.
    void string_column(std::string_view name, std::vector<std::string> const& values)
    {
        open_column(name);
        for (std::size_t i = 0; i < values.size(); ++i) {
            if (i > 0)
                raw(',');
            raw('"');
            for (char const c : values[i]) {
                auto const u = static_cast<unsigned char>(c);
                if (c == '"' || c == '\\') {
                    raw('\\');
                    raw(c);
                } else if (u < 0x20) { // never in a valid tag; escaped rather than sent raw
                    static constexpr char hex[] = "0123456789abcdef";
                    raw("\\u00");
                    raw(hex[static_cast<std::size_t>(u >> 4U)]);
                    raw(hex[static_cast<std::size_t>(u & 0xFU)]);
                } else {
                    raw(c);
                }
            }
            raw('"');
        }
        raw(']');
    }

    std::string take() const { return std::string(buffer_.get(), end_); }

private:
    /// The longest number written: a double's shortest form is at most 24 characters, and
    /// ".0" may follow; a 64-bit integer takes 20.
    static constexpr std::size_t max_number_chars = 32;
    static constexpr std::size_t max_integer_chars = 20;

    /// "00", "01", ... "99": two digits at a time.
    static constexpr auto digit_pairs = [] {
        std::array<char, 200> pairs{};
        for (std::size_t i = 0; i < 100; ++i) {
            pairs[2 * i] = static_cast<char>('0' + i / 10);
            pairs[2 * i + 1] = static_cast<char>('0' + i % 10);
        }
        return pairs;
    }();

    /// Writes x at `at` in decimal, as std::to_chars does (a '-' before a negative one);
    /// `at` has room for max_integer_chars. Returns the end. Below 10^8 without a branch
    /// on the value: the signs and lengths of a snapshot's numbers follow no pattern, and
    /// a mispredicted branch per number cost more than the digits.
    template <class Integer>
    static char* write_integer(char* at, Integer x)
    {
        std::uint64_t u = static_cast<std::uint64_t>(x);
        if constexpr (std::is_signed_v<Integer>) {
            bool const negative = x < 0;
            *at = '-';
            at += negative ? 1 : 0;
            u = negative ? 0 - u : u;
        }
        if (u < 10) { // most numbers of a delta: a branch that is mostly taken, or mostly not
            *at = static_cast<char>('0' + u);
            return at + 1;
        }
        if (std::endian::native != std::endian::little || u >= 100'000'000)
            return write_long_integer(at, u);
        // Eight digits, leading zeros included, as one little-endian word (first digit in
        // the lowest byte), made by multiplications on all of them at once: v split in two
        // halves of four digits (one in each 32-bit lane), each into two of two digits (16-bit
        // lanes), each into two digits (bytes). x / 100 is (x · 10486) >> 20 and x / 10 is
        // (x · 103) >> 10 for the x that occur here. The leading zeros are the low zero bytes;
        // shifted right past them, the word is stored whole.
        auto const v = static_cast<std::uint32_t>(u);
        std::uint64_t const halves = (v / 10000U) | std::uint64_t{v % 10000U} << 32U;
        std::uint64_t const high_pairs = ((halves * 10486U) >> 20U) & 0x0000007F'0000007FULL;
        std::uint64_t const pairs = (halves - 100U * high_pairs) << 16U | high_pairs;
        std::uint64_t const high_digits = ((pairs * 103U) >> 10U) & 0x000F000F'000F000FULL;
        std::uint64_t const digits = (pairs - 10U * high_digits) << 8U | high_digits;
        auto const zeros = static_cast<unsigned>(std::countr_zero(digits)) / 8U; // v >= 10: at most 6
        std::uint64_t const shown = (digits + 0x30303030'30303030ULL) >> (8U * zeros);
        std::memcpy(at, &shown, 8);
        return at + (8U - zeros);
    }

    /// Any 64-bit u, two digits at a time. Returns the end.
    static char* write_long_integer(char* at, std::uint64_t u)
    {
        std::array<char, max_integer_chars> scratch{};
        char* const last = scratch.data() + scratch.size();
        char* first = last;
        while (u >= 100) {
            std::uint64_t const pair = u % 100;
            u /= 100;
            first -= 2;
            std::memcpy(first, &digit_pairs[2 * pair], 2);
        }
        if (u >= 10) {
            first -= 2;
            std::memcpy(first, &digit_pairs[2 * u], 2);
        } else {
            *--first = static_cast<char>('0' + u);
        }
        auto const length = static_cast<std::size_t>(last - first);
        std::memcpy(at, first, length);
        return at + length;
    }

    void open_column(std::string_view name)
    {
        make_room(name.size() + 4);
        *end_++ = '"';
        std::memcpy(end_, name.data(), name.size());
        end_ += name.size();
        std::memcpy(end_, "\":[", 3);
        end_ += 3;
    }

    void make_room(std::size_t n)
    {
        if (static_cast<std::size_t>(capacity_end_ - end_) < n)
            grow(n);
    }

    void grow(std::size_t n)
    {
        std::size_t const used = buffer_ ? static_cast<std::size_t>(end_ - buffer_.get()) : 0;
        std::size_t const capacity = std::max(2 * static_cast<std::size_t>(capacity_end_ - buffer_.get()), used + n);
        auto bigger = std::make_unique_for_overwrite<char[]>(capacity);
        if (used > 0)
            std::memcpy(bigger.get(), buffer_.get(), used);
        buffer_ = std::move(bigger);
        end_ = buffer_.get() + used;
        capacity_end_ = buffer_.get() + capacity;
    }

    /// Writes x at end_, which has room for max_number_chars.
    template <class Number>
    void write_number(Number x)
    {
        if constexpr (std::is_floating_point_v<Number>) {
            if (!std::isfinite(x)) { // never sent by the server; what nlohmann would write
                std::memcpy(end_, "null", 4);
                end_ += 4;
                return;
            }
            char* const start = end_;
            end_ = std::to_chars(end_, end_ + max_number_chars, x).ptr;
            if (std::string_view(start, static_cast<std::size_t>(end_ - start)).find_first_of(".e") ==
                std::string_view::npos) {
                std::memcpy(end_, ".0", 2); // 3.0, not 3: a double stays a double on the wire
                end_ += 2;
            }
        } else {
            end_ = write_integer(end_, x);
        }
    }

    std::unique_ptr<char[]> buffer_;
    char* end_ = nullptr;
    char* capacity_end_ = nullptr;
};

} // namespace

std::string encode(snapshot const& message)
{
    body_columns const& b = message.bodies;
    snapshot_writer w(128 * b.size());
    w.raw(R"({"type":"snapshot","tick":)");
    w.number(message.tick);
    w.raw(R"(,"time":)");
    w.number(message.time);
    w.raw(message.paused ? R"(,"paused":true)" : R"(,"paused":false)");
    if (message.faults > 0) {
        w.raw(R"(,"faults":)");
        w.number(message.faults);
    }
    w.raw(R"(,"bodies":{)");
    w.column("id", b.id);
    w.raw(",");
    w.column("position", b.position);
    w.raw(",");
    w.column("velocity", b.velocity);
    w.raw(",");
    w.column("radius", b.radius);
    if (b.mass) {
        w.raw(",");
        w.column("mass", *b.mass);
    }
    if (b.charge) {
        w.raw(",");
        w.column("charge", *b.charge);
    }
    if (b.tag) {
        w.raw(",");
        w.string_column("tag", *b.tag);
    }
    w.raw("}}");
    return w.take();
}
std::string encode(pong const& message)
{
    return encode_message(message);
}

namespace {

void write_bodies(snapshot_writer& w, compact_bodies const& b)
{
    w.raw("{");
    w.gap_column("id", b.id);
    w.raw(",");
    w.column("p", b.position);
    w.raw(",");
    w.column("v", b.velocity);
    w.raw(",");
    w.constant_column("radius", b.radius);
    w.raw(",");
    w.constant_column("mass", b.mass);
    if (b.charge) {
        w.raw(",");
        w.constant_column("charge", *b.charge);
    }
    w.raw(",");
    w.column("owner", b.owner);
    if (b.tag) {
        w.raw(",");
        w.string_column("tag", *b.tag);
    }
    w.raw("}");
}

} // namespace

namespace {

// Written like the full form: straight into one buffer. `tick` comes right after `type` in
// both forms, so a client that only counts snapshots finds it without parsing. `body_list`
// stands for message.bodies (which is not read).
std::string encode_compact(compact_snapshot const& message, compact_bodies const* body_list)
{
    std::size_t const bodies = (body_list ? body_list->size() : 0) +
                               (message.appeared ? message.appeared->size() : 0) +
                               (message.moved ? message.moved->position.size() / 3 : 0);
    snapshot_writer w(24 * bodies);
    w.raw(R"({"type":"snapshot","tick":)");
    w.number(message.tick);
    w.raw(R"(,"form":")");
    w.raw(message.form);
    w.raw("\"");
    if (message.base) {
        w.raw(R"(,"base":)");
        w.number(*message.base);
    }
    w.raw(R"(,"time":)");
    w.number(message.time);
    if (message.paused)
        w.raw(R"(,"paused":true)");
    if (message.faults > 0) {
        w.raw(R"(,"faults":)");
        w.number(message.faults);
    }
    if (message.q) {
        w.raw(R"(,"q":[)");
        w.number((*message.q)[0]);
        w.raw(",");
        w.number((*message.q)[1]);
        w.raw("]");
    }
    if (body_list) {
        w.raw(R"(,"bodies":)");
        write_bodies(w, *body_list);
    }
    if (message.moved) {
        w.raw(R"(,"moved":{)");
        w.column("runs", message.moved->runs);
        w.raw(",");
        w.column("p", message.moved->position);
        w.raw(",");
        w.column("v", message.moved->velocity);
        w.raw("}");
    }
    if (message.appeared) {
        w.raw(R"(,"appeared":)");
        write_bodies(w, *message.appeared);
    }
    if (message.vanished) {
        w.raw(",");
        w.gap_column("vanished", *message.vanished);
    }
    w.raw("}");
    return w.take();
}

} // namespace

std::string encode(compact_snapshot const& message)
{
    return encode_compact(message, message.bodies ? &*message.bodies : nullptr);
}

std::string encode_keyframe(compact_state const& state)
{
    compact_snapshot const head = keyframe_head(state);
    return encode_compact(head, &state.bodies);
}

std::string encode(client_message const& message)
{
    return std::visit([](auto const& m) { return encode_message(m); }, message);
}

std::string encode(server_message const& message)
{
    return std::visit(
        []<class M>(M const& m) {
            if constexpr (std::is_same_v<M, compact_snapshot>)
                return encode(m);
            else
                return encode_message(m);
        },
        message);
}

} // namespace kugel::protocol
