// Players: every connection is a player with the id its welcome gives and the name its hello
// gives; each client hears who is in the room when it joins and who joins, is renamed or
// leaves after, over real WebSocket connections. Every message read is checked against its
// schema.

#include "server.hpp"

#include "protocol/message_schemas.hpp"
#include "support/http_get.hpp"
#include "support/in_process_server.hpp"
#include "support/scene_files.hpp"
#include "support/ws_client.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <map>
#include <optional>
#include <vector>
#include <memory>
#include <string>
#include <thread>

namespace kugel::server {
namespace {

using nlohmann::json;
using protocol::testing::schemas;
using test_support::ws_client;

server_options one_room(std::string const& name, int generated = 0)
{
    server_options o;
    o.rooms.push_back({"play", test_support::write_scene(testing::TempDir() + "kugel_players_" + name + ".json",
                                                         test_support::still_scene(generated))});
    return o;
}

/// A client that hears player messages, with its welcome read.
struct player_client
{
    ws_client ws;
    std::uint64_t id = 0;

    explicit player_client(std::uint16_t port) : ws(port, "/ws/play")
    {
        ws.hear_players();
        id = next("welcome").at("client").get<std::uint64_t>();
    }

    /// The next message of `type`, checked against its schema.
    json next(std::string const& type)
    {
        json message = ws.next(type);
        EXPECT_EQ(schemas().refusal(message), "") << message.dump();
        return message;
    }
};

json player(std::uint64_t id) { return {{"id", id}}; }
json player(std::uint64_t id, std::string const& name) { return {{"id", id}, {"name", name}}; }
json notice(std::string const& change, std::uint64_t id)
{
    return {{"type", "player"}, {"change", change}, {"id", id}};
}
json notice(std::string const& change, std::uint64_t id, std::string const& name)
{
    return {{"type", "player"}, {"change", change}, {"id", id}, {"name", name}};
}

/// The room's player count in /healthz, once it is `wanted` (a session that ended leaves
/// on the room's strand, a moment after its client saw the close).
std::uint64_t healthz_players(std::uint16_t port, std::uint64_t wanted)
{
    std::uint64_t players = 0;
    for (int i = 0; i < 500; ++i) {
        auto const reply = test_support::http_get(port, "/healthz");
        players = json::parse(reply.body).at("rooms").at("play").at("players").get<std::uint64_t>();
        if (players == wanted)
            break;
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return players;
}

TEST(Players, EachClientHearsWhoIsThereAndWhoJoinsIsRenamedAndLeaves)
{
    test_support::in_process_server s(one_room("story"));
    player_client ann(s.port());
    EXPECT_EQ(ann.next("players"), (json{{"type", "players"}, {"players", {player(ann.id)}}}));
    ann.ws.send(json{{"type", "hello"}, {"name", "ann"}});
    EXPECT_EQ(ann.next("player"), notice("renamed", ann.id, "ann")); // the renamed one hears it too

    player_client bob(s.port());
    EXPECT_NE(bob.id, ann.id);
    EXPECT_EQ(bob.next("players"), (json{{"type", "players"}, {"players", {player(ann.id, "ann"), player(bob.id)}}}));
    EXPECT_EQ(ann.next("player"), notice("joined", bob.id));
    bob.ws.send(json{{"type", "hello"}, {"name", "Bob 🎱"}});
    EXPECT_EQ(ann.next("player"), notice("renamed", bob.id, "Bob 🎱"));
    EXPECT_EQ(bob.next("player"), notice("renamed", bob.id, "Bob 🎱"));
    EXPECT_EQ(healthz_players(s.port(), 2), 2U);

    std::uint64_t cy_id = 0;
    {
        player_client cy(s.port());
        cy_id = cy.id;
        EXPECT_EQ(cy.next("players"),
                  (json{{"type", "players"}, {"players", {player(ann.id, "ann"), player(bob.id, "Bob 🎱"), player(cy.id)}}}));
        EXPECT_EQ(ann.next("player"), notice("joined", cy.id));
        EXPECT_EQ(bob.next("player"), notice("joined", cy.id));
        // The same name again renames nobody: the next notice either hears is cy leaving.
        ann.ws.send(json{{"type", "hello"}, {"name", "ann"}});
    } // cy closes
    EXPECT_EQ(ann.next("player"), notice("left", cy_id));
    EXPECT_EQ(bob.next("player"), notice("left", cy_id));
    EXPECT_EQ(healthz_players(s.port(), 2), 2U);

    bob.ws.send(json{{"type", "ping"}, {"ref", 1}}); // bob is still served
    EXPECT_EQ(bob.next("pong").at("ref"), 1);
}

// A name nobody else may see is refused, and nobody is told of it: the other player's next
// notice is the good name that followed.
TEST(Players, ABadNameIsRefusedAndNobodyHearsIt)
{
    test_support::in_process_server s(one_room("bad_name"));
    player_client ann(s.port());
    player_client bob(s.port());
    EXPECT_EQ(ann.next("player"), notice("joined", bob.id));
    bob.ws.send(std::string(R"({"type":"hello","name":"bob\u0007"})"));
    json const refusal = bob.next("error");
    EXPECT_EQ(refusal.at("code"), "bad_value");
    EXPECT_EQ(refusal.at("message"), "/name: must not hold control characters (found the byte 7)");
    bob.ws.send(json{{"type", "hello"}, {"name", std::string(65, 'b')}});
    EXPECT_EQ(bob.next("error").at("code"), "bad_value");
    bob.ws.send(json{{"type", "hello"}, {"name", "bob"}});
    EXPECT_EQ(ann.next("player"), notice("renamed", bob.id, "bob"));
}

// Renames are told to every player, so a hello with a name is a command for the rate limit:
// a flood of them is slowed, not multiplied by the room's size. With a burst of 4 and no
// tokens coming back, 4 of 10 renames go through and 6 are refused rate_limited; the other
// player hears exactly the 4.
TEST(Players, AFloodOfRenamesIsRateLimited)
{
    server_options options = one_room("flood");
    options.client.command_burst = 4;
    options.client.commands_per_second = 0.001;
    test_support::in_process_server s(options);
    player_client ann(s.port());
    auto bob = std::make_unique<player_client>(s.port());
    std::uint64_t const bob_id = bob->id;
    EXPECT_EQ(ann.next("player"), notice("joined", bob_id));
    for (int i = 0; i < 10; ++i)
        bob->ws.send(json{{"type", "hello"}, {"name", "bob " + std::to_string(i)}});
    for (int i = 0; i < 6; ++i)
        EXPECT_EQ(bob->next("error").at("code"), "rate_limited");
    for (int i = 0; i < 4; ++i)
        EXPECT_EQ(ann.next("player"), notice("renamed", bob_id, "bob " + std::to_string(i)));
    // Nothing more: bob leaving is the next thing ann hears.
    bob.reset();
    EXPECT_EQ(ann.next("player"), notice("left", bob_id, "bob 3"));
}

// Presence costs the room a message to every client for each join, rename and leave: a
// client that needs none (a load generator) says so, and hears nothing more until it asks
// again, when it gets the roster as it is then.
TEST(Players, AClientThatAsksForNoPlayerMessagesGetsNoneUntilItAsksAgain)
{
    test_support::in_process_server s(one_room("quiet"));
    player_client ann(s.port());
    EXPECT_EQ(ann.next("players").at("players").size(), 1U);
    ann.ws.send(json{{"type", "hello"}, {"players", false}});
    ann.ws.send(json{{"type", "ping"}, {"ref", 1}});
    EXPECT_EQ(ann.next("pong").at("ref"), 1); // the hello has reached the room
    auto bob = std::make_unique<player_client>(s.port());
    std::uint64_t const bob_id = bob->id;
    bob->ws.send(json{{"type", "hello"}, {"name", "bob"}});
    EXPECT_EQ(bob->next("player"), notice("renamed", bob_id, "bob"));
    // bob's join and name are known to the room now; ann's next player message is the roster
    // she asks for below, with bob in it: nothing came before it.
    ann.ws.send(json{{"type", "hello"}, {"players", true}});
    json roster;
    while (roster.is_null()) {
        json const m = ann.ws.read_json();
        ASSERT_NE(m.at("type"), "player") << m.dump(); // no notice while she asked for none
        if (m.at("type") == "players")
            roster = m;
    }
    EXPECT_EQ(roster, (json{{"type", "players"}, {"players", {player(ann.id), player(bob_id, "bob")}}}));
    bob.reset();
    EXPECT_EQ(ann.next("player"), notice("left", bob_id, "bob"));
}

// A crowd joining while a client is not reading does not fill that client's reply queue:
// its unsent player notices are replaced by one roster of the players they add up to. The
// client stops reading while a snapshot of 3,000 bodies fills its socket (a small send
// buffer), so everything after waits in the server; 30 players join and name themselves (60
// notices). When it reads again it is still connected, and what it hears adds up to the
// room as it is: every player, with its name.
TEST(Players, ACrowdJoiningWhileAClientIsBehindReachesItAsOneRoster)
{
    server_options options = one_room("crowd", 3000);
    options.client.send_buffer_bytes = 4096;
    test_support::in_process_server s(options);
    player_client ann(s.port());
    std::this_thread::sleep_for(std::chrono::milliseconds(300)); // snapshots fill ann's socket
    std::vector<std::unique_ptr<player_client>> crowd;
    std::map<std::uint64_t, std::string> named;
    for (int i = 0; i < 30; ++i) {
        crowd.push_back(std::make_unique<player_client>(s.port()));
        std::string const name = "guest " + std::to_string(i);
        crowd.back()->ws.send(json{{"type", "hello"}, {"name", name}});
        named[crowd.back()->id] = name;
        crowd.back()->next("players");
    }
    crowd.back()->ws.send(json{{"type", "ping"}, {"ref", 1}}); // the last rename has reached the room
    crowd.back()->next("pong");

    std::map<std::uint64_t, std::optional<std::string>> heard;
    std::size_t rosters = 0;
    auto const apply = [&](json const& m) {
        if (m.at("type") == "players") {
            ++rosters;
            heard.clear();
            for (json const& p : m.at("players"))
                heard[p.at("id").get<std::uint64_t>()] =
                    p.contains("name") ? std::optional(p.at("name").get<std::string>()) : std::nullopt;
        } else if (m.at("change") == "left") {
            heard.erase(m.at("id").get<std::uint64_t>());
        } else {
            heard[m.at("id").get<std::uint64_t>()] =
                m.contains("name") ? std::optional(m.at("name").get<std::string>()) : std::nullopt;
        }
    };
    std::map<std::uint64_t, std::optional<std::string>> wanted{{ann.id, std::nullopt}};
    for (auto const& [id, name] : named)
        wanted[id] = name;
    while (heard != wanted) {
        auto const text = ann.ws.read(std::chrono::seconds(10));
        ASSERT_TRUE(text) << "ann was closed or heard nothing more; heard " << heard.size() << " players";
        json const m = json::parse(*text);
        if (m.at("type") == "players" || m.at("type") == "player") {
            EXPECT_EQ(schemas().refusal(m), "") << *text;
            apply(m);
        }
    }
    EXPECT_GE(rosters, 2U); // the one after the welcome, and at least one in place of notices
    EXPECT_FALSE(ann.ws.closed());
}

} // namespace
} // namespace kugel::server
