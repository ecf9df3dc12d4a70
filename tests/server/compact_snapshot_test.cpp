// Compact snapshots over a real socket: a client that asks for them gets a welcome naming
// its quanta, a keyframe, then deltas it can always apply (also after it stalled and the
// server skipped snapshots for it, after spawns and removals and a reset); what it decodes is
// the full form of the same tick to the quantum; a client that asks for a lower rate gets
// every n-th snapshot, as deltas along its own chain.

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

#include <cmath>
#include <filesystem>
#include <map>
#include <string>
#include <thread>

namespace kugel::server {
namespace {

using nlohmann::json;
using test_support::ws_client;
namespace fs = std::filesystem;

/// A box of bodies flying under gravity and bouncing, some resting on the floor.
json churn_scene()
{
    json bodies = json::array();
    for (int i = 0; i < 60; ++i)
        bodies.push_back({{"position", {-4.0 + 0.3 * (i % 20), -2.0 + 1.5 * (i / 20), 1.0 + 0.1 * i}},
                          {"velocity", {0.5 * ((i % 3) - 1), 0.2, 0.0}},
                          {"radius", 0.1},
                          {"mass", 1.0 + i}});
    for (int i = 0; i < 40; ++i) // at rest: a field of point masses without gravity's reach
        bodies.push_back({{"position", {-4.0 + 0.2 * i, 4.0, 0.0}}, {"radius", 0.0}, {"mass", 1.0}});
    return {{"name", "churn"},
            {"dt", 1.0 / 100.0},
            {"integrator", "semi_implicit_euler"},
            {"collisions", {{"mode", "off"}}},
            {"box", {{"min", {-5, -5, -1}}, {"max", {5, 5, 20}}}},
            {"bodies", bodies}};
}

server_options churn_options(std::string const& file_name)
{
    server_options o;
    o.rooms.push_back({"churn", test_support::write_scene(fs::path(testing::TempDir()) / file_name, churn_scene())});
    o.tick_rate = 200.0;
    o.snapshot_rate = 100.0;
    o.admin_token = "compact-admin";
    o.keyframe_interval = 1.0;
    o.client.send_buffer_bytes = 4096; // a client that stops reading is soon behind
    return o;
}

/// A client of the compact form: applies what it receives, as a client library would.
struct compact_client
{
    ws_client ws;
    std::optional<protocol::compact_state> held;
    json welcome;
    int keys = 0, deltas = 0;
    std::vector<std::uint64_t> ticks;

    compact_client(std::uint16_t port, json hello) : ws(port, "/ws/churn")
    {
        ws.next("welcome");
        ws.send(hello);
        welcome = ws.next("welcome");
    }

