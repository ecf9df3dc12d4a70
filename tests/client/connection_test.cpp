// The client library against a real server in this process, on a free port. Nothing here
// measures time: waits have generous timeouts, and pace is counted in ticks.

#include "client/connection.hpp"
#include "server.hpp"
#include "support/in_process_server.hpp"

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <gtest/gtest.h>
#include <set>
#include <thread>

namespace kugel::client {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

fs::path example_scene(std::string const& name)
{
    return fs::path(KUGEL_SOURCE_DIR) / "client" / "examples" / "scenes" / (name + ".json");
}

/// A server with the example scenes as rooms "still" and "fall".
class running_server : public test_support::in_process_server
{
public:
    explicit running_server(server::server_options options = {})
        : in_process_server(with_examples(std::move(options)))
    {
    }
    std::string url(std::string const& room = "still") const { return in_process_server::url(room); }

private:
    static server::server_options with_examples(server::server_options o)
    {
        o.rooms = {{"still", example_scene("still")},
                   {"fall", example_scene("fall")},
                   {"goal", fs::path(KUGEL_SOURCE_DIR) / "scenes" / "goal.json"}};
        return o;
    }
};

protocol::spawn ball_at(protocol::vec3 position, double mass = 2.0)
{
    protocol::spawn s;
    s.body.position = position;
    s.body.radius = 0.25;
    s.body.mass = mass;
    return s;
}

TEST(Connection, ConnectsAndHasTheWelcome)
{
    running_server s;
    connection c(s.url("fall"));
    EXPECT_EQ(c.welcome().room, "fall");
    EXPECT_EQ(c.welcome().scene.name, "fall");
    EXPECT_EQ(c.welcome().dt, 0.015625);
    EXPECT_EQ(c.welcome().protocol, protocol::protocol_version);
    EXPECT_TRUE(c.is_open());
    EXPECT_NE(c.next_snapshot(10s), nullptr);
}

// A connection opened asking for the goal's events hands out each with next_event, and one
// that asked for none gets none; a ball rolled from the centre spot at 4 m/s enters the goal
// (x = 8) 2 s after its spawn's step starts.
TEST(Connection, AsksForSensorEventsAndHandsOutEach)
{
    running_server s;
    connection_options fan_options;
    fan_options.events = protocol::event_request{.filter = {.sensors = std::vector<std::string>{"goal"}}};
    connection fan(s.url("goal"), fan_options);
    connection quiet(s.url("goal"));
    // The hello went first: once a ping of the fan's is answered, the room holds it.
    ASSERT_TRUE(fan.await_reply(fan.send(protocol::ping{}), 10s));

    protocol::spawn roll = ball_at({0.0, 0.0, 0.0}, 0.4);
    roll.body.velocity = {4.0, 0.0, 0.0};
    roll.body.tag = "ball";
    auto const answer = quiet.await_reply(quiet.send(roll), 10s);
    ASSERT_TRUE(answer);
    auto const& ack = std::get<protocol::ack>(*answer);
    double const start = static_cast<double>(ack.tick - 1) * 0.015625;

    auto const entered = fan.next_event(10s);
    ASSERT_TRUE(entered);
    EXPECT_EQ(entered->kind, "entered");
    EXPECT_EQ(entered->sensor, "goal");
    EXPECT_EQ(entered->body, *ack.id);
    EXPECT_EQ(entered->tag, "ball");
    EXPECT_NEAR(entered->time, start + 2.0, 1e-9); // exact but for rounding (no force)
    EXPECT_FALSE(entered->missed);
    EXPECT_EQ(fan.stats().events, 1U);
    EXPECT_FALSE(fan.next_event(100ms)); // each is handed out once; the next comes after a bounce
    EXPECT_FALSE(quiet.next_event(100ms));
    EXPECT_EQ(quiet.stats().events, 0U);
}

// The newest welcome holds (PROTOCOL.md): a hello that makes the connection an admin brings
// one saying so, and an admin's load_scene one with the new scene; welcome() has each.
TEST(Connection, TheNewestWelcomeHolds)
{
    server::server_options o;
    o.admin_token = "a-token-for-this-test";
    running_server s(std::move(o));
    connection c(s.url("still"));
    EXPECT_FALSE(c.welcome().admin);
    std::string const still = c.welcome().scene.name;
    c.send(protocol::hello{.protocol = {}, .name = "admin", .admin_token = "a-token-for-this-test"});
    auto const admin_by = std::chrono::steady_clock::now() + 10s;
    while (!c.welcome().admin && std::chrono::steady_clock::now() < admin_by)
        std::this_thread::sleep_for(10ms);
    ASSERT_TRUE(c.welcome().admin);

    protocol::load_scene load;
    load.scene.text = R"({"name": "other", "dt": 0.03125, "box": {"min": [-1, -1, -1], "max": [1, 1, 1]}})";
    auto const ack = c.await_reply(c.send(load), 10s);
    ASSERT_TRUE(ack && std::holds_alternative<protocol::ack>(*ack));
    auto const loaded_by = std::chrono::steady_clock::now() + 10s;
    while (c.welcome().scene.name == still && std::chrono::steady_clock::now() < loaded_by)
        std::this_thread::sleep_for(10ms);
    EXPECT_EQ(c.welcome().scene.name, "other");
    EXPECT_EQ(c.welcome().dt, 0.03125);
    EXPECT_TRUE(c.welcome().admin);
}

// players() is the room as the roster and the notices add up to; next_player_notice hands
// each notice out once, in order.
TEST(Connection, KnowsTheRoomsPlayersAndHandsOutEachNotice)
{
    running_server s;
    connection ann(s.url("still"), {.name = "ann"});
    auto const own = ann.next_player_notice(10s); // a renamed player hears its own name
    ASSERT_TRUE(own);
    EXPECT_EQ(*own, (protocol::player_notice{.change = "renamed", .id = ann.welcome().client, .name = "ann"}));
    std::uint64_t bob_id = 0;
    {
        connection bob(s.url("still"), {.name = "bob"});
        bob_id = bob.welcome().client;
        auto const joined = ann.next_player_notice(10s);
        ASSERT_TRUE(joined);
        EXPECT_EQ(*joined, (protocol::player_notice{.change = "joined", .id = bob_id, .name = std::nullopt}));
        auto const renamed = ann.next_player_notice(10s);
        ASSERT_TRUE(renamed);
        EXPECT_EQ(renamed->name, "bob");
        EXPECT_EQ(ann.players(), (std::vector<protocol::player>{{ann.welcome().client, "ann"}, {bob_id, "bob"}}));
        auto const own_bob = bob.next_player_notice(10s); // bob's own name, heard by bob
        ASSERT_TRUE(own_bob);
        EXPECT_EQ(own_bob->name, "bob");
        EXPECT_EQ(bob.players(), ann.players()); // bob's roster named ann, and his own rename named him
    }
    auto const left = ann.next_player_notice(10s);
    ASSERT_TRUE(left);
    EXPECT_EQ(*left, (protocol::player_notice{.change = "left", .id = bob_id, .name = "bob"}));
    EXPECT_EQ(ann.players(), (std::vector<protocol::player>{{ann.welcome().client, "ann"}}));
    EXPECT_FALSE(ann.next_player_notice(100ms)); // each was handed out once
}

// A connection opened with a resume token is that player again: its id, a new token, and
// its body (a remove of it is its own). A token spent already is refused, and that connection
// goes on as the fresh player its first welcome named.
TEST(Connection, OpensAsThePlayerItsResumeTokenNames)
{
    server::server_options o;
    o.resume_grace = 60.0; // the example scenes set no players of their own
    running_server s(std::move(o));
    std::uint64_t ann_id = 0;
    std::uint64_t body = 0;
    std::string token;
    {
        connection ann(s.url(), {.name = "ann"});
        ASSERT_TRUE(ann.resume_token());
        token = *ann.resume_token();
        ann_id = ann.welcome().client;
        EXPECT_FALSE(ann.resumed());
        auto const ack = ann.await_reply(ann.send(ball_at({1, 2, 3})), 10s);
        ASSERT_TRUE(ack && std::holds_alternative<protocol::ack>(*ack));
        body = *std::get<protocol::ack>(*ack).id;
    } // closed: the room keeps ann for her grace

    connection back(s.url(), {.name = "ann", .resume_token = token});
    EXPECT_TRUE(back.resumed());
    EXPECT_FALSE(back.resume_refusal());
    EXPECT_EQ(back.welcome().client, ann_id);
    ASSERT_TRUE(back.resume_token());
    EXPECT_NE(*back.resume_token(), token);
    auto const removed = back.await_reply(back.send(protocol::remove{.id = body}), 10s);
    ASSERT_TRUE(removed);
    EXPECT_TRUE(std::holds_alternative<protocol::ack>(*removed));

    connection stranger(s.url(), {.resume_token = token}); // spent by `back`
    EXPECT_FALSE(stranger.resumed());
    ASSERT_TRUE(stranger.resume_refusal());
    EXPECT_EQ(stranger.resume_refusal()->code, protocol::error_code::bad_resume);
    EXPECT_NE(stranger.welcome().client, ann_id);
    EXPECT_TRUE(stranger.is_open());
}

TEST(Connection, SendGivesFreshRefsAndAwaitReplyTheirAnswers)
{
    running_server s;
    connection c(s.url());
    std::uint64_t const spawn_ref = c.send(ball_at({1, 2, 3}));
    std::uint64_t const ping_ref = c.send(protocol::ping{});
    EXPECT_NE(spawn_ref, ping_ref);
    auto const pong = c.await_reply(ping_ref, 10s);
    ASSERT_TRUE(pong);
    EXPECT_EQ(std::get<protocol::pong>(*pong).ref, ping_ref);
    auto const ack = c.await_reply(spawn_ref, 10s);
    ASSERT_TRUE(ack);
    ASSERT_TRUE(std::holds_alternative<protocol::ack>(*ack));
    EXPECT_TRUE(std::get<protocol::ack>(*ack).id);
    // Each answer is handed out once.
    EXPECT_EQ(c.await_reply(spawn_ref, 50ms), std::nullopt);
}

TEST(Connection, AnswersAreMatchedByRefNotByOrder)
{
    running_server s;
    connection c(s.url());
    // The spawn is refused at the next tick; the ping after it is answered at once.
    std::uint64_t const refused = c.send(ball_at({0, 0, 50}));
    std::uint64_t const ping = c.send(protocol::ping{});
    auto const error = c.await_reply(refused, 10s);
    ASSERT_TRUE(error);
    EXPECT_EQ(std::get<protocol::error>(*error).code, protocol::error_code::outside_world);
    EXPECT_TRUE(c.await_reply(ping, 10s));
    EXPECT_EQ(c.stats().errors.at("outside_world"), 1U);
}

TEST(Connection, AnswersToSentTextAreUnmatched)
{
    running_server s;
    connection c(s.url());
    c.send_text("{not json");
    auto const error = c.next_unmatched_reply(10s);
    ASSERT_TRUE(error);
    EXPECT_EQ(std::get<protocol::error>(*error).code, protocol::error_code::bad_json);
    EXPECT_EQ(ref_of(*error), std::nullopt);
    EXPECT_EQ(c.next_unmatched_reply(50ms), std::nullopt);
}

TEST(Connection, WaitForSnapshotFindsTheSpawnedBodyWithinTheTicks)
{
    running_server s;
    connection c(s.url());
    auto const ack = c.await_reply(c.send(ball_at({1, 1, 1})), 10s);
    ASSERT_TRUE(ack);
    std::uint64_t const id = *std::get<protocol::ack>(*ack).id;
    auto const seen = c.wait_for_snapshot(
        [id](protocol::snapshot const& snapshot) {
            auto const& ids = snapshot.bodies.id;
            return std::find(ids.begin(), ids.end(), id) != ids.end();
        },
        60, 10s);
    ASSERT_EQ(seen.outcome, wait_outcome::matched);
    EXPECT_GE(seen.snapshot->tick, std::get<protocol::ack>(*ack).tick);
}

// A spawn's tag reaches the decoded snapshots of both forms; a set moves the body under the
// same id, and a refused one is answered with its error.
TEST(Connection, SendsSetAndTagsAndDecodesTheTags)
{
    running_server s;
    connection full(s.url());
    connection_options compact_options;
    compact_options.snapshots = protocol::snapshot_request{.form = "compact", .rate = std::nullopt};
    connection compact(s.url(), compact_options);
    protocol::spawn tagged = ball_at({1, 1, 1});
    tagged.body.tag = "ann's \"ball\"";
    auto const ack = full.await_reply(full.send(tagged), 10s);
    ASSERT_TRUE(ack && std::holds_alternative<protocol::ack>(*ack));
    std::uint64_t const id = *std::get<protocol::ack>(*ack).id;
    auto const moved = full.await_reply(
        full.send(protocol::set{.ref = 0, .id = id, .position = protocol::vec3{-2, 0, 4}, .velocity = protocol::vec3{0, 0, 0}}),
        10s);
    ASSERT_TRUE(moved && std::holds_alternative<protocol::ack>(*moved));
    auto const set_tick = std::get<protocol::ack>(*moved).tick;
    auto const tag_of = [id](protocol::snapshot const& x) -> std::optional<std::string> {
        auto const at = std::find(x.bodies.id.begin(), x.bodies.id.end(), id);
        if (at == x.bodies.id.end() || !x.bodies.tag)
            return std::nullopt;
        return (*x.bodies.tag)[static_cast<std::size_t>(at - x.bodies.id.begin())];
    };
    for (connection* c : {&full, &compact}) {
        auto const seen = c->wait_for_snapshot(
            [&](protocol::snapshot const& x) { return x.tick >= set_tick && tag_of(x).has_value(); }, 600, 10s);
        ASSERT_EQ(seen.outcome, wait_outcome::matched);
        EXPECT_EQ(tag_of(*seen.snapshot), "ann's \"ball\"");
        auto const i = static_cast<std::size_t>(
            std::find(seen.snapshot->bodies.id.begin(), seen.snapshot->bodies.id.end(), id) - seen.snapshot->bodies.id.begin());
        EXPECT_NEAR(seen.snapshot->bodies.position[3 * i], -2.0, 1e-3);
        EXPECT_NEAR(seen.snapshot->bodies.position[3 * i + 2], 4.0, 1e-3);
    }
    auto const refused = full.await_reply(full.send(protocol::set{.ref = 0, .id = id, .position = protocol::vec3{0, 0, 11}}), 10s);
    ASSERT_TRUE(refused && std::holds_alternative<protocol::error>(*refused));
    EXPECT_EQ(std::get<protocol::error>(*refused).code, protocol::error_code::outside_world);
}

// An interest stated in the options narrows the snapshots from the hello on; the interest
// command changes it, and one without region or tags clears it.
TEST(Connection, AsksForAnInterestAndChangesItByCommand)
{
    running_server s;
    connection spawner(s.url());
    auto const id_of = [&](protocol::vec3 at) {
        auto const ack = spawner.await_reply(spawner.send(ball_at(at)), 10s);
        EXPECT_TRUE(ack && std::holds_alternative<protocol::ack>(*ack));
        return ack ? std::get<protocol::ack>(*ack).id.value_or(0) : 0;
    };
    std::uint64_t const near = id_of({1, 1, 1});
    std::uint64_t const far = id_of({5, 5, 5});
    connection_options options;
    options.interest = protocol::interest_filter{.box = protocol::interest_box{.min = {0, 0, 0}, .max = {2, 2, 2}}};
    connection watcher(s.url(), options);
    auto const has = [](protocol::snapshot const& x, std::uint64_t id) {
        return std::find(x.bodies.id.begin(), x.bodies.id.end(), id) != x.bodies.id.end();
    };
    auto const narrowed = watcher.wait_for_snapshot(
        [&](protocol::snapshot const& x) { return has(x, near) && !has(x, far); }, 120, 10s);
    ASSERT_EQ(narrowed.outcome, wait_outcome::matched);
    EXPECT_EQ(narrowed.snapshot->bodies.size(), 1U);

    auto const moved = watcher.await_reply(
        watcher.send(protocol::interest{.ref = 0, .box = protocol::interest_box{.min = {4, 4, 4}, .max = {6, 6, 6}}}), 10s);
    ASSERT_TRUE(moved && std::holds_alternative<protocol::ack>(*moved));
    auto const from = std::get<protocol::ack>(*moved).tick;
    auto const elsewhere = watcher.wait_for_snapshot([&](protocol::snapshot const& x) { return x.tick >= from; }, 120, 10s);
    ASSERT_EQ(elsewhere.outcome, wait_outcome::matched);
    EXPECT_EQ(elsewhere.snapshot->bodies.id, std::vector<std::uint64_t>{far});

    auto const cleared = watcher.await_reply(watcher.send(protocol::interest{}), 10s);
    ASSERT_TRUE(cleared && std::holds_alternative<protocol::ack>(*cleared));
    auto const all = watcher.wait_for_snapshot(
        [&](protocol::snapshot const& x) { return x.tick >= std::get<protocol::ack>(*cleared).tick; }, 120, 10s);
    ASSERT_EQ(all.outcome, wait_outcome::matched);
    EXPECT_TRUE(has(*all.snapshot, near) && has(*all.snapshot, far));
}

TEST(Connection, WaitForSnapshotGivesUpAfterItsTicks)
{
    running_server s;
    connection c(s.url());
    ASSERT_NE(c.take_latest_snapshot(10s), nullptr);
    std::uint64_t const start = c.latest_tick();
    auto const never = c.wait_for_snapshot([](protocol::snapshot const&) { return false; }, 6, 10s);
    EXPECT_EQ(never.outcome, wait_outcome::past_limit);
    ASSERT_NE(never.snapshot, nullptr);
    EXPECT_GT(never.snapshot->tick, start); // the last one looked at
    EXPECT_GT(c.latest_tick(), start + 6);
}

TEST(Connection, ASlowSnapshotCallbackHoldsUpNeitherTheIoThreadNorTheAnswers)
{
    running_server s;
    std::atomic<int> calls{0};
    std::atomic<bool> on_caller_thread{false};
    auto const caller = std::this_thread::get_id();
    connection_options options;
    options.on_snapshot = [&](std::shared_ptr<protocol::snapshot const> const&) {
        on_caller_thread = on_caller_thread || std::this_thread::get_id() == caller;
        ++calls;
        std::this_thread::sleep_for(300ms); // far slower than the snapshots
    };
    connection c(s.url(), options);
    while (calls == 0)
        std::this_thread::sleep_for(10ms);
    // While the callback sleeps, answers and snapshots still arrive.
    EXPECT_TRUE(c.await_reply(c.send(protocol::ping{}), 10s));
    std::uint64_t const counted = c.stats().snapshots;
    while (c.stats().snapshots < counted + 15)
        std::this_thread::sleep_for(10ms);
    EXPECT_LT(calls.load(), 10); // it was handed the newest, not every one
    EXPECT_FALSE(on_caller_thread);
}

TEST(Connection, AFullSnapshotQueueDropsTheOldest)
{
    running_server s;
    connection_options options;
    options.snapshot_queue = 2;
    connection c(s.url(), options);
    while (c.stats().snapshots < 8)
        std::this_thread::sleep_for(10ms);
    auto const first = c.next_snapshot(1s);
    auto const second = c.next_snapshot(1s);
    ASSERT_TRUE(first && second);
    EXPECT_GT(second->tick, first->tick);
    EXPECT_GE(c.stats().snapshots_dropped, 5U);
    EXPECT_GE(first->tick, c.stats().first_tick + 10); // not the first snapshots: they went
}

TEST(Connection, CountsWhatItSawOnTheIoThread)
{
    running_server s;
    connection c(s.url());
    for (int i = 0; i < 3; ++i)
        ASSERT_TRUE(c.await_reply(c.send(ball_at({static_cast<double>(i), 0, 0})), 10s));
    while (c.stats().snapshots < 10)
        std::this_thread::sleep_for(10ms);
    connection_stats const stats = c.stats();
    EXPECT_EQ(stats.commands_sent, 3U);
    EXPECT_EQ(stats.acks, 3U);
    EXPECT_EQ(stats.ack_latency.count(), 3U);
    EXPECT_GT(stats.ack_latency.max(), 0.0);
    EXPECT_EQ(stats.tick_gap_min, 2U); // 60 ticks/s, 30 snapshots/s
    EXPECT_GE(stats.tick_gaps, 9U);
    EXPECT_GT(stats.bytes_received, 0U);
    EXPECT_GE(stats.messages_sent, 4U); // hello and the three spawns
    EXPECT_EQ(stats.undecodable, 0U);
}

TEST(Connection, CountingSnapshotTicksOnlyKeepsTheCountsAndNoSnapshots)
{
    running_server s;
    connection_options options;
    options.snapshot_ticks_only = true;
    connection c(s.url(), options);
    ASSERT_TRUE(c.await_reply(c.send(ball_at({1, 0, 0})), 10s)); // answers still decoded
    while (c.stats().snapshots < 10)
        std::this_thread::sleep_for(10ms);
    connection_stats const stats = c.stats();
    EXPECT_EQ(stats.tick_gap_min, 2U); // the ticks were read: 60 ticks/s, 30 snapshots/s
    EXPECT_GE(stats.tick_gaps, 9U);
    EXPECT_GT(stats.last_tick, stats.first_tick);
    EXPECT_EQ(stats.acks, 1U);
    EXPECT_EQ(stats.undecodable, 0U);
    EXPECT_EQ(c.next_snapshot(100ms), nullptr); // counted, not kept
}

// Many connections on two shared I/O threads: each has its own welcome, answers and
// snapshots, closes cleanly, and one that cannot connect fails as a connection of its own
// thread does, without holding up the rest.
TEST(Connection, ManyConnectionsShareTwoIoThreads)
{
    running_server s;
    io_threads io(2);
    std::vector<std::unique_ptr<connection>> links;
    for (int i = 0; i < 24; ++i)
        links.push_back(std::make_unique<connection>(s.url(i % 2 == 0 ? "still" : "fall"), connection_options{}, io));
    std::set<std::uint64_t> ids;
    for (std::size_t i = 0; i < links.size(); ++i) {
        auto& c = *links[i];
        EXPECT_EQ(c.welcome().room, i % 2 == 0 ? "still" : "fall");
        ids.insert(c.welcome().client);
        auto const answer = c.await_reply(c.send(protocol::ping{}), 10s);
        ASSERT_TRUE(answer);
        EXPECT_TRUE(std::holds_alternative<protocol::pong>(*answer));
    }
    EXPECT_EQ(ids.size(), links.size()) << "every connection is a client of its own";
    for (auto& c : links)
        ASSERT_NE(c->next_snapshot(10s), nullptr);
    EXPECT_THROW(connection(s.url("nowhere"), connection_options{}, io), connection_error);
    for (auto& c : links) {
        c->close();
        ASSERT_TRUE(c->closed_with());
        EXPECT_EQ(c->closed_with()->code, 1000);
    }
    links.clear();
    connection late(s.url(), connection_options{}, io); // the threads still serve
    EXPECT_TRUE(late.await_reply(late.send(protocol::ping{}), 10s));
}

TEST(Connection, CloseIsCleanAndFinal)
{
    running_server s;
    connection c(s.url());
    c.close();
    auto const closed = c.closed_with();
    ASSERT_TRUE(closed);
    EXPECT_EQ(closed->code, 1000);
    EXPECT_FALSE(closed->by_server);
    EXPECT_FALSE(c.is_open());
    EXPECT_THROW(c.send(protocol::ping{}), connection_error);
    c.close(); // again: nothing happens
}

TEST(Connection, ServerShutdownIsReportedAsGoingAway)
{
    running_server s;
    connection c(s.url());
    s.stop();
    auto const closed = c.wait_closed(10s);
    ASSERT_TRUE(closed);
    EXPECT_EQ(closed->code, 1001);
    EXPECT_TRUE(closed->by_server);
}

TEST(Connection, AnUnknownRoomIsRefusedWithTheStatus)
{
    running_server s;
    try {
        connection c(s.url("nowhere"));
        FAIL() << "connected to a room that does not exist";
    } catch (connection_error const& e) {
        EXPECT_NE(std::string(e.what()).find("404"), std::string::npos) << e.what();
    }
}

TEST(Connection, NoServerIsAConnectionError)
{
    std::string url;
    {
        running_server s; // a port that was just free, and is again
        url = s.url();
    }
    connection_options options;
    options.connect_timeout = 5s;
    EXPECT_THROW(connection(url, options), connection_error);
}

} // namespace
} // namespace kugel::client

