// Persistence (--state DIR): a room's checkpoint restores the same world, ids and tick; an
// unusable checkpoint stops the start and is left untouched unless the user discards it; a
// kugel-server killed with SIGKILL comes back with its last checkpoint. No wall-clock time
// is asserted: waits have generous timeouts and only bound failures.

#include "checkpoint.hpp"
#include "room.hpp"
#include "server.hpp"

#include "support/child_process.hpp"
#include "support/in_process_server.hpp"
#include "support/state_hash.hpp"
#include "support/scene_files.hpp"
#include "support/ws_client.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <functional>
#include <fstream>
#include <set>
#include <sstream>
#include <thread>

namespace kugel::server {
namespace {

using nlohmann::json;
using test_support::index_of;
using test_support::ws_client;
namespace fs = std::filesystem;

/// An empty directory of its own for one test.
fs::path fresh_dir(std::string const& name)
{
    fs::path const dir = fs::path(testing::TempDir()) / ("kugel_persistence_test_" + name);
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir;
}

std::string read_text(fs::path const& file)
{
    std::ifstream in(file, std::ios::binary);
    std::stringstream text;
    text << in.rdbuf();
    return text.str();
}

void write_text(fs::path const& file, std::string const& text)
{
    std::ofstream(file, std::ios::binary) << text;
}

using test_support::still_scene;
using test_support::drop_scene;

fs::path write_scene(fs::path const& dir, std::string const& name, json const& scene)
{
    return test_support::write_scene(dir / (name + ".scene.json"), scene);
}

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

/// Every field equal, every double bit for bit.
void expect_identical(checkpoint const& a, checkpoint const& b)
{
    EXPECT_EQ(a.room, b.room);
    EXPECT_EQ(a.scene_name, b.scene_name);
    EXPECT_EQ(a.scene_fingerprint, b.scene_fingerprint);
    EXPECT_EQ(a.tick, b.tick);
    EXPECT_TRUE(same_bits(a.time, b.time));
    EXPECT_TRUE(same_bits(a.time_compensation, b.time_compensation));
    EXPECT_EQ(a.steps, b.steps);
    EXPECT_EQ(a.next_wire_id, b.next_wire_id);
    ASSERT_EQ(a.bodies.size(), b.bodies.size());
    for (std::size_t i = 0; i < a.bodies.size(); ++i) {
        physics::body_desc const& x = a.bodies[i].desc;
        physics::body_desc const& y = b.bodies[i].desc;
        EXPECT_EQ(a.bodies[i].wire_id, b.bodies[i].wire_id) << "slot " << i;
        for (int k = 0; k < 3; ++k) {
            EXPECT_TRUE(same_bits(x.position[k], y.position[k])) << "slot " << i;
            EXPECT_TRUE(same_bits(x.velocity[k], y.velocity[k])) << "slot " << i;
        }
        EXPECT_TRUE(same_bits(x.mass, y.mass)) << "slot " << i;
        EXPECT_TRUE(same_bits(x.radius, y.radius)) << "slot " << i;
        EXPECT_TRUE(same_bits(x.charge, y.charge)) << "slot " << i;
        EXPECT_EQ(x.is_static, y.is_static) << "slot " << i;
    }
}

json spawn_at(std::uint64_t ref, std::array<double, 3> position, std::array<double, 3> velocity = {},
              double radius = 0.25)
{
    return {{"type", "spawn"},
            {"ref", ref},
            {"body", {{"position", position}, {"velocity", velocity}, {"radius", radius}, {"mass", 1.0}}}};
}

/// A point mass overlaps nothing, so its spawn is taken wherever the arena's spheres have
/// moved by the tick it is applied in (which depends on how busy the machine is).
constexpr double point_mass = 0.0;

json remove(std::uint64_t ref, std::uint64_t id) { return {{"type", "remove"}, {"ref", ref}, {"id", id}}; }

/// The acked id of a spawn (or 0 for another ack).
std::uint64_t ack_of(ws_client& c, std::uint64_t ref)
{
    for (;;) {
        json const m = c.read_json();
        if (m.at("type") == "error")
            throw std::runtime_error(m.dump());
        if (m.at("type") == "ack" && m.at("ref") == ref)
            return m.contains("id") ? m.at("id").get<std::uint64_t>() : 0;
    }
}

json snapshot_at_or_after(ws_client& c, std::uint64_t tick)
{
    for (;;) {
        json s = c.next("snapshot");
        if (s.at("tick").get<std::uint64_t>() >= tick)
            return s;
    }
}

/// Runs the default room (the arena) with a spawn and a remove so that ids have a gap,
/// stops it, and returns its final checkpoint's file.
fs::path arena_checkpoint(fs::path const& dir, std::uint64_t& spawned, std::uint64_t& removed)
{
    server_options o;
    o.state_dir = dir;
    o.checkpoint_interval = std::chrono::hours(1); // only the final one
    o.admin_token = "persistence-test-admin-token";
    test_support::in_process_server s(o);
    ws_client c(s.port(), "/ws");
    c.next("welcome");
    // Body 7 came with the scene: only an admin may remove it.
    c.send(json{{"type", "hello"}, {"admin_token", o.admin_token}});
    c.next("welcome");
    c.send(spawn_at(1, {0.1 + 0.2, 1.0 / 3.0, 3.5}, {0.7, -1e-300, 3.0}, point_mass));
    spawned = ack_of(c, 1);
    removed = 7;
    c.send(remove(2, removed));
    ack_of(c, 2);
    snapshot_at_or_after(c, 30);
    s.stop();
    return checkpoint_path(dir, "default");
}

scene::scene arena() { return scene::parse_scene(default_scene_text(), "arena"); }

TEST(Persistence, CheckpointRestoresBitIdenticalStateIdsAndTick)
{
    fs::path const dir = fresh_dir("identical");
    std::uint64_t spawned = 0, removed = 0;
    fs::path const file = arena_checkpoint(dir, spawned, removed);
    std::string const text = read_text(file);
    checkpoint const saved = decode_checkpoint(text, file.string());
    EXPECT_GE(saved.tick, 30u);
    EXPECT_EQ(saved.steps, saved.tick);
    EXPECT_EQ(saved.scene_fingerprint, scene_fingerprint(default_scene_text()));

    // A room made from it (never started, so nothing else touches it) holds the same state.
    net::io_context io;
    room restored(io, io.get_executor(), "default", arena(), {}, saved.scene_fingerprint,
                  saved.scene_overrides, saved);
    checkpoint const again = restored.take_checkpoint();
    expect_identical(saved, again);
    EXPECT_EQ(encode_checkpoint(again), text); // byte for byte

    std::set<std::uint64_t> ids;
    for (checkpoint::body const& b : saved.bodies)
        ids.insert(b.wire_id);
    EXPECT_TRUE(ids.contains(spawned));
    EXPECT_FALSE(ids.contains(removed));
    EXPECT_EQ(saved.next_wire_id, spawned + 1);
}

TEST(Persistence, RestoredWorldStepsOnExactlyLikeTheOriginal)
{
    scene::scene const s = arena();
    physics::world original = scene::build_world(s);
    for (int i = 0; i < 40; ++i)
        original.step(s.dt);
    checkpoint c;
    c.time = original.time();
    c.time_compensation = original.time_compensation();
    c.steps = original.steps();
    for (std::size_t slot = 0; slot < original.bodies().size(); ++slot)
        c.bodies.push_back({slot + 1, original.bodies().describe(slot)});
    c.next_wire_id = c.bodies.size() + 1;
    physics::world restored =
        restored_world(s, decode_checkpoint(encode_checkpoint(c), "memory"), "memory");
    ASSERT_EQ(test_support::state_hash(restored), test_support::state_hash(original));
    for (int i = 0; i < 40; ++i) {
        original.step(s.dt);
        restored.step(s.dt);
    }
    EXPECT_EQ(test_support::state_hash(restored), test_support::state_hash(original));
    EXPECT_TRUE(same_bits(restored.time(), original.time()));
}

TEST(Persistence, TheIdCounterContinuesAfterARestart)
{
    fs::path const dir = fresh_dir("counter");
    std::uint64_t spawned = 0, removed = 0;
    checkpoint const saved = decode_checkpoint(read_text(arena_checkpoint(dir, spawned, removed)), "");

    server_options o;
    o.state_dir = dir;
    test_support::in_process_server s(o);
    ws_client c(s.port(), "/ws");
    c.next("welcome");
    json const first = c.next("snapshot");
    EXPECT_GT(first.at("tick").get<std::uint64_t>(), saved.tick);
    EXPECT_GE(index_of(first, spawned), 0);
    EXPECT_LT(index_of(first, removed), 0);
    c.send(spawn_at(1, {-3.0, 3.0, 1.0}, {}, point_mass));
    std::uint64_t const fresh = ack_of(c, 1);
    EXPECT_EQ(fresh, saved.next_wire_id);
    EXPECT_GT(fresh, spawned);
    for (checkpoint::body const& b : saved.bodies)
        EXPECT_NE(b.wire_id, fresh);
}

/// What a server (of `o`'s rooms) says about a bad checkpoint of room "default", and that it
/// left the file as it was.
std::string refusal(fs::path const& dir, std::string const& bad_text, server_options o = {})
{
    fs::path const file = checkpoint_path(dir, "default");
    write_text(file, bad_text);
    o.state_dir = dir;
    o.port = 0;
    std::string message;
    try {
        server s(o);
        ADD_FAILURE() << "the server started with a bad checkpoint";
    } catch (checkpoint_error const& e) {
        message = e.what();
    }
    EXPECT_EQ(read_text(file), bad_text) << "the bad checkpoint was changed";
    EXPECT_NE(message.find(file.string()), std::string::npos) << message;
    return message;
}

TEST(Persistence, ACorruptOrIncompatibleCheckpointIsRefusedAndLeftUntouched)
{
    fs::path const dir = fresh_dir("refused");
    std::uint64_t spawned = 0, removed = 0;
    std::string const good = read_text(arena_checkpoint(dir, spawned, removed));

    EXPECT_NE(refusal(dir, good.substr(0, good.size() / 2)).find("not valid JSON"), std::string::npos);
    EXPECT_NE(refusal(dir, "").find("not valid JSON"), std::string::npos);

    json wrong_version = json::parse(good);
    wrong_version["version"] = checkpoint_format_version + 1;
    EXPECT_NE(refusal(dir, wrong_version.dump()).find("/version"), std::string::npos);

    json other_scene = json::parse(good);
    other_scene["scene"]["fingerprint"] = scene_fingerprint("{\"name\": \"arena\"}");
    EXPECT_NE(refusal(dir, other_scene.dump()).find("another scene, or the scene file changed"),
              std::string::npos);

    json bad_body = json::parse(good);
    bad_body["bodies"]["mass"][0] = -1.0;
    EXPECT_NE(refusal(dir, bad_body.dump()).find("/bodies (body 0"), std::string::npos);

    json bad_tag = json::parse(good);
    bad_tag["bodies"]["tag"] = json::array();
    for (std::size_t i = 0; i < bad_tag["bodies"]["id"].size(); ++i)
        bad_tag["bodies"]["tag"].push_back(i == 3 ? "po\nst" : "");
    EXPECT_NE(refusal(dir, bad_tag.dump()).find("/bodies/tag/3: must be \"\" or a tag of 1 to 32 bytes"),
              std::string::npos);
    bad_tag["bodies"]["tag"].erase(0);
    EXPECT_NE(refusal(dir, bad_tag.dump()).find("/bodies/tag: must be an array of 400 values"), std::string::npos);

    // More bodies than the server lets a room hold (400 in the arena's checkpoint): refused
    // at the start, as a spawn past the limit is refused.
    server_options small;
    small.max_bodies = 100;
    EXPECT_NE(refusal(dir, good, small).find("holds 400 bodies, more than --max-bodies 100"), std::string::npos);

    // A file of another room's scene: a "still" room's checkpoint under the default room.
    fs::path const other = fresh_dir("refused_other");
    server_options o;
    o.state_dir = other;
    o.rooms.push_back({"default", write_scene(other, "still", still_scene())});
    {
        test_support::in_process_server s(o);
    }
    EXPECT_NE(refusal(dir, read_text(checkpoint_path(other, "default"))).find("scene 'still'"),
              std::string::npos);
}

// A restored room's welcome frames the scene as a fresh room's does: in a scene without
// walls two bodies fly apart for a second before the checkpoint, and the restored welcome's
// bounds are still those of the scene (bit for bit), not of where the bodies went.
TEST(Persistence, ARestoredRoomsWelcomeHasTheScenesBounds)
{
    fs::path const dir = fresh_dir("bounds");
    json scene = still_scene();
    scene.erase("box");
    scene["bodies"] = json::array({{{"position", {0, 0, 0}}, {"velocity", {-20, 0, 0}}, {"radius", 0.5}, {"mass", 1}},
                                   {{"position", {2, 0, 0}}, {"velocity", {20, 0, 0}}, {"radius", 0.5}, {"mass", 1}}});
    server_options o;
    o.rooms.push_back({"default", write_scene(dir, "apart", scene)});
    auto const bounds_of = [](json const& welcome) { return welcome.at("scene").at("bounds"); };
    json fresh_bounds;
    {
        test_support::in_process_server s(o);
        ws_client c(s.port(), "/ws");
        fresh_bounds = bounds_of(c.next("welcome"));
    }
    o.state_dir = dir;
    o.checkpoint_interval = std::chrono::hours(1); // only the final one
    {
        test_support::in_process_server s(o);
        ws_client c(s.port(), "/ws");
        c.next("welcome");
        snapshot_at_or_after(c, 64); // a second: the bodies are 40 m further apart
        s.stop();
    }
    test_support::in_process_server s(o);
    ws_client c(s.port(), "/ws");
    json const restored = c.next("welcome");
    EXPECT_EQ(bounds_of(restored), fresh_bounds);
    json const snapshot = c.next("snapshot");
    EXPECT_GT(snapshot.at("tick").get<std::uint64_t>(), 60U) << "the room was restored, not started afresh";
}

TEST(Persistence, DiscardBadStateMovesTheFileAsideAndStartsFresh)
{
    fs::path const dir = fresh_dir("discard");
    fs::path const file = checkpoint_path(dir, "default");
    write_text(file, "{\"format\": \"kugel-checkpoint\", \"vers");
    server_options o;
    o.state_dir = dir;
    o.discard_bad_state = true;
    {
        test_support::in_process_server s(o);
        ws_client c(s.port(), "/ws");
        c.next("welcome");
        EXPECT_LT(c.next("snapshot").at("tick").get<std::uint64_t>(), 1000u); // fresh
    }
    std::vector<fs::path> aside;
    for (auto const& entry : fs::directory_iterator(dir))
        if (entry.path().filename().string().starts_with("default.json.bad-"))
            aside.push_back(entry.path());
    ASSERT_EQ(aside.size(), 1u);
    EXPECT_EQ(read_text(aside[0]), "{\"format\": \"kugel-checkpoint\", \"vers");
    // The fresh room's own final checkpoint took the name.
    EXPECT_NO_THROW(decode_checkpoint(read_text(file), file.string()));
}

constexpr char const* admin_token = "persistence-test-admin-token";

/// Room "default" running the still scene (written to `dir`), checkpointed to `dir`.
server_options still_room(fs::path const& dir)
{
    server_options o;
    o.state_dir = dir;
    o.admin_token = admin_token;
    o.rooms.push_back({"default", write_scene(dir, "still", still_scene())});
    return o;
}

json load_drop_scene(std::uint64_t ref) { return {{"type", "load_scene"}, {"ref", ref}, {"scene", drop_scene()}}; }

std::vector<std::uint64_t> ids_of(json const& snapshot)
{
    return snapshot.at("bodies").at("id").get<std::vector<std::uint64_t>>();
}

/// Runs room "default" on the still scene, has an admin load the drop scene and spawn a body
/// in it, stops the server, and returns its final checkpoint's file.
fs::path loaded_scene_checkpoint(fs::path const& dir, std::uint64_t& spawned)
{
    server_options o = still_room(dir);
    o.checkpoint_interval = std::chrono::hours(1); // only the final one
    test_support::in_process_server s(o);
    ws_client c(s.port(), "/ws");
    c.next("welcome");
    c.send(json{{"type", "hello"}, {"admin_token", admin_token}});
    c.next("welcome");
    c.send(load_drop_scene(1));
    ack_of(c, 1);
    c.send(spawn_at(2, {-1.0, -1.0, 1.0 / 3.0 + 1.0}, {0.5, 0.1 + 0.2, 0.0}));
    spawned = ack_of(c, 2);
    snapshot_at_or_after(c, s.ticks("default") + 20);
    s.stop();
    return checkpoint_path(dir, "default");
}

TEST(Persistence, ALoadedSceneIsCheckpointedAndARestartRunsItWithTheSameBodiesIdsAndTick)
{
    fs::path const dir = fresh_dir("loaded");
    std::uint64_t spawned = 0;
    fs::path const file = loaded_scene_checkpoint(dir, spawned);
    std::string const text = read_text(file);
    checkpoint const saved = decode_checkpoint(text, file.string());
    EXPECT_EQ(json::parse(text).at("version"), checkpoint_format_version);
    EXPECT_EQ(saved.scene_name, "still"); // the room's own scene, still checked at a restart
    EXPECT_EQ(saved.scene_fingerprint, scene_fingerprint(read_text(dir / "still.scene.json")));
    ASSERT_TRUE(saved.loaded_scene);
    EXPECT_EQ(saved.loaded_scene->name, "drop");
    EXPECT_EQ(json::parse(saved.loaded_scene->text), drop_scene());
    EXPECT_EQ(saved.loaded_scene->fingerprint, scene_fingerprint(saved.loaded_scene->text));
    ASSERT_EQ(saved.bodies.size(), 3u); // the drop scene's two, then the spawned one
    EXPECT_EQ(saved.bodies[2].wire_id, spawned);
    EXPECT_EQ(saved.next_wire_id, spawned + 1);

    // A room made from it runs the loaded scene with the checkpoint's state, bit for bit.
    net::io_context io;
    scene::scene const still = scene::load_scene(dir / "still.scene.json");
    room restored(io, io.get_executor(), "default", still, {}, saved.scene_fingerprint,
                  saved.scene_overrides, saved);
    checkpoint const again = restored.take_checkpoint();
    expect_identical(saved, again);
    EXPECT_EQ(encode_checkpoint(again), text); // byte for byte, the loaded scene included

    // A server restarted from the directory: the drop scene's welcome (walls, obstacles, dt;
    // the bounds hold the bodies it has now, the spawned one too)...
    json drop_welcome;
    {
        fs::path const other = fresh_dir("loaded_reference");
        server_options o;
        o.rooms.push_back({"default", write_scene(other, "drop", drop_scene())});
        test_support::in_process_server reference(o);
        ws_client c(reference.port(), "/ws");
        drop_welcome = c.next("welcome");
    }
    test_support::in_process_server s(still_room(dir));
    ws_client c(s.port(), "/ws");
    json const welcome = c.next("welcome");
    EXPECT_EQ(welcome.at("scene").at("name"), "drop");
    EXPECT_EQ(welcome.at("scene").at("walls"), drop_welcome.at("scene").at("walls"));
    EXPECT_EQ(welcome.at("scene").at("obstacles"), drop_welcome.at("scene").at("obstacles"));
    EXPECT_EQ(welcome.at("dt"), 0.01);
    // ... the checkpoint's bodies and ids, its tick going on, and the drop scene's gravity.
    json const first = c.next("snapshot");
    EXPECT_GT(first.at("tick").get<std::uint64_t>(), saved.tick);
    std::vector<std::uint64_t> saved_ids;
    for (checkpoint::body const& b : saved.bodies)
        saved_ids.push_back(b.wire_id);
    EXPECT_EQ(ids_of(first), saved_ids);
    json const later = snapshot_at_or_after(c, first.at("tick").get<std::uint64_t>() + 2);
    auto const vz = [](json const& snapshot) { return snapshot.at("bodies").at("velocity")[2].get<double>(); };
    EXPECT_LT(vz(later), vz(first)) << "body 0 falls faster: the loaded scene's gravity acts";
    c.send(spawn_at(1, {1.0, 1.0, 1.0}));
    EXPECT_EQ(ack_of(c, 1), saved.next_wire_id);
}

TEST(Persistence, ResetAfterARestartGoesBackToTheLoadedScene)
{
    fs::path const dir = fresh_dir("loaded_reset");
    std::uint64_t spawned = 0;
    checkpoint const saved =
        decode_checkpoint(read_text(loaded_scene_checkpoint(dir, spawned)), "");

    test_support::in_process_server s(still_room(dir));
    ws_client c(s.port(), "/ws");
    c.next("welcome");
    c.send(json{{"type", "hello"}, {"admin_token", admin_token}});
    c.next("welcome");
    c.send(json{{"type", "reset"}, {"ref", 1}});
    json const reset = c.next("ack");
    // The drop scene's two bodies (the still scene has one, at the origin), with new ids.
    json const fresh = snapshot_at_or_after(c, reset.at("tick").get<std::uint64_t>());
    std::vector<std::uint64_t> const ids = ids_of(fresh);
    ASSERT_EQ(ids.size(), 2u) << fresh.dump();
    for (std::uint64_t const id : ids)
        EXPECT_GE(id, saved.next_wire_id);
    auto const& position = fresh.at("bodies").at("position");
    EXPECT_EQ(position[0], 0.0);
    EXPECT_EQ(position[3], 1.0);
    EXPECT_GT(position[2].get<double>(), 2.5); // dropped from 3 m, a few ticks ago
    EXPECT_LE(position[2].get<double>(), 3.0);

    // And a checkpoint after the reset still carries the loaded scene.
    s.stop();
    checkpoint const after = decode_checkpoint(read_text(checkpoint_path(dir, "default")), "");
    ASSERT_TRUE(after.loaded_scene);
    EXPECT_EQ(after.loaded_scene->text, saved.loaded_scene->text);
}

TEST(Persistence, AVersionOneCheckpointStillRestoresInTheRoomsOwnScene)
{
    fs::path const dir = fresh_dir("version_one");
    server_options o = still_room(dir);
    std::uint64_t spawned = 0;
    {
        test_support::in_process_server s(o);
        ws_client c(s.port(), "/ws");
        c.next("welcome");
        c.send(spawn_at(1, {1.0 / 3.0, 2.0, -1.0}));
        spawned = ack_of(c, 1);
        snapshot_at_or_after(c, 10);
    }
    // What a version-1 server wrote: the same document, without loaded_scene, version 1.
    fs::path const file = checkpoint_path(dir, "default");
    json version_one = json::parse(read_text(file));
    ASSERT_FALSE(version_one.contains("loaded_scene"));
    version_one["version"] = 1;
    write_text(file, version_one.dump() + "\n");
    checkpoint const saved = decode_checkpoint(read_text(file), file.string());
    EXPECT_FALSE(saved.loaded_scene);

    test_support::in_process_server s(o);
    ws_client c(s.port(), "/ws");
    EXPECT_EQ(c.next("welcome").at("scene").at("name"), "still");
    json const first = c.next("snapshot");
    EXPECT_GT(first.at("tick").get<std::uint64_t>(), saved.tick);
    EXPECT_EQ(ids_of(first), (std::vector<std::uint64_t>{1, spawned}));
    s.stop();
    EXPECT_EQ(json::parse(read_text(file)).at("version"), checkpoint_format_version); // written in the current version
}

// Tags are part of a body: a restart keeps them (snapshots show them), and with them the
// contacts a scene's rule asks about. A ball tagged "ball" is spawned flying at a post tagged
// "post" and the room stops before they meet; after the restart the checkpoint's tags are
// the bodies' again, and the contact, under the rule ["ball", "post"], is reported.
TEST(Persistence, TagsAndTheContactsTheyAskForSurviveARestart)
{
    fs::path const dir = fresh_dir("tags");
    json const scene = {{"name", "posts"},
                        {"dt", 1.0 / 64.0},
                        {"integrator", "semi_implicit_euler"},
                        {"collisions", {{"mode", "continuous"}}},
                        {"box", {{"min", {-10, -10, -10}}, {"max", {10, 10, 10}}}},
                        {"bodies", json::array({{{"position", {3, 0, 0}}, {"radius", 0.5}, {"mass", 0},
                                                 {"static", true}, {"tag", "post"}}})},
                        {"contacts", json::array({json::array({"ball", "post"})})}};
    server_options o;
    o.state_dir = dir;
    o.checkpoint_interval = std::chrono::hours(1); // only the final one
    o.rooms.push_back({"default", write_scene(dir, "posts", scene)});
    std::uint64_t ball = 0;
    {
        test_support::in_process_server s(o);
        ws_client c(s.port(), "/ws");
        c.next("welcome");
        json spawn = spawn_at(1, {-5, 0, 0}, {4, 0, 0}, 0.5);
        spawn["body"]["tag"] = "ball";
        c.send(spawn);
        ball = ack_of(c, 1);
        snapshot_at_or_after(c, 5); // 5/64 s of the 7/4 s the ball needs to reach the post
        s.stop();
    }
    fs::path const file = checkpoint_path(dir, "default");
    json const saved = json::parse(read_text(file));
    EXPECT_EQ(saved.at("version"), checkpoint_format_version);
    EXPECT_EQ(saved.at("bodies").at("tag"), json::array({"post", "ball"}));

    test_support::in_process_server s(o);
    ws_client c(s.port(), "/ws");
    c.next("welcome");
    c.send(json{{"type", "hello"}, {"events", {{"kinds", {"contact"}}}}});
    json const first = c.next("snapshot");
    EXPECT_EQ(first.at("bodies").at("id"), json::array({1, ball}));
    EXPECT_EQ(first.at("bodies").at("tag"), json::array({"post", "ball"}));
    json const contact = c.next("event");
    EXPECT_EQ(contact.at("bodies"), json::array({1, ball}));
    EXPECT_EQ(contact.at("tags"), json::array({"post", "ball"}));
    // The centre reaches x = 2 after 7 m at 4 m/s from the start of its spawn's step, a whole
    // number of 1/64 s steps: what the restart continued is the same straight path, so the
    // time less 7/4 s is still a whole number of steps, to rounding (1e-9 s).
    double const steps_before = (contact.at("time").get<double>() - 7.0 / 4.0) * 64.0;
    EXPECT_NEAR(steps_before, std::round(steps_before), 64.0 * 1e-9);
}

TEST(Persistence, ATamperedLoadedSceneIsRefusedAndLeftUntouched)
{
    fs::path const dir = fresh_dir("loaded_tampered");
    std::uint64_t spawned = 0;
    json const good = json::parse(read_text(loaded_scene_checkpoint(dir, spawned)));
    server_options const o = still_room(dir);
    auto const refused = [&](json const& bad) { return refusal(dir, bad.dump(), o); };

    // Each way of tampering with the file, and what its refusal must say.
    struct tampering
    {
        std::string what;
        std::function<void(json&)> change;
        std::vector<std::string> says;
    };
    json negative = drop_scene(); // a scene the scene loader refuses
    negative["bodies"][0]["radius"] = -1;
    std::vector<tampering> const cases{
        {"the scene's text edited (a radius): it no longer agrees with its fingerprint",
         [](json& c) {
             std::string& text = c["loaded_scene"]["text"].get_ref<std::string&>();
             std::size_t const radius = text.find("0.2");
             ASSERT_NE(radius, std::string::npos) << text;
             text.replace(radius, 3, "0.3");
         },
         {"/loaded_scene: its text's fingerprint is", "changed in the file, or the file is corrupt"}},
        {"its fingerprint edited",
         [](json& c) { c["loaded_scene"]["fingerprint"] = scene_fingerprint("{}"); },
         {"/loaded_scene: its text's fingerprint is"}},
        {"both changed to agree, on a scene the loader refuses: its message, in the file",
         [&](json& c) {
             c["loaded_scene"]["text"] = negative.dump();
             c["loaded_scene"]["fingerprint"] = scene_fingerprint(negative.dump());
         },
         {"/loaded_scene/text: /bodies/0/radius"}},
        {"renamed", [](json& c) { c["loaded_scene"]["name"] = "still"; }, {"/loaded_scene/name"}},
        {"not text", [](json& c) { c["loaded_scene"]["text"] = drop_scene(); },
         {"/loaded_scene/text: must be a string"}},
        {"no fingerprint", [](json& c) { c["loaded_scene"].erase("fingerprint"); },
         {"/loaded_scene/fingerprint: missing"}},
        {"the room's own scene file is still checked: another file refuses it too",
         [](json& c) { c["scene"]["fingerprint"] = scene_fingerprint("{\"name\": \"still\"}"); },
         {"another scene, or the scene file changed"}},
    };
    for (tampering const& t : cases) {
        SCOPED_TRACE(t.what);
        json bad = good;
        t.change(bad);
        std::string const message = refused(bad);
        for (std::string const& part : t.says)
            EXPECT_NE(message.find(part), std::string::npos) << message;
    }

    // --discard-bad-state moves it aside and starts the room from its own scene.
    server_options discard = o;
    discard.discard_bad_state = true;
    json edited_text = good;
    cases.front().change(edited_text); // the scene's text edited
    write_text(checkpoint_path(dir, "default"), edited_text.dump());
    test_support::in_process_server s(discard);
    ws_client c(s.port(), "/ws");
    EXPECT_EQ(c.next("welcome").at("scene").at("name"), "still");
    std::size_t aside = 0;
    for (auto const& entry : fs::directory_iterator(dir))
        aside += entry.path().filename().string().starts_with("default.json.bad-") ? 1u : 0u;
    EXPECT_EQ(aside, 1u);
}

// The fingerprint of a room's own scene covers its overrides: each one, its value and their
// order (a later override of the same field wins). Without overrides it is the text's alone,
// what checkpoints made before rooms took overrides hold.
TEST(Persistence, TheScenesFingerprintCoversItsOverridesAndTheirOrder)
{
    std::string const text = still_scene().dump();
    std::vector<std::string> const both{"dt=0.03125", "substeps=2"};
    std::set<std::string> const prints{
        scene_fingerprint(text),
        scene_fingerprint(text, both),
        scene_fingerprint(text, std::vector<std::string>{"substeps=2", "dt=0.03125"}),
        scene_fingerprint(text, std::vector<std::string>{"dt=0.03125"}),
        scene_fingerprint(text, std::vector<std::string>{"dt=0.0625", "substeps=2"}),
        // An override does not run into the text or into the next one.
        scene_fingerprint(text + "dt=0.03125"),
        scene_fingerprint(text, std::vector<std::string>{"dt=0.03125substeps=2"}),
        scene_fingerprint(text, std::vector<std::string>{"dt=0.03125", "", "substeps=2"}),
    };
    EXPECT_EQ(prints.size(), 8u);
    EXPECT_EQ(scene_fingerprint(text, {}), scene_fingerprint(text));
}

// A room's overrides are part of its scene. Its checkpoints record them, and a restart with
// the same ones restores it; one with none, another value or another order is refused,
// naming both, and the file is left as it is. A checkpoint made without overrides is
// refused by a room started with some.
TEST(Persistence, ARoomRestoresOnlyFromACheckpointMadeWithTheSameOverrides)
{
    fs::path const dir = fresh_dir("overrides");
    fs::path const scene_file = write_scene(dir, "still", still_scene());
    std::vector<std::string> const overrides{"dt=0.03125", "forces.uniform_field.g=[0, 0, -1]"};
    auto const started_with = [&](std::vector<std::string> const& these) {
        server_options o;
        o.rooms.push_back({"default", scene_file, these});
        o.state_dir = dir;
        o.checkpoint_interval = std::chrono::hours(1); // only the final one
        return o;
    };
    fs::path const file = checkpoint_path(dir, "default");
    std::uint64_t spawned = 0;
    {
        test_support::in_process_server s(started_with(overrides));
        ws_client c(s.port(), "/ws");
        EXPECT_EQ(c.next("welcome").at("dt"), 0.03125);
        c.send(spawn_at(1, {1.0, 1.0, 1.0}));
        spawned = ack_of(c, 1);
        snapshot_at_or_after(c, 10);
        s.stop();
    }
    std::string const text = read_text(file);
    checkpoint const saved = decode_checkpoint(text, file.string());
    EXPECT_EQ(saved.scene_name, "still");
    EXPECT_EQ(saved.scene_overrides, overrides);
    EXPECT_EQ(json::parse(text).at("scene").at("overrides"), json(overrides));
    EXPECT_EQ(saved.scene_fingerprint, scene_fingerprint(read_text(scene_file), overrides));

    std::string const made_with =
        R"('still' with overrides ["dt=0.03125","forces.uniform_field.g=[0, 0, -1]"])";
    std::vector<std::vector<std::string>> const others{
        {},
        {"dt=0.0625", overrides[1]},
        {overrides[1], overrides[0]},
    };
    for (std::vector<std::string> const& other : others) {
        SCOPED_TRACE(json(other).dump());
        std::string const message = refusal(dir, text, started_with(other));
        EXPECT_NE(message.find("/scene: it is of scene " + made_with), std::string::npos) << message;
        EXPECT_NE(message.find("the room was started with other overrides"), std::string::npos)
            << message;
        EXPECT_NE(message.find(other.empty() ? "'still' without overrides"
                                             : "'still' with overrides " + json(other).dump()),
                  std::string::npos)
            << message;
    }
    json tampered = json::parse(text);
    tampered["scene"]["overrides"] = json::array({0.03125});
    EXPECT_NE(refusal(dir, tampered.dump(), started_with(overrides)).find("/scene/overrides: must be an array of strings"),
              std::string::npos);

    // The same overrides: restored (the spawned body and the tick), the overrides in force.
    write_text(file, text);
    {
        test_support::in_process_server s(started_with(overrides));
        ws_client c(s.port(), "/ws");
        EXPECT_EQ(c.next("welcome").at("dt"), 0.03125);
        json const first = c.next("snapshot");
        EXPECT_GT(first.at("tick").get<std::uint64_t>(), saved.tick);
        EXPECT_EQ(ids_of(first), (std::vector<std::uint64_t>{1, spawned}));
        s.stop();
    }
    EXPECT_EQ(decode_checkpoint(read_text(file), file.string()).scene_overrides, overrides);

    // A checkpoint of the room without overrides: refused by the room with them.
    fs::remove(file);
    {
        test_support::in_process_server s(started_with({}));
    }
    std::string const plain = read_text(file);
    EXPECT_FALSE(json::parse(plain).at("scene").contains("overrides"));
    std::string const message = refusal(dir, plain, started_with(overrides));
    EXPECT_NE(message.find("it is of scene 'still' without overrides"), std::string::npos) << message;
    EXPECT_NE(message.find("the room's scene is " + made_with), std::string::npos) << message;
}

fs::path log_file(std::string const& name)
{
    return fs::path(testing::TempDir()) / ("kugel_persistence_test_" + name + ".log");
}

/// Waits up to 30 s for the checkpoint at `file` to be one that `wanted` accepts. A checkpoint
/// is renamed into place whole, so the file read is never half written.
template <class Wanted>
bool wait_for_checkpoint(fs::path const& file, Wanted const& wanted)
{
    auto const deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    while (std::chrono::steady_clock::now() < deadline) {
        if (fs::exists(file) && wanted(decode_checkpoint(read_text(file), file.string())))
            return true;
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return false;
}

TEST(PersistenceProcess, SigkillAfterACheckpointRestartsWithThatCheckpointsWorld)
{
    fs::path const dir = fresh_dir("sigkill");
    std::vector<std::string> const args{"--room", "still=" + write_scene(dir, "still", still_scene()).string(),
                                        "--state", dir.string(), "--checkpoint-interval", "0.05"};
    fs::path const file = checkpoint_path(dir, "still");
    std::uint64_t spawned = 0;
    std::string killed_at; // the checkpoint's text when the server died
    {
        test_support::server_child p(KUGEL_SERVER_EXE, args, log_file("sigkill_first"));
        ws_client c(p.port(), "/ws/still");
        c.next("welcome");
        c.send(spawn_at(1, {1.0 / 3.0, -2.5, 0.1 + 0.2}));
        spawned = ack_of(c, 1);
        // Wait for a checkpoint that holds the body, then kill the server without warning.
        ASSERT_TRUE(wait_for_checkpoint(file, [&](checkpoint const& c2) {
            return c2.bodies.size() == 2 && c2.bodies[1].wire_id == spawned;
        })) << p.log();
        p.kill();
        killed_at = read_text(file);
    }
    checkpoint const saved = decode_checkpoint(killed_at, file.string());

    test_support::server_child p(KUGEL_SERVER_EXE, args, log_file("sigkill_second"));
    EXPECT_NE(p.log().find("restored from"), std::string::npos) << p.log();
    ws_client c(p.port(), "/ws/still");
    c.next("welcome");
    json const s = c.next("snapshot");
    EXPECT_GT(s.at("tick").get<std::uint64_t>(), saved.tick);
    std::ptrdiff_t const at = index_of(s, spawned);
    ASSERT_GE(at, 0) << s.dump();
    auto const& position = s.at("bodies").at("position");
    auto const k = static_cast<std::size_t>(3 * at);
    // At rest with no forces: exactly where it was spawned, and where the checkpoint has it.
    EXPECT_EQ(position[k].get<double>(), 1.0 / 3.0);
    EXPECT_EQ(position[k + 1].get<double>(), -2.5);
    EXPECT_EQ(position[k + 2].get<double>(), 0.1 + 0.2);
    EXPECT_EQ(position[k + 2].get<double>(), saved.bodies[1].desc.position.z());
    c.send(spawn_at(2, {0.0, 3.0, 0.0}));
    EXPECT_EQ(ack_of(c, 2), spawned + 1);
}

TEST(PersistenceProcess, SigtermWritesAFinalCheckpoint)
{
    fs::path const dir = fresh_dir("sigterm");
    fs::path const file = checkpoint_path(dir, "still");
    test_support::server_child p(KUGEL_SERVER_EXE,
                                 {"--room", "still=" + write_scene(dir, "still", still_scene()).string(),
                                  "--state", dir.string(), "--checkpoint-interval", "3600"},
                                 log_file("sigterm"));
    ws_client c(p.port(), "/ws/still");
    c.next("welcome");
    c.send(spawn_at(1, {2.0, 2.0, 2.0}));
    std::uint64_t const spawned = ack_of(c, 1);
    std::uint64_t const seen = snapshot_at_or_after(c, 10).at("tick").get<std::uint64_t>();
    EXPECT_FALSE(fs::exists(file)); // the interval has not passed
    EXPECT_EQ(p.stop(), 0) << p.log();
    checkpoint const saved = decode_checkpoint(read_text(file), file.string());
    EXPECT_GE(saved.tick, seen);
    ASSERT_EQ(saved.bodies.size(), 2u);
    EXPECT_EQ(saved.bodies[1].wire_id, spawned);
    EXPECT_EQ(saved.next_wire_id, spawned + 1);
}

TEST(PersistenceProcess, SigkillWhileALoadedSceneRunsRestartsInThatScene)
{
    fs::path const dir = fresh_dir("sigkill_loaded");
    std::vector<std::string> const args{"--room", "still=" + write_scene(dir, "still", still_scene()).string(),
                                        "--state", dir.string(), "--checkpoint-interval", "0.05",
                                        "--admin-token", admin_token};
    fs::path const file = checkpoint_path(dir, "still");
    std::uint64_t spawned = 0;
    std::string killed_at; // the checkpoint's text when the server died
    {
        test_support::server_child p(KUGEL_SERVER_EXE, args, log_file("sigkill_loaded_first"));
        ws_client c(p.port(), "/ws/still");
        c.next("welcome");
        c.send(json{{"type", "hello"}, {"admin_token", admin_token}});
        c.next("welcome");
        c.send(load_drop_scene(1));
        ack_of(c, 1);
        c.send(spawn_at(2, {-1.0, 1.0, 1.0 / 3.0}));
        spawned = ack_of(c, 2);
        // The periodic checkpoints go on in the loaded scene: wait for one with the body.
        ASSERT_TRUE(wait_for_checkpoint(file, [&](checkpoint const& c2) {
            return c2.loaded_scene && c2.bodies.size() == 3 && c2.bodies[2].wire_id == spawned;
        })) << p.log();
        p.kill();
        killed_at = read_text(file);
    }
    checkpoint const saved = decode_checkpoint(killed_at, file.string());

    test_support::server_child p(KUGEL_SERVER_EXE, args, log_file("sigkill_loaded_second"));
    EXPECT_NE(p.log().find("scene 'drop' (loaded by an admin)"), std::string::npos) << p.log();
    ws_client c(p.port(), "/ws/still");
    json const welcome = c.next("welcome");
    EXPECT_EQ(welcome.at("scene").at("name"), "drop");
    EXPECT_EQ(welcome.at("dt"), 0.01);
    json const s = c.next("snapshot");
    EXPECT_GT(s.at("tick").get<std::uint64_t>(), saved.tick);
    std::vector<std::uint64_t> saved_ids;
    for (checkpoint::body const& b : saved.bodies)
        saved_ids.push_back(b.wire_id);
    EXPECT_EQ(ids_of(s), saved_ids);
    c.send(spawn_at(3, {1.0, -1.0, 1.0}));
    EXPECT_EQ(ack_of(c, 3), spawned + 1);
}

TEST(PersistenceProcess, ABadCheckpointStopsTheStartWithExitTwo)
{
    fs::path const dir = fresh_dir("exit_two");
    fs::path const file = checkpoint_path(dir, "still");
    write_text(file, "{\"truncated\": ");
    test_support::child_process p(KUGEL_SERVER_EXE,
                                  {"--port", "0", "--room",
                                   "still=" + write_scene(dir, "still", still_scene()).string(),
                                   "--state", dir.string()},
                                  log_file("exit_two"));
    EXPECT_EQ(p.wait(std::chrono::seconds(30)), 2);
    EXPECT_NE(p.output().find(file.string()), std::string::npos) << p.output();
    EXPECT_NE(p.output().find("--discard-bad-state"), std::string::npos) << p.output();
    EXPECT_EQ(read_text(file), "{\"truncated\": ");
}

// The same from the command line: a room started with --set ROOM:PATH=VALUE restarts from its
// checkpoint with the same --set, and without it stops the start with exit 2, saying why.
TEST(PersistenceProcess, ARoomStartedWithoutTheOverridesOfItsCheckpointExitsTwo)
{
    fs::path const dir = fresh_dir("overrides_process");
    fs::path const file = checkpoint_path(dir, "still");
    std::vector<std::string> const plain{"--room", "still=" + write_scene(dir, "still", still_scene()).string(),
                                         "--state", dir.string(), "--checkpoint-interval", "3600"};
    std::vector<std::string> overridden = plain;
    overridden.insert(overridden.end(), {"--set", "still:dt=0.03125"});
    {
        test_support::server_child p(KUGEL_SERVER_EXE, overridden, log_file("overrides_first"));
        ws_client c(p.port(), "/ws/still");
        EXPECT_EQ(c.next("welcome").at("dt"), 0.03125);
        snapshot_at_or_after(c, 5);
        EXPECT_EQ(p.stop(), 0) << p.log();
    }
    std::string const text = read_text(file);
    checkpoint const saved = decode_checkpoint(text, file.string());
    EXPECT_EQ(saved.scene_overrides, std::vector<std::string>{"dt=0.03125"});

    std::vector<std::string> args = plain;
    args.insert(args.begin(), {"--port", "0"});
    test_support::child_process refused(KUGEL_SERVER_EXE, args, log_file("overrides_refused"));
    EXPECT_EQ(refused.wait(std::chrono::seconds(30)), 2);
    EXPECT_NE(refused.output().find(file.string() + R"(: /scene: it is of scene 'still' with overrides ["dt=0.03125"])"),
              std::string::npos)
        << refused.output();
    EXPECT_NE(refused.output().find("the room was started with other overrides"), std::string::npos)
        << refused.output();
    EXPECT_EQ(read_text(file), text);

    test_support::server_child p(KUGEL_SERVER_EXE, overridden, log_file("overrides_restored"));
    EXPECT_NE(p.log().find("room 'still': restored from"), std::string::npos) << p.log();
    ws_client c(p.port(), "/ws/still");
    EXPECT_EQ(c.next("welcome").at("dt"), 0.03125);
    EXPECT_GT(c.next("snapshot").at("tick").get<std::uint64_t>(), saved.tick);
}

} // namespace
} // namespace kugel::server
