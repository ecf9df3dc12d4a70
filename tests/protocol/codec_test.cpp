#include "message_schemas.hpp"
#include "protocol/codec.hpp"
#include "sample_messages.hpp"

#include <bit>
#include <cmath>
#include <cstdint>
#include <gtest/gtest.h>
#include <limits>
#include <nlohmann/json.hpp>
#include <numbers>
#include <optional>
#include <set>
#include <string>
#include <vector>

namespace kugel::protocol {
namespace {

using nlohmann::json;
using testing::schemas;

template <class Message> std::string describe(decode_result<Message> const& result)
{
    return result.failure ? encode(*result.failure) : "(decoded)";
}

// Round trips ---------------------------------------------------------------------------

TEST(Codec, EveryClientMessageRoundTrips)
{
    for (client_message const& message : samples::client_messages()) {
        std::string const text = encode(message);
        SCOPED_TRACE(text);
        auto const decoded = decode(text);
        ASSERT_TRUE(decoded.message) << describe(decoded);
        EXPECT_FALSE(decoded.failure);
        EXPECT_EQ(*decoded.message, message);
    }
}

TEST(Codec, EveryServerMessageRoundTrips)
{
    for (server_message const& message : samples::server_messages()) {
        std::string const text = encode(message);
        SCOPED_TRACE(text);
        auto const decoded = decode_server_message(text);
        ASSERT_TRUE(decoded.message) << describe(decoded);
        EXPECT_FALSE(decoded.failure);
        EXPECT_EQ(*decoded.message, message);
    }
}

TEST(Codec, SamplesCoverEveryMessageType)
{
    std::set<std::size_t> client_types;
    for (auto const& m : samples::client_messages())
        client_types.insert(m.index());
    std::set<std::size_t> server_types;
    for (auto const& m : samples::server_messages())
        server_types.insert(m.index());
    EXPECT_EQ(client_types.size(), std::variant_size_v<client_message>);
    EXPECT_EQ(server_types.size(), std::variant_size_v<server_message>);
}

TEST(Codec, EncodeWritesTypeFirstAndNothingMore)
{
    EXPECT_EQ(encode(ping{.ref = 5}), R"({"type":"ping","ref":5})");
    EXPECT_EQ(encode(hello{}), R"({"type":"hello"})");
    EXPECT_EQ(encode(ack{.ref = 3, .tick = 1210}), R"({"type":"ack","ref":3,"tick":1210})");
    EXPECT_EQ(encode(ack{.ref = 1, .tick = 2, .id = 17}),
              R"({"type":"ack","ref":1,"tick":2,"id":17})");
    EXPECT_EQ(encode(error{.code = error_code::room_full, .message = "full"}),
              R"({"type":"error","code":"room_full","message":"full"})");
    EXPECT_EQ(encode(client_message{remove{.ref = 4, .id = 9}}),
              R"({"type":"remove","ref":4,"id":9})");
    EXPECT_EQ(encode(server_message{pong{.ref = 5, .tick = 6}}),
              R"({"type":"pong","ref":5,"tick":6})");
    EXPECT_EQ(encode(pause{.ref = 1}), R"({"type":"pause","ref":1})");
    EXPECT_EQ(encode(resume{.ref = 2}), R"({"type":"resume","ref":2})");
    EXPECT_EQ(encode(reset{.ref = 3}), R"({"type":"reset","ref":3})");
    EXPECT_EQ(encode(load_scene{.ref = 4, .scene = {R"({"name":"x","dt":0.5})"}}),
              R"({"type":"load_scene","ref":4,"scene":{"name":"x","dt":0.5}})");
}

TEST(Codec, LoadSceneCarriesTheSceneObjectAsItCame)
{
    auto const decoded = decode(R"({"type": "load_scene", "ref": 7,
        "scene": {"name": "z", "dt": 0.25, "bodies": [{"radius": 1e999999}]}})");
    // A number beyond a double is refused by the JSON reader before the scene is looked at.
    ASSERT_TRUE(decoded.failure);
    EXPECT_EQ(decoded.failure->code, error_code::not_finite);

    auto const good = decode(R"({"type": "load_scene", "ref": 7, "scene": {"b": 1, "a": [true]}})");
    ASSERT_TRUE(good.message) << good.failure->message;
    auto const& load = std::get<load_scene>(*good.message);
    EXPECT_EQ(load.ref, 7U);
    EXPECT_EQ(load.scene.text, R"({"b":1,"a":[true]})"); // key order kept
}

TEST(Codec, WelcomeAdminAndSnapshotPausedDefaultToFalse)
{
    json welcome_doc = json::parse(encode(samples::sample_welcome()));
    EXPECT_EQ(welcome_doc["admin"], false);
    EXPECT_FALSE(welcome_doc["limits"].contains("max_bodies_per_client"));
    welcome_doc.erase("admin"); // a server that predates admins
    auto const welcome_back = decode_server_message(welcome_doc.dump());
    ASSERT_TRUE(welcome_back.message) << welcome_back.failure->message;
    EXPECT_FALSE(std::get<welcome>(*welcome_back.message).admin);

    auto const snapshot_back = decode_server_message(
        R"({"type": "snapshot", "tick": 1, "time": 0.1, "bodies": {"id": [], "position": [],
            "velocity": [], "radius": []}})");
    ASSERT_TRUE(snapshot_back.message) << snapshot_back.failure->message;
    EXPECT_FALSE(std::get<snapshot>(*snapshot_back.message).paused);
    EXPECT_EQ(json::parse(encode(snapshot{.paused = true}))["paused"], true);
}

