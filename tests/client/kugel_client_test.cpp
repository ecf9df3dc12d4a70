// kugel-client as users run it: a child process against a kugel-server child process on a
// free port. Every example script in client/examples/ passes against the server it names;
// a wrong expectation fails naming its step; a short load completes with snapshots for
// every client. No test here asserts a time.

#include "client/script.hpp"
#include "support/child_process.hpp"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

namespace kugel::client {
namespace {

using namespace std::chrono_literals;
using test_support::child_process;
using test_support::server_child;
namespace fs = std::filesystem;

fs::path const examples_dir = fs::path(KUGEL_SOURCE_DIR) / "client" / "examples";

fs::path temp_file(std::string const& name)
{
    return fs::path(testing::TempDir()) / ("kugel_client_test_" + name);
}

/// The examples CMake found (client/examples/*.json), by file name.
std::vector<std::string> example_names()
{
    std::vector<std::string> names;
    std::stringstream list(KUGEL_CLIENT_EXAMPLES);
    for (std::string name; std::getline(list, name, ',');)
        if (!name.empty())
            names.push_back(name);
    return names;
}

/// A script's "server" arguments with each --room's scene made absolute (it is written
/// relative to the script), and the first room's name.
std::pair<std::vector<std::string>, std::string> server_arguments(fs::path const& script_file)
{
    script const s = load_script(script_file);
    std::vector<std::string> args = s.server;
    std::string first_room;
    for (std::size_t i = 0; i + 1 < args.size(); ++i) {
        if (args[i] != "--room")
            continue;
        std::string& spec = args[i + 1];
        auto const equals = spec.find('=');
        std::string const room = spec.substr(0, equals);
        spec = room + "=" + (script_file.parent_path() / spec.substr(equals + 1)).string();
        if (first_room.empty())
            first_room = room;
    }
    return {args, first_room.empty() ? "default" : first_room};
}

struct finished
{
    int status = -2; ///< exit status; -1: ended by a signal; -2: still running (killed)
    std::string output;
};

/// Runs kugel-client with `args` to the end (at most two minutes).
finished run_client(std::vector<std::string> args, std::string const& name)
{
    child_process p(KUGEL_CLIENT_EXE, std::move(args), temp_file(name + ".out"));
    auto const status = p.wait(120s);
    return {status.value_or(-2), p.output()};
}

class ExampleScript : public testing::TestWithParam<std::string>
{
};

TEST_P(ExampleScript, PassesAgainstTheServerItNames)
{
    fs::path const file = examples_dir / GetParam();
    auto const [server_args, room] = server_arguments(file);
    std::string const stem = file.stem().string();
    server_child server(KUGEL_SERVER_EXE, server_args, temp_file(stem + ".server.log"));
    finished const run = run_client({"run", file.string(), "--url", server.url(room)}, stem);
    EXPECT_EQ(run.status, 0) << run.output;
    EXPECT_NE(run.output.find("passed: "), std::string::npos) << run.output;
    EXPECT_EQ(server.stop(), 0) << server.log();
}

/// "two_clients" for two_clients.json.
std::string test_name(testing::TestParamInfo<std::string> const& example)
{
    return fs::path(example.param).stem().string();
}

INSTANTIATE_TEST_SUITE_P(Examples, ExampleScript, testing::ValuesIn(example_names()), test_name);

TEST(KugelClient, EveryExampleIsTested)
{
    std::set<std::string> on_disk;
    for (auto const& entry : fs::directory_iterator(examples_dir))
        if (entry.path().extension() == ".json")
            on_disk.insert(entry.path().filename().string());
    auto const names = example_names();
    EXPECT_EQ(on_disk, std::set<std::string>(names.begin(), names.end()))
        << "client/examples changed: re-run cmake so that the tests pick it up";
    EXPECT_GE(on_disk.size(), 4U);
}

TEST(KugelClient, AWrongExpectationFailsNamingItsStep)
{
    fs::path const file =
        fs::path(KUGEL_SOURCE_DIR) / "tests" / "client" / "scripts" / "wrong_velocity.json";
    auto const [server_args, room] = server_arguments(file);
    server_child server(KUGEL_SERVER_EXE, server_args, temp_file("wrong.server.log"));
    finished const run = run_client({"run", file.string(), "--url", server.url(room)}, "wrong");
    EXPECT_EQ(run.status, 1) << run.output;
    // The step by number and name, what it expected, and what arrived.
    EXPECT_NE(run.output.find("FAIL step 6 \"the velocity is J/m (this script says 2 J/m)\""),
              std::string::npos)
        << run.output;
    EXPECT_NE(run.output.find("expected: body 1, velocity [3.0, -1.0, 0.5] ± 0.0"),
              std::string::npos)
        << run.output;
    EXPECT_NE(run.output.find("arrived:  body 1 at tick"), std::string::npos) << run.output;
    EXPECT_NE(run.output.find("velocity [1.5, -0.5, 0.25]"), std::string::npos) << run.output;
    EXPECT_EQ(run.output.find("step 7"), std::string::npos) << "ran past the failure:\n"
                                                            << run.output;
}

TEST(KugelClient, AnUnreadableScriptExitsTwoNamingTheField)
{
    fs::path const file = temp_file("typo.json");
    std::ofstream(file)
        << R"({"steps": [{"send": {"type": "ping"}}, {"expect": {"tpye": "pong"}}]})";
    finished const run = run_client({"run", file.string(), "--url", "ws://127.0.0.1:1/ws"}, "typo");
    EXPECT_EQ(run.status, 2) << run.output;
    EXPECT_NE(run.output.find("step 2 (expect): /expect: unknown field \"tpye\""),
              std::string::npos)
        << run.output;
}

TEST(KugelClient, AShortLoadCompletesWithSnapshotsForEveryClient)
{
    server_child server(KUGEL_SERVER_EXE,
                        {"--room", "still=" + (examples_dir / "scenes" / "still.json").string()},
                        temp_file("load.server.log"));
    finished const run = run_client({"load", "--url", server.url("still"), "--clients", "4",
                                     "--duration", "3", "--commands-per-second", "10", "--json"},
                                    "load");
    ASSERT_EQ(run.status, 0) << run.output;
    nlohmann::json const report = nlohmann::json::parse(run.output);
    EXPECT_TRUE(report["ok"].get<bool>());
    EXPECT_FALSE(report["stopped_early"].get<bool>());
    ASSERT_EQ(report["per_client"].size(), 4U);
    for (auto const& client : report["per_client"]) {
        EXPECT_TRUE(client["connected"].get<bool>()) << client.dump();
        EXPECT_GT(client["snapshots_per_second"].get<double>(), 0.0) << client.dump();
        EXPECT_GT(client["acks"].get<std::uint64_t>(), 0U) << client.dump();
        EXPECT_TRUE(client["disconnected"].is_null()) << client.dump();
    }
    EXPECT_EQ(server.stop(), 0) << server.log();
}

TEST(KugelClient, WatchPrintsALinePerSnapshot)
{
    server_child server(KUGEL_SERVER_EXE,
                        {"--room", "still=" + (examples_dir / "scenes" / "still.json").string()},
                        temp_file("watch.server.log"));
    finished const lines = run_client({"watch", server.url("still"), "--count", "3"}, "watch");
    EXPECT_EQ(lines.status, 0) << lines.output;
    EXPECT_EQ(std::count(lines.output.begin(), lines.output.end(), '\n'), 4) // and the room line
        << lines.output;
    EXPECT_NE(lines.output.find("bodies 0"), std::string::npos) << lines.output;

    finished const json =
        run_client({"watch", server.url("still"), "--count", "1", "--json"}, "watch_json");
    EXPECT_EQ(json.status, 0) << json.output;
    EXPECT_NE(json.output.find(R"({"type":"snapshot","tick":)"), std::string::npos) << json.output;
}

// With --events, watch prints each event too, before the snapshot of its tick: a ball at
// 2 m/s from x = −9 brings its centre into a sensor whose box starts at x = 1.2 at 5.1 s,
// long after the watch has joined (even a server slowed by the sanitizers starts and
// answers within a second or two).
TEST(KugelClient, WatchPrintsEventsWhenAsked)
{
    fs::path const scene = temp_file("watch_events.json");
    std::ofstream(scene) << R"({"name": "line", "dt": 0.015625, "integrator": "semi_implicit_euler",
        "collisions": {"mode": "off"}, "box": {"min": [-10, -5, -1], "max": [10, 5, 1]},
        "bodies": [{"position": [-9, 0, 0], "velocity": [2, 0, 0], "radius": 0.2, "mass": 1, "tag": "ball"}],
        "sensors": [{"name": "line", "box": {"min": [1.2, -5, -1], "max": [2, 5, 1]}}]})";
    server_child server(KUGEL_SERVER_EXE, {"--room", "line=" + scene.string()},
                        temp_file("watch_events.server.log"));
    finished const lines = run_client({"watch", server.url("line"), "--count", "210", "--events"}, "watch_events");
    EXPECT_EQ(lines.status, 0) << lines.output;
    auto const event = lines.output.find("\nevent tick ");
    ASSERT_NE(event, std::string::npos) << lines.output;
    std::istringstream line(lines.output.substr(event + 1, lines.output.find('\n', event + 1) - event - 1));
    std::string word, kind, sensor, body, id, tag;
    std::uint64_t tick = 0;
    double time = 0.0;
    line >> word >> word >> tick >> word >> time >> word >> kind >> sensor >> body >> id >> tag;
    EXPECT_NEAR(time, 5.1, 1e-5) << line.str(); // printed to 6 digits
    EXPECT_EQ(kind, "entered");
    EXPECT_EQ(sensor, "line");
    EXPECT_EQ(tag, "(ball)");
    // The snapshot of its tick (or the first after, as the room sends every other) comes after it.
    auto const snapshot_after = [&](std::uint64_t from) {
        for (std::uint64_t t = from; t < from + 4; ++t)
            if (auto const at = lines.output.find("\ntick " + std::to_string(t) + "  time"); at != std::string::npos)
                return at;
        return std::string::npos;
    };
    auto const its_snapshot = snapshot_after(tick);
    ASSERT_NE(its_snapshot, std::string::npos) << lines.output;
    EXPECT_LT(event, its_snapshot) << lines.output;

