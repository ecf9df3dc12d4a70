#include "headless.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <array>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <set>
#include <string>
#include <vector>

namespace kugel::server {
namespace {

std::filesystem::path const source_dir = KUGEL_SOURCE_DIR;

struct process_result
{
    int exit_code;
    std::string out;
};

/// Runs kugel-server with arguments, capturing stdout (stderr, the log, is discarded unless
/// asked for: then it comes after stdout's lines, mixed in).
process_result run_server(std::string const& arguments, bool with_stderr = false)
{
    std::string const command =
        std::string(KUGEL_SERVER_EXE) + " " + arguments + (with_stderr ? " 2>&1" : " 2>/dev/null");
    std::unique_ptr<FILE, int (*)(FILE*)> pipe(popen(command.c_str(), "r"), pclose);
    std::string out;
    std::array<char, 4096> buffer{};
    while (auto n = std::fread(buffer.data(), 1, buffer.size(), pipe.get()))
        out.append(buffer.data(), n);
    int const status = pclose(pipe.release());
    return {WEXITSTATUS(status), out};
}

std::string scene(char const* name) { return (source_dir / "scenes" / name).string(); }

TEST(HeadlessCommand, KeplerPrintsOneJsonSummary)
{
    auto const r = run_server("--scene " + scene("kepler.json") + " --headless --steps 10000");
    ASSERT_EQ(r.exit_code, 0) << r.out;
    // exactly one JSON object, one line
    EXPECT_EQ(r.out.find('\n'), r.out.size() - 1);
    auto const summary = nlohmann::json::parse(r.out);
    for (char const* key : {"scene", "bodies", "steps", "dt", "integrator", "wall_ms_per_step",
                            "energy_initial", "energy_final", "energy_rel_drift",
                            "momentum_initial", "momentum_final"})
        EXPECT_TRUE(summary.contains(key)) << key;
    EXPECT_EQ(summary["scene"], "kepler");
    EXPECT_EQ(summary["bodies"], 2);
    EXPECT_EQ(summary["steps"], 10000);
    EXPECT_EQ(summary["integrator"], "velocity_verlet");
    // Two-body orbit, E = −G·m₁m₂/(2a) = −0.05; Verlet at ~6,000 steps per orbit keeps
    // energy to ~1e-6 relative (its error is O(h²) and bounded).
    EXPECT_NEAR(summary["energy_initial"].get<double>(), -0.05, 1e-12);
    EXPECT_LT(std::abs(summary["energy_rel_drift"].get<double>()), 1e-5);
    EXPECT_NEAR(summary["time"].get<double>(), 10.0, 1e-9);
}

TEST(HeadlessCommand, SetOverridesTakeEffect)
{
    auto const r = run_server("--scene " + scene("kepler.json") +
                              " --headless --steps 100 --set integrator=rk4 --set dt=0.002");
    ASSERT_EQ(r.exit_code, 0);
    auto const summary = nlohmann::json::parse(r.out);
    EXPECT_EQ(summary["integrator"], "rk4");
    EXPECT_EQ(summary["dt"], 0.002);
    EXPECT_EQ(summary["force_evaluations"], 400);
    EXPECT_NEAR(summary["time"].get<double>(), 0.2, 1e-12);
}

// The gas scene, at 1,000 spheres for test time: the summary counts collisions, nothing
// escapes, and energy is kept to rounding (continuous mode, e = 1, no forces).
TEST(HeadlessCommand, GasSummaryReportsCollisionsAndNothingEscapes)
{
    auto const r = run_server("--scene " + scene("gas.json") +
                              " --headless --steps 600 --set generators.0.count=1000");
    ASSERT_EQ(r.exit_code, 0);
    auto const summary = nlohmann::json::parse(r.out);
    EXPECT_EQ(summary["bodies"], 1000);
    EXPECT_EQ(summary["collision_mode"], "continuous");
    EXPECT_EQ(summary["escaped"], 0);
    EXPECT_EQ(summary["events_capped"], 0);
    EXPECT_GT(summary["sphere_collisions"].get<int>(), 100);
    // Every contact was an event; so were the cells crossed. On one thread the calendar takes
    // its events in one lane: no rounds, nothing undone.
    EXPECT_GT(summary["events"].get<std::uint64_t>(),
              summary["sphere_collisions"].get<std::uint64_t>() + summary["wall_collisions"].get<std::uint64_t>());
    EXPECT_EQ(summary["event_rounds"], 0);
    EXPECT_EQ(summary["events_undone"], 0);
    EXPECT_LE(summary["max_overlap"].get<double>(), 1e-9);
    EXPECT_LT(std::abs(summary["energy_rel_drift"].get<double>()), 1e-9);
    EXPECT_GT(summary["bounds"]["radius"].get<double>(), 0.0);
}

TEST(HeadlessCommand, PhaseTimesNameOnlyThePhasesTheSceneUses)
{
    auto const phases = [&](std::string const& file, std::string const& more) {
        auto const r = run_server("--scene " + scene(file.c_str()) + " --headless --steps 30" + more);
        EXPECT_EQ(r.exit_code, 0) << r.out;
        std::set<std::string> names;
        nlohmann::json const summary = nlohmann::json::parse(r.out);
        for (auto const& [name, ms] : summary.at("phase_ms_per_step").items()) {
            EXPECT_GT(ms.get<double>(), 0.0) << file << " " << name;
            names.insert(name);
        }
        return names;
    };
    using names = std::set<std::string>;
    EXPECT_EQ(phases("kepler.json", ""), names{"free_motion"}); // no collisions
    EXPECT_EQ(phases("pile.json", ""), (names{"free_motion", "walls", "cells", "velocity_passes",
                                              "position_passes", "write_back"}));
    // A gas without forces in discrete mode drifts in its wall pass: no free-motion phase.
    EXPECT_EQ(phases("gas.json", " --set collisions.mode=discrete --set generators.0.count=1000"),
              (names{"walls", "cells", "velocity_passes", "position_passes", "write_back"}));
    // In continuous mode its paths are the drift: no free-motion phase either.
    EXPECT_EQ(phases("gas.json", " --set generators.0.count=1000"), names{"continuous"});
    EXPECT_TRUE(phases("obstacles.json", " --set collisions.mode=discrete").contains("obstacles"));
}

// One table of exit codes (README, "Exit codes"): 0 for --help and --version, 2 for every
// mistake in the command line, whatever the argument parser would have said, and the message
// names what was wrong.
TEST(ServerCommand, HelpAndVersionExitZeroAndEveryBadCommandLineExitsTwoNamingIt)
{
    auto const version = run_server("--version");
    EXPECT_EQ(version.exit_code, 0);
    EXPECT_EQ(version.out.rfind("kugel-server ", 0), 0U) << version.out;
    EXPECT_NE(version.out.find("(protocol 1)"), std::string::npos) << version.out;
    EXPECT_EQ(run_server("--help").exit_code, 0);
    struct bad
    {
        std::string arguments;
        std::string named; ///< what the message must name
    };
    std::vector<bad> const cases{
        {"--bogus", "--bogus"},
        {"--port 99999", "--port"},
        {"--port seven", "--port"},
        {"--headless --scene " + scene("kepler.json") + " --steps -5", "--steps"},
        {"--headless --scene /nonexistent/scene.json", "/nonexistent/scene.json"},
        {"--room x=/nonexistent/scene.json", "/nonexistent/scene.json"},
        {"--scene " + scene("kepler.json"), "--headless"},
    };
    for (bad const& c : cases) {
        auto const r = run_server(c.arguments, true);
        EXPECT_EQ(r.exit_code, 2) << c.arguments << "\n" << r.out;
        EXPECT_NE(r.out.find(c.named), std::string::npos) << c.arguments << "\n" << r.out;
    }
}

/// The message of the log's first error line ("[time] [kugel] [error] MESSAGE"), or "".
std::string error_message(std::string const& log)
{
    std::string const tag = "[error] ";
    auto const at = log.find(tag);
    if (at == std::string::npos)
        return "";
    auto const end = log.find('\n', at);
    return log.substr(at + tag.size(), end == std::string::npos ? end : end - at - tag.size());
}

// A served room's bad override (--set ROOM:PATH=VALUE) stops the start with exit 2 before
// anything is served, and its message names the room, the field and what is wrong: for an
// override the scene refuses, the headless --set's own message after the room's name.
TEST(ServerCommand, ABadRoomOverrideExitsTwoNamingTheRoomTheFieldAndWhy)
{
    std::string const pile = scene("pile.json");
    struct bad
    {
        std::string set;
        std::vector<std::string> named; ///< what the message must name
    };
    std::vector<bad> const command_line{
        {"lobby:dt=0.01", {"--set lobby:dt=0.01: ", "no room 'lobby' is served (rooms: pile)"}},
        {"dt=0.01", {"--set dt=0.01: ", "ROOM:PATH=VALUE", "--set pile:dt=0.01", "--headless"}},
    };
    for (bad const& c : command_line) {
        auto const r = run_server("--port 0 --room pile=" + pile + " --set " + c.set, true);
        EXPECT_EQ(r.exit_code, 2) << c.set << "\n" << r.out;
        EXPECT_EQ(r.out.find("serving on"), std::string::npos) << r.out;
        for (std::string const& part : c.named)
            EXPECT_NE(error_message(r.out).find(part), std::string::npos) << c.set << "\n" << r.out;
    }
    auto const no_rooms = run_server("--port 0 --set lobby:dt=0.01", true);
    EXPECT_EQ(no_rooms.exit_code, 2);
    EXPECT_NE(error_message(no_rooms.out).find("(rooms: default)"), std::string::npos)
        << no_rooms.out;

    // Refused by the scene: a bad path, a field that does not exist, a bad value.
    std::vector<bad> const scene_refuses{
        {"generators.1.count=10", {"--set generators.1.count=10: index 1 is out of range"}},
        {"collisions.restitutio=0.2", {"/collisions/restitutio: unknown field"}},
        {"collisions.restitution=2", {"(with --set overrides): /collisions/restitution: "}},
        {"integrator=rk5", {"/integrator: unknown integrator 'rk5'"}},
    };
    for (bad const& c : scene_refuses) {
        auto const headless = run_server("--headless --scene " + pile + " --set " + c.set, true);
        ASSERT_EQ(headless.exit_code, 2) << headless.out;
        std::string const expected = error_message(headless.out);
        ASSERT_NE(expected, "") << headless.out;
        for (std::string const& part : c.named)
            EXPECT_NE(expected.find(part), std::string::npos) << expected;

        auto const served =
            run_server("--port 0 --room lobby=" + pile + " --room pile=" + pile + " --set pile:" + c.set, true);
        EXPECT_EQ(served.exit_code, 2) << served.out;
        EXPECT_EQ(served.out.find("serving on"), std::string::npos) << served.out;
        EXPECT_EQ(error_message(served.out), "room 'pile': " + expected) << served.out;
    }

    // The built-in room by its name, its scene named as the headless run cannot.
    auto const arena = run_server("--port 0 --set default:dt=-1", true);
    EXPECT_EQ(arena.exit_code, 2);
    EXPECT_EQ(error_message(arena.out),
              "room 'default': built-in arena scene (with --set overrides): /dt: must be > 0, got -1")
        << arena.out;
}

TEST(HeadlessCommand, BadSceneExitsNonZeroWithNoSummary)
{
    auto const r = run_server("--scene " + scene("kepler.json") + " --headless --set integrator=rk5");
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_TRUE(r.out.empty());
}

TEST(HeadlessRun, ProjectileWithTheExactIntegratorIsExact)
{
    auto s = scene::load_scene(scene("projectile.json"));
    auto const summary = run_headless(s, 120);
    EXPECT_TRUE(summary["integrator_exact"].get<bool>());
    // Energy is exactly conserved by the parabola; rounding over 120 steps stays ~1e-14.
    EXPECT_LT(std::abs(summary["energy_rel_drift"].get<double>()), 1e-12);
}

TEST(HeadlessRun, SingularForceStopsTheRunAndIsReported)
{
    // G = 1e-300 leaves the straight-line motion exactly unchanged (the velocity change is far
    // below one ulp), and ±0.5 m at ∓1 m/s with dt = 1/8 s are exact in binary: after four
    // steps both bodies sit at exactly 0, and the fifth step's force would divide by zero.
    auto const s = scene::parse_scene(
        R"({"name": "crash", "dt": 0.125, "integrator": "explicit_euler",
            "forces": {"gravity": {"G": 1e-300}},
            "bodies": [{"position": [-0.5,0,0], "velocity": [1,0,0], "mass": 1},
                       {"position": [0.5,0,0], "velocity": [-1,0,0], "mass": 1}]})",
        "crash.json");
    auto const summary = run_headless(s, 10);
    ASSERT_TRUE(summary.contains("error")) << summary.dump();
    EXPECT_NE(summary["error"].get<std::string>().find("softening"), std::string::npos);
    EXPECT_EQ(summary["steps_completed"], 4);
    EXPECT_EQ(summary["time"], 0.5);
}

