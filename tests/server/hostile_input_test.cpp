// Hostile input, one case per row: what a client sends over a real WebSocket and what the
// server must answer (an error with its code, the JSON pointer and the ref; a close code; or
// an ordinary answer where the input is odd but valid). For every row the test also checks
// that the server stays up, that a second client in the same room keeps receiving snapshots,
// and that a refused command changes nothing in the world. The room's scene has no forces,
// so its snapshots are bit for bit the same from tick to tick unless a command changes
// something: comparing them before and after a row compares the whole world.

#include "room.hpp"
#include "server.hpp"

#include "protocol/message_schemas.hpp"
#include "support/in_process_server.hpp"
#include "support/scene_files.hpp"
#include "support/ws_client.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <string>
#include <variant>
#include <vector>

namespace kugel::server {
namespace {

using nlohmann::json;
using test_support::ws_client;
namespace fs = std::filesystem;

using protocol::testing::schemas;

// What a row expects ----------------------------------------------------------------------

struct refused_with
{
    std::string code;
    std::string pointer;              ///< the error message starts with "POINTER: "
    std::optional<std::uint64_t> ref; ///< echoed; nullopt: the error has no ref
};
struct closed_with
{
    std::uint16_t code;
};
struct answered_with ///< odd but valid input, answered as usual
{
    std::string type;
    std::uint64_t ref;
};
struct no_answer ///< valid input that gets no answer (a good hello)
{
};
struct rate_limited_after ///< the frame sent `repeat` times: this many answered, the rest refused
{
    int answered;
};
struct welcomed_with ///< a hello asking for snapshots: a welcome saying what it gets
{
    std::string form;
    double rate; ///< Hz
};
using expectation =
    std::variant<refused_with, closed_with, answered_with, no_answer, rate_limited_after, welcomed_with>;

struct hostile_case
{
    std::string name;
    std::string frame;
    expectation expected;
    bool binary = false;
    int repeat = 1;
};

refused_with refused(std::string code, std::string pointer, std::optional<std::uint64_t> ref = std::nullopt)
{
    return {std::move(code), std::move(pointer), ref};
}

std::string spawn(std::uint64_t ref, std::string const& body)
{
    return R"({"type":"spawn","ref":)" + std::to_string(ref) + R"(,"body":)" + body + "}";
}

std::string spawn_at(std::uint64_t ref, std::string const& position, std::string const& rest = R"("radius":0.1,"mass":1)")
{
    return spawn(ref, R"({"position":)" + position + "," + rest + "}");
}

std::string repeated(std::string const& text, std::size_t times)
{
    std::string out;
    out.reserve(text.size() * times);
    for (std::size_t i = 0; i < times; ++i)
        out += text;
    return out;
}

std::string numbers(std::size_t count)
{
    std::string out = "[0";
    for (std::size_t i = 1; i < count; ++i)
        out += ",0";
    return out + "]";
}

constexpr std::size_t frame_limit = 128 * 1024; // bytes: room for 100000 '[' in one frame
constexpr int command_burst = 20;
constexpr std::uint64_t light_body = 2; // 1 µg: a modest impulse gives it a huge speed

// Body 1 is the scene's 2 kg sphere at the origin, body 2 its 1 µg point mass; walls at ±10 m.
std::vector<hostile_case> catalogue()
{
    using namespace std::string_literals;
    std::string const ok_body = R"({"position":[1,1,1],"radius":0.1,"mass":1})";
    return {
        // Not JSON, or not all of it.
        {"garbage", "{not json", refused("bad_json", "/")},
        {"empty frame", "", refused("bad_json", "/")},
        {"truncated after the ref", R"({"type":"ping","ref":1)", refused("bad_json", "/", 1)},
        {"truncated inside a vector", R"({"type":"spawn","ref":2,"body":{"position":[0,0,)",
         refused("bad_json", "/body/position/2", 2)},
        {"trailing garbage", R"({"type":"ping","ref":3}})", refused("bad_json", "/", 3)},
        {"trailing comma", R"({"type":"ping","ref":4,})", refused("bad_json", "/", 4)},
        {"single quotes", R"({'type':'ping','ref':5})", refused("bad_json", "/")},
        {"two messages in one frame", R"({"type":"ping","ref":6} {"type":"ping","ref":7})",
         refused("bad_json", "/", 6)},
        {"NUL byte", "\0"s, refused("bad_json", "/")},
        {"invalid UTF-8", "{\"type\":\"hello\",\"name\":\"\xff\xfe\"}", closed_with{1007}},
        {"unescaped control character", "{\"type\":\"hello\",\"name\":\"a\nb\"}",
         refused("bad_json", "/name")},
        {"comment", R"({"type":"ping", /* hi */ "ref":8})", refused("bad_json", "/")},
        // The parser reads ref 0 and then fails on "07" or "x10": the ref came before the fault.
        {"leading zero", R"({"type":"ping","ref":007})", refused("bad_json", "/", 0)},
        {"hex number", R"({"type":"ping","ref":0x10})", refused("bad_json", "/", 0)},

        // NaN and infinity, spelled every way a lenient parser might take them.
        {"NaN", spawn_at(10, "[NaN,0,0]"), refused("bad_json", "/body/position/0", 10)},
        {"nan", spawn_at(11, "[nan,0,0]"), refused("bad_json", "/body/position/0", 11)},
        {"Infinity", spawn_at(12, "[Infinity,0,0]"), refused("bad_json", "/body/position/0", 12)},
        {"-Infinity", spawn_at(13, "[-Infinity,0,0]"), refused("bad_json", "/body/position/0", 13)},
        {"inf", R"({"type":"impulse","ref":14,"id":1,"impulse":[0,0,inf]})",
         refused("bad_json", "/impulse/2", 14)},
        {"1e999", spawn_at(15, "[1e999,0,0]"), refused("not_finite", "/body/position/0", 15)},
        {"-1e999", spawn_at(16, "[0,-1e999,0]"), refused("not_finite", "/body/position/1", 16)},
        {"1e999 as a mass", spawn_at(17, "[1,1,1]", R"("radius":0.1,"mass":1e999)"),
         refused("not_finite", "/body/mass", 17)},
        {"\"NaN\" as a string", spawn_at(18, "[1,1,1]", R"("radius":"NaN","mass":1)"),
         refused("wrong_type", "/body/radius", 18)},
        {"\"Infinity\" as a string", R"({"type":"impulse","ref":19,"id":1,"impulse":[0,"Infinity",0]})",
         refused("wrong_type", "/impulse/1", 19)},

        // Numbers that parse, but put a body where none can be or make no body at all.
        {"1e308 position", spawn_at(20, "[1e308,0,0]"), refused("outside_world", "/body/position", 20)},
        {"-1e308 position", spawn_at(21, "[0,0,-1e308]", R"("radius":0,"mass":1)"),
         refused("outside_world", "/body/position", 21)},
        {"1e308 radius", spawn_at(22, "[0,5,0]", R"("radius":1e308,"mass":1)"),
         refused("overlaps_wall", "/body/position", 22)},
        {"negative radius", spawn_at(23, "[1,1,1]", R"("radius":-1,"mass":1)"),
         refused("bad_value", "/body/radius", 23)},
        {"zero mass", spawn_at(24, "[1,1,1]", R"("radius":0.1,"mass":0)"), refused("bad_value", "/body/mass", 24)},
        {"negative mass", spawn_at(25, "[1,1,1]", R"("radius":0.1,"mass":-2)"), refused("bad_value", "/body/mass", 25)},
        {"zero density", spawn_at(26, "[1,1,1]", R"("radius":0.1,"density":0)"),
         refused("bad_value", "/body/density", 26)},
        {"density of a point mass", spawn_at(27, "[1,1,1]", R"("radius":0,"density":1000)"),
         refused("bad_value", "/body/density", 27)},
        {"mass and density", spawn_at(28, "[1,1,1]", R"("radius":0.1,"mass":1,"density":1000)"),
         refused("bad_value", "/body", 28)},
        {"neither mass nor density", spawn_at(29, "[1,1,1]", R"("radius":0.1)"), refused("missing_field", "/body", 29)},
        {"mass too small to invert", spawn_at(30, "[1,1,1]", R"("radius":0.1,"mass":1e-320)"),
         refused("bad_value", "/body", 30)},
        {"density whose mass overflows", spawn_at(31, "[1,1,1]", R"("radius":1,"density":1e308)"),
         refused("bad_value", "/body", 31)},
        // Found as the message is read, before the walls are looked at: 1e200 m would
        // otherwise be overlaps_wall at the tick.
        {"radius whose mass overflows", spawn_at(34, "[1,1,1]", R"("radius":1e200,"density":1000)"),
         refused("bad_value", "/body", 34)},
        {"ref of -0", R"({"type":"ping","ref":-0})", answered_with{"pong", 0}},
        {"ref of -0.0", R"({"type":"ping","ref":-0.0})", answered_with{"pong", 0}},
        {"ref of -1e-300", R"({"type":"ping","ref":-1e-300})", refused("bad_value", "/ref")},
        {"impulse to an infinite speed",
         R"({"type":"impulse","ref":32,"id":)" + std::to_string(light_body) + R"(,"impulse":[1e305,0,0]})",
         refused("bad_value", "/impulse", 32)},
        {"spawn at an infinite speed after one tick", spawn_at(33, "[1,1,1]", R"("radius":0.1,"mass":1,"velocity":[1.7e308,0,0])"),
         refused("bad_value", "/body/velocity", 33)},

        // Wrong types and missing fields.
        {"ref as a string", R"({"type":"ping","ref":"one"})", refused("wrong_type", "/ref")},
        {"ref as null", R"({"type":"ping","ref":null})", refused("wrong_type", "/ref")},
        {"position as a string", spawn_at(40, R"("0,0,0")"), refused("wrong_type", "/body/position", 40)},
        {"position of two numbers", spawn_at(41, "[0,0]"), refused("bad_value", "/body/position", 41)},
        {"position of four numbers", spawn_at(42, "[0,0,0,0]"), refused("bad_value", "/body/position", 42)},
        {"null in a vector", spawn_at(43, "[null,0,0]"), refused("wrong_type", "/body/position/0", 43)},
        {"boolean in a vector", spawn_at(44, "[1,1,1]", R"("radius":0.1,"mass":1,"velocity":[true,0,0])"),
         refused("wrong_type", "/body/velocity/0", 44)},
        {"body as an array", spawn(45, "[]"), refused("wrong_type", "/body", 45)},
        {"body missing", R"({"type":"spawn","ref":46})", refused("missing_field", "/body", 46)},
        {"position missing", spawn(47, R"({"radius":0.1,"mass":1})"), refused("missing_field", "/body/position", 47)},
        {"impulse without id", R"({"type":"impulse","ref":48,"impulse":[1,0,0]})", refused("missing_field", "/id", 48)},
        {"remove without ref", R"({"type":"remove","id":1})", refused("missing_field", "/ref")},
        {"name as a number", R"({"type":"hello","name":7})", refused("wrong_type", "/name")},
        // A player's name is shown to every other player of the room.
        {"name of 65 bytes", R"({"type":"hello","name":")" + std::string(65, 'n') + R"("})", refused("bad_value", "/name")},
        {"name with a newline", R"({"type":"hello","name":"ann\nadmin: yes"})", refused("bad_value", "/name")},
        {"name with an escape", R"({"type":"hello","name":"\u001b[31mred"})", refused("bad_value", "/name")},
        {"empty name", R"({"type":"hello","name":""})", refused("bad_value", "/name")},

        // Huge arrays and deep nesting. Nothing may nest deeper than 32 levels: deeper text
        // is refused before it becomes a document (a deep value copied inside the parser
        // once overflowed a server thread's stack), naming where the 33rd level starts.
        {"position of 20000 numbers", spawn_at(50, numbers(20000)), refused("bad_value", "/body/position", 50)},
        {"impulse of 20000 numbers", R"({"type":"impulse","ref":51,"id":1,"impulse":)" + numbers(20000) + "}",
         refused("bad_value", "/impulse", 51)},
        {"100000 open brackets", std::string(100000, '['), refused("bad_message", repeated("/0", 32))},
        {"50000 nested arrays", repeated("[", 50000) + repeated("]", 50000),
         refused("bad_message", repeated("/0", 32))},
        {"deep nesting in an unknown field",
         R"({"type":"ping","ref":52,"extra":)" + repeated(R"({"a":)", 20000) + "1" + repeated("}", 20000) + "}",
         refused("bad_message", "/extra" + repeated("/a", 31), 52)},
        {"deep nesting where a vector belongs", spawn_at(53, repeated("[", 20000) + repeated("]", 20000)),
         refused("bad_message", "/body/position" + repeated("/0", 30), 53)},
        {"brackets in a string do not nest",
         R"({"type":"ping","ref":54,"extra":")" + std::string(1000, '[') + R"("})", answered_with{"pong", 54}},

        // Frames that are not one JSON object of a known type.
        {"binary frame", R"({"type":"ping","ref":60})", refused("bad_json", "/"), true},
        {"oversized frame", std::string(frame_limit + 1, ' '), closed_with{1009}},
        // Still arriving when the server closes: its rest is drained, not reset (1006).
        {"oversized frame of 4 MB", std::string(4 << 20, ' '), closed_with{1009}},
        {"unknown type", R"({"type":"teleport","ref":61})", refused("unknown_type", "/type", 61)},
        {"empty type", R"({"type":"","ref":62})", refused("unknown_type", "/type", 62)},
        {"type in capitals", R"({"type":"PING","ref":63})", refused("unknown_type", "/type", 63)},
        {"a server message sent back", R"({"type":"welcome","protocol":1})", refused("unknown_type", "/type")},
        {"type as a number", R"({"type":42,"ref":64})", refused("bad_message", "/type", 64)},
        {"no type", R"({"ref":65})", refused("bad_message", "/type", 65)},
        {"an array", R"([{"type":"ping","ref":66}])", refused("bad_message", "/")},
        {"a string", R"("ping")", refused("bad_message", "/")},
        {"null", "null", refused("bad_message", "/")},

        // Duplicated keys (the last one counts, as in JSON.parse) and extra fields (ignored).
        {"duplicated ref", R"({"type":"ping","ref":70,"ref":71})", answered_with{"pong", 71}},
        {"duplicated type", R"({"type":"spawn","type":"ping","ref":72})", answered_with{"pong", 72}},
        {"extra fields", R"({"type":"ping","ref":73,"colour":"red","body":{"mass":-1}})", answered_with{"pong", 73}},
        {"byte order mark", "\xEF\xBB\xBF" R"({"type":"ping","ref":74})", answered_with{"pong", 74}},

        // hello.
        {"hello, protocol 1", R"({"type":"hello","protocol":1,"name":"polite"})", no_answer{}},
        {"hello, protocol 2", R"({"type":"hello","protocol":2})", refused("unsupported_protocol", "/protocol")},
        {"hello, protocol 0", R"({"type":"hello","protocol":0})", refused("unsupported_protocol", "/protocol")},
        {"hello, protocol \"1\"", R"({"type":"hello","protocol":"1"})", refused("wrong_type", "/protocol")},
        {"hello, protocol 1.5", R"({"type":"hello","protocol":1.5})", refused("bad_value", "/protocol")},
        {"hello, protocol 1e300", R"({"type":"hello","protocol":1e300})", refused("bad_value", "/protocol")},

        // hello.snapshots: the form and rate a client asks for.
        {"snapshots compact", R"({"type":"hello","snapshots":{"form":"compact"}})", welcomed_with{"compact", 30.0}},
        {"snapshots full at 10 Hz", R"({"type":"hello","snapshots":{"form":"full","rate":10}})", welcomed_with{"full", 10.0}},
        {"snapshots at 7 Hz: every 5th", R"({"type":"hello","snapshots":{"form":"compact","rate":7}})",
         welcomed_with{"compact", 6.0}},
        {"snapshots faster than the room", R"({"type":"hello","snapshots":{"rate":1e300}})", welcomed_with{"full", 30.0}},
        {"snapshots at 1e-300 Hz: once a minute", R"({"type":"hello","snapshots":{"form":"compact","rate":1e-300}})",
         welcomed_with{"compact", 30.0 / 1800.0}},
        {"snapshots as a string", R"({"type":"hello","snapshots":"compact"})", refused("wrong_type", "/snapshots")},
        {"snapshots as an array", R"({"type":"hello","snapshots":["compact"]})", refused("wrong_type", "/snapshots")},
        {"snapshots of an unknown form", R"({"type":"hello","snapshots":{"form":"delta"}})",
         refused("bad_value", "/snapshots/form")},
        {"snapshots form as a number", R"({"type":"hello","snapshots":{"form":2}})", refused("wrong_type", "/snapshots/form")},
        {"snapshots form null", R"({"type":"hello","snapshots":{"form":null}})", refused("wrong_type", "/snapshots/form")},
        {"snapshots rate 0", R"({"type":"hello","snapshots":{"rate":0}})", refused("bad_value", "/snapshots/rate")},
        {"snapshots rate -30", R"({"type":"hello","snapshots":{"rate":-30}})", refused("bad_value", "/snapshots/rate")},
        {"snapshots rate as a string", R"({"type":"hello","snapshots":{"rate":"fast"}})",
         refused("wrong_type", "/snapshots/rate")},
        {"snapshots rate 1e999", R"({"type":"hello","snapshots":{"rate":1e999}})", refused("not_finite", "/snapshots/rate")},

        // hello.events: sensor events a client asks for (the lab's one sensor is "gate").
        {"events of the lab's sensor", R"({"type":"hello","events":{"sensors":["gate"],"kinds":["left"]}})", no_answer{}},
        {"events, all of them", R"({"type":"hello","events":true})", no_answer{}},
        {"events off", R"({"type":"hello","events":false})", no_answer{}},
        {"events of an unknown sensor", R"({"type":"hello","events":{"sensors":["gate","goal"]}})",
         refused("bad_value", "/events/sensors/1")},
        {"events as a string", R"({"type":"hello","events":"all"})", refused("wrong_type", "/events")},
        {"events null", R"({"type":"hello","events":null})", refused("wrong_type", "/events")},
        {"events sensors as a string", R"({"type":"hello","events":{"sensors":"gate"}})",
         refused("wrong_type", "/events/sensors")},
        {"events with an empty tag list", R"({"type":"hello","events":{"tags":[]}})", refused("bad_value", "/events/tags")},
        {"events of an unknown kind", R"({"type":"hello","events":{"kinds":["stayed"]}})",
         refused("bad_value", "/events/kinds/0")},
        {"events of a kind cased otherwise", R"({"type":"hello","events":{"kinds":["contact","Contact"]}})",
         refused("bad_value", "/events/kinds/1")},
        {"events sensor name with a newline", R"({"type":"hello","events":{"sensors":["ga\nte"]}})",
         refused("bad_value", "/events/sensors/0")},
        {"events with 65 sensors", R"({"type":"hello","events":{"sensors":)" + [] {
             std::string list = "[\"gate\"";
             for (int i = 1; i < 65; ++i)
                 list += ",\"gate\"";
             return list + "]";
         }() + "}}",
         refused("bad_value", "/events/sensors")},

        // Ids and refs that are not whole numbers below 2^53, and bodies that do not exist.
        {"id as a string", R"({"type":"impulse","ref":80,"id":"1","impulse":[0,0,1]})", refused("wrong_type", "/id", 80)},
        {"fractional id", R"({"type":"remove","ref":81,"id":1.5})", refused("bad_value", "/id", 81)},
        {"negative id", R"({"type":"remove","ref":82,"id":-1})", refused("bad_value", "/id", 82)},
        {"id of 2^53", R"({"type":"remove","ref":83,"id":9007199254740992})", refused("bad_value", "/id", 83)},
        {"id beyond 2^64", R"({"type":"remove","ref":84,"id":18446744073709551616})", refused("bad_value", "/id", 84)},
        {"id 1e20", R"({"type":"remove","ref":85,"id":1e20})", refused("bad_value", "/id", 85)},
        {"ref of 2^53", R"({"type":"ping","ref":9007199254740992})", refused("bad_value", "/ref")},
        {"negative ref", R"({"type":"ping","ref":-1})", refused("bad_value", "/ref")},
        {"largest id, no such body", R"({"type":"remove","ref":86,"id":9007199254740991})",
         refused("unknown_body", "/id", 86)},
        {"impulse on an unknown body", R"({"type":"impulse","ref":87,"id":424242,"impulse":[0,0,1]})",
         refused("unknown_body", "/id", 87)},
        {"remove of an unknown body", R"({"type":"remove","ref":88,"id":424242})", refused("unknown_body", "/id", 88)},
        {"id 0", R"({"type":"impulse","ref":89,"id":0,"impulse":[0,0,1]})", refused("unknown_body", "/id", 89)},

        // Admin commands and admin tokens from a client that is not an admin (the lab has no
        // admin token, so nobody is), and admin commands that are malformed.
        {"pause from a non-admin", R"({"type":"pause","ref":100})", refused("forbidden", "/type", 100)},
        {"resume from a non-admin", R"({"type":"resume","ref":101})", refused("forbidden", "/type", 101)},
        {"reset from a non-admin", R"({"type":"reset","ref":102})", refused("forbidden", "/type", 102)},
        {"load_scene from a non-admin", R"({"type":"load_scene","ref":103,"scene":{"name":"x","dt":1}})",
         refused("forbidden", "/type", 103)},
        {"remove of the scene's body by a non-admin", R"({"type":"remove","ref":104,"id":1})",
         refused("forbidden", "/id", 104)},
        {"hello with an admin token, none configured", R"({"type":"hello","admin_token":"guess"})",
         refused("forbidden", "/admin_token")},
        {"hello with an admin token of 60000 bytes",
         R"({"type":"hello","admin_token":")" + std::string(60000, 'a') + R"("})", refused("forbidden", "/admin_token")},
        {"admin token as a number", R"({"type":"hello","admin_token":1234})", refused("wrong_type", "/admin_token")},
        // Resume tokens (the lab keeps no player for a resume: its grace is 0). A token is a
        // secret: the refusals say its length at most, never its text.
        {"resume token, none kept", R"({"type":"hello","resume":"0123456789abcdef0123456789abcdef"})",
         refused("bad_resume", "/resume")},
        {"resume token of 129 bytes", R"({"type":"hello","resume":")" + std::string(129, 'f') + R"("})",
         refused("bad_value", "/resume")},
        {"resume token of 60000 bytes", R"({"type":"hello","resume":")" + std::string(60000, 'f') + R"("})",
         refused("bad_value", "/resume")},
        {"empty resume token", R"({"type":"hello","resume":""})", refused("bad_value", "/resume")},
        {"resume token as a number", R"({"type":"hello","resume":1234})", refused("wrong_type", "/resume")},
        {"resume token as an object", R"({"type":"hello","resume":{"token":"x"}})", refused("wrong_type", "/resume")},
        {"load_scene with a file name", R"({"type":"load_scene","ref":105,"scene":"arena.json"})",
         refused("wrong_type", "/scene", 105)},
        {"load_scene without a scene", R"({"type":"load_scene","ref":106})", refused("missing_field", "/scene", 106)},
        {"pause without a ref", R"({"type":"pause"})", refused("missing_field", "/ref")},

        // spawn.body.tag: shown to every client with the body, so short and printable.
        {"tag of 33 bytes", spawn_at(120, "[1,1,1]", R"("radius":0.1,"mass":1,"tag":")" + std::string(33, 't') + "\""),
         refused("bad_value", "/body/tag", 120)},
        {"tag of 60000 bytes", spawn_at(121, "[1,1,1]", R"("radius":0.1,"mass":1,"tag":")" + std::string(60000, 't') + "\""),
         refused("bad_value", "/body/tag", 121)},
        {"empty tag", spawn_at(122, "[1,1,1]", R"("radius":0.1,"mass":1,"tag":"")"), refused("bad_value", "/body/tag", 122)},
        {"tag with a newline", spawn_at(123, "[1,1,1]", R"("radius":0.1,"mass":1,"tag":"a\nb")"),
         refused("bad_value", "/body/tag", 123)},
        {"tag with an escape", spawn_at(124, "[1,1,1]", R"("radius":0.1,"mass":1,"tag":"\u001b[31mred")"),
         refused("bad_value", "/body/tag", 124)},
        {"tag with a NUL", spawn_at(125, "[1,1,1]", R"("radius":0.1,"mass":1,"tag":"a\u0000b")"),
         refused("bad_value", "/body/tag", 125)},
        {"tag as a number", spawn_at(126, "[1,1,1]", R"("radius":0.1,"mass":1,"tag":7)"), refused("wrong_type", "/body/tag", 126)},
        {"tag as null", spawn_at(127, "[1,1,1]", R"("radius":0.1,"mass":1,"tag":null)"), refused("wrong_type", "/body/tag", 127)},
        {"tag as an array", spawn_at(128, "[1,1,1]", R"("radius":0.1,"mass":1,"tag":["a"])"), refused("wrong_type", "/body/tag", 128)},

        // spawn.body.static: an obstacle only an admin may place, and it does not move.
        {"static from a non-admin", spawn_at(130, "[1,1,1]", R"("radius":0.1,"mass":1,"static":true)"),
         refused("forbidden", "/body/static", 130)},
        {"static and moving", spawn_at(131, "[1,1,1]", R"("radius":0.1,"mass":1,"static":true,"velocity":[1,0,0])"),
         refused("bad_value", "/body/velocity", 131)},
        {"static as a string", spawn_at(132, "[1,1,1]", R"("radius":0.1,"mass":1,"static":"true")"),
         refused("wrong_type", "/body/static", 132)},
        {"static as null", spawn_at(133, "[1,1,1]", R"("radius":0.1,"mass":1,"static":null)"),
         refused("wrong_type", "/body/static", 133)},
        {"static as 1", spawn_at(134, "[1,1,1]", R"("radius":0.1,"mass":1,"static":1)"), refused("wrong_type", "/body/static", 134)},

        // set: a body's new position and velocity, each checked as a spawn's would be.
        {"set without position or velocity", R"({"type":"set","ref":140,"id":1})", refused("missing_field", "/", 140)},
        {"set with both null", R"({"type":"set","ref":141,"id":1,"position":null,"velocity":null})",
         refused("wrong_type", "/position", 141)},
        {"set without id", R"({"type":"set","ref":142,"velocity":[0,0,0]})", refused("missing_field", "/id", 142)},
        {"set of an unknown body", R"({"type":"set","ref":143,"id":424242,"velocity":[0,0,0]})",
         refused("unknown_body", "/id", 143)},
        {"set of id 2^53", R"({"type":"set","ref":144,"id":9007199254740992,"velocity":[0,0,0]})",
         refused("bad_value", "/id", 144)},
        {"set position 1e999", R"({"type":"set","ref":145,"id":1,"position":[1e999,0,0]})",
         refused("not_finite", "/position/0", 145)},
        {"set position NaN", R"({"type":"set","ref":146,"id":1,"position":[NaN,0,0]})", refused("bad_json", "/position/0", 146)},
        {"set position 1e308", R"({"type":"set","ref":147,"id":1,"position":[1e308,0,0]})",
         refused("outside_world", "/position", 147)},
        {"set a point mass behind a wall", R"({"type":"set","ref":148,"id":)" + std::to_string(light_body) +
                                               R"(,"position":[0,0,-10.5]})",
         refused("outside_world", "/position", 148)},
        {"set a sphere across a wall", R"({"type":"set","ref":149,"id":1,"position":[9.8,0,0]})",
         refused("overlaps_wall", "/position", 149)},
        {"set position of 20000 numbers", R"({"type":"set","ref":150,"id":1,"position":)" + numbers(20000) + "}",
         refused("bad_value", "/position", 150)},
        {"set position as a string", R"({"type":"set","ref":151,"id":1,"position":"0,0,0"})",
         refused("wrong_type", "/position", 151)},
        {"set velocity at the speed of light", R"({"type":"set","ref":152,"id":1,"velocity":[299792458,0,0]})",
         refused("bad_value", "/velocity", 152)},
        {"set velocity 1.7e308", R"({"type":"set","ref":153,"id":1,"velocity":[1.7e308,1.7e308,0]})",
         refused("bad_value", "/velocity", 153)},
        {"set velocity -1e999", R"({"type":"set","ref":154,"id":1,"velocity":[0,-1e999,0]})",
         refused("not_finite", "/velocity/1", 154)},
        {"set velocity of two numbers", R"({"type":"set","ref":155,"id":1,"velocity":[0,0]})",
         refused("bad_value", "/velocity", 155)},
        {"set deep nesting where a vector belongs",
         R"({"type":"set","ref":156,"id":1,"position":)" + repeated("[", 20000) + repeated("]", 20000) + "}",
         refused("bad_message", "/position" + repeated("/0", 31), 156)},
        {"set a body where it is", R"({"type":"set","ref":157,"id":1,"position":[0,0,0],"velocity":[0,0,0]})",
         answered_with{"ack", 157}},

        // interest: what of the world a client is sent. Checked as the message is read, but
        // for the body an `around` follows, which the room looks for at the tick.
        {"interest in a box", R"({"type":"interest","ref":160,"box":{"min":[-1,-1,-1],"max":[1,1,1]},"tags":["red"]})",
         answered_with{"ack", 160}},
        {"interest around a body", R"({"type":"interest","ref":161,"around":{"body":1,"radius":2}})",
         answered_with{"ack", 161}},
        {"interest cleared", R"({"type":"interest","ref":162})", answered_with{"ack", 162}},
        {"interest box a point", R"({"type":"interest","ref":163,"box":{"min":[1,1,1],"max":[1,1,1]}})",
         answered_with{"ack", 163}},
        {"interest box of 1e308", R"({"type":"interest","ref":164,"box":{"min":[-1e308,-1e308,-1e308],"max":[1e308,1e308,1e308]}})",
         answered_with{"ack", 164}},
        {"interest box min above max", R"({"type":"interest","ref":165,"box":{"min":[0,2,0],"max":[1,1,1]}})",
         refused("bad_value", "/box/max/1", 165)},
        {"interest box min 1e999", R"({"type":"interest","ref":166,"box":{"min":[1e999,0,0],"max":[1,1,1]}})",
         refused("not_finite", "/box/min/0", 166)},
        {"interest box max NaN", R"({"type":"interest","ref":167,"box":{"min":[0,0,0],"max":[NaN,1,1]}})",
         refused("bad_json", "/box/max/0", 167)},
        {"interest box without max", R"({"type":"interest","ref":168,"box":{"min":[0,0,0]}})",
         refused("missing_field", "/box/max", 168)},
        {"interest box as an array", R"({"type":"interest","ref":169,"box":[0,0,0,1,1,1]})",
         refused("wrong_type", "/box", 169)},
        {"interest box min of two numbers", R"({"type":"interest","ref":170,"box":{"min":[0,0],"max":[1,1,1]}})",
         refused("bad_value", "/box/min", 170)},
        {"interest box min of 20000 numbers", R"({"type":"interest","ref":171,"box":{"min":)" + numbers(20000) + R"(,"max":[1,1,1]}})",
         refused("bad_value", "/box/min", 171)},
        {"interest box min as a string", R"({"type":"interest","ref":172,"box":{"min":"0,0,0","max":[1,1,1]}})",
         refused("wrong_type", "/box/min", 172)},
        {"interest radius 0", R"({"type":"interest","ref":173,"around":{"body":1,"radius":0}})",
         refused("bad_value", "/around/radius", 173)},
        {"interest radius -1", R"({"type":"interest","ref":174,"around":{"body":1,"radius":-1}})",
         refused("bad_value", "/around/radius", 174)},
        {"interest radius 1e16", R"({"type":"interest","ref":175,"around":{"body":1,"radius":1e16}})",
         refused("bad_value", "/around/radius", 175)},
        {"interest radius 1e999", R"({"type":"interest","ref":176,"around":{"body":1,"radius":1e999}})",
         refused("not_finite", "/around/radius", 176)},
        {"interest radius as a string", R"({"type":"interest","ref":177,"around":{"body":1,"radius":"2"}})",
         refused("wrong_type", "/around/radius", 177)},
        {"interest around without a radius", R"({"type":"interest","ref":178,"around":{"body":1}})",
         refused("missing_field", "/around/radius", 178)},
        {"interest around an unknown body", R"({"type":"interest","ref":179,"around":{"body":424242,"radius":2}})",
         refused("unknown_body", "/around/body", 179)},
        {"interest around body 0", R"({"type":"interest","ref":180,"around":{"body":0,"radius":2}})",
         refused("unknown_body", "/around/body", 180)},
        {"interest around body -1", R"({"type":"interest","ref":181,"around":{"body":-1,"radius":2}})",
         refused("bad_value", "/around/body", 181)},
        {"interest around body 2^53", R"({"type":"interest","ref":182,"around":{"body":9007199254740992,"radius":2}})",
         refused("bad_value", "/around/body", 182)},
        {"interest box and around", R"({"type":"interest","ref":183,"box":{"min":[0,0,0],"max":[1,1,1]},"around":{"body":1,"radius":2}})",
         refused("bad_value", "/around", 183)},
        {"interest with no tags", R"({"type":"interest","ref":184,"tags":[]})", refused("bad_value", "/tags", 184)},
        {"interest with 65 tags", R"({"type":"interest","ref":185,"tags":)" + [] {
             std::string list = "[\"t0\"";
             for (int i = 1; i < 65; ++i)
                 list += ",\"t" + std::to_string(i) + "\"";
             return list + "]";
         }() + "}",
         refused("bad_value", "/tags", 185)},
        {"interest tag of 33 bytes", R"({"type":"interest","ref":186,"tags":["red",")" + std::string(33, 't') + R"("]})",
         refused("bad_value", "/tags/1", 186)},
        {"interest empty tag", R"({"type":"interest","ref":187,"tags":[""]})", refused("bad_value", "/tags/0", 187)},
        {"interest tag with a newline", R"({"type":"interest","ref":188,"tags":["a\nb"]})", refused("bad_value", "/tags/0", 188)},
        {"interest tags as a string", R"({"type":"interest","ref":189,"tags":"red"})", refused("wrong_type", "/tags", 189)},
        {"interest tag as a number", R"({"type":"interest","ref":190,"tags":[7]})", refused("wrong_type", "/tags/0", 190)},
        {"interest without a ref", R"({"type":"interest","box":{"min":[0,0,0],"max":[1,1,1]}})",
         refused("missing_field", "/ref")},
        {"hello interest", R"({"type":"hello","interest":{"around":{"body":1,"radius":3},"tags":["red","red"]}})", no_answer{}},
        {"hello interest cleared", R"({"type":"hello","interest":{}})", no_answer{}},
        {"hello interest as a string", R"({"type":"hello","interest":"near"})", refused("wrong_type", "/interest")},
        {"hello interest null", R"({"type":"hello","interest":null})", refused("wrong_type", "/interest")},
        {"hello interest box min above max", R"({"type":"hello","interest":{"box":{"min":[0,0,5],"max":[1,1,1]}}})",
         refused("bad_value", "/interest/box/max/2")},
        {"hello interest around an unknown body", R"({"type":"hello","interest":{"around":{"body":424242,"radius":2}}})",
         refused("unknown_body", "/interest/around/body")},
        {"hello interest with no tags", R"({"type":"hello","interest":{"tags":[]}})", refused("bad_value", "/interest/tags")},

        // A flood: the burst passes, every command beyond it is refused.
        {"command flood", R"({"type":"ping","ref":90})", rate_limited_after{command_burst}, false, command_burst + 10},
    };
}

// The harness -----------------------------------------------------------------------------

/// A client whose every message must match its schema.
class checked_client
{
public:
    checked_client(std::uint16_t port, std::string const& target) : ws_(port, target) {}

