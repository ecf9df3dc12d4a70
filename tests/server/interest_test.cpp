// Interest over real WebSocket connections (PROTOCOL.md, interest regions): a client that
// states a box, a ball around a body or tags is sent only the bodies inside, in the full form
// and in the compact one, where bodies coming in and going out appear and vanish as spawns and
// removals do; what it decodes is the full form filtered by the same interest at every tick,
// through spawns, removals and changes of interest; a ball follows its body, and stays where
// the body was once it is gone; clients with the same interest share one encoding. Every
// message read is checked against its schema.

#include "room.hpp"
#include "server.hpp"

#include "protocol/codec.hpp"
#include "protocol/compact.hpp"
#include "protocol/message_schemas.hpp"
#include "support/same_snapshot.hpp"
#include "support/in_process_server.hpp"
#include "support/scene_files.hpp"
#include "support/ws_client.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <iterator>
#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

namespace kugel::server {
namespace {

using nlohmann::json;
using protocol::testing::schemas;
using test_support::ws_client;

constexpr char const* admin_token = "interest-admin";

/// No forces, no collisions. Forty bodies cross the middle of the world along x, back and
/// forth at their own speeds: spheres of 0.3 m and point masses, some tagged "red", some
/// "blue", some both ways untagged; and a static post at the origin, tagged "post".
json field_scene()
{
    json bodies = json::array();
    for (int i = 0; i < 40; ++i) {
        double const speed = (i % 2 == 0 ? 1.0 : -1.0) * (0.5 + 0.125 * (i % 7));
        json body = {{"position", {-6.0 + 0.3 * i, -3.0 + 0.15 * i, 0.1 * (i % 5)}},
                     {"velocity", {speed, 0.0, 0.0}},
                     {"radius", i % 3 == 0 ? 0.0 : 0.3},
                     {"mass", 1.0 + i}};
        if (i % 4 == 0)
            body["tag"] = "red";
        else if (i % 4 == 1)
            body["tag"] = "blue";
        bodies.push_back(body);
    }
    bodies.push_back({{"position", {0, 0, 0}}, {"radius", 0.5}, {"static", true}, {"tag", "post"}});
    return {{"name", "field"},
            {"dt", 1.0 / 64.0},
            {"integrator", "semi_implicit_euler"},
            {"collisions", {{"mode", "off"}}},
            {"box", {{"min", {-40, -40, -40}}, {"max", {40, 40, 40}}}},
            {"bodies", bodies}};
}

server_options field_options(std::string const& name)
{
    server_options o;
    o.admin_token = admin_token;
    o.rooms.push_back({"field", test_support::write_scene(testing::TempDir() + "kugel_interest_" + name + ".json",
                                                          field_scene())});
    o.tick_rate = 100.0;
    o.snapshot_rate = 50.0;
    o.keyframe_interval = 2.0;
    // The tests read their clients in turn, and under the sanitizers decoding a snapshot
    // takes longer than the room takes to send the next: a client waiting its turn is not
    // one that stopped reading.
    o.client.write_stall = std::chrono::milliseconds(120'000);
    return o;
}

/// An interest as the test states it, and the rule it holds snapshots to.
struct interest
{
    std::optional<std::array<std::array<double, 3>, 2>> box; ///< min, max
    std::optional<std::array<double, 3>> centre;            ///< a ball's, where it stands
    double radius = 0.0;
    std::optional<std::set<std::string>> tags;

    /// Whether body i of `s` is inside: its sphere touches the region and it carries a tag.
    bool holds(protocol::snapshot const& s, std::size_t i) const
    {
        if (tags) {
            std::string const tag = s.bodies.tag ? (*s.bodies.tag)[i] : std::string();
            if (tag.empty() || !tags->contains(tag))
                return false;
        }
        double const* x = &s.bodies.position[3 * i];
        double const r = s.bodies.radius[i];
        std::array<double, 3> gap{};
        for (std::size_t k = 0; k < 3; ++k) {
            if (box)
                gap[k] = std::max({(*box)[0][k] - x[k], x[k] - (*box)[1][k], 0.0});
            else if (centre)
                gap[k] = std::abs(x[k] - (*centre)[k]);
        }
        double const reach = box ? r : centre ? radius + r : 0.0;
        return std::hypot(gap[0], gap[1], gap[2]) <= reach;
    }

    std::set<std::uint64_t> ids_in(protocol::snapshot const& s) const
    {
        std::set<std::uint64_t> out;
        for (std::size_t i = 0; i < s.bodies.size(); ++i)
            if (holds(s, i))
                out.insert(s.bodies.id[i]);
        return out;
    }
};

std::set<std::uint64_t> ids_of(protocol::snapshot const& s)
{
    return {s.bodies.id.begin(), s.bodies.id.end()};
}

/// A client of room "field". Every message it reads is checked against its schema; compact
/// snapshots are applied as a client library would, and refused if they cannot be.
struct client
{
    ws_client ws;
    json welcome;
    bool compact = false;
    std::optional<protocol::compact_state> held;
    int keys = 0, deltas = 0;
    /// ids, over every snapshot applied: a delta's, and the difference a keyframe made
    std::multiset<std::uint64_t> appeared, vanished;
    json last_compact;                                ///< the last compact snapshot, as sent

    explicit client(std::uint16_t port, json const& hello = {}) : ws(port, "/ws/field")
    {
        welcome = expect("welcome");
        if (hello.is_null())
            return;
        ws.send(hello);
        if (hello.contains("snapshots")) {
            welcome = welcome_again();
            compact = welcome.at("snapshots").at("form") == "compact";
        }
    }

    /// The next welcome (after a hello that asks for one), passing snapshots on the way.
    json welcome_again()
    {
        for (;;) {
            json message = read();
            if (message.at("type") == "welcome")
                return message;
            if (message.at("type") == "snapshot")
                take(message);
            else
                answers.push_back(std::move(message));
        }
    }

    /// The tick from which what this client sent so far holds (a ping is answered at once,
    /// with the last tick completed; what was sent before it is applied at the next).
    std::uint64_t settled(std::uint64_t ref)
    {
        ws.send(json{{"type", "ping"}, {"ref", ref}});
        json const pong = answer(ref);
        EXPECT_EQ(pong.at("type"), "pong") << pong.dump();
        return pong.at("tick").get<std::uint64_t>() + 1;
    }

    json read()
    {
        json message = ws.read_json();
        EXPECT_EQ(schemas().refusal(message), "") << message.dump().substr(0, 300);
        return message;
    }

    json expect(std::string const& type)
    {
        json message = read();
        EXPECT_EQ(message.at("type"), type) << message.dump().substr(0, 300);
        return message;
    }

    /// The world as a snapshot shows it: the full form's columns (a compact one applied).
    protocol::snapshot take(json const& message)
    {
        auto const decoded = protocol::decode_server_message(message.dump());
        if (!decoded.message)
            throw std::runtime_error("undecodable: " + decoded.failure->message);
        if (auto const* full = std::get_if<protocol::snapshot>(&*decoded.message))
            return *full;
        auto const& c = std::get<protocol::compact_snapshot>(*decoded.message);
        (c.form == "key" ? keys : deltas) += 1;
        if (c.appeared)
            appeared.insert(c.appeared->id.begin(), c.appeared->id.end());
        if (c.vanished)
            vanished.insert(c.vanished->begin(), c.vanished->end());
        auto result = protocol::apply_compact(c, held ? &*held : nullptr);
        if (!result.state)
            throw std::runtime_error("a snapshot it cannot apply: " + result.failure);
        if (c.form == "key" && held) {
            // A keyframe after a skipped snapshot: what came and went since the one held
            std::vector<std::uint64_t> const& before = held->bodies.id;
            std::vector<std::uint64_t> const& after = result.state->bodies.id; // both sorted
            std::set_difference(after.begin(), after.end(), before.begin(), before.end(),
                                std::inserter(appeared, appeared.end()));
            std::set_difference(before.begin(), before.end(), after.begin(), after.end(),
                                std::inserter(vanished, vanished.end()));
        }
        held = std::move(result.state);
        last_compact = message;
        return protocol::to_snapshot(*held);
    }

    /// The next snapshot; answers on the way are kept for answer().
    protocol::snapshot next_snapshot()
    {
        for (;;) {
            json message = read();
            if (message.at("type") == "snapshot")
                return take(message);
            answers.push_back(std::move(message));
        }
    }

    /// The first snapshot of `tick` or later.
    protocol::snapshot snapshot_at_or_after(std::uint64_t tick)
    {
        for (;;) {
            protocol::snapshot s = next_snapshot();
            if (s.tick >= tick)
                return s;
        }
    }

    /// The first message other than a snapshot that `wanted` takes, applying the snapshots
    /// that come before it; the others are kept for later.
    template <class Wanted>
    json first_answer(Wanted wanted)
    {
        for (;;) {
            for (auto it = answers.begin(); it != answers.end(); ++it)
                if (wanted(*it)) {
                    json found = *it;
                    answers.erase(it);
                    return found;
                }
            json message = read();
            if (message.at("type") == "snapshot")
                take(message);
            else
                answers.push_back(std::move(message));
        }
    }

    /// The answer (ack or error) to `ref`.
    json answer(std::uint64_t ref)
    {
        return first_answer([&](json const& m) { return m.value("ref", json()) == ref; });
    }

    /// The next error without a ref (a hello's refusal).
    json refusal()
    {
        return first_answer([](json const& m) { return m.at("type") == "error" && !m.contains("ref"); });
    }

    /// Sends a command and returns the tick of its ack.
    std::uint64_t acked(json command)
    {
        std::uint64_t const ref = command.at("ref").get<std::uint64_t>();
        ws.send(command);
        json const a = answer(ref);
        EXPECT_EQ(a.at("type"), "ack") << a.dump();
        return a.value("tick", std::uint64_t{0});
    }

    std::vector<json> answers;
};


TEST(Interest, ABoxShowsTheBodiesTouchingItInTheFullForm)
{
    test_support::in_process_server s(field_options("box"));
    client everything(s.port());
    client watcher(s.port());
    interest const box{.box = std::array{std::array{-1.5, -1.0, -0.5}, std::array{1.5, 1.0, 0.5}}};
    std::uint64_t const from = watcher.acked(
        json{{"type", "interest"}, {"ref", 1}, {"box", {{"min", {-1.5, -1.0, -0.5}}, {"max", {1.5, 1.0, 0.5}}}}});

    int compared = 0;
    std::set<std::uint64_t> seen;
    bool touching_only = false; // a sphere inside whose centre is not
    while (compared < 60) {
        protocol::snapshot const mine = watcher.snapshot_at_or_after(from);
        protocol::snapshot const all = everything.snapshot_at_or_after(mine.tick);
        if (all.tick != mine.tick)
            continue; // one of them was sent a later snapshot: compare the next
        ++compared;
        ASSERT_EQ(ids_of(mine), box.ids_in(all)) << "tick " << mine.tick;
        for (std::size_t i = 0; i < mine.bodies.size(); ++i) {
            seen.insert(mine.bodies.id[i]);
            double const* x = &mine.bodies.position[3 * i];
            if (std::abs(x[0]) > 1.5 || std::abs(x[1]) > 1.0 || std::abs(x[2]) > 0.5)
                touching_only = true;
        }
        // The tag column only while a body sent has a tag, as the room writes it.
        if (mine.bodies.tag) {
            EXPECT_TRUE(std::any_of(mine.bodies.tag->begin(), mine.bodies.tag->end(),
                                    [](std::string const& t) { return !t.empty(); }));
        }
    }
    EXPECT_TRUE(seen.contains(41)) << "the static post at the origin is a body like any other";
    EXPECT_GE(seen.size(), 6U) << "bodies crossed the box";
    EXPECT_TRUE(touching_only) << "a sphere whose centre is outside the box, touching it, is inside";
}

// The compact stream of a client with an interest, against the full form of a client without
// one, filtered by the same interest, at every tick both were sent: through bodies crossing
// the region, an admin's spawns inside and outside it (tagged and not) and removals, and two
// changes of interest. Bodies that come in appear with their constants, those that go out
// vanish, and the stream is deltas.
TEST(Interest, TheCompactStreamIsTheFullFormFilteredByTheSameInterestThroughChurn)
{
    // Fewer snapshots than the other tests: each is decoded twice here, and a client that
    // falls behind has its snapshots replaced, which leaves fewer ticks to compare.
    server_options o = field_options("churn");
    o.snapshot_rate = 10.0;
    test_support::in_process_server s(o);
    client everything(s.port());
    client admin(s.port(), json{{"type", "hello"}, {"admin_token", admin_token}});
    admin.welcome_again();
    client watcher(s.port(), json{{"type", "hello"},
                                  {"snapshots", {{"form", "compact"}}},
                                  {"interest", {{"box", {{"min", {-2, -2, -1}}, {"max", {2, 2, 1}}}},
                                                {"tags", {"red", "blue"}}}}});
    ASSERT_TRUE(watcher.compact);
    std::uint64_t interest_from = watcher.settled(1);

    interest current{.box = std::array{std::array{-2.0, -2.0, -1.0}, std::array{2.0, 2.0, 1.0}},
                     .tags = std::set<std::string>{"red", "blue"}};
    std::uint64_t ref = 100;
    std::vector<std::uint64_t> spawned;
    int compared = 0;
    // Scene bodies (ids 1 to 41) are never spawned or removed: each of their appearances and
    // vanishings is a body crossing the region, or a change of interest.
    auto const scene_bodies = [](std::multiset<std::uint64_t> const& ids) {
        return std::count_if(ids.begin(), ids.end(), [](std::uint64_t id) { return id <= 41; });
    };
    // 24 rounds at least, and until 100 ticks were compared and scene bodies came and went 5
    // times each (a slow machine, or the sanitizers, skip more snapshots), at most 48
    auto const seen_enough = [&] {
        return compared >= 100 && scene_bodies(watcher.appeared) >= 5 && scene_bodies(watcher.vanished) >= 5;
    };
    for (int round = 0; round < 48 && (round < 24 || !seen_enough()); ++round) {
        // Churn from the admin: a tagged body inside the region, an untagged one, and one far
        // off; a removal every other round.
        for (int k = 0; k < 3; ++k) {
            json body = {{"position", {k == 2 ? 15.0 : -1.0 + 0.1 * round, 0.5 * k - 0.5, 0.0}},
                         {"velocity", {0.25 * (k - 1), 0.0, 0.0}},
                         {"radius", 0.1},
                         {"mass", 2.0}};
            if (k != 1)
                body["tag"] = round % 2 == 0 ? "red" : "blue";
            admin.ws.send(json{{"type", "spawn"}, {"ref", ++ref}, {"body", body}});
            json const a = admin.answer(ref);
            ASSERT_EQ(a.at("type"), "ack") << a.dump();
            spawned.push_back(a.at("id").get<std::uint64_t>());
        }
        if (round % 2 == 1) {
            admin.acked(json{{"type", "remove"}, {"ref", ++ref}, {"id", spawned.front()}});
            spawned.erase(spawned.begin());
        }
        // Changes of interest: a ball around a moving body, then tags alone, then back.
        if (round == 8) {
            interest_from = watcher.acked(json{{"type", "interest"}, {"ref", ++ref}, {"tags", {"red"}}});
            current = interest{.tags = std::set<std::string>{"red"}};
        }
        if (round == 16) {
            interest_from = watcher.acked(json{{"type", "interest"}, {"ref", ++ref},
                                               {"box", {{"min", {-3, -3, -1}}, {"max", {0, 3, 1}}}}});
            current = interest{.box = std::array{std::array{-3.0, -3.0, -1.0}, std::array{0.0, 3.0, 1.0}}};
        }
        for (int n = 0; n < 12; ++n) {
            protocol::snapshot const mine = watcher.next_snapshot();
            if (mine.tick < interest_from)
                continue; // the interest before
            protocol::snapshot const all = everything.snapshot_at_or_after(mine.tick);
            if (all.tick != mine.tick)
                continue;
            ++compared;
            ASSERT_EQ(ids_of(mine), current.ids_in(all)) << "tick " << mine.tick;
            test_support::expect_bodies_of(mine, all, watcher.held->q);
            if (HasFatalFailure())
                return;
        }
    }
    EXPECT_GE(compared, 100);
    EXPECT_GT(watcher.deltas, 10 * watcher.keys) << "deltas, not keyframes, are the stream";
    EXPECT_GE(scene_bodies(watcher.appeared), 5);
    EXPECT_GE(scene_bodies(watcher.vanished), 5);
}

// A change of interest comes as a delta from what the client holds (bodies that leave vanish,
// those that come appear), a refused change changes nothing, and a cleared interest is every
// body again.
TEST(Interest, ChangingAndClearingItAtRunTime)
{
    test_support::in_process_server s(field_options("change"));
    client everything(s.port());
    client watcher(s.port(), json{{"type", "hello"}, {"snapshots", {{"form", "compact"}}}});
    watcher.next_snapshot();

    // Only the red bodies, then the red and the blue, then only the blue: each change is a
    // delta from the bodies the client holds, its first snapshot of the tick acked.
    std::uint64_t t = watcher.acked(json{{"type", "interest"}, {"ref", 1}, {"tags", {"red"}}});
    protocol::snapshot mine = watcher.snapshot_at_or_after(t);
    interest const red{.tags = std::set<std::string>{"red"}};
    EXPECT_EQ(ids_of(mine).size(), 10U);
    protocol::snapshot all = everything.snapshot_at_or_after(mine.tick);
    if (all.tick == mine.tick) {
        EXPECT_EQ(ids_of(mine), red.ids_in(all));
    }

    t = watcher.acked(json{{"type", "interest"}, {"ref", 2}, {"tags", {"red", "blue"}}});
    mine = watcher.snapshot_at_or_after(t);
    EXPECT_EQ(watcher.last_compact.at("form"), "delta") << "a change of interest is a delta";
    EXPECT_EQ(watcher.last_compact.at("appeared").at("id").size(), 10U) << watcher.last_compact.dump();
    EXPECT_FALSE(watcher.last_compact.contains("vanished"));
    EXPECT_EQ(ids_of(mine).size(), 20U);

    t = watcher.acked(json{{"type", "interest"}, {"ref", 3}, {"tags", {"blue"}}});
    mine = watcher.snapshot_at_or_after(t);
    EXPECT_EQ(watcher.last_compact.at("form"), "delta");
    EXPECT_EQ(watcher.last_compact.at("vanished").size(), 10U) << watcher.last_compact.dump();
    EXPECT_FALSE(watcher.last_compact.contains("appeared"));
    interest const blue{.tags = std::set<std::string>{"blue"}};
    all = everything.snapshot_at_or_after(mine.tick);
    if (all.tick == mine.tick) {
        EXPECT_EQ(ids_of(mine), blue.ids_in(all));
    }

    // Refused: a ball around a body that is not there, by command and by hello. Nothing
    // changes: the next snapshots still hold the blue bodies.
    watcher.ws.send(json{{"type", "interest"}, {"ref", 30}, {"around", {{"body", 4242}, {"radius", 2}}}});
    json const refused = watcher.answer(30);
    EXPECT_EQ(refused.value("code", ""), "unknown_body") << refused.dump();
    EXPECT_EQ(refused.value("message", "").rfind("/around/body: ", 0), 0U) << refused.dump();
    watcher.ws.send(json{{"type", "hello"}, {"interest", {{"around", {{"body", 4242}, {"radius", 2}}}}}});
    json const hello_refused = watcher.refusal();
    EXPECT_EQ(hello_refused.value("code", ""), "unknown_body") << hello_refused.dump();
    EXPECT_EQ(hello_refused.value("message", "").rfind("/interest/around/body: ", 0), 0U) << hello_refused.dump();
    mine = watcher.snapshot_at_or_after(watcher.settled(4));
    EXPECT_EQ(ids_of(mine).size(), 10U);
    for (std::uint64_t const id : ids_of(mine))
        EXPECT_EQ((id - 1) % 4, 1U) << "body " << id << " is not blue";

    // Cleared by a hello's `{}`: every body again.
    watcher.ws.send(json{{"type", "hello"}, {"interest", json::object()}});
    mine = watcher.snapshot_at_or_after(watcher.settled(5));
    EXPECT_EQ(ids_of(mine).size(), 41U);
    // And the command without region or tags clears it too.
    t = watcher.acked(json{{"type", "interest"}, {"ref", 6}, {"tags", {"post"}}});
    EXPECT_EQ(ids_of(watcher.snapshot_at_or_after(t)), (std::set<std::uint64_t>{41}));
    t = watcher.acked(json{{"type", "interest"}, {"ref", 7}});
    EXPECT_EQ(ids_of(watcher.snapshot_at_or_after(t)).size(), 41U);
}

// A ball around a body moves with it: at every snapshot the bodies inside are those near the
// followed body there. Once the body is gone, the ball stays where it was last.
TEST(Interest, ABallFollowsItsBodyAndStaysWhereItWentOut)
{
    test_support::in_process_server s(field_options("around"));
    client everything(s.port());
    client watcher(s.port());
    // The runner: a point mass crossing the field along y = 0.5 faster than anything there.
    watcher.ws.send(json{{"type", "spawn"},
                         {"ref", 1},
                         {"body", {{"position", {-8, 0.5, 0}}, {"velocity", {3, 0, 0}}, {"radius", 0.0}, {"mass", 1.0}}}});
    json const spawned = watcher.answer(1);
    ASSERT_EQ(spawned.at("type"), "ack") << spawned.dump();
    std::uint64_t const runner = spawned.at("id").get<std::uint64_t>();
    std::uint64_t const from = watcher.acked(
        json{{"type", "interest"}, {"ref", 2}, {"around", {{"body", runner}, {"radius", 1.5}}}});

    int compared = 0;
    std::set<std::uint64_t> seen;
    while (compared < 80) {
        protocol::snapshot const mine = watcher.snapshot_at_or_after(from);
        protocol::snapshot const all = everything.snapshot_at_or_after(mine.tick);
        if (all.tick != mine.tick)
            continue;
        ++compared;
        auto const at = static_cast<std::size_t>(std::find(all.bodies.id.begin(), all.bodies.id.end(), runner) -
                                                 all.bodies.id.begin());
        ASSERT_LT(at, all.bodies.size());
        interest const ball{.centre = std::array{all.bodies.position[3 * at], all.bodies.position[3 * at + 1],
                                                 all.bodies.position[3 * at + 2]},
                            .radius = 1.5};
        ASSERT_EQ(ids_of(mine), ball.ids_in(all)) << "tick " << mine.tick;
        EXPECT_TRUE(ids_of(mine).contains(runner));
        seen.insert(mine.bodies.id.begin(), mine.bodies.id.end());
    }
    EXPECT_GE(seen.size(), 5U) << "the ball met bodies along the way";

    // Stopped, then removed: the ball stays where the runner stood.
    std::uint64_t const stopped = watcher.acked(json{{"type", "set"}, {"ref", 3}, {"id", runner}, {"velocity", {0, 0, 0}}});
    protocol::snapshot const last = everything.snapshot_at_or_after(stopped + 2);
    auto const at = static_cast<std::size_t>(std::find(last.bodies.id.begin(), last.bodies.id.end(), runner) -
                                             last.bodies.id.begin());
    ASSERT_LT(at, last.bodies.size());
    interest const ball{.centre = std::array{last.bodies.position[3 * at], last.bodies.position[3 * at + 1],
                                             last.bodies.position[3 * at + 2]},
                        .radius = 1.5};
    std::uint64_t const removed = watcher.acked(json{{"type", "remove"}, {"ref", 4}, {"id", runner}});
    for (compared = 0; compared < 30;) {
        protocol::snapshot const mine = watcher.snapshot_at_or_after(removed);
        protocol::snapshot const all = everything.snapshot_at_or_after(mine.tick);
        if (all.tick != mine.tick)
            continue;
        ++compared;
        EXPECT_FALSE(ids_of(mine).contains(runner));
        ASSERT_EQ(ids_of(mine), ball.ids_in(all)) << "tick " << mine.tick;
    }
}

// Clients with the same interest (tags in another order) are sent the same bytes, encoded once
// per snapshot; a client with another interest costs one more encoding.
TEST(Interest, ClientsWithTheSameInterestShareOneEncoding)
{
    test_support::in_process_server s(field_options("share"));
    auto const room = s.get().find_room("field");
    json const box = {{"min", {-2, -2, -1}}, {"max", {2, 2, 1}}};
    client ann(s.port(), json{{"type", "hello"}, {"interest", {{"box", box}, {"tags", {"red", "blue"}}}}});
    client bob(s.port(), json{{"type", "hello"}, {"interest", {{"box", box}, {"tags", {"blue", "red", "blue"}}}}});
    std::uint64_t const from = std::max(ann.settled(1), bob.settled(1));

    auto const full_encoded = [&] {
        return room->traffic().encoded.snapshots[static_cast<std::size_t>(snapshot_form::full)].load();
    };
    // Read past the interests' first ticks, then count from there.
    ann.snapshot_at_or_after(from);
    bob.snapshot_at_or_after(from);
    std::uint64_t const encoded_before = full_encoded();
    std::uint64_t const snapshots_before = room->counters().snapshots.load();
    std::map<std::uint64_t, std::string> ann_texts;
    int same = 0;
    for (int n = 0; n < 40; ++n) {
        json const a = ann.read();
        if (a.at("type") == "snapshot")
            ann_texts[a.at("tick").get<std::uint64_t>()] = a.dump();
    }
    for (int n = 0; n < 40; ++n) {
        json const b = bob.read();
        if (b.at("type") != "snapshot")
            continue;
        auto const found = ann_texts.find(b.at("tick").get<std::uint64_t>());
        if (found == ann_texts.end())
            continue;
        EXPECT_EQ(found->second, b.dump());
        ++same;
    }
    EXPECT_GE(same, 20);
    // One full form a snapshot for both (the one being encoded may be counted already).
    std::uint64_t const snapshots = room->counters().snapshots.load() - snapshots_before;
    EXPECT_LE(full_encoded() - encoded_before, snapshots + 1);
    EXPECT_GE(snapshots, 30U);

    // A third client with another interest: two full forms a snapshot from then on.
    client cy(s.port());
    std::uint64_t const t = cy.acked(json{{"type", "interest"}, {"ref", 1}, {"tags", {"post"}}});
    cy.snapshot_at_or_after(t + 1);
    std::uint64_t const encoded_then = full_encoded();
    std::uint64_t const snapshots_then = room->counters().snapshots.load();
    for (int n = 0; n < 20; ++n)
        cy.next_snapshot();
    std::uint64_t const later = room->counters().snapshots.load() - snapshots_then;
    EXPECT_GE(later, 10U);
    // (a snapshot being encoded when the counts were read may have had both views counted)
    EXPECT_GE(full_encoded() - encoded_then + 2, 2 * later);
}

} // namespace
} // namespace kugel::server
