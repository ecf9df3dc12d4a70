// Who may do what, end to end over real WebSocket connections to a server in this process:
// which browser origins may connect, what an admin may do that others may not (pause,
// resume, reset, load_scene, removing anyone's body), and the per-client body cap. Every
// message a client reads is checked against its schema. Waits count ticks, never time.

#include "room.hpp"
#include "server.hpp"

#include "protocol/message_schemas.hpp"
#include "support/http_get.hpp"
#include "support/in_process_server.hpp"
#include "support/scene_files.hpp"
#include "support/ws_client.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <stdexcept>
#include <string>

namespace kugel::server {
namespace {

using nlohmann::json;
using protocol::testing::schemas;
using test_support::ws_client;
using test_support::drop_scene;
namespace fs = std::filesystem;

constexpr char const* token = "correct-horse-battery-staple";

/// A client whose every message is checked against its schema.
class client
{
public:
    explicit client(std::uint16_t port, std::string const& target = "/ws/still",
                    std::string const& origin = {})
        : ws_(port, target, origin)
    {
        welcome_ = next("welcome");
    }

    json read()
    {
        json message = ws_.read_json();
        EXPECT_EQ(schemas().refusal(message), "") << message.dump();
        return message;
    }

    json next(std::string const& type)
    {
        for (int i = 0; i < 10'000; ++i) {
            json message = read();
            if (message.at("type") == type)
                return message;
        }
        throw std::runtime_error("no " + type);
    }

    /// The ack or error answering `ref`.
    json answer(std::uint64_t ref)
    {
        for (int i = 0; i < 10'000; ++i) {
            json message = read();
            if ((message.at("type") == "ack" || message.at("type") == "error") &&
                message.value("ref", json()) == ref)
                return message;
        }
        throw std::runtime_error("no answer to ref " + std::to_string(ref));
    }

    /// Sends a command and returns its answer.
    json command(json message)
    {
        std::uint64_t const ref = message.at("ref");
        ws_.send(message);
        return answer(ref);
    }

    /// Proves itself an admin; returns the welcome that answers.
    json become_admin()
    {
        ws_.send(json{{"type", "hello"}, {"admin_token", token}});
        welcome_ = next("welcome");
        return welcome_;
    }

    /// The first snapshot with tick >= `tick`.
    json snapshot_at_or_after(std::uint64_t tick)
    {
        for (;;) {
            json s = next("snapshot");
            if (s.at("tick").get<std::uint64_t>() >= tick)
                return s;
        }
    }

