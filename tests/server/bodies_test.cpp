// Owners and tags, permissions, set state and static spawns, over real WebSocket connections:
// a spawn's or a scene body's tag in both snapshot forms, the scene's push and remove rules
// (told in the welcome, refused with `forbidden` naming the rule), `set` and each of its
// refusals, and static bodies only admins may spawn. Every message read is checked against
// its schema, and every refusal is checked to change nothing.

#include "server.hpp"

#include "protocol/codec.hpp"
#include "protocol/compact.hpp"
#include "protocol/message_schemas.hpp"
#include "support/in_process_server.hpp"
#include "support/scene_files.hpp"
#include "support/ws_client.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace kugel::server {
namespace {

using nlohmann::json;
using protocol::testing::schemas;
using test_support::index_of;
using test_support::ws_client;

constexpr char const* admin_token = "yard-keeper";

/// Spheres collide; no forces, so nothing moves unless a command moves it. Body 1 is a 2 kg
/// sphere at the origin tagged "post", body 2 an untagged one at x = 3; a box obstacle
/// around [5, 5, 0]; walls at ±10 m.
json yard(json permissions = nullptr)
{
    json scene = {{"name", "yard"},
                  {"dt", 1.0 / 64.0},
                  {"integrator", "semi_implicit_euler"},
                  {"collisions", {{"mode", "discrete"}}},
                  {"box", {{"min", {-10, -10, -10}}, {"max", {10, 10, 10}}}},
                  {"obstacles", json::array({{{"centre", {5, 5, 0}}, {"half_extents", {1, 1, 1}}}})},
                  {"bodies", json::array({{{"position", {0, 0, 0}}, {"radius", 0.5}, {"mass", 2.0}, {"tag", "post"}},
                                          {{"position", {3, 0, 0}}, {"radius", 0.5}, {"mass", 2.0}}})}};
    if (!permissions.is_null())
        scene["permissions"] = permissions;
    return scene;
}

server_options room_of(std::string const& name, json const& scene)
{
    server_options o;
    o.rooms.push_back({"yard", test_support::write_scene(testing::TempDir() + "kugel_bodies_" + name + ".json", scene)});
    o.admin_token = admin_token;
    return o;
}

/// A client of the yard whose every message is checked against its schema.
class yard_client
{
public:
    explicit yard_client(std::uint16_t port, bool admin = false) : ws_(port, "/ws/yard")
    {
        welcome = next("welcome");
        if (admin) {
            ws_.send(json{{"type", "hello"}, {"admin_token", admin_token}});
            welcome = next("welcome");
            EXPECT_EQ(welcome.value("admin", false), true);
        }
        id = welcome.at("client").get<std::uint64_t>();
    }

    void send(json const& message) { ws_.send(message); }
    /// Sends a command with this ref and returns its answer (ack or error).
    json command(json message, std::uint64_t ref)
    {
        message["ref"] = ref;
        ws_.send(message);
        for (;;) {
            json answer = next_answer();
            if (answer.value("ref", json()) == ref)
                return answer;
        }
    }
    json next(std::string const& type)
    {
        json message = ws_.next(type);
        EXPECT_EQ(schemas().refusal(message), "") << message.dump();
        return message;
    }
    json next_answer()
    {
        for (;;) {
            auto const text = ws_.read();
            if (!text)
                throw std::runtime_error("no answer in time");
            json message = json::parse(*text);
            EXPECT_EQ(schemas().refusal(message), "") << text->substr(0, 300);
            if (message.at("type") != "snapshot")
                return message;
        }
    }
    json snapshot_at_or_after(std::uint64_t tick)
    {
        for (;;) {
            json s = next("snapshot");
            if (s.at("tick").get<std::uint64_t>() >= tick)
                return s;
        }
    }
    /// The world once every command sent so far has had its tick: a ping's tick and one more.
    json settled()
    {
        json const pong = command({{"type", "ping"}}, ++sync_ref_);
        return snapshot_at_or_after(pong.at("tick").get<std::uint64_t>() + 1);
    }

