// The network server end to end: a server in this process on a free port, clients over real
// WebSocket connections. Every message a client reads is checked against its schema in
// protocol/schema/. Nothing here measures time: waits have generous timeouts, and pace is
// checked by counting ticks.

#include "headless.hpp"
#include "http_session.hpp"
#include "room.hpp"
#include "server.hpp"
#include "static_files.hpp"

#include "protocol/message_schemas.hpp"
#include "support/child_process.hpp"
#include "support/http_get.hpp"
#include "support/in_process_server.hpp"
#include "support/scene_files.hpp"
#include "support/ws_client.hpp"

#include <boost/asio/connect.hpp>
#include <boost/beast/http.hpp>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <map>
#include <optional>
#include <thread>

namespace kugel::server {
namespace {

using nlohmann::json;
using test_support::index_of;
using test_support::ws_client;
namespace fs = std::filesystem;

using protocol::testing::schemas;

/// A client whose every message is checked against its schema.
class client
{
public:
    explicit client(std::uint16_t port, std::string const& target = "/ws") : ws_(port, target) {}

    json read(std::chrono::milliseconds timeout = std::chrono::seconds(10))
    {
        json message = ws_.read_json(timeout);
        EXPECT_EQ(schemas().refusal(message), "") << message.dump();
        return message;
    }

