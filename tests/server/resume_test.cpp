// Coming back: a player whose connection ended is kept for the room's resume_grace, and a new
// connection whose hello carries the player's resume_token becomes it again, with its id, its
// name, its bodies and its count of them; when the grace ends the player leaves, and its
// bodies stay or go as the room's bodies_on_leave says. Over real WebSocket connections, every
// message read checked against its schema. Graces are a few ticks of a fast tick rate, and
// what is checked is ticks and messages, never how long anything took.

#include "server.hpp"

#include "protocol/message_schemas.hpp"
#include "support/in_process_server.hpp"
#include "support/scene_files.hpp"
#include "support/ws_client.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdint>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

namespace kugel::server {
namespace {

using nlohmann::json;
using protocol::testing::schemas;
using test_support::ws_client;

constexpr double fast_tick_rate = 100.0; // Hz; a snapshot every tick

/// A room "play" of the still scene (collisions off: bodies may be spawned anywhere inside
/// its ±10 m box) whose scene sets `players`, ticking fast, 3 bodies per client at most.
server_options resume_room(std::string const& name, json players)
{
    json scene = test_support::still_scene();
    if (!players.is_null())
        scene["players"] = std::move(players);
    server_options o;
    o.tick_rate = fast_tick_rate;
    o.snapshot_rate = fast_tick_rate;
    o.client.max_bodies_per_client = 3;
    o.rooms.push_back({"play", test_support::write_scene(testing::TempDir() + "kugel_resume_" + name + ".json",
                                                         scene)});
    return o;
}

json rules(double grace, std::string const& bodies_on_leave)
{
    return {{"resume_grace", grace}, {"bodies_on_leave", bodies_on_leave}};
}

/// A client that hears player messages, with its welcome and first roster read.
struct player_client
{
    ws_client ws;
    json welcome;
    std::uint64_t id = 0;

    explicit player_client(std::uint16_t port) : ws(port, "/ws/play")
    {
        ws.hear_players();
        welcome = next("welcome");
        id = welcome.at("client").get<std::uint64_t>();
        next("players");
    }