    /// Reads messages until a snapshot is applied; returns it in the full form's columns.
    protocol::snapshot next_snapshot()
    {
        for (;;) {
            auto const text = ws.read(std::chrono::seconds(10));
            if (!text)
                throw std::runtime_error("no snapshot in time");
            EXPECT_EQ(protocol::testing::schemas().refusal(json::parse(*text)), "") << text->substr(0, 200);
            auto const decoded = protocol::decode_server_message(*text);
            if (!decoded.message)
                throw std::runtime_error("undecodable: " + decoded.failure->message);
            auto const* compact = std::get_if<protocol::compact_snapshot>(&*decoded.message);
            if (!compact)
                continue; // an ack, a welcome
            (compact->form == "key" ? keys : deltas) += 1;
            auto result = protocol::apply_compact(*compact, held ? &*held : nullptr);
            if (!result.state)
                throw std::runtime_error("a snapshot it cannot apply: " + result.failure);
            held = std::move(result.state);
            ticks.push_back(held->tick);
            return protocol::to_snapshot(*held);
        }
    }
};

/// The next full-form snapshot of `tick` or later.
protocol::snapshot full_at_or_after(ws_client& ws, std::uint64_t tick)
{
    for (;;) {
        json const m = ws.next("snapshot");
        if (m.at("tick").get<std::uint64_t>() < tick)
            continue;
        auto const decoded = protocol::decode_server_message(m.dump());
        return std::get<protocol::snapshot>(*decoded.message);
    }
}

TEST(CompactSnapshots, TheDecodedStreamIsTheFullFormToTheQuantumThroughChurnStallsAndAReset)
{
    test_support::in_process_server s(churn_options("kugel_compact_churn.json"));
    compact_client c(s.port(), {{"type", "hello"}, {"snapshots", {{"form", "compact"}}}});
    ASSERT_EQ(c.welcome.at("snapshots").at("form"), "compact");
    protocol::quanta const q{c.welcome.at("snapshots").at("position_quantum").get<double>(),
                             c.welcome.at("snapshots").at("velocity_quantum").get<double>()};
    ws_client full(s.port(), "/ws/churn");
    ws_client admin(s.port(), "/ws/churn");
    admin.next("welcome");
    admin.send(json{{"type", "hello"}, {"admin_token", "compact-admin"}});
    admin.next("welcome");

    std::uint64_t ref = 0;
    std::vector<std::uint64_t> spawned;
    for (int round = 0; round < 12; ++round) {
        // Churn: spawn two, remove one of the earlier ones; a reset halfway.
        for (int k = 0; k < 2; ++k)
            admin.send(json{{"type", "spawn"}, {"ref", ++ref},
                            {"body", {{"position", {0.3 * round, 0.1 * k, 3.0}}, {"velocity", {0, 0, 1}},
                                      {"radius", 0.05}, {"mass", 2.0}}}});
        if (!spawned.empty() && round % 2 == 1) {
            admin.send(json{{"type", "remove"}, {"ref", ++ref}, {"id", spawned.front()}});
            spawned.erase(spawned.begin());
        }
        if (round == 6) {
            admin.send(json{{"type", "reset"}, {"ref", ++ref}});
            spawned.clear();
        }
        for (;;) { // the answers, for the spawned ids
            json const m = admin.read_json();
            if (m.at("type") == "ack" && m.contains("id") && round != 6)
                spawned.push_back(m.at("id").get<std::uint64_t>());
            if (m.at("type") != "snapshot" && m.value("ref", 0ULL) == ref)
                break;
        }
        if (round % 4 == 3) // a stall: the server replaces what it has not sent
            std::this_thread::sleep_for(std::chrono::milliseconds(400));
        // Every snapshot the client applies for a while, each against the full form.
        for (int n = 0; n < 15; ++n) {
            protocol::snapshot const mine = c.next_snapshot();
            protocol::snapshot const theirs = full_at_or_after(full, mine.tick);
            if (theirs.tick == mine.tick) // the full client may have skipped it
                test_support::expect_same_to_the_quantum(mine, theirs, q);
            if (HasFatalFailure())
                return;
        }
    }
    EXPECT_GT(c.deltas, 10 * c.keys) << "deltas, not keyframes, are the stream";
    EXPECT_GE(c.keys, 2) << "a keyframe at the start and after a stall or the reset";
}

// A client that stops reading for a while falls behind: the server replaces the snapshots
// it has not sent, and the next it sends is the delta from the state the client holds (a
// catch-up delta, shared by every client that holds that state), not a keyframe many times
// a delta's size, which would only put it further behind.
TEST(CompactSnapshots, AClientThatFellBehindCatchesUpWithADeltaFromTheStateItHolds)
{
    server_options o = churn_options("kugel_compact_catch_up.json");
    o.keyframe_interval = 600.0; // none due in this test: a keyframe would be for falling behind
    test_support::in_process_server s(o);
    compact_client c(s.port(), {{"type", "hello"}, {"snapshots", {{"form", "compact"}}}});
    c.ws.set_receive_buffer(4096);
    protocol::quanta const q{c.welcome.at("snapshots").at("position_quantum").get<double>(),
                             c.welcome.at("snapshots").at("velocity_quantum").get<double>()};
    ws_client full(s.port(), "/ws/churn");
    for (int n = 0; n < 5; ++n)
        c.next_snapshot();
    ASSERT_EQ(c.keys, 1);
    for (int stall = 0; stall < 3; ++stall) {
        std::this_thread::sleep_for(std::chrono::milliseconds(500));
        // What the socket's buffers held, then the snapshot after the gap, then a few more.
        int after_gap = -1;
        for (int n = 0; n < 400 && after_gap < 5; ++n) {
            protocol::snapshot const mine = c.next_snapshot();
            if (after_gap >= 0 || c.ticks.back() - c.ticks[c.ticks.size() - 2] > 2)
                ++after_gap;
            protocol::snapshot const theirs = full_at_or_after(full, mine.tick);
            if (theirs.tick == mine.tick)
                test_support::expect_same_to_the_quantum(mine, theirs, q);
            if (HasFatalFailure())
                return;
        }
    }
    // 200 ticks/s, 100 snapshots/s: 2 ticks apart unless the server skipped some.
    std::size_t skips = 0;
    for (std::size_t i = 1; i < c.ticks.size(); ++i)
        skips += c.ticks[i] - c.ticks[i - 1] > 2 ? 1 : 0;
    ASSERT_GE(skips, 3U) << "each stall made the server skip snapshots";
    EXPECT_EQ(c.keys, 1) << "every stall was caught up by a delta";
}

TEST(CompactSnapshots, ALowerRateTakesEveryNthSnapshotAsDeltas)
{
    test_support::in_process_server s(churn_options("kugel_compact_rate.json"));
    compact_client c(s.port(), {{"type", "hello"}, {"snapshots", {{"form", "compact"}, {"rate", 25}}}});
    EXPECT_EQ(c.welcome.at("snapshots").at("rate").get<double>(), 25.0);
    for (int n = 0; n < 40; ++n)
        c.next_snapshot();
    // Two ticks per room snapshot, every fourth snapshot: 8 ticks apart at least.
    for (std::size_t i = 1; i < c.ticks.size(); ++i)
        EXPECT_GE(c.ticks[i] - c.ticks[i - 1], 8U);
    EXPECT_GT(c.deltas, 3 * c.keys);
}

TEST(CompactSnapshots, TheScenesQuantaAreAnnouncedAndTheServersOptionWins)
{
    json scene = churn_scene();
    scene["snapshots"] = {{"position_quantum", 0.002}, {"velocity_quantum", 0.05}};
    server_options o = churn_options("kugel_compact_quanta.json");
    o.rooms[0].scene_file = test_support::write_scene(fs::path(testing::TempDir()) / "kugel_compact_quanta.json", scene);
    auto const announced = [](server_options const& options) {
        test_support::in_process_server s(options);
        compact_client c(s.port(), {{"type", "hello"}, {"snapshots", {{"form", "compact"}}}});
        c.next_snapshot();
        EXPECT_EQ(c.keys, 1);
        EXPECT_EQ(c.held->q.position, c.welcome.at("snapshots").at("position_quantum").get<double>());
        EXPECT_EQ(c.held->q.velocity, c.welcome.at("snapshots").at("velocity_quantum").get<double>());
        return c.held->q;
    };
    EXPECT_EQ(announced(o), (protocol::quanta{0.002, 0.05})); // the scene's
    o.position_quantum = 0.004;
    EXPECT_EQ(announced(o), (protocol::quanta{0.004, 0.05})); // the server's option, then the scene's
    o.velocity_quantum = 0.25;
    EXPECT_EQ(announced(o), (protocol::quanta{0.004, 0.25}));
    o.rooms[0].overrides = {"snapshots.velocity_quantum=0.125"}; // the option still wins
    EXPECT_EQ(announced(o), (protocol::quanta{0.004, 0.25}));
    o.velocity_quantum = 0.0;
    EXPECT_EQ(announced(o), (protocol::quanta{0.004, 0.125}));
}

TEST(CompactSnapshots, AClientThatAsksForNothingGetsTheFullFormAndNoSecondWelcome)
{
    test_support::in_process_server s(churn_options("kugel_compact_none.json"));
    ws_client plain(s.port(), "/ws/churn");
    json const welcome = plain.next("welcome");
    EXPECT_FALSE(welcome.contains("snapshots"));
    plain.send(json{{"type", "hello"}, {"protocol", 1}, {"name", "old script"}});
    for (int n = 0; n < 5; ++n) {
        json const m = plain.read_json();
        EXPECT_EQ(m.at("type"), "snapshot") << m.dump();
        EXPECT_FALSE(m.contains("form"));
        EXPECT_TRUE(m.at("bodies").contains("position"));
    }
}

} // namespace
} // namespace kugel::server