    /// The next message other than a snapshot; nullopt once the connection closed.
    std::optional<json> next_answer(std::chrono::milliseconds timeout = std::chrono::seconds(10))
    {
        auto const deadline = ws_client::clock::now() + timeout;
        while (ws_client::clock::now() < deadline) {
            auto const text = ws_.read(std::chrono::duration_cast<std::chrono::milliseconds>(
                deadline - ws_client::clock::now()));
            if (!text)
                break;
            json message = checked(*text);
            if (message.at("type") != "snapshot")
                return message;
        }
        if (!ws_.closed())
            throw std::runtime_error("no answer in time");
        return std::nullopt;
    }

    /// The first snapshot with tick >= `tick`.
    json snapshot_at_or_after(std::uint64_t tick)
    {
        for (;;) {
            auto const text = ws_.read();
            if (!text)
                throw std::runtime_error(ws_.closed() ? "the observer was disconnected" : "no snapshot in time");
            json message = checked(*text);
            if (message.at("type") == "snapshot" && message.at("tick").get<std::uint64_t>() >= tick)
                return message;
        }
    }

    ws_client& raw() { return ws_; }

private:
    static json checked(std::string const& text)
    {
        json message = json::parse(text);
        EXPECT_EQ(schemas().refusal(message), "") << text.substr(0, 300);
        return message;
    }

