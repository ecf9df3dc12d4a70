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

} // namespace
} // namespace kugel::server