TEST(Codec, SnapshotBodiesAreColumns)
{
    snapshot const s{.tick = 2,
                     .time = 0.5,
                     .bodies = {.id = {4, 9},
                                .position = {1, 2, 3, 4, 5, 6},
                                .velocity = {0, 0, 0, 0, 0, -1},
                                .radius = {0.5, 0.25}}};
    EXPECT_EQ(encode(s),
              R"({"type":"snapshot","tick":2,"time":0.5,"paused":false,"bodies":{"id":[4,9],)"
              R"("position":[1.0,2.0,3.0,4.0,5.0,6.0],"velocity":[0.0,0.0,0.0,0.0,0.0,-1.0],)"
              R"("radius":[0.5,0.25]}})");

    auto with_charges = s;
    with_charges.bodies.charge = std::vector{1e-6, -1e-6};
    json const doc = json::parse(encode(with_charges));
    EXPECT_FALSE(doc["bodies"].contains("mass"));
    EXPECT_EQ(doc["bodies"]["charge"], json::parse("[1e-6, -1e-6]"));
}

TEST(Codec, DoublesParseBackToTheSameBits)
{
    std::vector<double> const values{
        0.1,
        1.0 / 3.0,
        -0.0,
        std::numbers::pi,
        std::numeric_limits<double>::denorm_min(),
        std::numeric_limits<double>::min(),
        std::numeric_limits<double>::max(),
        std::numeric_limits<double>::lowest(),
        std::numeric_limits<double>::epsilon(),
        std::nextafter(1.0, 2.0),
        std::nextafter(0.3, 0.0),
        9007199254740993.0, // 2^53 + 1 rounds to 2^53
        1e22,
        1e23,
        5e-324 * 3,
        123456.789e-300,
        -2.2250738585072011e-308,
    };
    snapshot s{.tick = 1, .time = 0.1};
    for (double const x : values) {
        s.bodies.id.push_back(s.bodies.id.size());
        s.bodies.position.insert(s.bodies.position.end(), {x, -x, x / 7.0});
        s.bodies.velocity.insert(s.bodies.velocity.end(), {x * 0.5, x, -x});
        s.bodies.radius.push_back(std::abs(x));
    }
    s.bodies.mass = s.bodies.radius;
    std::string const text = encode(s);

    auto const same_bits = [](std::vector<double> const& a, std::vector<double> const& b) {
        if (a.size() != b.size())
            return false;
        for (std::size_t i = 0; i < a.size(); ++i)
            if (std::bit_cast<std::uint64_t>(a[i]) != std::bit_cast<std::uint64_t>(b[i]))
                return false;
        return true;
    };
    // An independent reader (nlohmann's parser, strtod underneath) gets the same bits ...
    json const doc = json::parse(text);
    EXPECT_TRUE(same_bits(doc["bodies"]["position"].get<std::vector<double>>(), s.bodies.position));
    EXPECT_TRUE(same_bits(doc["bodies"]["velocity"].get<std::vector<double>>(), s.bodies.velocity));
    EXPECT_TRUE(same_bits(doc["bodies"]["mass"].get<std::vector<double>>(), *s.bodies.mass));
    // ... and so does decode.
    auto const decoded = decode_server_message(text);
    ASSERT_TRUE(decoded.message) << describe(decoded);
    auto const& back = std::get<snapshot>(*decoded.message);
    EXPECT_TRUE(same_bits(back.bodies.position, s.bodies.position));
    EXPECT_TRUE(same_bits(back.bodies.velocity, s.bodies.velocity));
    EXPECT_TRUE(same_bits(back.bodies.radius, s.bodies.radius));
}

// Decoding what clients send ------------------------------------------------------------

TEST(Decode, AppliesDefaults)
{
    auto const decoded = decode(
        R"({"type": "spawn", "ref": 7, "body": {"position": [1, 2, 3], "radius": 0, "mass": 2}})");
    ASSERT_TRUE(decoded.message) << describe(decoded);
    auto const& s = std::get<spawn>(*decoded.message);
    EXPECT_EQ(s.ref, 7U);
    EXPECT_EQ(s.body.position, (vec3{1, 2, 3}));
    EXPECT_EQ(s.body.velocity, (vec3{0, 0, 0}));
    EXPECT_EQ(s.body.charge, 0.0);
    EXPECT_EQ(s.body.mass, 2.0);
    EXPECT_FALSE(s.body.density);
}

