// Hostile clients that play by the protocol's rules: every message is well formed and under
// the rate limit, and yet it aims at the room. A burst of commands at once; bodies whose
// forces no double can hold; spheres spawned into each other. Each over a real WebSocket
// to a server in this process. The room must answer every command once, keep its rate, and
// keep stepping its world for everyone else.

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
#include <fstream>
#include <thread>
#include <map>
#include <string>

namespace kugel::server {
namespace {

using nlohmann::json;
using test_support::ws_client;
namespace fs = std::filesystem;

server_options one_room(std::string const& test_name, json const& scene)
{
    server_options o;
    o.rooms.push_back({"r", test_support::write_scene(fs::path(testing::TempDir()) /
                                                          ("kugel_hostile_world_" + test_name + ".json"),
                                                      scene)});
    return o;
}

/// Reads until every ref in [first, last] has its answer; returns the answers by ref.
std::map<std::uint64_t, json> answers(ws_client& c, std::uint64_t first, std::uint64_t last)
{
    std::map<std::uint64_t, json> out;
    while (out.size() < last - first + 1) {
        auto const text = c.read(std::chrono::seconds(10));
        if (!text) {
            ADD_FAILURE() << (c.closed() ? "closed with " + std::to_string(c.close_code())
                                         : std::string("no answer in time"))
                          << " after " << out.size() << " answers";
            break;
        }
        json const m = json::parse(*text);
        EXPECT_EQ(protocol::testing::schemas().refusal(m), "") << *text;
        if (m.at("type") == "snapshot" || m.at("type") == "welcome")
            continue;
        std::uint64_t const ref = m.at("ref");
        EXPECT_TRUE(ref >= first && ref <= last) << *text;
        EXPECT_FALSE(out.contains(ref)) << "a second answer to ref " << ref;
        out[ref] = m;
    }
    return out;
}

json spawn(std::uint64_t ref, std::array<double, 3> position, json body_rest = {{"radius", 0.1}, {"mass", 1.0}})
{
    body_rest["position"] = position;
    return {{"type", "spawn"}, {"ref", ref}, {"body", body_rest}};
}

// Bursts ----------------------------------------------------------------------------------

TEST(HostileBurst, ABurstUnderTheRateLimitIsAnsweredCommandByCommandAndNeverClosed)
{
    // The defaults: 200 commands a second, a burst of 200.
    test_support::in_process_server s(one_room("burst", test_support::still_scene()));
    constexpr std::uint64_t spawns = 190;
    ws_client spawner(s.port(), "/ws/r");
    spawner.next("welcome");
    for (std::uint64_t ref = 1; ref <= spawns; ++ref) // a 19 x 10 grid, 0.5 m apart
        spawner.send(spawn(ref, {-4.5 + 0.5 * static_cast<double>(ref % 19), 2.0 + 0.5 * static_cast<double>(ref / 19), 0}));
    auto const spawned = answers(spawner, 1, spawns);
    for (auto const& [ref, answer] : spawned)
        EXPECT_EQ(answer.at("type"), "ack") << answer.dump();
    EXPECT_FALSE(spawner.closed());

    ws_client pusher(s.port(), "/ws/r");
    pusher.next("welcome");
    constexpr std::uint64_t impulses = 199;
    for (std::uint64_t ref = 1; ref <= impulses; ++ref)
        pusher.send(json{{"type", "impulse"}, {"ref", ref}, {"id", 1}, {"impulse", {0, 0, 1e-3}}});
    auto const pushed = answers(pusher, 1, impulses);
    for (auto const& [ref, answer] : pushed)
        EXPECT_EQ(answer.at("type"), "ack") << answer.dump();
    EXPECT_FALSE(pusher.closed());
    EXPECT_EQ(s.get().find_room("r")->counters().bodies.load(), spawns + 1);
}

// Forces no step can hold -------------------------------------------------------------------

json scene_file(std::string const& name)
{
    std::ifstream in(fs::path(KUGEL_SOURCE_DIR) / "scenes" / (name + ".json"));
    return json::parse(in);
}

/// A scene of the project's with another integrator and, for a 1/r² law, its method.
json variant(std::string const& name, std::string const& integrator, std::string const& method = "direct")
{
    json s = scene_file(name);
    s["integrator"] = integrator;
    for (auto& [model, settings] : s["forces"].items())
        if (model == "gravity" || model == "coulomb") {
            settings["method"] = method;
            if (method == "tree")
                settings["theta"] = 0.5;
        }
    return s;
}

/// The room's time in a snapshot at least `ticks` after the one read first; the room
/// stands still if it does not grow.
double time_after(ws_client& c, std::uint64_t ticks)
{
    json first = c.next("snapshot");
    for (;;) {
        json const later = c.next("snapshot");
        EXPECT_FALSE(later.value("paused", false));
        if (later.at("tick").get<std::uint64_t>() >= first.at("tick").get<std::uint64_t>() + ticks) {
            EXPECT_GT(later.at("time").get<double>(), first.at("time").get<double>()) << "time stands still";
            return later.at("time").get<double>();
        }
    }
}

struct breaking_case
{
    std::string name;
    json scene;
    std::vector<json> bodies; ///< spawned in this order; the last is the one refused
    std::string code;         ///< what the last one gets
};

std::vector<breaking_case> breaking_catalogue()
{
    json const heavy = {{"radius", 0.0}, {"mass", 1e300}};
    json const point = {{"radius", 0.0}, {"mass", 1.0}};
    auto charged = [](double q) { return json{{"radius", 0.0}, {"mass", 1.0}, {"charge", q}}; };
    auto at = [](json body, std::array<double, 3> x) {
        body["position"] = x;
        return body;
    };
    std::vector<breaking_case> rows;
    // Every integrator a 1/r² scene may use, each with one of the two methods, both methods
    // with two integrators: the check is the force loop's, whatever integrates after it.
    std::array<std::pair<std::string, std::string>, 4> const kinds{{{"explicit_euler", "direct"},
                                                                    {"semi_implicit_euler", "tree"},
                                                                    {"velocity_verlet", "direct"},
                                                                    {"rk4", "tree"}}};
    for (auto const& [integrator, method] : kinds) {
        {
            std::string const with = " (" + integrator + ", " + method + ")";
            json const charges = variant("charges", integrator, method);
            json const kepler = variant("kepler", integrator, method);
            rows.push_back({"a charge of 1e200 C" + with, charges, {at(charged(1e200), {3, 3, 0})}, "singular_force"});
            rows.push_back({"two charges of 1e200 C" + with, charges,
                            {at(charged(1e-300), {3, 3, 0}), at(charged(1e200), {-3, 3, 0})}, "singular_force"});
            // 1e14 C at 4.2 m from the scene's fixed 2 C: 1.1e13 m/s² on 1 kg, while c/dt is
            // 3e11 m/s²: finite, but its first step alone would pass the speed of light.
            rows.push_back({"a charge whose pull changes a speed by c in a step" + with, charges,
                            {at(charged(1e14), {3, 3, 0})}, "singular_force"});
            rows.push_back({"a charge on top of another, softened" + with, charges,
                            {at(charged(1e150), {1, 0, 0})}, "singular_force"});
            rows.push_back({"a mass of 1e300 kg" + with, kepler, {at(heavy, {5, 5, 0})}, "singular_force"});
            rows.push_back({"two point masses on one point, softening 0" + with, kepler,
                            {at(point, {5, 5, 0}), at(point, {5, 5, 0})}, "singular_force"});
            // The scene's planet held still: a moving one has left the point by the tick the
            // spawn applies at whenever the room ticked more than once before it (1.7 mm a
            // tick), and on a loaded machine it did.
            json fixed_planet = kepler;
            fixed_planet["bodies"][1]["static"] = true;
            fixed_planet["bodies"][1]["velocity"] = {0, 0, 0};
            rows.push_back({"a point mass on a scene body's centre" + with, fixed_planet,
                            {at(point, {0.45454545454545453, 0, 0})}, "singular_force"});
            rows.push_back({"a point mass a hair from another" + with, kepler,
                            {at(point, {5, 5, 0}), at(point, {5, 5, 1e-150})}, "singular_force"});
        }
    }
    return rows;
}

TEST(HostileWorld, ABodyWhoseForcesNoStepCanHoldIsRefusedAndTheWorldStepsOn)
{
    for (breaking_case const& c : breaking_catalogue()) {
        SCOPED_TRACE(c.name);
        test_support::in_process_server s(one_room("breaking", c.scene));
        ws_client attacker(s.port(), "/ws/r");
        attacker.next("welcome");
        std::uint64_t ref = 0;
        for (json const& body : c.bodies)
            attacker.send(json{{"type", "spawn"}, {"ref", ++ref}, {"body", body}});
        auto const replies = answers(attacker, 1, ref);
        for (auto const& [r, answer] : replies) {
            if (r < ref) {
                EXPECT_EQ(answer.at("type"), "ack") << answer.dump();
                continue;
            }
            EXPECT_EQ(answer.at("type"), "error") << answer.dump();
            EXPECT_EQ(answer.value("code", ""), c.code) << answer.dump();
            EXPECT_EQ(answer.value("message", "").rfind("/body: ", 0), 0U) << answer.dump();
        }
        ws_client bystander(s.port(), "/ws/r");
        bystander.next("welcome");
        time_after(bystander, 5);
        EXPECT_EQ(s.get().find_room("r")->counters().step_faults.load(), 0U);
    }
}

/// A world with gravity so weak that it changes no speed a double can tell, softening 0,
/// and a static point mass at the origin. A point mass sent at it at 32 m/s from 1 m away,
/// with dt = 1/64 s, lands exactly on it after two steps, where 1/r² is singular. No
/// spawn-time check can see that coming.
json collision_course_scene()
{
    return {{"name", "course"},
            {"dt", 1.0 / 64.0},
            {"integrator", "semi_implicit_euler"},
            {"forces", {{"gravity", {{"G", 1e-300}, {"softening", 0.0}}}}},
            {"bodies", json::array({{{"position", {0, 0, 0}}, {"radius", 0.0}, {"mass", 1.0}, {"static", true}}})}};
}

void send_on_collision_course(ws_client& attacker, std::uint64_t ref)
{
    attacker.send(json{{"type", "spawn"}, {"ref", ref},
                       {"body", {{"position", {-1, 0, 0}}, {"velocity", {32, 0, 0}}, {"radius", 0}, {"mass", 1}}}});
    EXPECT_EQ(answers(attacker, ref, ref).at(ref).at("type"), "ack");
}

TEST(HostileWorld, AStepThatFailsCostsTheBodyThatCameLastAndTheRoomSaysSo)
{
    fs::path const state = fs::path(testing::TempDir()) / "kugel_hostile_world_state";
    fs::remove_all(state);
    server_options o = one_room("course", collision_course_scene());
    o.state_dir = state;
    o.checkpoint_interval = std::chrono::milliseconds(50);
    {
        test_support::in_process_server s(o);
        room const& r = *s.get().find_room("r");
        ws_client attacker(s.port(), "/ws/r");
        attacker.next("welcome");
        send_on_collision_course(attacker, 1);
        // The snapshots count the fault, and the world goes on without the attacker's body.
        json snapshot;
        do
            snapshot = attacker.next("snapshot");
        while (!snapshot.contains("faults"));
        EXPECT_EQ(snapshot.at("faults"), 1);
        EXPECT_EQ(snapshot.at("bodies").at("id"), json::array({1}));
        time_after(attacker, 5);
        EXPECT_EQ(r.counters().step_faults.load(), 1U);
        EXPECT_EQ(r.counters().bodies.load(), 1U);

        json const health = json::parse(test_support::http_get(s.port(), "/healthz").body);
        EXPECT_EQ(health.at("status"), "ok");
        EXPECT_EQ(health.at("rooms").at("r").at("step_faults"), 1);
        std::string const fault = health.at("rooms").at("r").at("last_fault");
        EXPECT_NE(fault.find("removed body 2"), std::string::npos) << fault;
        EXPECT_NE(fault.find("they coincide"), std::string::npos) << fault;
        std::string const metrics = test_support::http_get(s.port(), "/metrics").body;
        EXPECT_NE(metrics.find("kugel_step_faults_total{room=\"r\"} 1"), std::string::npos);

        // A second try costs the attacker the same, and nobody else anything.
        send_on_collision_course(attacker, 2);
        do
            snapshot = attacker.next("snapshot");
        while (snapshot.value("faults", 0) < 2);
        EXPECT_EQ(snapshot.at("bodies").at("id"), json::array({1}));
        // The checkpoint holds the world as it stepped on.
        auto const deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
        while (!fs::exists(state / "r.json") && std::chrono::steady_clock::now() < deadline)
            std::this_thread::sleep_for(std::chrono::milliseconds(10));
        ASSERT_TRUE(fs::exists(state / "r.json"));
    }
    // After a restart the room steps from its checkpoint: the scene's body, time going on.
    test_support::in_process_server again(o);
    ws_client watcher(again.port(), "/ws/r");
    watcher.next("welcome");
    json const first = watcher.next("snapshot");
    EXPECT_EQ(first.at("bodies").at("id"), json::array({1}));
    time_after(watcher, 5);
}

TEST(HostileWorld, AFaultBetweenTheScenesOwnBodiesIsRecoveredFromToo)
{
    // Two of the scene's bodies on a collision course: nothing was spawned, the room starts
    // with them, and its second step brings them onto one point.
    json scene = collision_course_scene();
    scene["bodies"] = json::array({{{"position", {0, 5, 0}}, {"radius", 0.0}, {"mass", 1.0}},
                                   {{"position", {-1, 0, 0}}, {"velocity", {32, 0, 0}}, {"radius", 0}, {"mass", 1}},
                                   {{"position", {1, 0, 0}}, {"velocity", {-32, 0, 0}}, {"radius", 0}, {"mass", 1}}});
    test_support::in_process_server s(one_room("scene_course", scene));
    ws_client watcher(s.port(), "/ws/r");
    watcher.next("welcome");
    time_after(watcher, 10);
    json const snapshot = watcher.next("snapshot");
    EXPECT_EQ(snapshot.at("faults"), 1);
    EXPECT_EQ(snapshot.at("bodies").at("id"), json::array({1, 2})); // the later of the two went
}

// Spheres into spheres --------------------------------------------------------------------

TEST(HostileWorld, ASphereSpawnedIntoAnotherIsRefusedWhereSpheresCollide)
{
    for (std::string const mode : {"discrete", "continuous"}) {
        SCOPED_TRACE(mode);
        json scene = test_support::still_scene();
        scene["collisions"] = {{"mode", mode}};
        test_support::in_process_server s(one_room("overlap_" + mode, scene));
        ws_client c(s.port(), "/ws/r");
        c.next("welcome");
        // 200 spheres at the same point, as a hostile client sent them; the first fits.
        constexpr std::uint64_t count = 200;
        for (std::uint64_t ref = 1; ref <= count; ++ref)
            c.send(spawn(ref, {5, 5, 5}, {{"radius", 0.2}, {"mass", 1.0}}));
        c.send(spawn(count + 1, {0, 0, 0.69}, {{"radius", 0.2}, {"mass", 1.0}})); // into the scene's
        c.send(spawn(count + 2, {0, 0, 0.71}, {{"radius", 0.2}, {"mass", 1.0}})); // just clear of it
        c.send(spawn(count + 3, {0, 0, 0.6}, {{"radius", 0.0}, {"mass", 1.0}}));  // a point mass
        auto const replies = answers(c, 1, count + 3);
        for (auto const& [ref, answer] : replies) {
            bool const fits = ref == 1 || ref == count + 2 || ref == count + 3;
            EXPECT_EQ(answer.at("type"), fits ? "ack" : "error") << answer.dump();
            if (!fits) {
                EXPECT_EQ(answer.value("code", ""), "overlaps_body") << answer.dump();
                EXPECT_EQ(answer.value("message", "").rfind("/body/position: ", 0), 0U) << answer.dump();
            }
        }
        EXPECT_EQ(s.get().find_room("r")->counters().bodies.load(), 4U);
    }
    // Where spheres do not collide, they may share a place.
    test_support::in_process_server s(one_room("overlap_off", test_support::still_scene()));
    ws_client c(s.port(), "/ws/r");
    c.next("welcome");
    c.send(spawn(1, {0, 0, 0.1}, {{"radius", 0.2}, {"mass", 1.0}}));
    EXPECT_EQ(answers(c, 1, 1).at(1).at("type"), "ack");
}

} // namespace
} // namespace kugel::server