    ws_client ws_;
};

json lab_scene()
{
    return {{"name", "lab"},
            {"dt", 1.0 / 64.0},
            {"integrator", "semi_implicit_euler"},
            {"collisions", {{"mode", "off"}}},
            {"box", {{"min", {-10, -10, -10}}, {"max", {10, 10, 10}}}},
            {"sensors", json::array({{{"name", "gate"}, {"box", {{"min", {5, -1, -1}}, {"max", {6, 1, 1}}}}}})},
            {"bodies", json::array({{{"position", {0, 0, 0}}, {"radius", 0.5}, {"mass", 2.0}},
                                    {{"position", {3, 0, 0}}, {"radius", 0.0}, {"mass", 1e-9}}})}};
}

server_options lab_options()
{
    fs::path const file =
        test_support::write_scene(fs::path(testing::TempDir()) / "kugel_hostile_input_lab.json", lab_scene());
    server_options o;
    o.rooms.push_back({"lab", file});
    o.client.max_message_bytes = frame_limit;
    // The burst, then one command per 1000 s: no token accrues while the test runs, so the
    // flood row sees exactly the burst pass; every other row uses at most two commands.
    o.client.command_burst = command_burst;
    o.client.commands_per_second = 0.001;
    return o;
}

/// Sends the row and checks its answer; returns whether the connection is still open.
bool send_and_check(checked_client& hostile, hostile_case const& c)
{
    ws_client& ws = hostile.raw();
    for (int i = 0; i < c.repeat; ++i) {
        if (c.binary)
            ws.send_binary(c.frame);
        else
            ws.send(c.frame);
    }
    return std::visit(
        [&](auto const& expected) -> bool {
            using E = std::decay_t<decltype(expected)>;
            if constexpr (std::is_same_v<E, refused_with>) {
                auto const answer = hostile.next_answer();
                if (!answer) {
                    ADD_FAILURE() << "closed with " << ws.close_code() << " instead of an error";
                    return false;
                }
                EXPECT_EQ(answer->at("type"), "error") << answer->dump();
                EXPECT_EQ(answer->value("code", ""), expected.code) << answer->dump();
                std::string const message = answer->value("message", "");
                EXPECT_EQ(message.substr(0, expected.pointer.size() + 2), expected.pointer + ": ")
                    << message;
                if (expected.ref)
                    EXPECT_EQ(answer->value("ref", json()), *expected.ref) << answer->dump();
                else
                    EXPECT_FALSE(answer->contains("ref")) << answer->dump();
                return true;
            } else if constexpr (std::is_same_v<E, closed_with>) {
                while (auto const answer = hostile.next_answer())
                    ADD_FAILURE() << "an answer before the close: " << answer->dump();
                EXPECT_EQ(ws.close_code(), expected.code);
                return false;
            } else if constexpr (std::is_same_v<E, answered_with>) {
                auto const answer = hostile.next_answer();
                if (!answer) {
                    ADD_FAILURE() << "closed with " << ws.close_code();
                    return false;
                }
                EXPECT_EQ(answer->at("type"), expected.type) << answer->dump();
                EXPECT_EQ(answer->value("ref", json()), expected.ref) << answer->dump();
                return true;
            } else if constexpr (std::is_same_v<E, no_answer>) {
                return true; // the ping that follows must be the next answer
            } else if constexpr (std::is_same_v<E, welcomed_with>) {
                auto const answer = hostile.next_answer();
                if (!answer) {
                    ADD_FAILURE() << "closed with " << ws.close_code();
                    return false;
                }
                EXPECT_EQ(answer->at("type"), "welcome") << answer->dump();
                json const stream = answer->value("snapshots", json::object());
                EXPECT_EQ(stream.value("form", ""), expected.form) << answer->dump();
                EXPECT_DOUBLE_EQ(stream.value("rate", 0.0), expected.rate) << answer->dump();
                EXPECT_GT(stream.value("position_quantum", 0.0), 0.0) << answer->dump();
                return true;
            } else {
                int answered = 0;
                int limited = 0;
                for (int i = 0; i < c.repeat; ++i) {
                    auto const answer = hostile.next_answer();
                    if (!answer) {
                        ADD_FAILURE() << "closed with " << ws.close_code();
                        return false;
                    }
                    if (answer->at("type") == "pong")
                        ++answered;
                    else if (answer->value("code", "") == "rate_limited")
                        ++limited;
                    else
                        ADD_FAILURE() << "unexpected " << answer->dump();
                }
                EXPECT_EQ(answered, expected.answered);
                EXPECT_EQ(limited, c.repeat - expected.answered);
                return false; // no token left for the ping that would follow
            }
        },
        c.expected);
}

TEST(HostileInput, CatalogueHasAtLeastFortyRows)
{
    EXPECT_GE(catalogue().size(), 40U);
}

TEST(HostileInput, EachIsAnsweredAsDocumentedAndChangesNothing)
{
    test_support::in_process_server s(lab_options());
    auto const lab = s.get().find_room("lab");
    checked_client observer(s.port(), "/ws/lab");
    json last = observer.snapshot_at_or_after(1);

    std::uint64_t sync_ref = 1'000'000;
    for (hostile_case const& c : catalogue()) {
        SCOPED_TRACE(c.name);
        json const before = observer.snapshot_at_or_after(last.at("tick").get<std::uint64_t>() + 1);
        std::uint64_t const bodies_before = lab->counters().bodies.load();

        checked_client hostile(s.port(), "/ws/lab");
        auto const welcome = hostile.next_answer();
        ASSERT_TRUE(welcome && welcome->at("type") == "welcome");
        bool const still_open = send_and_check(hostile, c);

        // The world after every command sent so far had its tick: a pong carries the last
        // tick completed, and every answer above came at or before it.
        std::uint64_t settled = lab->counters().ticks.load() + 1;
        if (still_open) {
            hostile.raw().send(json{{"type", "ping"}, {"ref", ++sync_ref}});
            auto const pong = hostile.next_answer();
            ASSERT_TRUE(pong) << "closed with " << hostile.raw().close_code();
            ASSERT_EQ(pong->at("type"), "pong") << pong->dump();
            EXPECT_EQ(pong->at("ref"), sync_ref);
            settled = pong->at("tick").get<std::uint64_t>() + 1;
        }
        last = observer.snapshot_at_or_after(settled);
        EXPECT_GT(last.at("tick").get<std::uint64_t>(), before.at("tick").get<std::uint64_t>());
        EXPECT_EQ(last.at("bodies"), before.at("bodies")) << "the world changed";
        EXPECT_EQ(lab->counters().bodies.load(), bodies_before);
    }

    // Afterwards the room still takes commands from a polite client, and the observer sees them.
    checked_client polite(s.port(), "/ws/lab");
    polite.raw().send(json{{"type", "spawn"}, {"ref", 1}, {"body", {{"position", {1, 2, 3}}, {"radius", 0.1}, {"mass", 1}}}});
    auto const welcome = polite.next_answer();
    ASSERT_TRUE(welcome);
    auto const ack = polite.next_answer();
    ASSERT_TRUE(ack);
    ASSERT_EQ(ack->at("type"), "ack") << ack->dump();
    json const after = observer.snapshot_at_or_after(ack->at("tick").get<std::uint64_t>());
    EXPECT_EQ(after.at("bodies").at("id").size(), 3U);
    EXPECT_EQ(lab->counters().bodies.load(), 3U);
}

// Resume tokens that name no player this connection may become, in rooms that keep players
// for a resume: a wrong one, one of another room, one used already (replayed), one of the
// connection itself. Each is refused bad_resume, the connection stays the player it was, and
// the world is unchanged.
TEST(HostileInput, ResumeTokensThatNameNoPlayerHereAreRefusedAndChangeNothing)
{
    json scene = lab_scene();
    scene["players"] = {{"resume_grace", 600}, {"bodies_on_leave", "remove"}};
    server_options o = lab_options();
    o.rooms.clear();
    for (std::string const room : {"den", "attic"})
        o.rooms.push_back({room, test_support::write_scene(fs::path(testing::TempDir()) /
                                                               ("kugel_hostile_resume_" + room + ".json"),
                                                           scene)});
    test_support::in_process_server s(o);
    checked_client observer(s.port(), "/ws/den");
    json last = observer.snapshot_at_or_after(1);

    auto const token_of = [](json const& welcome) { return welcome.at("resume_token").get<std::string>(); };
    // A player of the attic, and a player of the den who spawns a body, drops, and is resumed
    // once (so that its first token is spent).
    checked_client attic(s.port(), "/ws/attic");
    std::string const attic_token = token_of(*attic.next_answer());
    std::string spent_token;
    std::string own_token;
    std::uint64_t spawned_at = 0;
    auto resumed = std::make_unique<checked_client>(s.port(), "/ws/den");
    {
        checked_client ann(s.port(), "/ws/den");
        spent_token = token_of(*ann.next_answer());
        ann.raw().send(json{{"type", "spawn"}, {"ref", 1}, {"body", {{"position", {1, 2, 3}}, {"radius", 0.1}, {"mass", 1}}}});
        json const ack = *ann.next_answer();
        ASSERT_EQ(ack.at("type"), "ack") << ack.dump();
        spawned_at = ack.at("tick").get<std::uint64_t>();
    }
    resumed->next_answer(); // its welcome
    resumed->raw().send(json{{"type", "hello"}, {"resume", spent_token}});
    json const welcome = *resumed->next_answer();
    ASSERT_EQ(welcome.at("type"), "welcome") << welcome.dump();
    own_token = token_of(welcome);
    last = observer.snapshot_at_or_after(spawned_at); // the world the attempts must leave alone

    struct attempt
    {
        std::string what;
        std::string token;
        std::string says;
    };
    std::vector<attempt> const attempts{
        {"a wrong token", std::string(32, '0'), "no player of this room holds this token"},
        {"a token of another room", attic_token, "no player of this room holds this token"},
        {"a replayed token", spent_token, "no player of this room holds this token"},
        {"a wrong token of the right length and alphabet", std::string(own_token.rbegin(), own_token.rend()),
         "no player of this room holds this token"},
    };
    std::uint64_t sync_ref = 1'000;
    for (attempt const& a : attempts) {
        SCOPED_TRACE(a.what);
        json const before = observer.snapshot_at_or_after(last.at("tick").get<std::uint64_t>() + 1);
        std::uint64_t const bodies_before = s.bodies("den");
        checked_client hostile(s.port(), "/ws/den");
        std::uint64_t const id = hostile.next_answer()->at("client").get<std::uint64_t>();
        hostile.raw().send(json{{"type", "hello"}, {"resume", a.token}});
        json const refusal = *hostile.next_answer();
        EXPECT_EQ(refusal.value("code", ""), "bad_resume") << refusal.dump();
        std::string const message = refusal.value("message", "");
        EXPECT_EQ(message.rfind("/resume: " + a.says, 0), 0U) << message;
        EXPECT_EQ(message.find(a.token), std::string::npos) << "the token was echoed";
        EXPECT_NE(message.find("stays player " + std::to_string(id)), std::string::npos) << message;
        hostile.raw().send(json{{"type", "ping"}, {"ref", ++sync_ref}});
        json const pong = *hostile.next_answer();
        ASSERT_EQ(pong.at("type"), "pong") << pong.dump();
        last = observer.snapshot_at_or_after(pong.at("tick").get<std::uint64_t>() + 1);
        EXPECT_EQ(last.at("bodies"), before.at("bodies")) << "the world changed";
        EXPECT_EQ(s.bodies("den"), bodies_before);
    }
    // Its own token, sent by the connection that holds it: it is that player already.
    checked_client self(s.port(), "/ws/den");
    std::string const self_token = token_of(*self.next_answer());
    self.raw().send(json{{"type", "hello"}, {"resume", self_token}});
    json const own = *self.next_answer();
    EXPECT_EQ(own.value("code", ""), "bad_resume") << own.dump();
    EXPECT_EQ(own.value("message", "").rfind("/resume: that is this connection's own token", 0), 0U) << own.dump();
}

} // namespace
} // namespace kugel::server