TEST(Decode, IgnoresUnknownFields)
{
    auto const plain = decode(R"({"type": "impulse", "ref": 1, "id": 2, "impulse": [0, 0, 1]})");
    auto const extra = decode(R"({"type": "impulse", "ref": 1, "later": {"x": [1, "a"]}, "id": 2,
                                  "impulse": [0, 0, 1], "comment": null})");
    ASSERT_TRUE(plain.message) << describe(plain);
    ASSERT_TRUE(extra.message) << describe(extra);
    EXPECT_EQ(*plain.message, *extra.message);

    auto const nested = decode(R"({"type": "spawn", "ref": 1, "body": {"position": [0, 0, 0],
                                   "radius": 1, "mass": 1, "colour": "red"}})");
    EXPECT_TRUE(nested.message) << describe(nested);
}

TEST(Decode, ReadsWholeNumbersUpTo2To53Minus1)
{
    auto const ref_of = [](std::string const& ref) -> std::optional<std::uint64_t> {
        auto const decoded = decode(R"({"type": "ping", "ref": )" + ref + "}");
        if (!decoded.message)
            return std::nullopt;
        return std::get<ping>(*decoded.message).ref;
    };
    EXPECT_EQ(ref_of("0"), 0U);
    EXPECT_EQ(ref_of("7.0"), 7U);
    EXPECT_EQ(ref_of("1e3"), 1000U);
    EXPECT_EQ(ref_of("9007199254740991"), max_safe_integer);
    EXPECT_EQ(ref_of("9007199254740992"), std::nullopt);
    EXPECT_EQ(ref_of("18446744073709551615"), std::nullopt);
    EXPECT_EQ(ref_of("-1"), std::nullopt);
    EXPECT_EQ(ref_of("0.5"), std::nullopt);
}

TEST(Decode, NeverThrowsOnDeepOrOddInput)
{
    std::string const deep = std::string(100000, '[') + std::string(100000, ']');
    EXPECT_EQ(decode(deep).failure.value().code, error_code::bad_message);
    std::string const deep_type =
        R"({"type": )" + std::string(50000, '[') + std::string(50000, ']') + "}";
    EXPECT_EQ(decode(deep_type).failure.value().code, error_code::bad_message);
    // Nesting deeper than 32 levels is refused before the text is parsed to its end, so an
    // unclosed run of brackets is too deep before it is unfinished.
    auto const unclosed = decode(std::string(100000, '['));
    EXPECT_EQ(unclosed.failure.value().code, error_code::bad_message);
    EXPECT_LT(unclosed.failure.value().message.size(), 500U) << "the pointer is cut short";
    EXPECT_EQ(decode(std::string(20, '[')).failure.value().code, error_code::bad_json)
        << "shallow and unfinished: not valid JSON";
    EXPECT_EQ(decode(std::string("\0\0\0", 3)).failure.value().code, error_code::bad_json);
    EXPECT_EQ(decode("{}{}").failure.value().code, error_code::bad_json);
    EXPECT_EQ(decode("\xEF\xBB\xBF{\"type\": \"ping\", \"ref\": 1}").failure, std::nullopt)
        << "a UTF-8 byte order mark is skipped";
}

TEST(Decode, EchoesInvalidUtf8OnlyAsValidText)
{
    // An unknown type is echoed in the message, cut short; bytes that are not UTF-8 must
    // not make the error itself unencodable.
    std::string const type = std::string(38, 'x') + "\xC3\xA9" + "yyy"; // é across the cut
    auto const decoded = decode(R"({"type": ")" + type + R"(", "ref": 2})");
    ASSERT_TRUE(decoded.failure);
    EXPECT_EQ(decoded.failure->ref, 2U);
    std::string const text = encode(*decoded.failure);
    EXPECT_TRUE(json::accept(text)) << text;

    error const raw{.code = error_code::bad_value, .message = "got \xFF\xFE"};
    EXPECT_TRUE(json::accept(encode(raw)));
}

struct bad_case
{
    char const* what;
    std::string text;
    error_code code;
    char const* message;              ///< must appear in the error: the pointer and the reason
    std::optional<std::uint64_t> ref; ///< echoed when it could be read
    bool schema_can_tell = true;      ///< false: not JSON at all, or a rule no schema states
};

void PrintTo(bad_case const& c, std::ostream* out)
{
    *out << c.what;
}

class BadClientMessage : public ::testing::TestWithParam<bad_case>
{
};

TEST_P(BadClientMessage, IsRefusedWithItsCodePointerAndRef)
{
    auto const& c = GetParam();
    auto const decoded = decode(c.text);
    ASSERT_FALSE(decoded.message) << "accepted: " << c.text;
    ASSERT_TRUE(decoded.failure);
    EXPECT_EQ(name(decoded.failure->code), name(c.code)) << decoded.failure->message;
    EXPECT_NE(decoded.failure->message.find(c.message), std::string::npos)
        << "got: " << decoded.failure->message;
    EXPECT_EQ(decoded.failure->ref, c.ref);
    if (c.schema_can_tell) {
        EXPECT_FALSE(schemas().accepts(json::parse(c.text))) << "the schema accepts it";
    }
}

std::string const huge_integer = "1" + std::string(400, '0');

