// Sensor events over real WebSocket connections: a client that asks (hello.events) is told
// when a body's centre enters or leaves one of the scene's sensors, at the world time of the
// crossing, before the snapshot of its tick; one that does not ask is told nothing; filters,
// a bounded queue with counted overflow, and refused subscriptions. Every message read is
// checked against its schema.

#include "server.hpp"

#include "protocol/message_schemas.hpp"
#include "support/http_get.hpp"
#include "support/in_process_server.hpp"
#include "support/scene_files.hpp"
#include "support/ws_client.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <tuple>
#include <vector>

namespace kugel::server {
namespace {

using nlohmann::json;
using protocol::testing::schemas;
using test_support::ws_client;

constexpr char const* admin_token = "gate-keeper";
constexpr double dt = 1.0 / 64.0; // a power of two: world time is a sum of exact steps

/// No forces, no collisions, walls at ±10 m; a sensor box "goal" (x from 1 to 2) and a
/// sensor ball "zone" (centre x = 3.5, radius 0.5), both around the x axis.
json sensor_scene()
{
    return {{"name", "sensors"},
            {"dt", dt},
            {"integrator", "semi_implicit_euler"},
            {"collisions", {{"mode", "off"}}},
            {"box", {{"min", {-10, -10, -10}}, {"max", {10, 10, 10}}}},
            {"sensors", json::array({{{"name", "goal"}, {"box", {{"min", {1, -1, -1}}, {"max", {2, 1, 1}}}}},
                                     {{"name", "zone"}, {"ball", {{"centre", {3.5, 0, 0}}, {"radius", 0.5}}}}})}};
}

server_options one_room(std::string const& name, json const& scene)
{
    server_options o;
    o.admin_token = admin_token;
    o.rooms.push_back({"play", test_support::write_scene(testing::TempDir() + "kugel_events_" + name + ".json", scene)});
    return o;
}

/// A client of room "play" with its welcome read.
struct client
{
    ws_client ws;
    json welcome;

    explicit client(std::uint16_t port) : ws(port, "/ws/play") { welcome = next("welcome"); }

    json next(std::string const& type)
    {
        json message = ws.next(type);
        EXPECT_EQ(schemas().refusal(message), "") << message.dump();
        return message;
    }

    /// Sends a hello with `events`, then a ping: once its pong comes, the room holds the
    /// subscription (the room takes both in the order sent).
    void subscribe(json const& events, std::uint64_t ref)
    {
        ws.send(json{{"type", "hello"}, {"events", events}});
        ws.send(json{{"type", "ping"}, {"ref", ref}});
        json const pong = next("pong");
        ASSERT_EQ(pong.at("ref"), ref);
    }

    /// Spawns a point mass and returns its id and the tick the spawn took effect in.
    std::pair<std::uint64_t, std::uint64_t> spawn(std::uint64_t ref, std::array<double, 3> position,
                                                  std::array<double, 3> velocity,
                                                  std::optional<std::string> tag = std::nullopt)
    {
        json body = {{"position", position}, {"velocity", velocity}, {"radius", 0.0}, {"mass", 1.0}};
        if (tag)
            body["tag"] = *tag;
        ws.send(json{{"type", "spawn"}, {"ref", ref}, {"body", body}});
        json const ack = next("ack");
        EXPECT_EQ(ack.at("ref"), ref) << ack.dump();
        return {ack.at("id").get<std::uint64_t>(), ack.at("tick").get<std::uint64_t>()};
    }