    json checked(json message)
    {
        EXPECT_EQ(schemas().refusal(message), "") << message.dump();
        return message;
    }
    /// The next message of `type`, passing over others.
    json next(std::string const& type) { return checked(ws.next(type)); }
    /// The next message that is not a snapshot.
    json next_not_snapshot()
    {
        for (;;) {
            json message = checked(ws.read_json());
            if (message.at("type") != "snapshot")
                return message;
        }
    }
    /// The next message that is neither a snapshot nor a player message: the answer to a
    /// hello, mostly.
    json reply()
    {
        for (;;) {
            json message = checked(ws.read_json());
            std::string const type = message.at("type").get<std::string>();
            if (type != "snapshot" && type != "player" && type != "players")
                return message;
        }
    }
    /// The answer to a command: the next ack or error, passing over snapshots and notices.
    json answer()
    {
        for (;;) {
            json message = checked(ws.read_json());
            if (message.at("type") == "ack" || message.at("type") == "error")
                return message;
        }
    }
    json spawn(std::uint64_t ref, double x)
    {
        ws.send(json{{"type", "spawn"}, {"ref", ref},
                     {"body", {{"position", {x, 5, 0}}, {"radius", 0.1}, {"mass", 1}}}});
        return answer();
    }
    json remove(std::uint64_t ref, std::uint64_t body)
    {
        ws.send(json{{"type", "remove"}, {"ref", ref}, {"id", body}});
        return answer();
    }
    void resume(std::string const& token) { ws.send(json{{"type", "hello"}, {"resume", token}}); }
};

json notice(std::string const& change, std::uint64_t id)
{
    return {{"type", "player"}, {"change", change}, {"id", id}};
}
json notice(std::string const& change, std::uint64_t id, std::string const& name)
{
    return {{"type", "player"}, {"change", change}, {"id", id}, {"name", name}};
}

std::set<std::uint64_t> ids_in(json const& snapshot)
{
    auto const ids = snapshot.at("bodies").at("id").get<std::vector<std::uint64_t>>();
    return {ids.begin(), ids.end()};
}

bool holds(json const& snapshot, std::vector<std::uint64_t> const& bodies)
{
    std::set<std::uint64_t> const ids = ids_in(snapshot);
    return std::all_of(bodies.begin(), bodies.end(), [&](std::uint64_t id) { return ids.contains(id); });
}

bool holds_none(json const& snapshot, std::vector<std::uint64_t> const& bodies)
{
    std::set<std::uint64_t> const ids = ids_in(snapshot);
    return std::none_of(bodies.begin(), bodies.end(), [&](std::uint64_t id) { return ids.contains(id); });
}

void expect_bad_resume(json const& answer, std::string const& says)
{
    EXPECT_EQ(answer.at("type"), "error") << answer.dump();
    EXPECT_EQ(answer.value("code", ""), "bad_resume") << answer.dump();
    EXPECT_FALSE(answer.contains("ref")) << answer.dump();
    std::string const message = answer.value("message", "");
    EXPECT_EQ(message.rfind("/resume: ", 0), 0U) << message;
    EXPECT_NE(message.find(says), std::string::npos) << message;
}

bool is_hex_token(json const& token)
{
    if (!token.is_string())
        return false;
    std::string const text = token.get<std::string>();
    return text.size() == 32 && text.find_first_not_of("0123456789abcdef") == std::string::npos;
}

// The story of a resume: ann spawns her 3 bodies (the cap), her connection drops, bob hears
// she is away; a new connection resumes her with her token and is ann again: her id, her
// name, her bodies (bob may not remove them, she may) and her count (at the cap, a spawn is
// refused until she removes one). The token she used is spent: replayed, it is refused.
TEST(Resume, AfterADropTheSamePlayerComesBackWithItsNameBodiesAndCount)
{
    test_support::in_process_server s(resume_room("story", rules(60.0, "stay")));
    player_client bob(s.port());
    auto ann = std::make_unique<player_client>(s.port());
    EXPECT_EQ(ann->welcome.at("resume_grace"), 60.0);
    EXPECT_EQ(ann->welcome.at("bodies_on_leave"), "stay");
    ASSERT_TRUE(is_hex_token(ann->welcome.value("resume_token", json()))) << ann->welcome.dump();
    std::string const token = ann->welcome.at("resume_token").get<std::string>();
    std::uint64_t const ann_id = ann->id;
    EXPECT_EQ(bob.next("player"), notice("joined", ann_id));
    ann->ws.send(json{{"type", "hello"}, {"name", "ann"}});
    EXPECT_EQ(bob.next("player"), notice("renamed", ann_id, "ann"));

    std::vector<std::uint64_t> bodies;
    for (std::uint64_t ref = 1; ref <= 3; ++ref) {
        json const ack = ann->spawn(ref, -3.0 + static_cast<double>(ref));
        ASSERT_EQ(ack.at("type"), "ack") << ack.dump();
        bodies.push_back(ack.at("id").get<std::uint64_t>());
    }
    EXPECT_EQ(ann->spawn(4, 2.0).value("code", ""), "too_many_bodies");

    ann.reset(); // the connection drops
    EXPECT_EQ(bob.next("player"), notice("away", ann_id, "ann"));

    player_client back(s.port());
    EXPECT_NE(back.id, ann_id); // a fresh player until its hello says otherwise
    EXPECT_EQ(bob.next("player"), notice("joined", back.id));
    back.resume(token);
    json const welcome = back.next_not_snapshot();
    ASSERT_EQ(welcome.at("type"), "welcome") << welcome.dump();
    EXPECT_EQ(welcome.at("client"), ann_id);
    ASSERT_TRUE(is_hex_token(welcome.value("resume_token", json()))) << welcome.dump();
    EXPECT_NE(welcome.at("resume_token"), token); // a new token for the next time
    EXPECT_EQ(back.next_not_snapshot(),
              (json{{"type", "players"}, {"players", {{{"id", bob.id}}, {{"id", ann_id}, {"name", "ann"}}}}}));
    // bob: the fresh player is gone, ann is back.
    EXPECT_EQ(bob.next("player"), notice("left", back.id));
    EXPECT_EQ(bob.next("player"), notice("back", ann_id, "ann"));

    // Her bodies are hers: bob may not remove one, she may.
    EXPECT_EQ(bob.remove(10, bodies[0]).value("code", ""), "forbidden");
    json const removed = back.remove(5, bodies[0]);
    EXPECT_EQ(removed.at("type"), "ack") << removed.dump();
    // Her count came back with her: 2 of 3 now, so one more spawn, and then the cap.
    EXPECT_EQ(back.spawn(6, 3.0).at("type"), "ack");
    EXPECT_EQ(back.spawn(7, 4.0).value("code", ""), "too_many_bodies");

    // The token she came back with is spent: another connection replaying it stays itself.
    player_client replay(s.port());
    replay.resume(token);
    expect_bad_resume(replay.reply(), "no player of this room holds this token");
    replay.ws.send(json{{"type", "ping"}, {"ref", 1}});
    EXPECT_EQ(replay.reply().at("type"), "pong");
    EXPECT_EQ(bob.next("player"), notice("joined", replay.id));
    replay.ws.send(json{{"type", "hello"}, {"name", "eve"}});
    EXPECT_EQ(bob.next("player"), notice("renamed", replay.id, "eve")); // not ann
    // And a connection resumes once: ann's connection may not resume another player.
    back.resume(replay.welcome.at("resume_token").get<std::string>());
    expect_bad_resume(back.reply(), "resumes once");
}

// When the grace ends without a resume the player leaves: the others hear `left`, its token
// is refused, and its bodies stay or go by the room's rule. The grace is 5 ticks; the bodies
// are in every snapshot until at least 5 ticks after the last snapshot bob had before he
// heard she was away.
class AfterTheGrace : public ::testing::TestWithParam<std::string>
{
};

TEST_P(AfterTheGrace, TheTokenIsRefusedTheOthersHearLeftAndTheBodiesFollowTheRule)
{
    std::string const rule = GetParam();
    constexpr double grace_ticks = 5.0;
    test_support::in_process_server s(resume_room("grace_" + rule, rules(grace_ticks / fast_tick_rate, rule)));
    player_client bob(s.port());
    auto ann = std::make_unique<player_client>(s.port());
    EXPECT_EQ(ann->welcome.at("bodies_on_leave"), rule);
    std::string const token = ann->welcome.at("resume_token").get<std::string>();
    std::uint64_t const ann_id = ann->id;
    std::vector<std::uint64_t> bodies;
    std::uint64_t spawned_at = 0;
    for (std::uint64_t ref = 1; ref <= 2; ++ref) {
        json const ack = ann->spawn(ref, static_cast<double>(ref));
        ASSERT_EQ(ack.at("type"), "ack") << ack.dump();
        bodies.push_back(ack.at("id").get<std::uint64_t>());
        spawned_at = ack.at("tick").get<std::uint64_t>();
    }
    // bob sees them.
    for (;;) {
        json const m = bob.checked(bob.ws.read_json());
        if (m.at("type") == "snapshot" && m.at("tick").get<std::uint64_t>() >= spawned_at) {
            ASSERT_TRUE(holds(m, bodies)) << m.dump();
            break;
        }
    }

    ann.reset(); // the connection drops
    std::uint64_t last_before_away = 0;
    std::optional<std::uint64_t> first_without;
    bool away = false;
    bool left = false;
    std::uint64_t after_left = 0; // snapshots of ticks after the `left`
    while (!(left && (rule == "remove" ? first_without.has_value() : after_left >= 3))) {
        json const m = bob.checked(bob.ws.read_json());
        if (m.at("type") == "player") {
            if (!away) {
                EXPECT_EQ(m, notice("away", ann_id));
                away = true;
            } else {
                EXPECT_EQ(m, notice("left", ann_id));
                left = true;
            }
            continue;
        }
        if (m.at("type") != "snapshot")
            continue;
        std::uint64_t const tick = m.at("tick").get<std::uint64_t>();
        if (!away)
            last_before_away = tick;
        // A bound, so that a broken grace fails here rather than waits forever: 5 s of ticks.
        ASSERT_LT(tick, spawned_at + 500) << "no `left`, or the bodies stayed: away " << away << ", left " << left;
        if (rule == "remove" && !first_without && holds_none(m, bodies))
            first_without = tick;
        if (rule == "stay") {
            EXPECT_TRUE(holds(m, bodies)) << m.dump();
            after_left += left ? 1 : 0;
        }
    }
    if (rule == "remove") {
        EXPECT_GE(*first_without, last_before_away + static_cast<std::uint64_t>(grace_ticks))
            << "the bodies went before the grace ended";
        EXPECT_EQ(s.bodies("play"), 1U); // the scene's own body
    } else {
        EXPECT_EQ(s.bodies("play"), 3U);
    }

    // Too late: the token is refused, and the connection stays the fresh player it is.
    player_client late(s.port());
    EXPECT_EQ(bob.next("player"), notice("joined", late.id));
    late.resume(token);
    expect_bad_resume(late.reply(), "its player's grace ended");
    late.ws.send(json{{"type", "hello"}, {"name", "late"}});
    EXPECT_EQ(bob.next("player"), notice("renamed", late.id, "late"));
    // Ann's bodies are nobody's now: not the late comer's to remove.
    if (rule == "stay") {
        EXPECT_EQ(late.remove(3, bodies[0]).value("code", ""), "forbidden");
    }
}

INSTANTIATE_TEST_SUITE_P(Rules, AfterTheGrace, ::testing::Values("stay", "remove"));

// A resume of a player whose connection still looks open (a client that gave up on it before
// the server noticed): that connection is closed with 4000, and the new one is the player. The
// others never hear it left.
TEST(Resume, OfAPlayerStillConnectedClosesItsOldConnectionWith4000)
{
    test_support::in_process_server s(resume_room("open", rules(60.0, "remove")));
    player_client bob(s.port());
    player_client ann(s.port());
    EXPECT_EQ(bob.next("player"), notice("joined", ann.id));
    json const ack = ann.spawn(1, 1.0);
    ASSERT_EQ(ack.at("type"), "ack") << ack.dump();
    std::uint64_t const body = ack.at("id").get<std::uint64_t>();

    player_client again(s.port());
    EXPECT_EQ(bob.next("player"), notice("joined", again.id));
    again.resume(ann.welcome.at("resume_token").get<std::string>());
    EXPECT_EQ(again.reply().at("client"), ann.id);
    EXPECT_EQ(bob.next("player"), notice("left", again.id));
    EXPECT_EQ(bob.next("player"), notice("back", ann.id));

    while (!ann.ws.closed())
        ann.ws.read(std::chrono::seconds(10));
    EXPECT_EQ(ann.ws.close_code(), 4000);
    // Her body stayed hers (bodies_on_leave "remove" applies to players that leave; she did
    // not): the new connection removes it.
    EXPECT_EQ(again.remove(2, body).at("type"), "ack");
    // The next thing bob hears is her new name, not that she left.
    again.ws.send(json{{"type", "hello"}, {"name", "ann"}});
    EXPECT_EQ(bob.next("player"), notice("renamed", ann.id, "ann"));
}

// Grace 0 (the default): a player leaves with its connection, as before resumes existed; no
// token is given and a resume is refused. With bodies_on_leave "remove" its bodies go at the
// next tick.
TEST(Resume, WithNoGraceAPlayerLeavesWithItsConnectionAndCannotResume)
{
    test_support::in_process_server s(resume_room("none", rules(0.0, "remove")));
    player_client bob(s.port());
    auto ann = std::make_unique<player_client>(s.port());
    EXPECT_EQ(ann->welcome.at("resume_grace"), 0.0);
    EXPECT_FALSE(ann->welcome.contains("resume_token")) << ann->welcome.dump();
    std::uint64_t const ann_id = ann->id;
    EXPECT_EQ(bob.next("player"), notice("joined", ann_id));
    ann->resume("0123456789abcdef0123456789abcdef");
    expect_bad_resume(ann->reply(), "keeps no player for a resume");
    json const ack = ann->spawn(1, 1.0);
    ASSERT_EQ(ack.at("type"), "ack") << ack.dump();
    std::uint64_t const body = ack.at("id").get<std::uint64_t>();

    ann.reset();
    EXPECT_EQ(bob.next("player"), notice("left", ann_id));
    std::uint64_t const left_by = bob.next("snapshot").at("tick").get<std::uint64_t>();
    for (;;) {
        json const m = bob.next("snapshot");
        if (holds_none(m, {body}))
            break;
        ASSERT_LT(m.at("tick").get<std::uint64_t>(), left_by + 500) << "the body stayed";
    }
    EXPECT_EQ(s.bodies("play"), 1U);
}

// A resume token is a password: each try is a command for the rate limit. With a burst of 3
// and no tokens coming back, 3 of 5 guesses are looked at and 2 refused rate_limited.
TEST(Resume, AttemptsCountAgainstTheCommandRate)
{
    server_options options = resume_room("rate", rules(60.0, "stay"));
    options.client.command_burst = 3;
    options.client.commands_per_second = 0.001;
    test_support::in_process_server s(options);
    player_client guesser(s.port());
    for (int i = 0; i < 5; ++i)
        guesser.resume(std::string(32, static_cast<char>('a' + i)));
    int refused = 0;
    int limited = 0;
    for (int i = 0; i < 5; ++i) {
        json const answer = guesser.reply();
        std::string const code = answer.value("code", "");
        refused += code == "bad_resume" ? 1 : 0;
        limited += code == "rate_limited" ? 1 : 0;
    }
    EXPECT_EQ(refused, 3);
    EXPECT_EQ(limited, 2);
}

// The rules are the scene's when it sets them, else the server's: a demo gets what it was
// written for, and --resume-grace and --bodies-on-leave serve scenes that say nothing.
TEST(Resume, TheScenesRulesWinOverTheServersDefaults)
{
    server_options options = resume_room("scene_wins", rules(2.5, "stay"));
    options.resume_grace = 30.0;
    options.remove_bodies_on_leave = true;
    json plain = test_support::still_scene();
    options.rooms.push_back({"plain", test_support::write_scene(testing::TempDir() + "kugel_resume_plain.json", plain)});
    test_support::in_process_server s(options);

    player_client in_play(s.port());
    EXPECT_EQ(in_play.welcome.at("resume_grace"), 2.5);
    EXPECT_EQ(in_play.welcome.at("bodies_on_leave"), "stay");
    ws_client in_plain(s.port(), "/ws/plain");
    json const welcome = in_plain.next("welcome");
    EXPECT_EQ(schemas().refusal(welcome), "");
    EXPECT_EQ(welcome.at("resume_grace"), 30.0);
    EXPECT_EQ(welcome.at("bodies_on_leave"), "remove");
    EXPECT_TRUE(is_hex_token(welcome.value("resume_token", json()))) << welcome.dump();
}

} // namespace
} // namespace kugel::server