    json welcome;
    std::uint64_t id = 0;

private:
    ws_client ws_;
    std::uint64_t sync_ref_ = 1'000'000;
};

json spawn_body(std::array<double, 3> position, json extra = json::object())
{
    json body = {{"position", position}, {"radius", 0.25}, {"mass", 1.0}};
    body.update(extra);
    return {{"type", "spawn"}, {"body", body}};
}

std::array<double, 3> column3(json const& snapshot, char const* column, std::uint64_t id)
{
    auto const i = static_cast<std::size_t>(index_of(snapshot, id));
    auto const& c = snapshot.at("bodies").at(column);
    return {c[3 * i].get<double>(), c[3 * i + 1].get<double>(), c[3 * i + 2].get<double>()};
}

/// The tag a full snapshot gives a body: "" for none (no column, or "" in it).
std::string tag_of(json const& snapshot, std::uint64_t id)
{
    json const& bodies = snapshot.at("bodies");
    if (!bodies.contains("tag"))
        return "";
    return bodies.at("tag")[static_cast<std::size_t>(index_of(snapshot, id))].get<std::string>();
}

void expect_refused(json const& answer, std::string const& code, std::string const& message_start)
{
    EXPECT_EQ(answer.at("type"), "error") << answer.dump();
    EXPECT_EQ(answer.value("code", ""), code) << answer.dump();
    EXPECT_EQ(answer.value("message", "").substr(0, message_start.size()), message_start) << answer.dump();
}

// Tags ------------------------------------------------------------------------------------

// A scene body's tag and a spawn's are in every full snapshot, in a column written only
// while some body has a tag ("" for the others); when the last tagged body goes, so does
// the column.
TEST(Tags, FullSnapshotsCarryTheTagsOfTaggedBodiesOnly)
{
    json scene = yard();
    scene["bodies"][0].erase("tag");
    test_support::in_process_server s(room_of("tags_full", scene));
    yard_client c(s.port());
    json const untagged = c.settled();
    EXPECT_FALSE(untagged.at("bodies").contains("tag")) << "no body has a tag: no column";

    json const ack = c.command(spawn_body({-3, 0, 0}, {{"tag", "red 🎱"}}), 1);
    ASSERT_EQ(ack.at("type"), "ack") << ack.dump();
    auto const red = ack.at("id").get<std::uint64_t>();
    json const tagged = c.snapshot_at_or_after(ack.at("tick").get<std::uint64_t>());
    EXPECT_EQ(tag_of(tagged, red), "red 🎱");
    EXPECT_EQ(tagged.at("bodies").at("tag")[static_cast<std::size_t>(index_of(tagged, 1))], "");
    EXPECT_EQ(tagged.at("bodies").at("tag").size(), 3U);

    ASSERT_EQ(c.command({{"type", "remove"}, {"id", red}}, 2).at("type"), "ack");
    EXPECT_FALSE(c.settled().at("bodies").contains("tag")) << "the tagged body is gone";
}

// In the compact form a tag comes with the body's constants: in the keyframe a client
// starts from (the scene's tagged body) and in a delta's `appeared` (a tagged spawn), and
// nowhere else; apply_compact gives the tags to the client's state, and its full-form
// columns.
TEST(Tags, CompactSnapshotsSendATagOnlyWithTheBodysConstants)
{
    test_support::in_process_server s(room_of("tags_compact", yard()));
    yard_client c(s.port());
    c.send(json{{"type", "hello"}, {"snapshots", {{"form", "compact"}}}});
    c.next("welcome");
    json key;
    do
        key = c.next("snapshot");
    while (key.value("form", "") != "key");
    EXPECT_EQ(key.at("bodies").at("tag"), json::array({"post", ""}));

    auto const decoded_key = protocol::decode_server_message(key.dump());
    ASSERT_TRUE(decoded_key.message);
    auto held = protocol::apply_compact(std::get<protocol::compact_snapshot>(*decoded_key.message), nullptr);
    ASSERT_TRUE(held.state) << held.failure;

    json const ack = c.command(spawn_body({-3, 0, 0}, {{"tag", "blue"}}), 1);
    ASSERT_EQ(ack.at("type"), "ack") << ack.dump();
    auto const blue = ack.at("id").get<std::uint64_t>();
    bool appeared = false;
    while (held.state->bodies.id.back() != blue) {
        json const next = c.next("snapshot");
        if (next.value("form", "") == "delta") {
            if (next.contains("moved") || next.contains("vanished"))
                ADD_FAILURE() << "nothing moves or goes here: " << next.dump();
            if (next.contains("appeared")) {
                EXPECT_EQ(next.at("appeared").at("tag"), json::array({"blue"}));
                appeared = true;
            } else {
                EXPECT_FALSE(next.dump().find("tag") != std::string::npos) << next.dump();
            }
        }
        auto const decoded = protocol::decode_server_message(next.dump());
        ASSERT_TRUE(decoded.message);
        held = protocol::apply_compact(std::get<protocol::compact_snapshot>(*decoded.message), &*held.state);
        ASSERT_TRUE(held.state) << held.failure;
    }
    EXPECT_TRUE(appeared) << "the tagged body came in a keyframe, not a delta";
    protocol::snapshot const full = protocol::to_snapshot(*held.state);
    ASSERT_TRUE(full.bodies.tag);
    EXPECT_EQ(*full.bodies.tag, (std::vector<std::string>{"post", "", "blue"}));
    EXPECT_EQ(full.bodies.id.back(), blue);
}

// A scene whose body has a bad tag is refused by the loader, naming the body; in a
// load_scene that is bad_value and the room is unchanged.
TEST(Tags, ABadSceneTagIsRefusedNamingTheBody)
{
    test_support::in_process_server s(room_of("tags_scene", yard()));
    yard_client admin(s.port(), true);
    json scene = yard();
    scene["bodies"][1]["tag"] = std::string(33, 'x');
    json const refusal = admin.command({{"type", "load_scene"}, {"scene", scene}}, 1);
    expect_refused(refusal, "bad_value", "/scene: /bodies/1/tag: a body's tag must be 1 to 32 bytes");
    EXPECT_EQ(tag_of(admin.settled(), 1), "post") << "the room runs its scene still";
}

// Permissions -----------------------------------------------------------------------------

// Without `permissions` a room keeps the rules it always had, and says so.
TEST(Permissions, TheDefaultsAreTodaysRulesAndTheWelcomeSaysThem)
{
    test_support::in_process_server s(room_of("defaults", yard()));
    yard_client ann(s.port());
    yard_client bob(s.port());
    EXPECT_EQ(ann.welcome.at("permissions"), (json{{"push", "anyone"}, {"remove", "owner"}}));
    json const ack = ann.command(spawn_body({-3, 0, 0}), 1);
    auto const anns = ack.at("id").get<std::uint64_t>();
    EXPECT_EQ(bob.command({{"type", "impulse"}, {"id", anns}, {"impulse", {1, 0, 0}}}, 1).at("type"), "ack");
    EXPECT_EQ(bob.command({{"type", "set"}, {"id", 1}, {"velocity", {0, 1, 0}}}, 2).at("type"), "ack");
    expect_refused(bob.command({{"type", "remove"}, {"id", anns}}, 3), "forbidden",
                   "/id: body " + std::to_string(anns) + " was spawned by another client; this room's remove rule is \"owner\"");
    expect_refused(bob.command({{"type", "remove"}, {"id", 2}}, 4), "forbidden",
                   "/id: body 2 came with the scene; this room's remove rule is \"owner\"");
    EXPECT_EQ(ann.command({{"type", "remove"}, {"id", anns}}, 2).at("type"), "ack");
}

// push "owner": only the body's owner (or an admin) may push it; the scene's bodies have no
// owner, so only admins push them. A refusal names the rule and changes nothing.
TEST(Permissions, PushOwnerLetsOnlyTheOwnerAndAdminsPush)
{
    test_support::in_process_server s(room_of("push_owner", yard({{"push", "owner"}})));
    yard_client ann(s.port());
    yard_client bob(s.port());
    yard_client admin(s.port(), true);
    EXPECT_EQ(bob.welcome.at("permissions"), (json{{"push", "owner"}, {"remove", "owner"}}));
    auto const anns = ann.command(spawn_body({-3, 0, 0}), 1).at("id").get<std::uint64_t>();
    json const before = bob.settled();

    std::string const rule = "; this room's push rule is \"owner\"";
    expect_refused(bob.command({{"type", "impulse"}, {"id", anns}, {"impulse", {1, 0, 0}}}, 1), "forbidden",
                   "/id: body " + std::to_string(anns) + " was spawned by another client" + rule);
    expect_refused(bob.command({{"type", "set"}, {"id", anns}, {"position", {-4, 0, 0}}}, 2), "forbidden",
                   "/id: body " + std::to_string(anns) + " was spawned by another client" + rule);
    expect_refused(ann.command({{"type", "impulse"}, {"id", 1}, {"impulse", {1, 0, 0}}}, 2), "forbidden",
                   "/id: body 1 came with the scene" + rule);
    expect_refused(ann.command({{"type", "set"}, {"id", 2}, {"velocity", {1, 0, 0}}}, 3), "forbidden",
                   "/id: body 2 came with the scene" + rule);
    EXPECT_EQ(bob.settled().at("bodies"), before.at("bodies")) << "a refusal changed the world";

    EXPECT_EQ(ann.command({{"type", "impulse"}, {"id", anns}, {"impulse", {2, 0, 0}}}, 4).at("type"), "ack");
    EXPECT_EQ(admin.command({{"type", "set"}, {"id", 1}, {"velocity", {0, 0.5, 0}}}, 1).at("type"), "ack");
    json const after = bob.settled();
    EXPECT_EQ(column3(after, "velocity", anns), (std::array<double, 3>{2.0, 0.0, 0.0}));
    EXPECT_EQ(column3(after, "velocity", 1), (std::array<double, 3>{0.0, 0.5, 0.0}));
}

// push "admins" and remove "admins": nobody but an admin pushes or removes, not even a
// body of its own.
TEST(Permissions, AdminsOnlyRulesRefuseEvenTheOwner)
{
    test_support::in_process_server s(room_of("admins", yard({{"push", "admins"}, {"remove", "admins"}})));
    yard_client ann(s.port());
    yard_client admin(s.port(), true);
    EXPECT_EQ(ann.welcome.at("permissions"), (json{{"push", "admins"}, {"remove", "admins"}}));
    auto const anns = ann.command(spawn_body({-3, 0, 0}), 1).at("id").get<std::uint64_t>();
    json const before = ann.settled();
    expect_refused(ann.command({{"type", "impulse"}, {"id", anns}, {"impulse", {1, 0, 0}}}, 2), "forbidden",
                   "/id: this room's push rule is \"admins\"");
    expect_refused(ann.command({{"type", "set"}, {"id", anns}, {"velocity", {1, 0, 0}}}, 3), "forbidden",
                   "/id: this room's push rule is \"admins\"");
    expect_refused(ann.command({{"type", "remove"}, {"id", anns}}, 4), "forbidden",
                   "/id: this room's remove rule is \"admins\"");
    EXPECT_EQ(ann.settled().at("bodies"), before.at("bodies"));
    EXPECT_EQ(admin.command({{"type", "impulse"}, {"id", anns}, {"impulse", {1, 0, 0}}}, 1).at("type"), "ack");
    EXPECT_EQ(admin.command({{"type", "remove"}, {"id", anns}}, 2).at("type"), "ack");
    EXPECT_EQ(index_of(ann.settled(), anns), -1);
}

// An unknown rule in a scene is refused by the loader.
TEST(Permissions, AnUnknownRuleIsRefusedByTheLoader)
{
    test_support::in_process_server s(room_of("bad_rule", yard()));
    yard_client admin(s.port(), true);
    json const refusal =
        admin.command({{"type", "load_scene"}, {"scene", yard({{"push", "everyone"}})}}, 1);
    expect_refused(refusal, "bad_value", "/scene: /permissions/push: unknown rule 'everyone'");
}

// Set -------------------------------------------------------------------------------------

// A set puts the body where it says, with the velocity it says, at the start of the acked
// tick, and keeps its id: the snapshot of that tick shows the new position stepped once by
// the new velocity (dt = 1/64 s, exact in binary). What it does not give stays.
TEST(Set, SetsPositionAndVelocityAtTheAckedTickKeepingTheId)
{
    test_support::in_process_server s(room_of("set", yard()));
    yard_client c(s.port());
    json const ack = c.command({{"type", "set"}, {"id", 2}, {"position", {3, 4, -2}}, {"velocity", {2, 0, -1}}}, 1);
    ASSERT_EQ(ack.at("type"), "ack") << ack.dump();
    EXPECT_FALSE(ack.contains("id"));
    auto const tick = ack.at("tick").get<std::uint64_t>();
    json snapshot = c.snapshot_at_or_after(tick - 1);
    if (snapshot.at("tick").get<std::uint64_t>() == tick - 1) {
        EXPECT_EQ(column3(snapshot, "position", 2), (std::array<double, 3>{3, 0, 0})) << "set before its tick";
    }
    snapshot = c.snapshot_at_or_after(tick);
    auto const ticks_since = static_cast<double>(snapshot.at("tick").get<std::uint64_t>() - tick + 1);
    EXPECT_EQ(column3(snapshot, "position", 2),
              (std::array<double, 3>{3 + 2 * ticks_since / 64, 4, -2 - ticks_since / 64}));
    EXPECT_EQ(column3(snapshot, "velocity", 2), (std::array<double, 3>{2, 0, -1}));

    ASSERT_EQ(c.command({{"type", "set"}, {"id", 2}, {"velocity", {0, 0, 0}}}, 2).at("type"), "ack");
    json const stopped = c.settled();
    json const later = c.settled();
    EXPECT_EQ(column3(later, "velocity", 2), (std::array<double, 3>{0, 0, 0}));
    EXPECT_EQ(column3(later, "position", 2), column3(stopped, "position", 2)) << "the position stayed";
    // A position alone keeps the velocity; the body may be set where it is (not into itself).
    ASSERT_EQ(c.command({{"type", "set"}, {"id", 1}, {"position", {0, 0, 0}}}, 3).at("type"), "ack");
}

// Each refusal of a set has its code and pointer, and changes nothing: an unknown id, a
// place behind a wall, across one, in an obstacle, in another sphere, a velocity for a
// static body; and the decoder's (neither field, a speed of c).
TEST(Set, EachRefusalHasItsCodeAndChangesNothing)
{
    json scene = yard();
    scene["bodies"].push_back({{"position", {-5, -5, -5}}, {"radius", 0.5}, {"static", true}});
    test_support::in_process_server s(room_of("set_refusals", scene));
    yard_client c(s.port());
    json const before = c.settled();
    auto const set = [](std::uint64_t id, json fields) {
        fields["type"] = "set";
        fields["id"] = id;
        return fields;
    };
    expect_refused(c.command(set(424242, {{"position", {1, 1, 1}}}), 1), "unknown_body", "/id: no body 424242");
    expect_refused(c.command(set(2, {{"position", {3, 0, 11}}}), 2), "outside_world", "/position: [3, 0, 11] is behind wall");
    expect_refused(c.command(set(2, {{"position", {3, 0, 9.75}}}), 3), "overlaps_wall",
                   "/position: a sphere of radius 0.5 m at [3, 0, 9.75] crosses wall");
    expect_refused(c.command(set(2, {{"position", {5, 4, 0}}}), 4), "overlaps_wall",
                   "/position: a sphere of radius 0.5 m at [5, 4, 0] overlaps obstacle 0");
    expect_refused(c.command(set(2, {{"position", {0.9, 0, 0}}}), 5), "overlaps_body",
                   "/position: a sphere of radius 0.5 m at [0.9, 0, 0] overlaps body 1");
    expect_refused(c.command(set(3, {{"velocity", {1, 0, 0}}}), 6), "bad_value", "/velocity: body 3 is static");
    expect_refused(c.command(set(2, json::object()), 7), "missing_field", "/: needs a position (m), a velocity (m/s) or both");
    expect_refused(c.command(set(2, {{"velocity", {0, 299792458, 0}}}), 8), "bad_value",
                   "/velocity: a speed of 299792458 m/s is not below the speed of light");
    expect_refused(c.command(set(2, {{"position", {3, 0, 0}}, {"velocity", {0, 0, 1e300}}}), 9), "bad_value", "/velocity");
    EXPECT_EQ(c.settled().at("bodies"), before.at("bodies")) << "a refusal changed the world";
    // A static body may be put elsewhere: it stays still there.
    ASSERT_EQ(c.command(set(3, {{"position", {-5, -5, -4}}, {"velocity", {0, 0, 0}}}), 10).at("type"), "ack");
    json const moved = c.settled();
    EXPECT_EQ(column3(moved, "position", 3), (std::array<double, 3>{-5, -5, -4}));
    EXPECT_EQ(column3(c.settled(), "position", 3), (std::array<double, 3>{-5, -5, -4}));
}

// A sleeping body that is set wakes: a ball resting on the floor of a room under gravity
// falls asleep (a snapshot then shows its velocity exactly zero, tick after tick); set
// moving sideways, it moves (asleep, it would keep its place).
TEST(Set, ASleepingBodyThatIsSetWakes)
{
    json scene = {{"name", "floor"},
                  {"dt", 1.0 / 60.0},
                  {"integrator", "semi_implicit_euler"},
                  {"forces", {{"uniform_field", {{"g", {0, 0, -9.81}}}}}},
                  {"collisions", {{"mode", "discrete"}, {"sleep_time", 0.1}}},
                  {"box", {{"min", {-4, -4, 0}}, {"max", {4, 4, 4}}}},
                  {"bodies", json::array({{{"position", {0, 0, 0.25}}, {"radius", 0.25}, {"mass", 1.0}}})}};
    test_support::in_process_server s(room_of("sleep", scene));
    yard_client c(s.port());
    // Still, bit for bit, for 30 ticks (0.5 s, five times sleep_time): asleep by then.
    json rest;
    json still_since = c.next("snapshot");
    for (int i = 0; i < 1000 && rest.is_null(); ++i) {
        json const now = c.next("snapshot");
        if (now.at("bodies") != still_since.at("bodies") ||
            column3(now, "velocity", 1) != std::array<double, 3>{0, 0, 0})
            still_since = now;
        else if (now.at("tick").get<std::uint64_t>() >= still_since.at("tick").get<std::uint64_t>() + 30)
            rest = now;
    }
    ASSERT_FALSE(rest.is_null()) << "the ball never came to rest";
    ASSERT_EQ(c.command({{"type", "set"}, {"id", 1}, {"velocity", {1, 0, 0}}}, 1).at("type"), "ack");
    json const after = c.settled();
    EXPECT_GT(column3(after, "position", 1)[0], column3(rest, "position", 1)[0]) << "it kept its place: still asleep";
}

// Static spawns ---------------------------------------------------------------------------

// Only an admin may spawn a static body; it shows in snapshots as a scene's static body
// does, and nothing moves it: an impulse leaves it still, and a set may not give it a
// velocity.
TEST(StaticSpawn, OnlyAdminsSpawnThemAndNothingMovesThem)
{
    test_support::in_process_server s(room_of("static", yard()));
    yard_client ann(s.port());
    yard_client admin(s.port(), true);
    json const post = spawn_body({-3, 3, 0}, {{"static", true}, {"tag", "pillar"}});
    json const before = ann.settled();
    expect_refused(ann.command(post, 1), "forbidden", "/body/static: only an admin may spawn a static body");
    EXPECT_EQ(ann.settled().at("bodies"), before.at("bodies"));

    json const ack = admin.command(post, 1);
    ASSERT_EQ(ack.at("type"), "ack") << ack.dump();
    auto const pillar = ack.at("id").get<std::uint64_t>();
    EXPECT_EQ(ann.command({{"type", "impulse"}, {"id", pillar}, {"impulse", {5, 0, 0}}}, 2).at("type"), "ack");
    expect_refused(ann.command({{"type", "set"}, {"id", pillar}, {"velocity", {1, 0, 0}}}, 3), "bad_value", "/velocity");
    json const after = ann.settled();
    EXPECT_EQ(column3(after, "position", pillar), (std::array<double, 3>{-3, 3, 0}));
    EXPECT_EQ(column3(after, "velocity", pillar), (std::array<double, 3>{0, 0, 0}));
    EXPECT_EQ(tag_of(after, pillar), "pillar");
    EXPECT_EQ(after.at("bodies").at("mass")[static_cast<std::size_t>(index_of(after, pillar))], 1.0);
    // A sphere spawned into it is refused as into any other.
    expect_refused(ann.command(spawn_body({-3, 3, 0.4}), 4), "overlaps_body", "/body/position");
}

} // namespace
} // namespace kugel::server
