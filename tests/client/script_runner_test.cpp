// Scripts run in this process against a server in this process: how steps pass and fail.
// The example scripts, and the kugel-client executable, are tested in kugel_client_test.cpp.

#include "client/script_runner.hpp"
#include "server.hpp"
#include "support/in_process_server.hpp"

#include <filesystem>
#include <gtest/gtest.h>

#include <thread>
#include <sstream>

namespace kugel::client {
namespace {

using namespace std::chrono_literals;

constexpr char const* admin_token = "script-runner-admin-token";

/// A server with the example scene "still" as room "still", and an admin token.
class running_server : public test_support::in_process_server
{
public:
    running_server() : in_process_server(options()) {}
    std::string url() const { return in_process_server::url("still"); }

private:
    static server::server_options options()
    {
        server::server_options o;
        o.rooms = {{"still", std::filesystem::path(KUGEL_SOURCE_DIR) / "client" / "examples" /
                                 "scenes" / "still.json"}};
        o.admin_token = admin_token;
        return o;
    }
};

struct outcome
{
    run_result result;
    std::string log;
};

outcome run(std::string const& url, std::string const& text,
            std::optional<protocol::snapshot_request> snapshots = std::nullopt)
{
    std::ostringstream log;
    run_options options;
    options.url = url;
    options.timeout = 10s;
    options.snapshots = std::move(snapshots);
    run_result result = run_script(parse_script(text), options, log);
    return {std::move(result), log.str()};
}

TEST(ScriptRunner, KeptValuesAreUsedLater)
{
    running_server s;
    outcome const o = run(s.url(), R"({"steps": [
        {"send": {"type": "spawn", "body": {"position": [3, 0, 0], "radius": 0.5, "mass": 4}}},
        {"expect": {"type": "ack", "keep": {"b": "id", "t": "tick"}}},
        {"wait_until_tick": "$t"},
        {"expect_body": {"id": "$b", "position": [3, 0, 0], "tolerance": 0, "keep": {"x": "/position/0"}}},
        {"send": {"type": "remove", "id": "$b"}},
        {"expect": {"type": "ack", "fields": {"ref": 2}}},
        {"wait_for_body": {"id": "$b", "exists": false, "max_ticks": 30}},
        {"send": {"type": "spawn", "body": {"position": ["= $x - 1", 0, 0], "radius": 0.5, "mass": 4}}},
        {"expect": {"type": "ack", "fields": {"/id": "= $b + 1"}}}
    ]})");
    EXPECT_TRUE(o.result.passed) << o.log;
    EXPECT_EQ(o.result.failed_step, 0U);
    EXPECT_NE(o.log.find("passed: 9 steps"), std::string::npos) << o.log;
}

// On the compact form a script sees positions to the announced quantum: a check within the
// quantum passes, an exact one fails (0.123456789 m is no whole number of quanta), and the
// quanta are variables for tolerances. On the full form the exact check passes.
TEST(ScriptRunner, CompactSnapshotsAreCheckedToTheAnnouncedQuantum)
{
    running_server s;
    auto const script = [](std::string const& tolerance) {
        return R"({"steps": [
            {"send": {"type": "spawn", "body": {"position": [3, 0.123456789, 0], "radius": 0.5, "mass": 4}}},
            {"expect": {"type": "ack", "keep": {"b": "id", "t": "tick"}}},
            {"wait_until_tick": "$t"},
            {"expect_body": {"id": "$b", "position": [3, 0.123456789, 0], "tolerance": )" +
               tolerance + R"(}},
            {"send": {"type": "remove", "id": "$b"}},
            {"expect": {"type": "ack"}}
        ]})";
    };
    protocol::snapshot_request const compact{.form = "compact"};
    outcome const within = run(s.url(), script(R"("= $position_quantum / 2")"), compact);
    EXPECT_TRUE(within.result.passed) << within.log;
    outcome const exact = run(s.url(), script("0"), compact);
    EXPECT_FALSE(exact.result.passed) << exact.log;
    EXPECT_EQ(exact.result.failed_step, 4U) << exact.log;
    outcome const full = run(s.url(), script("0"));
    EXPECT_TRUE(full.result.passed) << full.log;
    outcome const no_quanta = run(s.url(), script(R"("$position_quantum")"));
    EXPECT_FALSE(no_quanta.result.passed) << "the full form announces no quanta";
}

TEST(ScriptRunner, AFailureNamesTheStepWhatWasExpectedAndWhatArrived)
{
    running_server s;
    outcome const o = run(s.url(), R"({"steps": [
        {"send": {"type": "spawn", "body": {"position": [0, 0, 0], "radius": 0.5, "mass": 2}}},
        {"expect": {"type": "ack", "keep": {"b": "id"}}},
        {"send": {"type": "impulse", "id": "$b", "impulse": [1, 0, 0]}},
        {"expect": {"type": "ack"}},
        {"name": "too fast", "wait_for_body": {"id": "$b", "velocity": [1, 0, 0], "tolerance": 0.1, "max_ticks": 10}},
        {"name": "never reached", "wait_ticks": 1}
    ]})");
    EXPECT_FALSE(o.result.passed);
    EXPECT_EQ(o.result.failed_step, 5U);
    auto const& f = o.result.failure;
    EXPECT_NE(f.find("FAIL step 5 \"too fast\" (wait_for_body, client main)"), std::string::npos)
        << f;
    EXPECT_NE(f.find("expected: body 1, velocity [1.0, 0.0, 0.0] ± 0.1 within 10 ticks"),
              std::string::npos)
        << f;
    EXPECT_NE(f.find("velocity [0.5, 0.0, 0.0]"), std::string::npos) << f;
    EXPECT_EQ(o.log.find("never reached"), std::string::npos) << "ran past the failure:\n" << o.log;
}