namespace kugel::client {
namespace {

// A connection that asks for compact snapshots gets them in the full form's columns: the
// same bodies as a connection of the full form sees at the same tick, each to half its
// quantum, through spawns and removes.
TEST(Connection, CompactSnapshotsDecodeToTheFullFormToTheQuantum)
{
    running_server s;
    connection_options compact_options;
    compact_options.snapshots = protocol::snapshot_request{.form = "compact", .rate = std::nullopt};
    connection compact(s.url("fall"), compact_options);
    connection full(s.url("fall"));
    auto const by = std::chrono::steady_clock::now() + 10s;
    while (!compact.welcome().snapshots && std::chrono::steady_clock::now() < by)
        std::this_thread::sleep_for(10ms);
    ASSERT_TRUE(compact.welcome().snapshots);
    EXPECT_EQ(compact.welcome().snapshots->form, "compact");
    EXPECT_FALSE(full.welcome().snapshots);
    double const pq = compact.welcome().snapshots->position_quantum;
    double const vq = compact.welcome().snapshots->velocity_quantum;

    std::vector<std::uint64_t> mine;
    int compared = 0;
    for (int round = 0; round < 20; ++round) {
        auto const ref = compact.send(ball_at({0.6 * (round % 5) - 1.2, 0.6 * (round / 5) - 1.2, 3.0}, 1.0 + round));
        auto const answer = compact.await_reply(ref, 10s);
        ASSERT_TRUE(answer);
        if (auto const* ack = std::get_if<protocol::ack>(&*answer); ack && ack->id)
            mine.push_back(*ack->id);
        if (round % 3 == 2 && !mine.empty()) {
            compact.send(protocol::remove{.ref = 0, .id = mine.front()});
            mine.erase(mine.begin());
        }
        auto const c = compact.next_snapshot(10s);
        ASSERT_NE(c, nullptr);
        auto const f = full.wait_for_snapshot([&](protocol::snapshot const& x) { return x.tick >= c->tick; }, 1000, 10s);
        ASSERT_EQ(f.outcome, wait_outcome::matched);
        if (f.snapshot->tick != c->tick)
            continue; // one of them skipped that tick
        ASSERT_EQ(c->bodies.size(), f.snapshot->bodies.size());
        for (std::size_t i = 0; i < f.snapshot->bodies.size(); ++i) {
            auto const at = std::find(c->bodies.id.begin(), c->bodies.id.end(), f.snapshot->bodies.id[i]);
            ASSERT_NE(at, c->bodies.id.end());
            auto const j = static_cast<std::size_t>(at - c->bodies.id.begin());
            for (std::size_t k = 0; k < 3; ++k) {
                EXPECT_LE(std::abs(c->bodies.position[3 * j + k] - f.snapshot->bodies.position[3 * i + k]),
                          0.5 * pq * (1 + 1e-9));
                EXPECT_LE(std::abs(c->bodies.velocity[3 * j + k] - f.snapshot->bodies.velocity[3 * i + k]),
                          0.5 * vq * (1 + 1e-9));
            }
        }
        ++compared;
    }
    EXPECT_GT(compared, 5);
    EXPECT_EQ(compact.stats().undecodable, 0U) << compact.stats().last_undecodable;
}

} // namespace
} // namespace kugel::client