    void send(json const& message) { ws_.send(message); }
    json const& welcome() const { return welcome_; }

private:
    ws_client ws_;
    json welcome_;
};

server_options still_room(std::string const& test_name)
{
    server_options o;
    o.rooms.push_back({"still", test_support::write_scene(fs::path(testing::TempDir()) /
                                                              ("kugel_access_" + test_name + ".json"),
                                                          test_support::still_scene())});
    o.admin_token = token;
    return o;
}

json spawn_at(std::uint64_t ref, std::array<double, 3> position)
{
    return {{"type", "spawn"}, {"ref", ref}, {"body", {{"position", position}, {"radius", 0.1}, {"mass", 1.0}}}};
}

json command(std::string const& type, std::uint64_t ref)
{
    return {{"type", type}, {"ref", ref}};
}

json impulse(std::uint64_t ref, std::uint64_t id, std::array<double, 3> j)
{
    return {{"type", "impulse"}, {"ref", ref}, {"id", id}, {"impulse", j}};
}

json remove(std::uint64_t ref, std::uint64_t id)
{
    return {{"type", "remove"}, {"ref", ref}, {"id", id}};
}

std::vector<std::uint64_t> ids(json const& snapshot)
{
    return snapshot.at("bodies").at("id").get<std::vector<std::uint64_t>>();
}

void expect_refused(json const& answer, std::string const& code, std::string const& pointer)
{
    EXPECT_EQ(answer.at("type"), "error") << answer.dump();
    EXPECT_EQ(answer.value("code", ""), code) << answer.dump();
    EXPECT_EQ(answer.value("message", "").rfind(pointer + ": ", 0), 0U) << answer.dump();
}

// Origins ---------------------------------------------------------------------------------

TEST(Access, AnotherSitesPageIsRefusedWith403SayingWhichOriginAndHowToAllowIt)
{
    test_support::in_process_server s(still_room("origin_refused"));
    std::string const host = "127.0.0.1:" + std::to_string(s.port());
    auto const reply = test_support::websocket_upgrade(s.port(), "/ws/still", "http://evil.example", host);
    EXPECT_EQ(reply.status, 403U);
    EXPECT_NE(reply.body.find("http://evil.example"), std::string::npos) << reply.body;
    EXPECT_NE(reply.body.find("--allow-origin http://evil.example"), std::string::npos) << reply.body;
    // Another port of the same machine is another site.
    EXPECT_EQ(test_support::websocket_upgrade(s.port(), "/ws/still", "http://127.0.0.1:1", host).status, 403U);
    EXPECT_THROW(ws_client(s.port(), "/ws/still", "http://evil.example"), std::exception);
}

TEST(Access, TheServersOwnPageAndProgramsWithoutOriginAreLetIn)
{
    test_support::in_process_server s(still_room("origin_own"));
    std::string const own = "http://127.0.0.1:" + std::to_string(s.port());
    std::string const host = "127.0.0.1:" + std::to_string(s.port());
    EXPECT_EQ(test_support::websocket_upgrade(s.port(), "/ws/still", own, host).status, 101U);
    EXPECT_EQ(test_support::websocket_upgrade(s.port(), "/ws/still", "", host).status, 101U);
    client page(s.port(), "/ws/still", own);
    EXPECT_EQ(page.welcome().at("room"), "still");
}

TEST(Access, AllowedOriginsAreLetInAndStarLetsEveryOriginIn)
{
    server_options o = still_room("origin_allowed");
    o.allowed_origins = {"https://viewer.example.org"};
    test_support::in_process_server s(o);
    std::string const host = "127.0.0.1:" + std::to_string(s.port());
    EXPECT_EQ(test_support::websocket_upgrade(s.port(), "/ws/still", "https://viewer.example.org", host).status, 101U);
    EXPECT_EQ(test_support::websocket_upgrade(s.port(), "/ws/still", "https://other.example.org", host).status, 403U);
    client viewer(s.port(), "/ws/still", "https://viewer.example.org");
    EXPECT_EQ(viewer.welcome().at("room"), "still");

    server_options every = still_room("origin_star");
    every.allowed_origins = {"*"};
    test_support::in_process_server open(every);
    EXPECT_EQ(test_support::websocket_upgrade(open.port(), "/ws/still", "http://evil.example",
                                              "127.0.0.1:" + std::to_string(open.port()))
                  .status,
              101U);
}

TEST(Access, AnAllowOriginThatIsNoOriginStopsTheStart)
{
    server_options o = still_room("origin_bad");
    o.allowed_origins = {"example.org/page"};
    EXPECT_THROW(test_support::in_process_server{o}, std::invalid_argument);
}

// Admins ----------------------------------------------------------------------------------

TEST(Admin, TheRightTokenMakesAnAdminAndANewWelcomeSaysSo)
{
    test_support::in_process_server s(still_room("admin_welcome"));
    client c(s.port());
    json const first = c.welcome();
    EXPECT_EQ(first.at("admin"), false);
    EXPECT_EQ(first.at("limits").at("max_bodies_per_client"), 1000);
    json const welcome = c.become_admin();
    EXPECT_EQ(welcome.at("admin"), true);
    EXPECT_EQ(welcome.at("client"), first.at("client"));
    EXPECT_EQ(welcome.at("scene"), first.at("scene"));
    EXPECT_FALSE(welcome.at("limits").contains("max_bodies_per_client")); // admins are exempt
    EXPECT_EQ(c.command(command("pause", 1)).at("type"), "ack");
}

TEST(Admin, AWrongTokenIsForbiddenAndTheClientStaysOrdinary)
{
    test_support::in_process_server s(still_room("admin_wrong"));
    client c(s.port());
    c.send(json{{"type", "hello"}, {"admin_token", "correct-horse-battery-stapler"}});
    json const refused = c.next("error");
    expect_refused(refused, "forbidden", "/admin_token");
    EXPECT_FALSE(refused.contains("ref"));
    expect_refused(c.command(command("pause", 2)), "forbidden", "/type");

    // Without a configured token nobody is an admin, whatever the hello says.
    server_options none = still_room("admin_none");
    none.admin_token.clear();
    test_support::in_process_server s2(none);
    client d(s2.port());
    d.send(json{{"type", "hello"}, {"admin_token", ""}});
    expect_refused(d.next("error"), "forbidden", "/admin_token");
    expect_refused(d.command(command("reset", 3)), "forbidden", "/type");
}

TEST(Admin, EveryAdminCommandFromANonAdminIsForbiddenAndChangesNothing)
{
    test_support::in_process_server s(still_room("admin_forbidden"));
    client admin(s.port());
    admin.become_admin();
    client mallory(s.port());
    // Something that moves, so that a pause or a reset would show.
    ASSERT_EQ(admin.command(impulse(1, 1, {2.0, 0.0, 0.0})).at("type"), "ack");
    json const spawned = admin.command(spawn_at(2, {0, 5, 0}));
    ASSERT_EQ(spawned.at("type"), "ack");

    std::uint64_t ref = 10;
    for (json const& m : {command("pause", ref++), command("resume", ref++), command("reset", ref++),
                          json{{"type", "load_scene"}, {"ref", ref++}, {"scene", drop_scene()}},
                          remove(ref++, 1), remove(ref++, spawned.at("id"))}) {
        SCOPED_TRACE(m.dump());
        json const answer = mallory.command(m);
        expect_refused(answer, "forbidden", m.at("type") == "remove" ? "/id" : "/type");
        EXPECT_EQ(answer.at("ref"), m.at("ref"));
    }

    // Nothing changed: the room runs (time goes on), both bodies are there, and the admin
    // is still an admin.
    json const probe = admin.command(impulse(20, 1, {0.0, 0.0, 0.0}));
    ASSERT_EQ(probe.at("type"), "ack");
    json const now = mallory.snapshot_at_or_after(probe.at("tick"));
    json const next = mallory.snapshot_at_or_after(now.at("tick").get<std::uint64_t>() + 1);
    EXPECT_EQ(ids(now), (std::vector<std::uint64_t>{1, spawned.at("id").get<std::uint64_t>()}));
    EXPECT_EQ(now.at("paused"), false);
    EXPECT_GT(next.at("time").get<double>(), now.at("time").get<double>());
    EXPECT_EQ(admin.command(command("pause", 21)).at("type"), "ack");
}

TEST(Admin, PauseStopsTimeWhileTicksAndCommandsGoOnAndResumeStepsAgain)
{
    test_support::in_process_server s(still_room("admin_pause"));
    client admin(s.port());
    admin.become_admin();
    client watcher(s.port());
    ASSERT_EQ(admin.command(impulse(1, 1, {2.0, 0.0, 0.0})).at("type"), "ack"); // 1 m/s along x

    json const paused = admin.command(command("pause", 2));
    ASSERT_EQ(paused.at("type"), "ack");
    std::uint64_t const pause_tick = paused.at("tick");
    json const first = watcher.snapshot_at_or_after(pause_tick);
    json const later = watcher.snapshot_at_or_after(first.at("tick").get<std::uint64_t>() + 3);
    EXPECT_EQ(first.at("paused"), true);
    EXPECT_EQ(later.at("paused"), true);
    EXPECT_GT(later.at("tick"), first.at("tick")) << "ticks go on";
    EXPECT_EQ(later.at("time"), first.at("time")) << "time stands still";
    EXPECT_EQ(later.at("bodies").at("position"), first.at("bodies").at("position"));

    // Commands still apply while paused: a spawn appears, where it was put.
    json const spawned = watcher.command(spawn_at(3, {0, 5, 0}));
    ASSERT_EQ(spawned.at("type"), "ack");
    json const with_spawn = watcher.snapshot_at_or_after(spawned.at("tick"));
    EXPECT_EQ(ids(with_spawn).size(), 2U);
    EXPECT_EQ(with_spawn.at("time"), first.at("time"));
    EXPECT_EQ(admin.command(command("pause", 4)).at("type"), "ack") << "pausing twice is fine";

    json const resumed = admin.command(command("resume", 5));
    ASSERT_EQ(resumed.at("type"), "ack");
    json const running = watcher.snapshot_at_or_after(resumed.at("tick"));
    json const after = watcher.snapshot_at_or_after(running.at("tick").get<std::uint64_t>() + 1);
    EXPECT_EQ(running.at("paused"), false);
    EXPECT_GT(running.at("time").get<double>(), first.at("time").get<double>());
    EXPECT_GT(after.at("time").get<double>(), running.at("time").get<double>());
}

TEST(Admin, ResetBringsBackTheScenesBodiesUnderNewIdsAndIdsKeepIncreasing)
{
    test_support::in_process_server s(still_room("admin_reset"));
    client admin(s.port());
    admin.become_admin();
    client player(s.port());
    ASSERT_EQ(player.command(impulse(1, 1, {2.0, 0.0, 0.0})).at("type"), "ack");
    json const a = player.command(spawn_at(2, {0, 5, 0}));
    json const b = player.command(spawn_at(3, {0, -5, 0}));
    ASSERT_EQ(b.at("type"), "ack");
    std::uint64_t const highest = b.at("id");

    json const reset = admin.command(command("reset", 4));
    ASSERT_EQ(reset.at("type"), "ack");
    json const fresh = player.snapshot_at_or_after(reset.at("tick"));
    ASSERT_EQ(ids(fresh).size(), 1U) << "the spawned bodies are gone";
    EXPECT_GT(ids(fresh)[0], highest) << "the scene's body has a new id";
    EXPECT_EQ(fresh.at("bodies").at("position"), json::array({0.0, 0.0, 0.0}));
    EXPECT_EQ(fresh.at("bodies").at("velocity"), json::array({0.0, 0.0, 0.0}));
    EXPECT_EQ(fresh.at("paused"), false);

    expect_refused(player.command(remove(5, a.at("id"))), "unknown_body", "/id");
    json const again = player.command(spawn_at(6, {0, 5, 0}));
    ASSERT_EQ(again.at("type"), "ack");
    EXPECT_GT(again.at("id").get<std::uint64_t>(), ids(fresh)[0]);
}

TEST(Admin, LoadSceneReplacesTheWorldAndEveryClientGetsAWelcomeOfIt)
{
    test_support::in_process_server s(still_room("admin_load"));
    client admin(s.port());
    admin.become_admin();
    client player(s.port());
    json const before = player.snapshot_at_or_after(1);

    json const loaded = admin.command(json{{"type", "load_scene"}, {"ref", 1}, {"scene", drop_scene()}});
    ASSERT_EQ(loaded.at("type"), "ack") << loaded.dump();
    json const welcome = player.next("welcome");
    EXPECT_EQ(welcome.at("scene").at("name"), "drop");
    EXPECT_EQ(welcome.at("dt"), 0.01);
    EXPECT_EQ(welcome.at("admin"), false);
    EXPECT_EQ(welcome.at("client"), player.welcome().at("client"));
    json const admin_welcome = admin.next("welcome");
    EXPECT_EQ(admin_welcome.at("admin"), true);

    json const after = player.snapshot_at_or_after(loaded.at("tick"));
    ASSERT_EQ(ids(after).size(), 2U);
    for (std::uint64_t const id : ids(after))
        EXPECT_GT(id, ids(before).back()) << "new ids, never an old one";
    EXPECT_GE(after.at("time").get<double>(), before.at("time").get<double>()) << "time goes on";

    // Reset now goes back to the loaded scene.
    json const reset = admin.command(command("reset", 2));
    ASSERT_EQ(reset.at("type"), "ack");
    EXPECT_EQ(ids(player.snapshot_at_or_after(reset.at("tick"))).size(), 2U);
}

TEST(Admin, ABadSceneIsRefusedWithTheLoadersMessageAndChangesNothing)
{
    server_options o = still_room("admin_bad_scene");
    o.max_bodies = 5;
    test_support::in_process_server s(o);
    client admin(s.port());
    admin.become_admin();

    json bad = drop_scene();
    bad["bodies"][1]["radius"] = -1;
    json const refused = admin.command(json{{"type", "load_scene"}, {"ref", 1}, {"scene", bad}});
    expect_refused(refused, "bad_value", "/scene");
    EXPECT_NE(refused.at("message").get<std::string>().find("/bodies/1/radius"), std::string::npos)
        << refused.dump();

    json crowded = drop_scene();
    for (int i = 0; i < 4; ++i) // 6 bodies, one more than the room holds
        crowded["bodies"].push_back({{"position", {-1.5 + i, 1, 1}}, {"radius", 0.1}, {"mass", 1}});
    expect_refused(admin.command(json{{"type", "load_scene"}, {"ref", 2}, {"scene", crowded}}),
                   "room_full", "/scene");
    expect_refused(admin.command(json{{"type", "load_scene"}, {"ref", 3}, {"scene", json::object()}}),
                   "bad_value", "/scene");
    json odd_quanta = drop_scene();
    odd_quanta["snapshots"] = {{"position_quantum", -0.001}};
    json const quanta_refused = admin.command(json{{"type", "load_scene"}, {"ref", 5}, {"scene", odd_quanta}});
    expect_refused(quanta_refused, "bad_value", "/scene");
    EXPECT_NE(quanta_refused.at("message").get<std::string>().find("/snapshots/position_quantum: must be > 0"),
              std::string::npos)
        << quanta_refused.dump();

    // Still the still scene: its one body, and no new welcome came before this snapshot.
    json const spawned = admin.command(spawn_at(4, {0, 5, 0}));
    ASSERT_EQ(spawned.at("type"), "ack");
    json const snapshot = admin.snapshot_at_or_after(spawned.at("tick"));
    EXPECT_EQ(ids(snapshot), (std::vector<std::uint64_t>{1, spawned.at("id").get<std::uint64_t>()}));
}

// Ownership and the per-client cap ----------------------------------------------------------

TEST(Ownership, AClientRemovesOnlyItsOwnBodiesAndAnAdminAnyBody)
{
    test_support::in_process_server s(still_room("ownership"));
    client alice(s.port());
    client bob(s.port());
    client admin(s.port());
    admin.become_admin();
    json const alices = alice.command(spawn_at(1, {0, 5, 0}));
    json const bobs = bob.command(spawn_at(1, {0, -5, 0}));
    ASSERT_EQ(bobs.at("type"), "ack");

    expect_refused(bob.command(remove(2, alices.at("id"))), "forbidden", "/id");
    expect_refused(bob.command(remove(3, 1)), "forbidden", "/id"); // the scene's body
    EXPECT_EQ(bob.command(impulse(4, alices.at("id"), {0, 0, 1})).at("type"), "ack") << "impulses stay open";
    EXPECT_EQ(alice.command(remove(2, alices.at("id"))).at("type"), "ack");
    EXPECT_EQ(admin.command(remove(1, bobs.at("id"))).at("type"), "ack");
    json const removed = admin.command(remove(2, 1));
    ASSERT_EQ(removed.at("type"), "ack");
    EXPECT_TRUE(ids(alice.snapshot_at_or_after(removed.at("tick"))).empty());
}

TEST(BodyCap, SpawnsBeyondTheCapAreRefusedAndRemovalsMakeRoom)
{
    server_options o = still_room("body_cap");
    o.client.max_bodies_per_client = 2;
    test_support::in_process_server s(o);
    client alice(s.port());
    EXPECT_EQ(alice.welcome().at("limits").at("max_bodies_per_client"), 2);
    json const first = alice.command(spawn_at(1, {0, 5, 0}));
    ASSERT_EQ(alice.command(spawn_at(2, {0, 6, 0})).at("type"), "ack");
    json const third = alice.command(spawn_at(3, {0, 7, 0}));
    expect_refused(third, "too_many_bodies", "/");

    client bob(s.port()); // a cap per client, not per room
    EXPECT_EQ(bob.command(spawn_at(1, {0, -5, 0})).at("type"), "ack");

    ASSERT_EQ(alice.command(remove(4, first.at("id"))).at("type"), "ack");
    EXPECT_EQ(alice.command(spawn_at(5, {0, 7, 0})).at("type"), "ack") << "a removal made room";
    expect_refused(alice.command(spawn_at(6, {0, 8, 0})), "too_many_bodies", "/");

    client admin(s.port());
    admin.become_admin();
    for (std::uint64_t ref = 1; ref <= 4; ++ref)
        EXPECT_EQ(admin.command(spawn_at(ref, {1, static_cast<double>(ref), 0})).at("type"), "ack")
            << "admins are exempt";
}

} // namespace
} // namespace kugel::server