// The gas scene with discrete collisions, at the same density with 20,000 spheres: enough
// for the world to use a lent pool (physics::world::bodies_worth_sharing), in five chunks
// of bodies, so a pool of three threads really splits the work. Threads change only how long a step takes:
// every figure of the summary but the wall times is the same, bit for bit (exact equality
// of doubles is the right tolerance; the engine promises it, DiscreteThreads.*).
TEST(HeadlessRun, PhysicsThreadsChangeNothingButTheTime)
{
    // The box of gas.json, 1.871 m a half-side for 10,000, times the cube root of 2.
    std::vector<std::string> const discrete{
        "collisions.mode=discrete", "generators.0.count=20000",
        R"(box={"min": [-2.358, -2.358, -2.358], "max": [2.358, 2.358, 2.358]})",
        R"(generators.0.region={"min": [-2.358, -2.358, -2.358], "max": [2.358, 2.358, 2.358]})"};
    auto const s = scene::load_scene(scene("gas.json"), discrete);
    auto one = run_headless(s, 20, 1);
    auto three = run_headless(s, 20, 3);
    EXPECT_EQ(one["physics_threads"], 1);
    EXPECT_EQ(three["physics_threads"], 3);
    EXPECT_EQ(one["bodies"], 20000);
    EXPECT_GT(one["sphere_collisions"].get<std::uint64_t>(), 0u);
    for (char const* key : {"wall_ms", "wall_ms_per_step", "phase_ms_per_step", "physics_threads"}) {
        one.erase(key);
        three.erase(key);
    }
    EXPECT_EQ(one, three) << one.dump() << "\n" << three.dump();
}

