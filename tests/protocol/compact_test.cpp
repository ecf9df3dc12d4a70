#include "protocol/codec.hpp"
#include "protocol/compact.hpp"

#include <algorithm>
#include <cmath>
#include <gtest/gtest.h>
#include <random>
#include <string>
#include <vector>

namespace kugel::protocol {
namespace {

constexpr quanta q{1e-3, 1e-2};

/// A world of bodies that a test moves by hand: some at rest, some flying under gravity.
struct toy_world
{
    std::uint64_t tick = 0;
    double time = 0.0;
    std::uint64_t next_id = 1;
    struct body
    {
        std::uint64_t id;
        std::array<double, 3> x, v;
        double radius, mass;
        bool resting;
    };
    std::vector<body> bodies;
    std::mt19937_64 random{42};

    void spawn(bool resting)
    {
        std::uniform_real_distribution<double> u(-3.0, 3.0);
        body b{next_id++, {u(random), u(random), u(random) + 5.0}, {0, 0, 0}, 0.1, 2.5, resting};
        if (!resting)
            b.v = {u(random), u(random), u(random)};
        bodies.push_back(b);
    }

    void step(double dt)
    {
        ++tick;
        time += dt;
        for (body& b : bodies) {
            if (b.resting)
                continue;
            b.v[2] -= 9.81 * dt;
            for (std::size_t k = 0; k < 3; ++k)
                b.x[k] += b.v[k] * dt;
            if (b.x[2] < 0.0) { // a bounce: the velocity jumps
                b.x[2] = -b.x[2];
                b.v[2] = -0.8 * b.v[2];
            }
        }
    }