std::vector<bad_case> bad_client_messages()
{
    return {
        bad_case{"truncated", R"({"type": "ping", "ref": 5)", error_code::bad_json,
                 "/: not valid JSON: parse error at line 1, column 26", 5, false},
        bad_case{"nan_literal", R"({"type": "spawn", "ref": 1, "body": {"position": [NaN, 0, 0]}})",
                 error_code::bad_json, "/body/position/0: not valid JSON", 1, false},
        bad_case{"not_utf8", "{\"type\": \"hello\", \"name\": \"\xFF\"}", error_code::bad_json,
                 "/name: not valid JSON", std::nullopt, false},
        bad_case{"empty", "", error_code::bad_json, "/: not valid JSON", std::nullopt, false},
        bad_case{"array", R"([{"type": "ping", "ref": 1}])", error_code::bad_message,
                 "/: a message must be a JSON object, got array of 1"},
        bad_case{"no_type", R"({"ref": 3})", error_code::bad_message,
                 "/type: missing: every message names its type", 3},
        bad_case{"type_not_a_string", R"({"type": 4, "ref": 3})", error_code::bad_message,
                 "/type: must be a string, got number 4", 3},
        bad_case{
            "unknown_type", R"({"type": "jump", "ref": 5})", error_code::unknown_type,
            R"(/type: unknown message type "jump" (known: hello, spawn, impulse, remove, ping, pause, resume, reset, load_scene, set, interest))",
            5},
        bad_case{"server_type_from_client", R"({"type": "welcome"})", error_code::unknown_type,
                 R"(/type: unknown message type "welcome")"},
        bad_case{"missing_ref", R"({"type": "ping"})", error_code::missing_field,
                 "/ref: missing (required)"},
        bad_case{"missing_id", R"({"type": "remove", "ref": 3})", error_code::missing_field,
                 "/id: missing (required)", 3},
        bad_case{"missing_position",
                 R"({"type": "spawn", "ref": 1, "body": {"radius": 1, "mass": 1}})",
                 error_code::missing_field, "/body/position: missing (required)", 1},
        bad_case{"missing_radius",
                 R"({"type": "spawn", "ref": 1, "body": {"position": [0, 0, 0], "mass": 1}})",
                 error_code::missing_field, "/body/radius: missing (required)", 1},
        bad_case{"no_mass_or_density",
                 R"({"type": "spawn", "ref": 1, "body": {"position": [0, 0, 0], "radius": 1}})",
                 error_code::missing_field, "/body: needs a mass (kg) or a density (kg/m^3)", 1},
        bad_case{"id_as_string",
                 R"({"type": "impulse", "ref": 2, "id": "17", "impulse": [0, 0, 1]})",
                 error_code::wrong_type, R"(/id: must be a whole number, got string "17")", 2},
        bad_case{"ref_as_string", R"({"type": "ping", "ref": "5"})", error_code::wrong_type,
                 R"(/ref: must be a whole number, got string "5")"},
        bad_case{"body_not_an_object", R"({"type": "spawn", "ref": 1, "body": [0, 0, 0]})",
                 error_code::wrong_type, "/body: must be an object, got array of 3", 1},
        bad_case{"impulse_not_an_array", R"({"type": "impulse", "ref": 2, "id": 1, "impulse": 5})",
                 error_code::wrong_type,
                 "/impulse: must be an array of 3 numbers [x, y, z], got number 5", 2},
        bad_case{"vector_with_a_string",
                 R"({"type": "impulse", "ref": 2, "id": 1, "impulse": [0, "1", 0]})",
                 error_code::wrong_type, R"(/impulse/1: must be a number, got string "1")", 2},
        bad_case{"name_not_a_string", R"({"type": "hello", "name": 42})", error_code::wrong_type,
                 "/name: must be a string, got number 42"},
        // A player's name is shown to every other player: bounded, no control characters.
        bad_case{"name_empty", R"({"type": "hello", "name": ""})", error_code::bad_value,
                 "/name: must be 1 to 64 bytes of UTF-8, got 0"},
        bad_case{"name_too_long", R"({"type": "hello", "name": ")" + std::string(65, 'x') + R"("})",
                 error_code::bad_value, "/name: must be 1 to 64 bytes of UTF-8, got 65"},
        bad_case{"name_of_33_two_byte_letters", R"({"type": "hello", "name": ")" + [] {
                     std::string s;
                     for (int i = 0; i < 33; ++i)
                         s += "\u00e9";
                     return s;
                 }() + R"("})",
                 error_code::bad_value, "/name: must be 1 to 64 bytes of UTF-8, got 66", std::nullopt,
                 false}, // a schema's maxLength counts characters (33)
        bad_case{"name_with_a_newline", R"({"type": "hello", "name": "ann\nbob"})", error_code::bad_value,
                 "/name: must not hold control characters (found the byte 10)"},
        bad_case{"name_with_a_delete", R"({"type": "hello", "name": "ann\u007f"})", error_code::bad_value,
                 "/name: must not hold control characters (found the byte 127)"},
        bad_case{
            "null_velocity",
            R"({"type": "spawn", "ref": 1, "body": {"position": [0, 0, 0], "velocity": null, "radius": 1, "mass": 1}})",
            error_code::wrong_type,
            "/body/velocity: must be an array of 3 numbers [x, y, z], got null", 1},
        bad_case{
            "overflowing_number",
            R"({"type": "spawn", "ref": 4, "body": {"position": [0, 1e999, 0], "radius": 1, "mass": 1}})",
            error_code::not_finite, "/body/position/1: 1e999 is beyond the range of a double", 4,
            false},
        bad_case{"overflowing_integer",
                 R"({"type": "impulse", "ref": 6, "id": 1, "impulse": [0, 0, )" + huge_integer +
                     "]}",
                 error_code::not_finite, "/impulse/2: 1000000000000000000000000000000000000...", 6,
                 false},
        bad_case{
            "negative_radius",
            R"({"type": "spawn", "ref": 1, "body": {"position": [0, 0, 0], "radius": -1, "mass": 1}})",
            error_code::bad_value, "/body/radius: must be >= 0, got -1", 1},
        bad_case{
            "zero_mass",
            R"({"type": "spawn", "ref": 1, "body": {"position": [0, 0, 0], "radius": 1, "mass": 0}})",
            error_code::bad_value, "/body/mass: must be > 0, got 0", 1},
        bad_case{
            "negative_density",
            R"({"type": "spawn", "ref": 1, "body": {"position": [0, 0, 0], "radius": 1, "density": -2.5}})",
            error_code::bad_value, "/body/density: must be > 0, got -2.5", 1},
        bad_case{
            "mass_and_density",
            R"({"type": "spawn", "ref": 1, "body": {"position": [0, 0, 0], "radius": 1, "mass": 1, "density": 2}})",
            error_code::bad_value, "/body: give either mass or density, not both", 1},
        bad_case{
            "density_of_a_point",
            R"({"type": "spawn", "ref": 1, "body": {"position": [0, 0, 0], "radius": 0, "density": 2}})",
            error_code::bad_value, "/body/density: needs a radius > 0", 1},
        bad_case{
            "faster_than_light",
            R"({"type": "spawn", "ref": 1, "body": {"position": [0, 0, 0], "velocity": [2e8, 2e8, 2e8], "radius": 1, "mass": 1}})",
            error_code::bad_value,
            "/body/velocity: a speed of 346410161.51", 1,
            false},
        bad_case{
            "speed_near_the_largest_double",
            R"({"type": "spawn", "ref": 1, "body": {"position": [0, 0, 0], "velocity": [1.7e308, 1.7e308, 0], "radius": 1, "mass": 1}})",
            error_code::bad_value, "/body/velocity: a speed beyond the range of a double is not below", 1, false},
        // A body's tag is shown to every client: bounded, no control characters.
        bad_case{"interest_box_min_above_max",
                 R"({"type": "interest", "ref": 7, "box": {"min": [0, 0, 0], "max": [1, -1, 1]}})",
                 error_code::bad_value, "/box/max/1: must be >= min[1] = 0, got -1", 7, false},
        bad_case{"interest_radius_zero", R"({"type": "interest", "ref": 7, "around": {"body": 3, "radius": 0}})",
                 error_code::bad_value, "/around/radius: must be > 0 and at most 1e+15 m, got 0", 7},
        bad_case{"interest_radius_huge", R"({"type": "interest", "ref": 7, "around": {"body": 3, "radius": 2e15}})",
                 error_code::bad_value, "/around/radius: must be > 0 and at most 1e+15 m, got 2e+15", 7},
        bad_case{"interest_box_and_around",
                 R"({"type": "interest", "ref": 7, "box": {"min": [0, 0, 0], "max": [1, 1, 1]}, "around": {"body": 3, "radius": 1}})",
                 error_code::bad_value, "/around: give one region, a box or a ball around a body, not both", 7},
        bad_case{"interest_tags_empty", R"({"type": "interest", "ref": 7, "tags": []})", error_code::bad_value,
                 "/tags: must hold at least one tag", 7},
        bad_case{"interest_tag_too_long", R"({"type": "interest", "ref": 7, "tags": [")" + std::string(33, 'x') + R"("]})",
                 error_code::bad_value, "/tags/0: must be 1 to 32 bytes of UTF-8, got 33", 7},
        bad_case{"interest_box_without_min", R"({"type": "interest", "ref": 7, "box": {"max": [1, 1, 1]}})",
                 error_code::missing_field, "/box/min: missing (required)", 7},
        bad_case{"interest_around_body_fractional", R"({"type": "interest", "ref": 7, "around": {"body": 1.5, "radius": 1}})",
                 error_code::bad_value, "/around/body: must be a whole number", 7},
        bad_case{"hello_interest_a_string", R"({"type": "hello", "interest": "near"})", error_code::wrong_type,
                 "/interest: must be an object, got string", std::nullopt},
        bad_case{"hello_interest_box_inverted", R"({"type": "hello", "interest": {"box": {"min": [2, 0, 0], "max": [1, 1, 1]}}})",
                 error_code::bad_value, "/interest/box/max/0: must be >= min[0] = 2, got 1", std::nullopt, false},
        bad_case{"events_a_string", R"({"type": "hello", "events": "all"})", error_code::wrong_type,
                 "/events: must be true, false or an object {sensors, tags, kinds}, got string", std::nullopt},
        bad_case{"events_sensors_not_a_list", R"({"type": "hello", "events": {"sensors": "goal"}})",
                 error_code::wrong_type, "/events/sensors: must be an array", std::nullopt},
        bad_case{"events_sensors_empty", R"({"type": "hello", "events": {"sensors": []}})", error_code::bad_value,
                 "/events/sensors: must hold at least one entry (leave the list out to match every event)",
                 std::nullopt},
        bad_case{"events_sensor_name_too_long", R"({"type": "hello", "events": {"sensors": ["goal", ")" +
                                                    std::string(33, 's') + R"("]}})",
                 error_code::bad_value, "/events/sensors/1: must be 1 to 32 bytes of UTF-8, got 33", std::nullopt},
        bad_case{"events_tag_with_a_tab", R"({"type": "hello", "events": {"tags": ["a\tb"]}})", error_code::bad_value,
                 "/events/tags/0: must not hold control characters (found the byte 9)", std::nullopt},
        bad_case{"events_unknown_kind", R"({"type": "hello", "events": {"kinds": ["entered", "stayed"]}})",
                 error_code::bad_value, "/events/kinds/1: must be \"entered\", \"left\" or \"contact\", got \"stayed\"",
                 std::nullopt},
        bad_case{"events_too_many_tags", R"({"type": "hello", "events": {"tags": [)" + [] {
                     std::string list;
                     for (int i = 0; i < 65; ++i)
                         list += (i == 0 ? "\"t" : ", \"t") + std::to_string(i) + "\"";
                     return list;
                 }() + R"(]}})",
                 error_code::bad_value, "/events/tags: must hold at most 64 entries, got 65", std::nullopt},
        bad_case{"tag_empty", R"({"type": "spawn", "ref": 1, "body": {"position": [0, 0, 0], "radius": 1, "mass": 1, "tag": ""}})",
                 error_code::bad_value, "/body/tag: must be 1 to 32 bytes of UTF-8, got 0", 1},
        bad_case{"tag_too_long", R"({"type": "spawn", "ref": 1, "body": {"position": [0, 0, 0], "radius": 1, "mass": 1, "tag": ")" +
                                     std::string(33, 't') + R"("}})",
                 error_code::bad_value, "/body/tag: must be 1 to 32 bytes of UTF-8, got 33", 1},
        bad_case{"tag_with_a_newline", R"({"type": "spawn", "ref": 1, "body": {"position": [0, 0, 0], "radius": 1, "mass": 1, "tag": "a\nb"}})",
                 error_code::bad_value, "/body/tag: must not hold control characters (found the byte 10)", 1},
        bad_case{"tag_as_a_number", R"({"type": "spawn", "ref": 1, "body": {"position": [0, 0, 0], "radius": 1, "mass": 1, "tag": 7}})",
                 error_code::wrong_type, "/body/tag: must be a string, got number 7", 1},
        bad_case{"static_as_a_string", R"({"type": "spawn", "ref": 1, "body": {"position": [0, 0, 0], "radius": 1, "mass": 1, "static": "yes"}})",
                 error_code::wrong_type, R"(/body/static: must be true or false, got string "yes")", 1},
        bad_case{"static_and_moving", R"({"type": "spawn", "ref": 1, "body": {"position": [0, 0, 0], "velocity": [1, 0, 0], "radius": 1, "mass": 1, "static": true}})",
                 error_code::bad_value, "/body/velocity: a static body cannot move", 1},
        // set: an id and at least one of position and velocity.
        bad_case{"set_without_either", R"({"type": "set", "ref": 7, "id": 1})", error_code::missing_field,
                 "/: needs a position (m), a velocity (m/s) or both", 7},
        bad_case{"set_without_id", R"({"type": "set", "ref": 7, "position": [0, 0, 0]})", error_code::missing_field,
                 "/id: missing (required)", 7},
        bad_case{"set_position_of_two", R"({"type": "set", "ref": 7, "id": 1, "position": [0, 0]})", error_code::bad_value,
                 "/position: must be an array of 3 numbers [x, y, z], got array of 2", 7},
        bad_case{"set_velocity_as_null", R"({"type": "set", "ref": 7, "id": 1, "velocity": null})", error_code::wrong_type,
                 "/velocity: must be an array of 3 numbers [x, y, z], got null", 7},
        bad_case{"set_position_overflowing", R"({"type": "set", "ref": 7, "id": 1, "position": [0, 0, -1e999]})",
                 error_code::not_finite, "/position/2: -1e999 is beyond the range of a double", 7, false},
        bad_case{"set_faster_than_light", R"({"type": "set", "ref": 7, "id": 1, "velocity": [0, 299792458, 0]})",
                 error_code::bad_value, "/velocity: a speed of 299792458 m/s is not below the speed of light", 7, false},
        bad_case{"set_negative_id", R"({"type": "set", "ref": 7, "id": -3, "velocity": [0, 0, 0]})", error_code::bad_value,
                 "/id: must be a whole number from 0 to 9007199254740991, got -3", 7},
        bad_case{"negative_ref", R"({"type": "ping", "ref": -1})", error_code::bad_value,
                 "/ref: must be a whole number from 0 to 9007199254740991, got -1"},
        bad_case{"ref_beyond_2_to_53", R"({"type": "ping", "ref": 9007199254740992})",
                 error_code::bad_value,
                 "/ref: must be a whole number from 0 to 9007199254740991, got 9007199254740992"},
        bad_case{"fractional_id", R"({"type": "remove", "ref": 8, "id": 1.5})",
                 error_code::bad_value,
                 "/id: must be a whole number from 0 to 9007199254740991, got 1.5", 8},
        bad_case{"vector_of_two", R"({"type": "impulse", "ref": 2, "id": 1, "impulse": [0, 1]})",
                 error_code::bad_value,
                 "/impulse: must be an array of 3 numbers [x, y, z], got array of 2", 2},
        bad_case{"scene_not_an_object", R"({"type": "load_scene", "ref": 3, "scene": "arena.json"})",
                 error_code::wrong_type, R"(/scene: must be an object, got string "arena.json")", 3},
        bad_case{"load_scene_without_scene", R"({"type": "load_scene", "ref": 4})",
                 error_code::missing_field, "/scene: missing (required)", 4},
        bad_case{"pause_without_ref", R"({"type": "pause"})", error_code::missing_field,
                 "/ref: missing (required)"},
        bad_case{"admin_token_as_a_number", R"({"type": "hello", "admin_token": 12345})",
                 error_code::wrong_type, "/admin_token: must be a string, got number 12345"},
        // A resume token is a secret: a refusal says only its length, never its text.
        bad_case{"resume_as_a_number", R"({"type": "hello", "resume": 12345})",
                 error_code::wrong_type, "/resume: must be a string, got number 12345"},
        bad_case{"resume_empty", R"({"type": "hello", "resume": ""})", error_code::bad_value,
                 "/resume: must be 1 to 128 bytes (a welcome's resume_token), got 0"},
        bad_case{"resume_too_long", R"({"type": "hello", "resume": ")" + std::string(129, 'f') + R"("})",
                 error_code::bad_value, "/resume: must be 1 to 128 bytes (a welcome's resume_token), got 129"},
        bad_case{"resume_as_null", R"({"type": "hello", "resume": null})", error_code::wrong_type,
                 "/resume: must be a string, got null"},
        bad_case{"unsupported_protocol", R"({"type": "hello", "protocol": 2})",
                 error_code::unsupported_protocol,
                 "/protocol: protocol 2 is not spoken here (this side speaks 1)"},
    };
}