    json next(std::string const& type, std::chrono::milliseconds timeout = std::chrono::seconds(10))
    {
        auto const deadline = ws_client::clock::now() + timeout;
        while (ws_client::clock::now() < deadline) {
            json message = read(std::chrono::duration_cast<std::chrono::milliseconds>(
                deadline - ws_client::clock::now()));
            if (message.at("type") == type)
                return message;
        }
        throw std::runtime_error("no " + type + " in time");
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
    void send_text(std::string const& text) { ws_.send(text); }
    ws_client& raw() { return ws_; }

private:
    ws_client ws_;
};

/// A snapshot's tick found by a search, not a parse (a reader that parsed every large
/// snapshot would fall behind in a sanitizer build); nothing for another message.
std::optional<std::uint64_t> snapshot_tick(std::string const& text)
{
    if (text.rfind("{\"type\":\"snapshot\",\"tick\":", 0) != 0)
        return std::nullopt;
    return std::stoull(text.substr(std::string_view(R"({"type":"snapshot","tick":)").size(), 20));
}

/// A scene file written for one test.
fs::path write_scene(std::string const& name, json const& scene)
{
    return test_support::write_scene(fs::path(testing::TempDir()) / ("kugel_server_test_" + name + ".json"), scene);
}

using test_support::still_scene;

using running_server = test_support::in_process_server;

server_options rooms(std::initializer_list<std::pair<std::string, json>> scenes)
{
    server_options o;
    for (auto const& [name, scene] : scenes)
        o.rooms.push_back({name, write_scene(name, scene)});
    return o;
}

json spawn_at(std::uint64_t ref, std::array<double, 3> position, double radius = 0.25, double mass = 1.0)
{
    return {{"type", "spawn"},
            {"ref", ref},
            {"body", {{"position", position}, {"radius", radius}, {"mass", mass}}}};
}

std::array<double, 3> column3(json const& snapshot, char const* column, std::ptrdiff_t i)
{
    auto const& c = snapshot.at("bodies").at(column);
    auto const k = static_cast<std::size_t>(3 * i);
    return {c[k].get<double>(), c[k + 1].get<double>(), c[k + 2].get<double>()};
}

TEST(Server, WelcomeComesFirstAndDescribesTheRoom)
{
    running_server s(rooms({{"still", still_scene()}}));
    client c(s.port(), "/ws/still");
    json const welcome = c.read();
    ASSERT_EQ(welcome.at("type"), "welcome");
    EXPECT_EQ(welcome.at("protocol"), 1);
    EXPECT_EQ(welcome.at("room"), "still");
    EXPECT_EQ(welcome.at("dt"), 1.0 / 64.0);
    EXPECT_EQ(welcome.at("tick_rate"), 60.0);
    EXPECT_EQ(welcome.at("snapshot_rate"), 30.0);
    EXPECT_EQ(welcome.at("scene").at("name"), "still");
    EXPECT_EQ(welcome.at("scene").at("walls").size(), 6U); // the box
    // The next messages are snapshots of the one body.
    json const snapshot = c.next("snapshot");
    EXPECT_EQ(snapshot.at("bodies").at("id").size(), 1U);
}

TEST(Server, ARoomNobodyWatchesEncodesNoSnapshotAndAWatchedOneDoes)
{
    // Snapshots are encoded off the tick, once per due snapshot for all the room's clients,
    // and only when the room has any. 30 ticks without a client span 15 due snapshots.
    running_server s(rooms({{"still", still_scene()}}));
    auto const room = s.get().find_room("still");
    while (s.ticks("still") < 30)
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    EXPECT_EQ(room->counters().snapshots.load(), 0U);

    client c(s.port(), "/ws/still");
    ASSERT_EQ(c.read().at("type"), "welcome");
    std::uint64_t last = 0;
    for (int i = 0; i < 5; ++i) { // in tick order, one due snapshot apart at least
        std::uint64_t const tick = c.next("snapshot").at("tick").get<std::uint64_t>();
        EXPECT_GT(tick, last);
        last = tick;
    }
    EXPECT_GE(room->counters().snapshots.load(), 5U);
}

TEST(Server, DefaultRoomServesTheBuiltInSceneOnWs)
{
    running_server s(server_options{});
    client c(s.port(), "/ws");
    json const welcome = c.read();
    EXPECT_EQ(welcome.at("room"), "default");
    EXPECT_EQ(welcome.at("scene").at("name"), "arena");
    json const snapshot = c.next("snapshot");
    EXPECT_GE(snapshot.at("bodies").at("id").size(), 100U); // a few hundred spheres
}

TEST(DefaultScene, NeverSettlesAndKeepsItsEnergy)
{
    // The default room must look alive whenever someone opens the page, not only in its
    // first seconds: every bounce is elastic and continuous mode keeps the energy, so after
    // a simulated minute the spheres still fly. A settled pile would have kinetic energy
    // near 0; an elastic gas under gravity keeps a large share of the total (0.57 of it
    // when measured), so a fifth is a safe floor. Energy to 1e-9: continuous mode with
    // e = 1 keeps it to rounding (1.4e-14 measured over 36,000 steps).
    scene::scene const arena = scene::parse_scene(default_scene_text(), "arena");
    auto const summary = run_headless(arena, 3600);
    EXPECT_EQ(summary.at("escaped"), 0);
    EXPECT_LE(std::abs(summary.at("energy_rel_drift").get<double>()), 1e-9);
    EXPECT_GE(summary.at("kinetic_final").get<double>(),
              0.2 * summary.at("energy_initial").get<double>());
}

// Two servers host the same discrete gas of 1,000 spheres, one stepping it on the room's
// thread alone, one with three physics threads, lent from the first body on (the grid's
// slabs are then shared among them). At the same tick their snapshots are the same, to the
// last bit: the threads change when a step ends, never what it computes. At 10 ticks a
// second every snapshot reaches the client, so both find a tick in common. The clients take
// each snapshot's tick by a search and parse only the two compared: parsing and
// schema-checking every snapshot made this test take minutes under the sanitizers.
TEST(Server, PhysicsThreadsStepTheRoomToTheSameWorld)
{
    json gas = json::parse(std::ifstream(fs::path(KUGEL_SOURCE_DIR) / "scenes" / "gas.json"));
    // gas.json's density: a half-side of 1.871 m for 10,000 spheres, 0.868 m for 1,000.
    json const box = {{"min", {-0.868, -0.868, -0.868}}, {"max", {0.868, 0.868, 0.868}}};
    gas["box"] = box;
    gas["generators"][0]["region"] = box;
    gas["generators"][0]["count"] = 1000;
    gas["collisions"]["mode"] = "discrete";
    auto const serve = [&](std::size_t physics_threads) {
        server_options o = rooms({{"gas", gas}});
        o.tick_rate = 10.0;
        o.snapshot_rate = 10.0;
        o.physics_threads = physics_threads;
        o.physics_threads_from = 0; // 1,000 bodies are too few to share by default
        return std::make_unique<running_server>(o);
    };
    auto const alone = serve(1);
    auto const pooled = serve(3);
    ws_client a(alone->port(), "/ws/gas");
    ws_client b(pooled->port(), "/ws/gas");
    struct snapshot_text
    {
        std::uint64_t tick = 0;
        std::string text;
    };
    // The next snapshot with tick >= `tick`.
    auto const at_or_after = [](ws_client& c, std::uint64_t tick) {
        for (;;) {
            auto text = c.read();
            if (!text)
                throw std::runtime_error("no snapshot in time");
            auto const t = snapshot_tick(*text);
            if (t && *t >= tick)
                return snapshot_text{*t, std::move(*text)};
        }
    };
    snapshot_text sa = at_or_after(a, 5);
    snapshot_text sb = at_or_after(b, sa.tick);
    while (sa.tick != sb.tick) {
        if (sa.tick < sb.tick)
            sa = at_or_after(a, sb.tick);
        else
            sb = at_or_after(b, sa.tick);
    }
    json const ja = json::parse(sa.text);
    json const jb = json::parse(sb.text);
    EXPECT_EQ(schemas().refusal(ja), "");
    ASSERT_EQ(ja.at("bodies").at("id").size(), 1000U);
    EXPECT_TRUE(ja.at("bodies") == jb.at("bodies")) << "tick " << sa.tick;
}

TEST(Server, SpawnIsAckedWithAnIdAndAppearsFromTheAckedTickWhereItWasPut)
{
    running_server s(rooms({{"still", still_scene()}}));
    client c(s.port(), "/ws/still");
    c.send(spawn_at(7, {1.5, -2.0, 3.25}));
    json const ack = c.next("ack");
    EXPECT_EQ(ack.at("ref"), 7);
    auto const id = ack.at("id").get<std::uint64_t>();
    auto const tick = ack.at("tick").get<std::uint64_t>();
    json const snapshot = c.snapshot_at_or_after(tick);
    auto const i = index_of(snapshot, id);
    ASSERT_GE(i, 0) << "the spawned body is missing from the snapshot at tick " << snapshot["tick"];
    // No forces and zero velocity: it stays exactly where it was put.
    EXPECT_EQ(column3(snapshot, "position", i), (std::array<double, 3>{1.5, -2.0, 3.25}));
    EXPECT_EQ(snapshot.at("bodies").at("radius")[static_cast<std::size_t>(i)], 0.25);
    EXPECT_EQ(snapshot.at("bodies").at("mass")[static_cast<std::size_t>(i)], 1.0);
    EXPECT_FALSE(snapshot.at("bodies").contains("charge")); // the scene has no Coulomb force
}

TEST(Server, ImpulseChangesVelocityByExactlyJOverMAtTheAckedTick)
{
    running_server s(rooms({{"still", still_scene()}}));
    client c(s.port(), "/ws/still");
    json const first = c.next("snapshot");
    auto const id = first.at("bodies").at("id")[0].get<std::uint64_t>(); // 2 kg at rest
    c.send({{"type", "impulse"}, {"ref", 1}, {"id", id}, {"impulse", {3.0, -1.0, 0.5}}});
    json const ack = c.next("ack");
    auto const tick = ack.at("tick").get<std::uint64_t>();
    for (;;) {
        json const snapshot = c.next("snapshot");
        auto const v = column3(snapshot, "velocity", index_of(snapshot, id));
        if (snapshot.at("tick").get<std::uint64_t>() < tick) {
            EXPECT_EQ(v, (std::array<double, 3>{0.0, 0.0, 0.0})) << "pushed before its tick";
            continue;
        }
        // J/m with m = 2 kg is exact in binary, so equality is the right test.
        EXPECT_EQ(v, (std::array<double, 3>{1.5, -0.5, 0.25}));
        break;
    }
}

TEST(Server, TwoClientsSeeTheSameWorldAndEachOthersCommands)
{
    running_server s(rooms({{"still", still_scene()}}));
    client a(s.port(), "/ws/still");
    client b(s.port(), "/ws/still");
    EXPECT_NE(a.next("welcome").at("client"), b.next("welcome").at("client"));
    a.send(spawn_at(1, {4.0, 4.0, 4.0}));
    json const ack = a.next("ack");
    auto const id = ack.at("id").get<std::uint64_t>();
    json const seen_by_a = a.snapshot_at_or_after(ack.at("tick"));
    json seen_by_b = b.snapshot_at_or_after(ack.at("tick"));
    while (seen_by_b.at("tick") != seen_by_a.at("tick")) {
        ASSERT_LT(seen_by_b.at("tick").get<std::uint64_t>(), seen_by_a.at("tick").get<std::uint64_t>());
        seen_by_b = b.next("snapshot");
    }
    EXPECT_GE(index_of(seen_by_b, id), 0);
    EXPECT_EQ(seen_by_a.at("bodies"), seen_by_b.at("bodies")); // the same truth, bit for bit
}

TEST(Server, BadInputGetsItsErrorCodeAndTheConnectionStaysUsable)
{
    running_server s(rooms({{"still", still_scene()}}));
    client c(s.port(), "/ws/still");
    c.next("welcome");
    auto const error_for = [&](std::string const& text) {
        c.send_text(text);
        return c.next("error");
    };
    EXPECT_EQ(error_for("{not json").at("code"), "bad_json");
    EXPECT_EQ(error_for(R"({"type":"spawn","ref":"one","body":{}})").at("code"), "wrong_type");
    json const not_finite = error_for(
        R"({"type":"spawn","ref":3,"body":{"position":[1e999,0,0],"radius":0.1,"mass":1}})");
    EXPECT_EQ(not_finite.at("code"), "not_finite");
    EXPECT_EQ(not_finite.at("ref"), 3);
    EXPECT_EQ(error_for(R"({"type":"teleport","ref":4})").at("code"), "unknown_type");
    json const unknown = error_for(R"({"type":"impulse","ref":5,"id":999999,"impulse":[1,0,0]})");
    EXPECT_EQ(unknown.at("code"), "unknown_body");
    EXPECT_EQ(unknown.at("ref"), 5);
    EXPECT_EQ(error_for(R"({"type":"remove","ref":6,"id":424242})").at("code"), "unknown_body");
    EXPECT_EQ(error_for(spawn_at(7, {0, 0, 12}).dump()).at("code"), "outside_world");
    EXPECT_EQ(error_for(spawn_at(8, {9.9, 0, 0}).dump()).at("code"), "overlaps_wall");
    json const negative = error_for(spawn_at(9, {1, 1, 1}, -0.5).dump());
    EXPECT_EQ(negative.at("code"), "bad_value");
    EXPECT_NE(negative.at("message").get<std::string>().find("/body/radius"), std::string::npos);

    // After all that, the same connection still works; unknown fields are ignored.
    json spawn = spawn_at(10, {2, 2, 2});
    spawn["colour"] = "red";
    c.send(spawn);
    json const ack = c.next("ack");
    EXPECT_EQ(ack.at("ref"), 10);
    EXPECT_TRUE(ack.contains("id"));
    c.send({{"type", "ping"}, {"ref", 11}});
    json const pong = c.next("pong");
    EXPECT_EQ(pong.at("ref"), 11);
    // after ticks (an ack names one), the pong says what the last tick took
    ASSERT_TRUE(pong.contains("tick_ms")) << pong;
    EXPECT_GE(pong.at("tick_ms").get<double>(), 0.0);
}

TEST(Server, OversizedFrameIsClosedWith1009)
{
    server_options options = rooms({{"still", still_scene()}});
    options.client.max_message_bytes = 1024;
    running_server s(options);
    client c(s.port(), "/ws/still");
    c.next("welcome");
    c.send_text(std::string(2048, ' '));
    while (c.raw().read(std::chrono::seconds(10))) {
    }
    ASSERT_TRUE(c.raw().closed());
    EXPECT_EQ(c.raw().close_code(), 1009);
}

TEST(Server, SpawnBeyondTheBodyLimitIsRefusedWithRoomFull)
{
    server_options options = rooms({{"still", still_scene()}});
    options.max_bodies = 2; // the scene's body plus one
    running_server s(options);
    client c(s.port(), "/ws/still");
    c.send(spawn_at(1, {1, 1, 1}));
    EXPECT_EQ(c.next("ack").at("ref"), 1);
    c.send(spawn_at(2, {-1, -1, -1}));
    json const refused = c.next("error");
    EXPECT_EQ(refused.at("code"), "room_full");
    EXPECT_EQ(refused.at("ref"), 2);
}

TEST(Server, CommandsBeyondTheRateLimitAreRefusedWithRateLimited)
{
    server_options options = rooms({{"still", still_scene()}});
    // A burst of 5, then one more command per 1000 s: no new token can accrue while the test
    // runs, however slow the machine, so exactly the burst passes.
    options.client.commands_per_second = 0.001;
    options.client.command_burst = 5.0;
    running_server s(options);
    client c(s.port(), "/ws/still");
    for (int ref = 1; ref <= 10; ++ref)
        c.send({{"type", "ping"}, {"ref", ref}});
    int pongs = 0;
    int limited = 0;
    while (pongs + limited < 10) {
        json const m = c.read();
        if (m.at("type") == "pong")
            ++pongs;
        if (m.at("type") == "error" && m.at("code") == "rate_limited")
            ++limited;
    }
    EXPECT_EQ(pongs, 5);
    EXPECT_EQ(limited, 5);
}

/// Many bodies, so that each snapshot is large and a client that does not read fills its
/// socket buffers within a few snapshots.
json crowded_scene()
{
    json scene = test_support::still_scene(2000);
    scene["name"] = "crowded";
    return scene;
}

TEST(Server, AClientThatNeverReadsHoldsUpNeitherTheTickNorAnotherClient)
{
    server_options options = rooms({{"crowded", crowded_scene()}});
    options.client.write_stall = std::chrono::milliseconds(1000);
    running_server s(options);
    ws_client stalled(s.port(), "/ws/crowded"); // connects, never reads
    ws_client reader(s.port(), "/ws/crowded");
    EXPECT_EQ(reader.read_json().at("type"), "welcome");

    // The reader takes only each snapshot's tick (a search, not a parse), so that it keeps
    // up even in a sanitizer build: a reader slower than its snapshots would rightly be
    // dropped too. 120 snapshots (4 s at 30 Hz) are long enough for the stalled client's
    // socket buffers to fill (each snapshot is about 250 kB) and for it to be dropped after
    // its 1 s stall.
    auto const next_tick = [&] {
        auto const text = reader.read();
        if (!text)
            throw std::runtime_error(reader.closed() ? "the reader was disconnected" : "no snapshot in time");
        auto const tick = snapshot_tick(*text);
        EXPECT_TRUE(tick.has_value()) << text->substr(0, 80);
        return tick.value_or(0);
    };
    std::uint64_t const skipped_before = s.snapshots_skipped("crowded");
    std::uint64_t const first_tick = next_tick();
    std::uint64_t last = first_tick;
    int received = 0;
    while (received < 120) {
        std::uint64_t const tick = next_tick();
        ASSERT_GT(tick, last) << "snapshot ticks must advance";
        last = tick;
        ++received;
    }
    // Every snapshot due in between reached the reader, unless the room skipped it (the
    // last was still being encoded, which a slow build under load does) or a newer one
    // replaced it before the reader took it (a few): 120 snapshots at one per two ticks
    // span 240 ticks plus two for each skipped, and at most 40 more. The room itself is at
    // least as far on.
    std::uint64_t const skipped = s.snapshots_skipped("crowded") - skipped_before;
    EXPECT_GE(last - first_tick, 2U * static_cast<std::uint64_t>(received) - 2U);
    EXPECT_LE(last - first_tick, 2U * (static_cast<std::uint64_t>(received) + skipped) + 40U)
        << skipped << " skipped";
    EXPECT_GE(s.ticks("crowded"), last);

    // The stalled client, once it does read, finds it was disconnected.
    while (stalled.read(std::chrono::seconds(10))) {
    }
    EXPECT_TRUE(stalled.closed());
}

/// The niceness of each of this process's threads (field 19 of /proc/self/task/TID/stat).
std::vector<int> thread_niceness()
{
    std::vector<int> niceness;
    for (auto const& task : fs::directory_iterator("/proc/self/task")) {
        std::ifstream in(task.path() / "stat");
        std::string stat((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
        // Fields after the command name, which is in parentheses and may hold spaces.
        std::istringstream rest(stat.substr(stat.rfind(')') + 2));
        std::string field;
        for (int k = 3; k <= 19 && rest >> field; ++k) {
        }
        niceness.push_back(std::stoi(field));
    }
    return niceness;
}

// --io-niceness lowers the priority of the connection threads, and of nothing else: the
// rooms' ticks keep theirs. The test server runs two connection threads and one room.
TEST(Server, IoNicenessLowersTheConnectionThreadsOnly)
{
    auto const before = thread_niceness();
    auto const at = [](std::vector<int> const& all, int value) {
        return std::count(all.begin(), all.end(), value);
    };
    server_options o = rooms({{"still", still_scene()}});
    o.io_niceness = 7;
    running_server s(o);
    client c(s.port(), "/ws/still");
    EXPECT_EQ(c.next("welcome").at("room"), "still");
    // One thread has answered; the other may not have started yet: wait for it.
    auto during = thread_niceness();
    for (int tries = 0; tries < 500 && at(during, 7) - at(before, 7) < 2; ++tries) {
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
        during = thread_niceness();
    }
    EXPECT_EQ(at(during, 7) - at(before, 7), 2);
    EXPECT_GE(at(during, 0) - at(before, 0), 1); // the room's thread keeps niceness 0

    for (int bad : {-1, 20}) {
        server_options refused = rooms({{"still", still_scene()}});
        refused.io_niceness = bad;
        EXPECT_THROW(running_server{refused}, std::invalid_argument) << bad;
    }
}

TEST(Server, RoomsAreIsolated)
{
    json other = still_scene();
    other["name"] = "other";
    running_server s(rooms({{"one", still_scene()}, {"two", other}}));
    client one(s.port(), "/ws/one");
    client two(s.port(), "/ws/two");
    EXPECT_EQ(one.next("welcome").at("room"), "one");
    EXPECT_EQ(two.next("welcome").at("room"), "two");
    one.send(spawn_at(1, {3, 3, 3}));
    json const ack = one.next("ack");
    auto const id = ack.at("id").get<std::uint64_t>();
    json const in_one = one.snapshot_at_or_after(ack.at("tick").get<std::uint64_t>() + 2);
    json const in_two = two.snapshot_at_or_after(ack.at("tick").get<std::uint64_t>() + 2);
    EXPECT_EQ(in_one.at("bodies").at("id").size(), 2U);
    EXPECT_EQ(in_two.at("bodies").at("id").size(), 1U);
    // Ids are per room, so `id` may exist in room two, but not at (3, 3, 3).
    auto const i = index_of(in_two, id);
    if (i >= 0) {
        EXPECT_NE(column3(in_two, "position", i), (std::array<double, 3>{3.0, 3.0, 3.0}));
    }
    // A command in room two cannot reach the body spawned in room one.
    two.send({{"type", "remove"}, {"ref", 2}, {"id", id + 100}});
    EXPECT_EQ(two.next("error").at("code"), "unknown_body");
}

TEST(Server, StopClosesEveryClientWithGoingAway)
{
    running_server s(rooms({{"still", still_scene()}}));
    client c(s.port(), "/ws/still");
    c.next("welcome");
    s.get().stop();
    while (c.raw().read(std::chrono::seconds(10))) {
    }
    ASSERT_TRUE(c.raw().closed());
    EXPECT_EQ(c.raw().close_code(), 1001);
}

/// One HTTP GET on a fresh connection: (status, body).
std::pair<unsigned, std::string> http_get(std::uint16_t port, std::string const& target)
{
    auto reply = test_support::http_get(port, target);
    return {reply.status, std::move(reply.body)};
}

TEST(Server, ServesHealthAndTheWebRootAndNothingOutsideIt)
{
    fs::path const root = fs::path(testing::TempDir()) / "kugel_server_test_web";
    fs::create_directories(root);
    std::ofstream(root / "index.html") << "<!doctype html><title>kugel</title>";
    server_options options = rooms({{"still", still_scene()}});
    options.web_root = root;
    running_server s(options);

    auto const [health_status, health] = http_get(s.port(), "/healthz");
    EXPECT_EQ(health_status, 200U);
    json const h = json::parse(health);
    EXPECT_EQ(h.at("status"), "ok");
    EXPECT_TRUE(h.at("rooms").contains("still"));

    auto const [index_status, index] = http_get(s.port(), "/");
    EXPECT_EQ(index_status, 200U);
    EXPECT_EQ(index, "<!doctype html><title>kugel</title>");
    EXPECT_EQ(http_get(s.port(), "/../../etc/passwd").first, 404U);
    EXPECT_EQ(http_get(s.port(), "/missing.js").first, 404U);
    EXPECT_THROW(ws_client(s.port(), "/ws/no-such-room"), std::exception); // 404, no upgrade
}

TEST(Server, RoomOfTargetMapsWebSocketPaths)
{
    EXPECT_EQ(room_of_target("/ws"), "default");
    EXPECT_EQ(room_of_target("/ws/"), "default");
    EXPECT_EQ(room_of_target("/ws/lab?x=1"), "lab");
    EXPECT_EQ(room_of_target("/ws/a/b"), std::nullopt);
    EXPECT_EQ(room_of_target("/index.html"), std::nullopt);
}

} // namespace
} // namespace kugel::server

namespace kugel::server {
namespace {

fs::path log_file(std::string const& name)
{
    return fs::path(testing::TempDir()) / ("kugel_server_test_" + name + ".log");
}

TEST(ServerProcess, SigtermClosesEveryClientWithGoingAwayAndExitsZero)
{
    test_support::server_child p(KUGEL_SERVER_EXE,
                                 {"--room", "still=" + write_scene("process", still_scene()).string()},
                                 log_file("process"));
    client c(p.port(), "/ws/still");
    c.next("welcome");
    c.next("snapshot");
    auto const status = p.stop(); // SIGTERM
    while (c.raw().read(std::chrono::seconds(10))) {
    }
    ASSERT_TRUE(c.raw().closed());
    EXPECT_EQ(c.raw().close_code(), 1001);
    EXPECT_EQ(status, 0) << p.log();
}

// --max-queued-events sets how many events a client may have unsent: the welcome's limits say
// it; out of range, the server refuses to start and names the option.
TEST(ServerProcess, MaxQueuedEventsIsAnnouncedAndBounded)
{
    std::string const scene = write_scene("events_limit", still_scene()).string();
    test_support::server_child p(KUGEL_SERVER_EXE, {"--room", "still=" + scene, "--max-queued-events", "17"},
                                 log_file("events_limit"));
    client c(p.port(), "/ws/still");
    EXPECT_EQ(c.next("welcome").at("limits").at("max_queued_events"), 17);
    EXPECT_EQ(p.stop(), 0) << p.log();
    for (std::string const bad : {"0", "65537", "many"}) {
        test_support::child_process refused(KUGEL_SERVER_EXE,
                                            {"--room", "still=" + scene, "--max-queued-events", bad},
                                            log_file("events_limit_" + bad));
        EXPECT_EQ(refused.wait(std::chrono::seconds(10)), 2) << bad;
        EXPECT_NE(refused.output().find("--max-queued-events"), std::string::npos) << refused.output();
    }
}

/// Writes a small file (creating its folders).
void write_file(fs::path const& file, std::string const& text)
{
    fs::create_directories(file.parent_path());
    std::ofstream(file) << text;
}

// Without --web-root the server looks for the page next to its executable (bin/web), then in
// its install prefix (share/kugel/web), then in the source tree it was built from
// (web/dist), and serves the first that holds an index.html; a folder named index.html is no
// page, and with none anywhere there is no page.
TEST(PagePlaces, TheFirstPlaceWithAnIndexIsTheOneServed)
{
    fs::path const root = fs::path(testing::TempDir()) / "kugel_page_places";
    fs::remove_all(root);
    fs::path const executable = root / "prefix" / "bin" / "kugel-server";
    fs::path const source = root / "source";
    auto const places = page_places(executable, source);
    ASSERT_EQ(places.size(), 3U);
    EXPECT_EQ(find_page(places), std::nullopt);
    fs::create_directories(root / "prefix" / "bin" / "web" / "index.html"); // a folder
    EXPECT_EQ(find_page(places), std::nullopt);
    write_file(source / "web" / "dist" / "index.html", "source");
    ASSERT_TRUE(find_page(places));
    EXPECT_EQ(find_page(places)->root, source / "web" / "dist");
    EXPECT_EQ(find_page(places)->where, "in the source tree it was built from");
    write_file(root / "prefix" / "share" / "kugel" / "web" / "index.html", "installed");
    EXPECT_EQ(find_page(places)->root, root / "prefix" / "share" / "kugel" / "web");
    EXPECT_EQ(find_page(places)->where, "in the install prefix");
    fs::remove_all(root / "prefix" / "bin" / "web");
    write_file(root / "prefix" / "bin" / "web" / "index.html", "beside");
    EXPECT_EQ(find_page(places)->where, "next to the executable");
    EXPECT_EQ(page_places(executable, {}).size(), 2U); // no source tree known: two places
    fs::remove_all(root);
}

// kugel-server run from its build directory without --web-root serves the page built in its
// source tree, and says so in its log; when that page was not built (no Node.js), it says
// where it looked and serves none.
TEST(ServerProcess, WithoutAWebRootServesThePageItFindsAndSaysWhere)
{
    fs::path const built = fs::path(KUGEL_SOURCE_DIR) / "web" / "dist";
    test_support::server_child p(KUGEL_SERVER_EXE,
                                 {"--room", "still=" + write_scene("page", still_scene()).string()},
                                 log_file("page"));
    auto const reply = test_support::http_get(p.port(), "/");
    if (fs::is_regular_file(built / "index.html")) {
        EXPECT_NE(p.log().find("the page: " + built.string() + " (in the source tree it was built from"),
                  std::string::npos) << p.log();
        EXPECT_EQ(reply.status, 200U);
        std::ifstream in(built / "index.html");
        std::string const page{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
        EXPECT_EQ(reply.body, page);
    } else {
        EXPECT_NE(p.log().find("no page to serve: no index.html in"), std::string::npos) << p.log();
        EXPECT_EQ(reply.status, 404U);
    }
}

// --set ROOM:PATH=VALUE changes one field of one served room's scene: the room's welcome shows
// it and its world runs it, while another room of the same scene file runs the file as it is.
// In the still scene a body of 2 kg rests at the origin; overridden, dt is 1/32 s and a field
// of 2 m/s^2 pulls it down, so that after n ticks (semi-implicit Euler) its velocity is
// exactly -n/16 m/s and the clock n/32 s.
TEST(ServerProcess, ARoomsOverridesShowInItsWelcomeAndItsWorldAndNowhereElse)
{
    std::string const file = write_scene("overridden", still_scene()).string();
    test_support::server_child p(KUGEL_SERVER_EXE,
                                 {"--room", "falling=" + file, "--room", "still=" + file, "--set",
                                  "falling:dt=0.03125", "--set",
                                  R"(falling:forces={"uniform_field": {"g": [0, 0, -2]}})"},
                                 log_file("overridden"));
    EXPECT_NE(p.log().find("room 'falling': scene 'still' (with dt=0.03125, forces="),
              std::string::npos)
        << p.log();
    client falling(p.port(), "/ws/falling");
    EXPECT_EQ(falling.next("welcome").at("dt"), 0.03125);
    json const fell = falling.snapshot_at_or_after(4);
    double const n = fell.at("tick").get<double>();
    EXPECT_EQ(fell.at("time"), n / 32.0);
    EXPECT_EQ(column3(fell, "velocity", 0), (std::array<double, 3>{0.0, 0.0, -n / 16.0}));

    client still(p.port(), "/ws/still");
    EXPECT_EQ(still.next("welcome").at("dt"), 1.0 / 64.0);
    json const rested = still.snapshot_at_or_after(4);
    EXPECT_EQ(rested.at("time"), rested.at("tick").get<double>() / 64.0);
    EXPECT_EQ(column3(rested, "velocity", 0), (std::array<double, 3>{0.0, 0.0, 0.0}));
}

// Without --room, the built-in room is 'default' and takes overrides by that name.
TEST(ServerProcess, TheDefaultRoomTakesOverridesByItsName)
{
    test_support::server_child p(KUGEL_SERVER_EXE, {"--set", "default:dt=0.03125"},
                                 log_file("default_overridden"));
    client c(p.port(), "/ws");
    json const welcome = c.next("welcome");
    EXPECT_EQ(welcome.at("room"), "default");
    EXPECT_EQ(welcome.at("scene").at("name"), "arena");
    EXPECT_EQ(welcome.at("dt"), 0.03125);
}

TEST(ServerProcess, RefusesABadRoomSceneWithExitTwoAndTheReason)
{
    json bad = still_scene();
    bad["dt"] = -1;
    test_support::child_process p(KUGEL_SERVER_EXE,
                                  {"--port", "0", "--room", "bad=" + write_scene("bad", bad).string()},
                                  log_file("bad"));
    EXPECT_EQ(p.wait(std::chrono::seconds(30)), 2);
    EXPECT_NE(p.output().find("/dt"), std::string::npos) << p.output();
}

} // namespace
} // namespace kugel::server