TEST(HeadlessCommand, PhysicsThreadsOutOfRangeIsRefused)
{
    auto const r = run_server("--scene " + scene("kepler.json") + " --headless --physics-threads 0");
    EXPECT_NE(r.exit_code, 0);
    EXPECT_TRUE(r.out.empty());
}

// The galaxy scene, shrunk to 1,000 bodies: the tree method is reported, and over 50 steps
// (half a crossing time) velocity Verlet with tree forces keeps energy to about 1e-4 of its
// scale (a full 10,000-body run of 100 steps measured 3.8e-5; see bench/README.md).
TEST(HeadlessRun, GalaxyRunsWithTheTreeAndKeepsEnergy)
{
    std::vector<std::string> const smaller{"generators.0.count=1000", "generators.0.mass=0.001"};
    auto const s = scene::load_scene(scene("galaxy.json"), smaller);
    auto const summary = run_headless(s, 50);
    EXPECT_EQ(summary["force_methods"]["gravity"]["method"], "tree");
    EXPECT_EQ(summary["force_methods"]["gravity"]["theta"], 0.5);
    EXPECT_EQ(summary["bodies"], 1000);
    EXPECT_LT(std::abs(summary["energy_rel_drift"].get<double>()), 1e-3) << summary.dump();
}

// Coulomb through the tree with charges of both signs: the summary says the bound holds per
// sign only; with one sign (or the direct sum) it says nothing of the kind.
TEST(HeadlessRun, TreeCoulombWithMixedChargesSaysTheBoundIsPerSign)
{
    auto const mixed = scene::parse_scene(
        R"({"dt": 0.001, "forces": {"coulomb": {"k": 1, "softening": 0.1, "method": "tree"}},
            "bodies": [{"position": [0,0,0], "mass": 1, "charge": 1},
                       {"position": [1,0,0], "mass": 1, "charge": -1}]})",
        "mixed.json");
    auto const summary = run_headless(mixed, 1);
    EXPECT_EQ(summary["force_methods"]["coulomb"]["method"], "tree");
    EXPECT_NE(summary["force_methods"]["coulomb"]["error_bound"].get<std::string>().find("per sign"),
              std::string::npos);
    auto const one_sign = scene::parse_scene(
        R"({"dt": 0.001, "forces": {"coulomb": {"k": 1, "softening": 0.1, "method": "tree"}},
            "bodies": [{"position": [0,0,0], "mass": 1, "charge": 1},
                       {"position": [1,0,0], "mass": 1, "charge": 2}]})",
        "one_sign.json");
    EXPECT_FALSE(run_headless(one_sign, 1)["force_methods"]["coulomb"].contains("error_bound"));
    auto const direct = scene::parse_scene(R"({"dt": 0.001, "forces": {"coulomb": {}}})", "d.json");
    EXPECT_EQ(run_headless(direct, 1)["force_methods"]["coulomb"]["method"], "direct");
}