INSTANTIATE_TEST_SUITE_P(Cases, BadClientMessage, ::testing::ValuesIn(bad_client_messages()));

TEST(Decode, EveryCodeOfTheDecoderHasABadCase)
{
    std::set<error_code> seen;
    for (auto const& c : bad_client_messages())
        seen.insert(c.code);
    for (error_code const code :
         {error_code::bad_json, error_code::bad_message, error_code::unknown_type,
          error_code::missing_field, error_code::wrong_type, error_code::not_finite,
          error_code::bad_value, error_code::unsupported_protocol})
        EXPECT_TRUE(seen.contains(code)) << name(code);
}

// Decoding what the server sends --------------------------------------------------------

TEST(DecodeServerMessage, ChecksColumnLengths)
{
    auto const decoded = decode_server_message(
        R"({"type": "snapshot", "tick": 1, "time": 0.1, "bodies": {"id": [1, 2],
            "position": [0, 0, 0, 1, 1], "velocity": [0, 0, 0, 0, 0, 0], "radius": [1, 1]}})");
    ASSERT_TRUE(decoded.failure);
    EXPECT_EQ(decoded.failure->code, error_code::bad_value);
    EXPECT_EQ(decoded.failure->message,
              "/bodies/position: must hold 6 numbers (3 for each of the 2 ids), got 5");

    auto const short_mass = decode_server_message(
        R"({"type": "snapshot", "tick": 1, "time": 0.1, "bodies": {"id": [1],
            "position": [0, 0, 0], "velocity": [0, 0, 0], "radius": [1], "mass": []}})");
    ASSERT_TRUE(short_mass.failure);
    EXPECT_EQ(short_mass.failure->message,
              "/bodies/mass: must hold 1 numbers (1 for each of the 1 ids), got 0");
}