    /// The full form, bodies in a shuffled order (the server's slots are not in id order).
    snapshot full()
    {
        std::vector<body> order = bodies;
        std::shuffle(order.begin(), order.end(), random);
        snapshot s{.tick = tick, .time = time, .bodies = {}};
        s.bodies.mass.emplace();
        for (body const& b : order) {
            s.bodies.id.push_back(b.id);
            s.bodies.position.insert(s.bodies.position.end(), b.x.begin(), b.x.end());
            s.bodies.velocity.insert(s.bodies.velocity.end(), b.v.begin(), b.v.end());
            s.bodies.radius.push_back(b.radius);
            s.bodies.mass->push_back(b.mass);
        }
        return s;
    }
};

/// The decoded state in the full form's columns, and the full form itself, agree body by
/// body to half a quantum.
void expect_within_quantum(snapshot const& decoded, snapshot const& full, quanta const& qq)
{
    ASSERT_EQ(decoded.tick, full.tick);
    ASSERT_EQ(decoded.bodies.size(), full.bodies.size());
    for (std::size_t i = 0; i < full.bodies.size(); ++i) {
        auto const at = std::find(decoded.bodies.id.begin(), decoded.bodies.id.end(), full.bodies.id[i]);
        ASSERT_NE(at, decoded.bodies.id.end()) << "body " << full.bodies.id[i];
        auto const j = static_cast<std::size_t>(at - decoded.bodies.id.begin());
        for (std::size_t k = 0; k < 3; ++k) {
            EXPECT_LE(std::abs(decoded.bodies.position[3 * j + k] - full.bodies.position[3 * i + k]),
                      0.5 * qq.position * (1 + 1e-9));
            EXPECT_LE(std::abs(decoded.bodies.velocity[3 * j + k] - full.bodies.velocity[3 * i + k]),
                      0.5 * qq.velocity * (1 + 1e-9));
        }
        EXPECT_EQ(decoded.bodies.radius[j], full.bodies.radius[i]);
        EXPECT_EQ((*decoded.bodies.mass)[j], (*full.bodies.mass)[i]);
    }
}

/// Decodes text as the server would send it, and applies it to what the client holds.
compact_state decode_and_apply(std::string const& text, compact_state const* held)
{
    auto const decoded = decode_server_message(text);
    EXPECT_TRUE(decoded.message) << (decoded.failure ? decoded.failure->message : "");
    auto const& message = std::get<compact_snapshot>(*decoded.message);
    auto result = apply_compact(message, held);
    EXPECT_TRUE(result.state) << result.failure;
    return result.state ? *result.state : compact_state{};
}

TEST(CompactSnapshots, QuantizeRoundsToTheNearestStepAndClampsFarAway)
{
    EXPECT_EQ(quantize(0.0014, 1e-3), 1);
    EXPECT_EQ(quantize(-0.0016, 1e-3), -2);
    EXPECT_EQ(quantize(1e300, 1e-3), max_quantized);
    EXPECT_EQ(quantize(-1e300, 1e-3), -max_quantized);
}

TEST(CompactSnapshots, QuantizeAndPredictionAreTheFloorFormulasExactly)
{
    // The formulas of PROTOCOL.md with std::floor, against the library's own rounding, on
    // halves, values next to whole numbers, the clamp's edges and random values.
    auto const limit = static_cast<double>(max_quantized);
    auto const by_formula = [&](double x, double quantum) -> std::int64_t {
        double const steps = std::floor(x / quantum + 0.5);
        if (std::isnan(steps))
            return 0;
        return static_cast<std::int64_t>(std::clamp(steps, -limit, limit));
    };
    std::vector<double> xs{0.0, -0.0, 0.5, -0.5, 1.5, -1.5, 2.5, -2.5, 1e-300, -1e-300,
                           std::nextafter(0.5, 0.0), std::nextafter(-0.5, -1.0), limit - 0.5,
                           limit - 1.0, -limit + 0.5, -limit + 0.25, -limit - 1.0, limit * 4.0,
                           -limit * 4.0, 1e300, -1e300, std::nan("")};
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (int i = 0; i < 100000; ++i)
        xs.push_back(u(rng) * std::pow(10.0, static_cast<double>(rng() % 40) - 10.0));
    for (double const x : xs) {
        EXPECT_EQ(quantize(x, 1.0), by_formula(x, 1.0)) << x;
        EXPECT_EQ(quantize(x, 1e-3), by_formula(x, 1e-3)) << x;
    }
    for (int i = 0; i < 100000; ++i) {
        auto const base = static_cast<std::int64_t>(rng() % 2000000) - 1000000;
        auto const v0 = static_cast<std::int64_t>(rng() % 20001) - 10000;
        auto const v1 = static_cast<std::int64_t>(rng() % 20001) - 10000;
        double const k = prediction_factor(0.0, static_cast<double>(rng() % 100) / 60.0, {1e-3, 1e-2});
        double const m = static_cast<double>(v0 + v1) * k;
        EXPECT_EQ(predicted_position(base, v0, v1, k), base + static_cast<std::int64_t>(std::floor(m + 0.5)));
    }
    EXPECT_EQ(predicted_position(5, max_quantized, max_quantized, 1.0), 5); // no prediction that far
}

TEST(CompactSnapshots, AKeyframeDecodesToTheFullFormToTheQuantum)
{
    toy_world w;
    for (int i = 0; i < 50; ++i)
        w.spawn(i % 3 == 0);
    w.step(1.0 / 60);
    snapshot const full = w.full();
    compact_state const server = quantize(full, {}, q);
    compact_state const client = decode_and_apply(encode(keyframe(server)), nullptr);
    EXPECT_EQ(client, server);
    expect_within_quantum(to_snapshot(client), full, q);
}

// The property the compact form rests on: a client that applies the stream holds exactly the
// server's quantized state, every snapshot, over a long run with spawns and removals and a
// client that misses snapshots and takes a keyframe to go on.
TEST(CompactSnapshots, ADeltaChainWithChurnKeepsTheClientOnTheServersState)
{
    toy_world w;
    for (int i = 0; i < 200; ++i)
        w.spawn(i % 2 == 0);
    std::vector<body_owner> const owners{{5, 9}, {230, 4}};
    compact_state base = quantize(w.full(), owners, q);
    compact_state held = decode_and_apply(encode(keyframe(base)), nullptr);
    std::size_t delta_bytes = 0, deltas = 0;
    for (int n = 1; n <= 600; ++n) {
        w.step(1.0 / 60);
        w.step(1.0 / 60);
        if (n % 7 == 0)
            w.spawn(n % 2 == 0);
        if (n % 11 == 0)
            w.bodies.erase(w.bodies.begin() + static_cast<std::ptrdiff_t>(static_cast<std::size_t>(n) % w.bodies.size()));
        snapshot const full = w.full();
        compact_state const now = quantize(full, owners, q);
        auto const d = delta(base, now);
        ASSERT_TRUE(d);
        std::string const text = encode(*d);
        delta_bytes += text.size();
        ++deltas;
        if (n % 50 == 0) {
            base = now; // the client misses this one: the chain goes on without it
            continue;
        }
        if (held.tick != *d->base) {
            // It cannot apply the next delta, and takes the keyframe instead.
            EXPECT_FALSE(apply_compact(*d, &held).state);
            held = decode_and_apply(encode(keyframe(now)), nullptr);
        } else {
            held = decode_and_apply(text, &held);
        }
        ASSERT_EQ(held, now) << "at snapshot " << n;
        expect_within_quantum(to_snapshot(held), full, q);
        base = now;
    }
    // Half the bodies rest: they cost nothing; the others a few bytes each.
    EXPECT_LT(delta_bytes / deltas, 100 * 20 + 200);
}

TEST(CompactSnapshots, RestingBodiesAreNotInADelta)
{
    toy_world w;
    for (int i = 0; i < 100; ++i)
        w.spawn(true);
    compact_state const a = quantize(w.full(), {}, q);
    w.step(1.0 / 60);
    w.step(1.0 / 60);
    compact_state const b = quantize(w.full(), {}, q);
    auto const d = delta(a, b);
    ASSERT_TRUE(d);
    EXPECT_FALSE(d->moved);
    EXPECT_FALSE(d->appeared);
    EXPECT_FALSE(d->vanished);
    EXPECT_EQ(encode(*d), R"({"type":"snapshot","tick":2,"form":"delta","base":0,"time":)" +
                              std::string(R"(0.03333333333333333})"));
}

TEST(CompactSnapshots, AReplacedWorldGivesAKeyframeNotADelta)
{
    toy_world w;
    for (int i = 0; i < 100; ++i)
        w.spawn(false);
    compact_state const a = quantize(w.full(), {}, q);
    w.bodies.clear();
    for (int i = 0; i < 100; ++i)
        w.spawn(false);
    w.step(1.0 / 60);
    EXPECT_FALSE(delta(a, quantize(w.full(), {}, q)));
    EXPECT_FALSE(delta(a, quantize(w.full(), {}, quanta{1e-2, 1e-2}))) << "other quanta";
}

TEST(CompactSnapshots, ADeltaThatContradictsItsBaseIsRefused)
{
    compact_state held{.tick = 10, .time = 1.0, .q = q, .bodies = {}};
    held.bodies = {.id = {1, 2}, .position = {0, 0, 0, 1, 1, 1}, .velocity = {0, 0, 0, 0, 0, 0},
                   .radius = {0.1, 0.1}, .mass = {1, 1}, .owner = {0, 0}};
    auto const refused = [&](std::string const& text) {
        auto const decoded = decode_server_message(text);
        if (!decoded.message)
            return true;
        return !apply_compact(std::get<compact_snapshot>(*decoded.message), &held).state;
    };
    std::string const head = R"({"type":"snapshot","tick":12,"form":"delta","base":10,"time":1.1)";
    EXPECT_FALSE(refused(head + "}"));
    EXPECT_TRUE(refused(R"({"type":"snapshot","tick":12,"form":"delta","base":9,"time":1.1})"));
    EXPECT_TRUE(refused(head + R"(,"moved":{"runs":[2,1],"p":[0,0,0],"v":[0,0,0]}})"));
    EXPECT_TRUE(refused(head + R"(,"moved":{"runs":[0,1],"p":[0,0,0],"v":[0,0,0]},"vanished":[1]})"));
    EXPECT_TRUE(refused(head + R"(,"vanished":[3]})"));
    EXPECT_TRUE(refused(head + R"(,"vanished":[2,0]})"));
    EXPECT_TRUE(refused(head + R"(,"appeared":{"id":[2],"p":[0,0,0],"v":[0,0,0],"radius":[1],"mass":[1],"owner":[0]}})"));
    EXPECT_TRUE(refused(head + R"(,"moved":{"runs":[1,1],"p":[9007199254740991,0,0],"v":[0,0,0]}})"));
    EXPECT_TRUE(refused(head + R"(,"moved":{"runs":[0,1],"p":[0,0],"v":[0,0,0]}})"));
    EXPECT_TRUE(refused(head + R"(,"moved":{"runs":[0,9007199254740991,0,9007199254740991],"p":[],"v":[]}})"));
    EXPECT_TRUE(refused(R"({"type":"snapshot","tick":12,"form":"key","time":1,"q":[0,1],"bodies":{"id":[],"p":[],"v":[],"radius":[],"mass":[],"owner":[]}})"));
    EXPECT_TRUE(refused(R"({"type":"snapshot","tick":12,"form":"rows","time":1})"));
    EXPECT_TRUE(refused(R"({"type":"snapshot","tick":12,"form":"delta","base":12,"time":1})"));
}

TEST(CompactSnapshots, AMovedBodyCostsAFewBytes)
{
    // A body flying under gravity: its prediction from the mean velocity is exact for a
    // parabola; this world's semi-implicit Euler steps miss it by g·dt² (3 quanta).
    toy_world w;
    for (int i = 0; i < 400; ++i)
        w.spawn(false);
    for (auto& b : w.bodies)
        b.x[2] += 100.0; // no bounce
    compact_state const a = quantize(w.full(), {}, q);
    w.step(1.0 / 60);
    w.step(1.0 / 60);
    auto const d = delta(a, quantize(w.full(), {}, q));
    ASSERT_TRUE(d && d->moved);
    for (std::int64_t const r : d->moved->position)
        EXPECT_LE(std::abs(r), 4);
    EXPECT_LE(static_cast<double>(encode(*d).size()) / 400.0, 16.0);
}

} // namespace
} // namespace kugel::protocol