// A state whose diagnostics cannot be finite is refused before it runs: 1e308 kg at 2 m/s has
// a kinetic energy of 2e308 J, beyond the largest double (issue #29: it ran, printed null
// energies and exited 0).
TEST(HeadlessCommand, AStateWithoutFiniteEnergyIsRefusedNamingWhy)
{
    auto const r = run_server("--scene " + scene("projectile.json") +
                                  " --headless --steps 10 --set bodies.0.mass=1e308 --set bodies.0.velocity=[2,0,0]",
                              true);
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.out.find("projectile.json: the scene's initial state has no finite energy"), std::string::npos)
        << r.out;
    EXPECT_NE(r.out.find("kinetic infinite J"), std::string::npos) << r.out;
}

// A run that overflows stops at the step that did it (dt = 1e200: the first step of the
// projectile leaves v·dt + g·dt²/2 beyond the largest double), and the process says so in
// its exit status; what the summary says is in the extremes suite (SceneGuards).
TEST(HeadlessCommand, ARunThatLeavesTheDoublesExitsOne)
{
    auto const r = run_server("--scene " + scene("projectile.json") + " --headless --steps 10 --set dt=1e200");
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_NE(r.out.find("step 1 left body "), std::string::npos) << r.out;
}

TEST(HeadlessCommand, SingularSceneExitsNonZero)
{
    auto const r = run_server("--scene " + scene("kepler.json") +
                              " --headless --set bodies.1.position=[-0.045454545454545456,0,0]");
    EXPECT_EQ(r.exit_code, 1);
}

} // namespace
} // namespace kugel::server