TEST(DecodeServerMessage, RefusesWhatAClientCouldMisread)
{
    auto const code_of = [](std::string const& text) {
        auto const decoded = decode_server_message(text);
        return decoded.failure
                   ? std::string(name(decoded.failure->code)) + " " + decoded.failure->message
                   : std::string("(decoded)");
    };
    json welcome_doc = json::parse(encode(samples::sample_welcome()));
    welcome_doc["protocol"] = 2;
    EXPECT_EQ(code_of(welcome_doc.dump()),
              "unsupported_protocol /protocol: protocol 2 is not spoken here (this side speaks 1)");

    welcome_doc = json::parse(encode(samples::sample_welcome()));
    welcome_doc["scene"]["obstacles"][0]["axes"][2] = json::array({0, 0});
    EXPECT_EQ(code_of(welcome_doc.dump()), "bad_value /scene/obstacles/0/axes/2: must be an array "
                                           "of 3 numbers [x, y, z], got array of 2");

    welcome_doc = json::parse(encode(samples::sample_welcome()));
    welcome_doc["bodies_on_leave"] = "vanish";
    EXPECT_EQ(code_of(welcome_doc.dump()),
              R"(bad_value /bodies_on_leave: must be "stay" or "remove", got "vanish")");
    welcome_doc["bodies_on_leave"] = "remove";
    welcome_doc["resume_grace"] = -1;
    EXPECT_EQ(code_of(welcome_doc.dump()), "bad_value /resume_grace: must be >= 0, got -1");

    welcome_doc = json::parse(encode(samples::sample_welcome()));
    welcome_doc["scene"]["walls"][1].erase("damping");
    EXPECT_EQ(code_of(welcome_doc.dump()),
              "missing_field /scene/walls/1/damping: missing (required)");

    EXPECT_EQ(code_of(R"({"type": "error", "code": "teapot", "message": "?"})"),
              R"(bad_value /code: unknown error code string "teapot")");
    EXPECT_EQ(
        code_of(R"({"type": "ping", "ref": 1})"),
        R"(unknown_type /type: unknown message type "ping" (known: welcome, ack, error, snapshot, pong, players, player, event))");
    EXPECT_EQ(code_of(R"({"type": "player", "change": "kicked", "id": 3})"),
              R"(bad_value /change: must be "joined", "renamed", "away", "back" or "left", got "kicked")");
    EXPECT_EQ(code_of(R"({"type": "players", "players": [{"id": 1, "name": ""}]})"),
              "bad_value /players/0/name: must be 1 to 64 bytes of UTF-8, got 0");

    welcome_doc = json::parse(encode(samples::sample_welcome()));
    welcome_doc["permissions"]["push"] = "everybody";
    EXPECT_EQ(code_of(welcome_doc.dump()),
              R"(bad_value /permissions/push: must be "anyone", "owner" or "admins", got "everybody")");
    welcome_doc["permissions"] = {{"push", "owner"}, {"remove", "anyone"}};
    EXPECT_EQ(code_of(welcome_doc.dump()),
              R"(bad_value /permissions/remove: must be "owner" or "admins", got "anyone")");
    EXPECT_EQ(code_of(R"({"type": "snapshot", "tick": 1, "time": 0.1, "bodies": {"id": [1, 2],
            "position": [0, 0, 0, 1, 1, 1], "velocity": [0, 0, 0, 0, 0, 0], "radius": [1, 1], "tag": ["a"]}})"),
              "bad_value /bodies/tag: must hold 2 numbers (1 for each of the 2 ids), got 1");
    EXPECT_EQ(code_of(R"({"type": "snapshot", "tick": 1, "form": "key", "time": 0.1, "q": [0.001, 0.01],
            "bodies": {"id": [1], "p": [0, 0, 0], "v": [0, 0, 0], "radius": [1], "mass": [1], "owner": [0],
            "tag": ["a\u0001"]}})"),
              "bad_value /bodies/tag/0: must not hold control characters (found the byte 1)");
}