namespace kugel::protocol {
namespace {

/// Two bodies at rest, body 1 tagged when `tag_first`, and a third (tagged "third") from
/// tick 2 on, in the full form the server copies: the tag column only while some body has a tag.
snapshot tagged_world(std::uint64_t tick, bool tag_first, bool third)
{
    snapshot s{.tick = tick, .time = static_cast<double>(tick) / 64.0, .bodies = {}};
    std::vector<std::string> tags;
    for (std::uint64_t id = 1; id <= (third ? 3U : 2U); ++id) {
        s.bodies.id.push_back(id);
        s.bodies.position.insert(s.bodies.position.end(), {static_cast<double>(id), 0.0, 0.0});
        s.bodies.velocity.insert(s.bodies.velocity.end(), {0.0, 0.0, 0.0});
        s.bodies.radius.push_back(0.5);
        tags.push_back(id == 1 && tag_first ? "post" : id == 3 ? "third" : "");
    }
    s.bodies.mass.emplace(s.bodies.size(), 1.0);
    if (std::any_of(tags.begin(), tags.end(), [](std::string const& t) { return !t.empty(); }))
        s.bodies.tag = tags;
    return s;
}

// A tag is one of a body's constants: the keyframe carries the tag column (only when some
// body has a tag), a delta carries a tag only for a body that appeared, and the client's
// state after applying both is the server's, tags and all; a body without one reads "".
TEST(CompactSnapshots, TagsComeWithTheConstantsOnly)
{
    compact_state const untagged = quantize(tagged_world(1, false, false), {}, q);
    EXPECT_FALSE(untagged.bodies.tag);
    EXPECT_EQ(encode(keyframe(untagged)).find("tag"), std::string::npos);

    compact_state const base = quantize(tagged_world(1, true, false), {}, q);
    ASSERT_TRUE(base.bodies.tag);
    EXPECT_EQ(*base.bodies.tag, (std::vector<std::string>{"post", ""}));
    std::string const key = encode(keyframe(base));
    EXPECT_NE(key.find(R"("owner":[0,0],"tag":["post",""])"), std::string::npos) << key;
    compact_state const held = decode_and_apply(key, nullptr);
    EXPECT_EQ(held, base);

    compact_state const same = quantize(tagged_world(2, true, false), {}, q);
    auto const quiet = delta(base, same);
    ASSERT_TRUE(quiet);
    EXPECT_EQ(encode(*quiet).find("tag"), std::string::npos) << "nothing appeared: no tag is sent";

    compact_state const now = quantize(tagged_world(2, true, true), {}, q);
    auto const d = delta(base, now);
    ASSERT_TRUE(d);
    std::string const text = encode(*d);
    EXPECT_NE(text.find(R"("appeared":{"id":[3])"), std::string::npos) << text;
    EXPECT_NE(text.find(R"("tag":["third"])"), std::string::npos) << text;
    EXPECT_EQ(text.find("post"), std::string::npos) << "a held body's tag is not sent again";
    compact_state const after = decode_and_apply(text, &held);
    EXPECT_EQ(after, now);
    EXPECT_EQ(to_snapshot(after).bodies.tag, (std::vector<std::string>{"post", "", "third"}));

    // The tagged bodies gone, the column goes too: the client's state is the server's.
    snapshot only_second = tagged_world(3, false, false); // bodies 1 and 3 removed
    only_second.bodies.id.erase(only_second.bodies.id.begin());
    only_second.bodies.position.erase(only_second.bodies.position.begin(), only_second.bodies.position.begin() + 3);
    only_second.bodies.velocity.erase(only_second.bodies.velocity.begin(), only_second.bodies.velocity.begin() + 3);
    only_second.bodies.radius.erase(only_second.bodies.radius.begin());
    only_second.bodies.mass->erase(only_second.bodies.mass->begin());
    compact_state const none = quantize(only_second, {}, q);
    auto const gone = delta(now, none);
    ASSERT_TRUE(gone);
    EXPECT_EQ(decode_and_apply(encode(*gone), &after).bodies.tag, std::nullopt);
}

} // namespace
} // namespace kugel::protocol