    finished const json =
        run_client({"watch", server.url("line"), "--count", "1", "--json", "--events"}, "watch_events_json");
    EXPECT_EQ(json.status, 0) << json.output;
    EXPECT_NE(json.output.find(R"({"type":"snapshot")"), std::string::npos) << json.output;
}

TEST(KugelClient, EveryCommandHasHelp)
{
    for (std::string const command : {"watch", "run", "load"}) {
        finished const help = run_client({command, "--help"}, "help_" + command);
        EXPECT_EQ(help.status, 0) << help.output;
        EXPECT_NE(help.output.find("Usage"), std::string::npos) << help.output;
    }
    finished const none = run_client({}, "help_none");
    EXPECT_EQ(none.status, 2);
    EXPECT_NE(none.output.find("watch, run or load"), std::string::npos) << none.output;
}

// The same exit codes as kugel-server's (client/README.md): 0 for --version, 2 for every
// mistake in the command line, named.
TEST(KugelClient, VersionExitsZeroAndEveryBadCommandLineExitsTwoNamingIt)
{
    finished const version = run_client({"--version"}, "version");
    EXPECT_EQ(version.status, 0);
    EXPECT_EQ(version.output.rfind("kugel-client ", 0), 0U) << version.output;
    EXPECT_NE(version.output.find("(protocol 1)"), std::string::npos) << version.output;
    struct bad
    {
        std::vector<std::string> arguments;
        std::string named;
    };
    std::vector<bad> const cases{
        {{"--bogus"}, "--bogus"},
        {{"watch", "--bogus", "ws://127.0.0.1:1/ws"}, "--bogus"},
        {{"run", "/nonexistent/script.json", "--url", "ws://127.0.0.1:1/ws"}, "/nonexistent/script.json"},
        {{"load", "--clients", "-3", "--url", "ws://127.0.0.1:1/ws"}, "--clients"},
    };
    int k = 0;
    for (bad const& c : cases) {
        finished const r = run_client(c.arguments, "bad_" + std::to_string(k++));
        EXPECT_EQ(r.status, 2) << c.arguments.front() << "\n" << r.output;
        EXPECT_NE(r.output.find(c.named), std::string::npos) << r.output;
    }
}

} // namespace
} // namespace kugel::client