TEST(ScriptRunner, AWrongAnswerIsShownWhole)
{
    running_server s;
    outcome const o = run(s.url(), R"({"steps": [
        {"send": {"type": "remove", "id": 12345}},
        {"expect": {"type": "ack"}}
    ]})");
    EXPECT_EQ(o.result.failed_step, 2U);
    EXPECT_NE(o.result.failure.find("expected: ack"), std::string::npos) << o.result.failure;
    EXPECT_NE(o.result.failure.find(R"("code":"unknown_body")"), std::string::npos)
        << o.result.failure;
}

TEST(ScriptRunner, AnAdminHelloLetsAScriptSendAdminCommands)
{
    running_server s;
    outcome const o = run(s.url(), std::string(R"({"steps": [
        {"send": {"type": "pause"}},
        {"expect": {"code": "forbidden", "message_contains": "/type"}},
        {"send": {"type": "hello", "admin_token": ")") + admin_token + R"("}},
        {"send": {"type": "pause"}},
        {"expect": {"type": "ack"}},
        {"send": {"type": "load_scene", "scene": {"name": "empty", "dt": 0.01}}},
        {"expect": {"type": "ack"}},
        {"send": {"type": "reset"}},
        {"expect": {"type": "ack"}},
        {"send": {"type": "resume"}},
        {"expect": {"type": "ack"}}
    ]})");
    EXPECT_TRUE(o.result.passed) << o.log;
}

TEST(ScriptRunner, AMessageTheProtocolRefusesIsNotSent)
{
    running_server s;
    outcome const o = run(s.url(), R"({"steps": [
        {"send": {"type": "spawn", "body": {"position": [0, 0, 0], "radius": -1, "mass": 1}}}
    ]})");
    EXPECT_EQ(o.result.failed_step, 1U);
    EXPECT_NE(o.result.failure.find("bad_value: /body/radius"), std::string::npos)
        << o.result.failure;
}

TEST(ScriptRunner, AnUnsetVariableFailsItsStep)
{
    running_server s;
    outcome const o = run(s.url(), R"({"steps": [
        {"send": {"type": "remove", "id": "$nobody"}}
    ]})");
    EXPECT_EQ(o.result.failed_step, 1U);
    EXPECT_NE(o.result.failure.find("$nobody is not set"), std::string::npos) << o.result.failure;
}

TEST(ScriptRunner, NoServerFailsTheFirstStepThatConnects)
{
    std::string url;
    {
        running_server s;
        url = s.url();
    }
    run_options options;
    options.url = url;
    options.timeout = 5s;
    std::ostringstream log;
    run_result const result =
        run_script(parse_script(R"({"steps": [{"wait_ticks": 1}]})"), options, log);
    EXPECT_EQ(result.failed_step, 1U);
    EXPECT_NE(result.failure.find("connection: cannot connect"), std::string::npos)
        << result.failure;
}

// Cleanup: at the end, passed or failed, each client removes what it spawned, so a script run
// again and again against a long-lived room leaves nothing behind. Two clients spawn three
// bodies, one of them removes one itself, and the script fails at its last step: the room
// holds what it held before, and the log says what each client removed. Without cleanup the
// bodies stay.
TEST(ScriptRunner, CleanupRemovesWhatEachClientSpawnedPassOrFail)
{
    running_server s;
    std::string const script = R"({"cleanup": CLEANUP, "steps": [
        {"send": {"type": "spawn", "body": {"position": [3, 0, 0], "radius": 0.5, "mass": 4}}},
        {"expect": {"type": "ack", "keep": {"a": "id"}}},
        {"send": {"type": "spawn", "body": {"position": [-3, 0, 0], "radius": 0.5, "mass": 4}}},
        {"expect": {"type": "ack"}},
        {"client": "other", "send": {"type": "spawn", "body": {"position": [0, 3, 0], "radius": 0.5, "mass": 4}}},
        {"client": "other", "expect": {"type": "ack"}},
        {"send": {"type": "remove", "id": "$a"}},
        {"expect": {"type": "ack"}},
        {"wait_ticks": 2},
        {"expect_body": {"id": 424242, "position": [0, 0, 0], "tolerance": 0}}
    ]})";
    auto const with = [&](char const* cleanup) {
        std::string text = script;
        text.replace(text.find("CLEANUP"), 7, cleanup);
        return text;
    };
    auto const before = s.bodies("still");
    outcome const cleaned = run(s.url(), with("true"));
    EXPECT_FALSE(cleaned.result.passed);
    EXPECT_EQ(cleaned.result.failed_step, 10U) << cleaned.log;
    EXPECT_NE(cleaned.log.find("client main removed 1 of the 2 bodies it spawned"), std::string::npos) << cleaned.log;
    EXPECT_NE(cleaned.log.find("client other removed 1 of the 1 bodies it spawned"), std::string::npos) << cleaned.log;
    for (int tick = 0; tick < 200 && s.bodies("still") != before; ++tick)
        std::this_thread::sleep_for(10ms); // the removes take effect at the next tick
    EXPECT_EQ(s.bodies("still"), before);
    outcome const kept = run(s.url(), with("false"));
    EXPECT_EQ(kept.log.find("removed"), std::string::npos) << kept.log;
    for (int tick = 0; tick < 200 && s.bodies("still") != before + 2; ++tick)
        std::this_thread::sleep_for(10ms);
    EXPECT_EQ(s.bodies("still"), before + 2);
}

} // namespace
} // namespace kugel::client