// A welcome from a server before permissions were told reads as today's rules; the tag
// columns are written only when given, and a snapshot's tags read back as sent.
TEST(Codec, PermissionsDefaultAndTagsRoundTrip)
{
    json welcome_doc = json::parse(encode(samples::sample_welcome()));
    EXPECT_EQ(welcome_doc.at("permissions"), (json{{"push", "anyone"}, {"remove", "owner"}}));
    welcome_doc.erase("permissions");
    auto const decoded = decode_server_message(welcome_doc.dump());
    ASSERT_TRUE(decoded.message) << describe(decoded);
    EXPECT_EQ(std::get<welcome>(*decoded.message).permissions, room_permissions{});

    snapshot untagged{.tick = 1, .bodies = {.id = {1}, .position = {0, 0, 0}, .velocity = {0, 0, 0}, .radius = {1}}};
    EXPECT_EQ(encode(untagged).find("tag"), std::string::npos);
    snapshot tagged = untagged;
    tagged.bodies.tag = std::vector<std::string>{"a\"b"};
    EXPECT_NE(encode(tagged).find(R"("tag":["a\"b"])"), std::string::npos) << encode(tagged);
    EXPECT_EQ(encode(spawn{.ref = 1, .body = {.radius = 1, .mass = 1}}).find("static"), std::string::npos);
    EXPECT_NE(encode(spawn{.ref = 1, .body = {.radius = 1, .mass = 1, .is_static = true}}).find(R"("static":true)"),
              std::string::npos);
}

// Error codes ---------------------------------------------------------------------------

TEST(ErrorCodes, HaveUniqueSnakeCaseNamesThatReadBack)
{
    std::set<std::string_view> names;
    for (error_code const code : all_error_codes) {
        std::string_view const n = name(code);
        EXPECT_TRUE(names.insert(n).second) << n;
        EXPECT_EQ(n.find_first_not_of("abcdefghijklmnopqrstuvwxyz_"), std::string_view::npos) << n;
        EXPECT_EQ(error_code_named(n), code);
    }
    EXPECT_EQ(error_code_named("teapot"), std::nullopt);
}

} // namespace
} // namespace kugel::protocol