    /// Every message until a snapshot with tick >= `tick`: the events among them, and the
    /// message types in the order they came.
    std::vector<json> events_until(std::uint64_t tick, std::vector<json>* everything = nullptr)
    {
        std::vector<json> events;
        for (;;) {
            json message = ws.read_json();
            EXPECT_EQ(schemas().refusal(message), "") << message.dump();
            if (everything)
                everything->push_back(message);
            if (message.at("type") == "event")
                events.push_back(message);
            if (message.at("type") == "snapshot" && message.at("tick").get<std::uint64_t>() >= tick)
                return events;
        }
    }
};

std::uint64_t metric(std::uint16_t port, std::string const& name)
{
    auto const reply = test_support::http_get(port, "/metrics");
    std::string const prefix = name + "{room=\"play\"} ";
    auto const at = reply.body.find(prefix);
    if (at == std::string::npos)
        return ~std::uint64_t{0};
    return std::stoull(reply.body.substr(at + prefix.size()));
}

// A ball spawned at x = 0 at 2.5 m/s along x enters the goal (x = 1) 0.4 s and leaves it
// (x = 2) 0.8 s after the start of its spawn's step. With no force the engine follows the
// body's straight path, and the crossing time is that path's root: exact but for rounding
// (world time is a sum of steps of 1/64 s, exact in binary; the root is found to the
// precision of a double), so 1e-9 s is a tolerance a million times above rounding and far
// below a step (0.016 s), which also pins each event to its tick.
TEST(Events, ACrossingIsReportedAtItsAnalyticTimeBeforeTheSnapshotOfItsTick)
{
    test_support::in_process_server s(one_room("crossing", sensor_scene()));
    client watcher(s.port());
    client deaf(s.port()); // asks for nothing
    EXPECT_EQ(watcher.welcome.at("limits").at("max_queued_events"), 256);
    watcher.subscribe(json{{"sensors", {"goal"}}}, 1);

    auto const [id, spawn_tick] = watcher.spawn(2, {0, 0, 0}, {2.5, 0, 0}, "ball");
    double const start = static_cast<double>(spawn_tick - 1) * dt; // the spawn's step starts here
    double const t_enter = start + 1.0 / 2.5;
    double const t_leave = start + 2.0 / 2.5;
    std::uint64_t const enter_tick = spawn_tick + 25; // its step runs from start + 25·dt to start + 26·dt
    std::uint64_t const leave_tick = spawn_tick + 51; // from start + 51·dt to start + 52·dt
    ASSERT_LT(static_cast<double>(enter_tick - 1) * dt, t_enter);
    ASSERT_GT(static_cast<double>(enter_tick) * dt, t_enter);
    ASSERT_LT(static_cast<double>(leave_tick - 1) * dt, t_leave);
    ASSERT_GT(static_cast<double>(leave_tick) * dt, t_leave);

    std::vector<json> seen;
    auto const events = watcher.events_until(leave_tick, &seen);
    ASSERT_EQ(events.size(), 2U);
    EXPECT_EQ(events[0].at("kind"), "entered");
    EXPECT_EQ(events[0].at("sensor"), "goal");
    EXPECT_EQ(events[0].at("body"), id);
    EXPECT_EQ(events[0].at("tag"), "ball");
    EXPECT_EQ(events[0].at("tick"), enter_tick);
    EXPECT_NEAR(events[0].at("time").get<double>(), t_enter, 1e-9);
    EXPECT_FALSE(events[0].contains("missed"));
    EXPECT_EQ(events[1].at("kind"), "left");
    EXPECT_EQ(events[1].at("sensor"), "goal");
    EXPECT_EQ(events[1].at("body"), id);
    EXPECT_EQ(events[1].at("tick"), leave_tick);
    EXPECT_NEAR(events[1].at("time").get<double>(), t_leave, 1e-9);

    // No snapshot of an event's tick (or later) came before the event; each snapshot shows
    // the ball on the side of the goal's faces that its tick says.
    std::size_t events_seen = 0;
    for (json const& m : seen) {
        if (m.at("type") == "event") {
            ++events_seen;
            continue;
        }
        if (m.at("type") != "snapshot")
            continue;
        auto const tick = m.at("tick").get<std::uint64_t>();
        if (tick >= enter_tick) {
            EXPECT_GE(events_seen, 1U) << "the snapshot of tick " << tick << " came before the entry";
        }
        if (tick >= leave_tick) {
            EXPECT_GE(events_seen, 2U) << "the snapshot of tick " << tick << " came before the exit";
        }
        auto const i = test_support::index_of(m, id);
        if (i < 0)
            continue;
        double const x = m.at("bodies").at("position").at(static_cast<std::size_t>(3 * i)).get<double>();
        EXPECT_EQ(x >= 1.0, tick >= enter_tick) << "tick " << tick << " x " << x;
        EXPECT_EQ(x > 2.0, tick >= leave_tick) << "tick " << tick << " x " << x;
    }

    // The client that did not ask heard nothing of it.
    EXPECT_TRUE(deaf.events_until(leave_tick).empty());
    EXPECT_EQ(metric(s.port(), "kugel_events_sent_total"), 2U);
    EXPECT_EQ(metric(s.port(), "kugel_events_dropped_total"), 0U);
}

using crossing = std::tuple<std::string, std::string, std::uint64_t>; // kind, sensor, body

std::multiset<crossing> crossings(std::vector<json> const& events)
{
    std::multiset<crossing> out;
    for (json const& e : events)
        out.insert({e.at("kind").get<std::string>(), e.at("sensor").get<std::string>(),
                    e.at("body").get<std::uint64_t>()});
    return out;
}

// A tagged ball and an untagged puck both pass through both sensors: each client hears the
// events its filter matches, and a client that turned its events off hears none.
TEST(Events, FiltersBySensorTagAndKind)
{
    test_support::in_process_server s(one_room("filters", sensor_scene()));
    client all(s.port());
    client zone(s.port());
    client balls(s.port());
    client leaving(s.port());
    client narrow(s.port());
    client off(s.port());
    all.subscribe(true, 1);
    zone.subscribe(json{{"sensors", {"zone"}}}, 1);
    balls.subscribe(json{{"tags", {"ball"}}}, 1);
    leaving.subscribe(json{{"kinds", {"left"}}}, 1);
    narrow.subscribe(json{{"sensors", {"goal"}}, {"tags", {"ball"}}, {"kinds", {"entered"}}}, 1);
    off.subscribe(true, 1);
    off.subscribe(false, 2);

    // Spawned by a client that hears no events, so that reading its acks skips none.
    client spawner(s.port());
    auto const spawned_ball = spawner.spawn(2, {0, 0, 0}, {5, 0, 0}, "ball");
    auto const spawned_puck = spawner.spawn(3, {0, 0.2, 0}, {5, 0, 0}, "puck");
    std::uint64_t const ball = spawned_ball.first;
    std::uint64_t const puck = spawned_puck.first;
    std::uint64_t const done = spawned_puck.second + 64; // 1 s: past x = 4 at 5 m/s

    std::multiset<crossing> every;
    for (std::uint64_t const body : {ball, puck})
        for (char const* sensor : {"goal", "zone"})
            for (char const* kind : {"entered", "left"})
                every.insert({std::string(kind), std::string(sensor), body});
    auto const only = [&](auto keep) {
        std::multiset<crossing> out;
        for (crossing const& c : every)
            if (keep(c))
                out.insert(c);
        return out;
    };

    auto const all_events = all.events_until(done);
    EXPECT_EQ(crossings(all_events), every);
    for (json const& e : all_events) // the tag comes with every event of a tagged body
        EXPECT_EQ(e.at("tag"), e.at("body") == ball ? "ball" : "puck");
    EXPECT_EQ(crossings(zone.events_until(done)), only([](crossing const& c) { return std::get<1>(c) == "zone"; }));
    EXPECT_EQ(crossings(balls.events_until(done)), only([&](crossing const& c) { return std::get<2>(c) == ball; }));
    EXPECT_EQ(crossings(leaving.events_until(done)), only([](crossing const& c) { return std::get<0>(c) == "left"; }));
    EXPECT_EQ(crossings(narrow.events_until(done)), (std::multiset<crossing>{{"entered", "goal", ball}}));
    EXPECT_TRUE(off.events_until(done).empty());
    // each client's events come in time order
    for (std::size_t k = 1; k < all_events.size(); ++k)
        EXPECT_LE(all_events[k - 1].at("time").get<double>(), all_events[k].at("time").get<double>());
}

// With room for 4 unsent events, a tick with 20 (a reset puts the scene's 20 bodies back
// inside a sensor: each enters at the next step) queues 4 and drops 16; the next event the
// client is sent says so, /metrics counts them, and the connection stays open.
TEST(Events, OverflowIsDroppedCountedAndToldWithTheNextEvent)
{
    json scene = sensor_scene();
    scene["sensors"] = json::array({{{"name", "pen"}, {"box", {{"min", {-5, -5, -5}}, {"max", {5, 5, 5}}}}}});
    scene["bodies"] = json::array();
    for (int i = 0; i < 20; ++i)
        scene["bodies"].push_back({{"position", {-4.0 + 0.4 * i, 0, 0}}, {"radius", 0.0}, {"mass", 1.0}});
    server_options o = one_room("overflow", scene);
    o.client.max_queued_events = 4;
    test_support::in_process_server s(o);

    client admin(s.port());
    EXPECT_EQ(admin.welcome.at("limits").at("max_queued_events"), 4);
    // The scene's bodies entered the pen at the room's first step: past it before subscribing.
    while (admin.next("snapshot").at("tick").get<std::uint64_t>() < 2) {
    }
    admin.ws.send(json{{"type", "hello"}, {"admin_token", admin_token}});
    ASSERT_TRUE(admin.next("welcome").at("admin").get<bool>());
    admin.subscribe(json{{"sensors", {"pen"}}}, 1);
    admin.ws.send(json{{"type", "reset"}, {"ref", 2}});
    std::uint64_t const reset_tick = admin.next("ack").at("tick").get<std::uint64_t>();
    auto const burst = admin.events_until(reset_tick);
    ASSERT_EQ(burst.size(), 4U);
    for (json const& e : burst) {
        EXPECT_EQ(e.at("tick"), reset_tick);
        EXPECT_EQ(e.at("kind"), "entered");
        EXPECT_FALSE(e.contains("missed"));
    }

    auto const [id, spawn_tick] = admin.spawn(3, {0, 1, 0}, {0, 0, 0});
    auto const next = admin.events_until(spawn_tick);
    ASSERT_EQ(next.size(), 1U);
    EXPECT_EQ(next[0].at("body"), id);
    EXPECT_EQ(next[0].at("kind"), "entered");
    EXPECT_EQ(next[0].at("missed"), 16);
    EXPECT_EQ(metric(s.port(), "kugel_events_dropped_total"), 16U);
    EXPECT_EQ(metric(s.port(), "kugel_events_sent_total"), 5U);

    admin.ws.send(json{{"type", "ping"}, {"ref", 4}}); // still served
    EXPECT_EQ(admin.next("pong").at("ref"), 4);
    EXPECT_FALSE(admin.ws.closed());
}

// Refused subscriptions say what was wrong (an unknown sensor names the scene's) and change
// nothing: the subscription held before still holds.
TEST(Events, BadSubscriptionsAreRefusedAndChangeNothing)
{
    test_support::in_process_server s(one_room("refused", sensor_scene()));
    client c(s.port());
    c.subscribe(json{{"sensors", {"zone"}}}, 1);

    c.ws.send(json{{"type", "hello"}, {"events", {{"sensors", {"zone", "gaol"}}}}});
    json const unknown = c.next("error");
    EXPECT_EQ(unknown.at("code"), "bad_value");
    EXPECT_EQ(unknown.at("message"),
              "/events/sensors/1: the room's scene has no sensor \"gaol\" (its sensors: \"goal\", \"zone\")");
    EXPECT_FALSE(unknown.contains("ref"));
    c.ws.send(json{{"type", "hello"}, {"events", {{"kinds", {"stayed"}}}}});
    EXPECT_EQ(c.next("error").at("message"), "/events/kinds/0: must be \"entered\", \"left\" or \"contact\", got \"stayed\"");
    c.ws.send(json{{"type", "hello"}, {"events", {{"tags", json::array()}}}});
    EXPECT_EQ(c.next("error").at("code"), "bad_value");
    c.ws.send(json{{"type", "hello"}, {"events", "all"}});
    EXPECT_EQ(c.next("error").at("code"), "wrong_type");

    // Still subscribed to "zone" alone: the goal's events do not come, the zone's do.
    auto const [id, tick] = c.spawn(2, {0, 0, 0}, {5, 0, 0});
    auto const events = c.events_until(tick + 64);
    EXPECT_EQ(crossings(events), (std::multiset<crossing>{{"entered", "zone", id}, {"left", "zone", id}}));
}

// A scene without sensors: a subscription to every event is taken, and nothing comes; one
// naming a sensor is refused saying the scene has none.
TEST(Events, ASceneWithoutSensorsHasNone)
{
    json scene = sensor_scene();
    scene.erase("sensors");
    test_support::in_process_server s(one_room("none", scene));
    client c(s.port());
    c.subscribe(true, 1);
    c.ws.send(json{{"type", "hello"}, {"events", {{"sensors", {"goal"}}}}});
    EXPECT_EQ(c.next("error").at("message"),
              "/events/sensors/0: the room's scene has no sensor \"goal\" (it has no sensors)");
    auto const [id, tick] = c.spawn(2, {0, 0, 0}, {5, 0, 0});
    (void)id;
    EXPECT_TRUE(c.events_until(tick + 20).empty());
}

/// Continuous mode, no forces, walls at ±10 m: a fixed post (tag "post", radius 0.5) at x =
/// 3, a fixed rock (tag "rock") off the axis, and one rule: contacts between a "ball" and a
/// "post".
json contact_scene()
{
    return {{"name", "contacts"},
            {"dt", dt},
            {"integrator", "semi_implicit_euler"},
            {"collisions", {{"mode", "continuous"}}},
            {"box", {{"min", {-10, -10, -10}}, {"max", {10, 10, 10}}}},
            {"bodies", json::array({{{"position", {3, 0, 0}}, {"radius", 0.5}, {"mass", 0}, {"static", true}, {"tag", "post"}},
                                    {{"position", {3, 4, 0}}, {"radius", 0.5}, {"mass", 0}, {"static", true}, {"tag", "rock"}}})},
            {"contacts", json::array({json::array({"ball", "post"})})}};
}

// A ball (radius 0.5) spawned at x = −0.1 moving at 2 m/s along x touches the post (radius
// 0.5, centre x = 3) when its centre reaches x = 2, 1.05 s (67.2 steps) after its step's start. Continuous mode
// times the contact at its event, the root of the pair's distance along a straight path:
// exact but for rounding, so 1e-9 s (as for crossings) also pins it to its tick. The event
// names both bodies, ascending, with their tags; a ball aimed at the rock, which no rule
// pairs with a ball, and an untagged ball aimed at the post are not reported.
TEST(Events, AContactBetweenTaggedBodiesIsReportedAtItsTimeOfImpact)
{
    test_support::in_process_server s(one_room("contact", contact_scene()));
    client watcher(s.port());
    client sensors_only(s.port());
    watcher.subscribe(json{{"tags", {"post"}}}, 1);
    sensors_only.subscribe(json{{"kinds", {"entered", "left"}}}, 1);

    auto spawn_ball = [&](std::uint64_t ref, std::array<double, 3> at, std::optional<std::string> tag) {
        json body = {{"position", at}, {"velocity", {2, 0, 0}}, {"radius", 0.5}, {"mass", 1.0}};
        if (tag)
            body["tag"] = *tag;
        watcher.ws.send(json{{"type", "spawn"}, {"ref", ref}, {"body", body}});
        json const ack = watcher.next("ack");
        return std::pair{ack.at("id").get<std::uint64_t>(), ack.at("tick").get<std::uint64_t>()};
    };
    auto const [ball, tick] = spawn_ball(2, {-0.1, 0, 0}, "ball");
    spawn_ball(3, {-0.1, 4, 0}, "ball");    // at the rock: no rule
    spawn_ball(4, {-6, 0, 0}, std::nullopt); // untagged, behind the first
    double const t_touch = static_cast<double>(tick - 1) * dt + 1.05;
    std::uint64_t const touch_tick = tick + 67; // its step runs from start + 67·dt to start + 68·dt
    auto const events = watcher.events_until(touch_tick + 8);
    ASSERT_EQ(events.size(), 1U) << events.back().dump();
    json const& e = events[0];
    EXPECT_EQ(e.at("kind"), "contact");
    EXPECT_EQ(e.at("bodies"), json::array({1, ball})) << "the post is the scene's first body";
    EXPECT_EQ(e.at("tags"), json::array({"post", "ball"}));
    EXPECT_FALSE(e.contains("sensor"));
    EXPECT_FALSE(e.contains("body"));
    EXPECT_NEAR(e.at("time").get<double>(), t_touch, 1e-9);
    EXPECT_EQ(e.at("tick"), touch_tick);
    EXPECT_TRUE(sensors_only.events_until(touch_tick + 8).empty()) << "kinds without contact";
}

} // namespace
} // namespace kugel::server
