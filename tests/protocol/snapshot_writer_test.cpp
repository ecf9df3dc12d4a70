// The snapshot writer against the one it replaced: the text of both forms, full and compact,
// is pinned byte for byte on random snapshots (negative, large and one-digit numbers, runs of
// equal constants, charges, pauses, faults), so a faster writer cannot change the wire.
// `old_writer` below is the earlier writer, kept verbatim as the reference.

#include "protocol/codec.hpp"
#include "protocol/compact.hpp"

#include <gtest/gtest.h>

#include <array>
#include <bit>
#include <charconv>
#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <vector>

namespace kugel::protocol {
namespace {

namespace old_writer {

class snapshot_writer
{
public:
    explicit snapshot_writer(std::size_t bodies) { out_.reserve(64 + 160 * bodies); }

    void raw(std::string_view text) { out_ += text; }

    template <class Number>
    void number(Number x)
    {
        if constexpr (std::is_floating_point_v<Number>) {
            if (!std::isfinite(x)) { // never sent by the server; what nlohmann would write
                out_ += "null";
                return;
            }
        }
        std::array<char, 32> buffer{};
        auto const [end, ec] = std::to_chars(buffer.data(), buffer.data() + buffer.size(), x);
        out_.append(buffer.data(), end);
        if constexpr (std::is_floating_point_v<Number>) {
            if (std::string_view(buffer.data(), end).find_first_of(".e") == std::string_view::npos)
                out_ += ".0"; // 3.0, not 3: a double stays a double on the wire, as elsewhere
        }
    }

    template <class Number>
    void column(std::string_view name, std::vector<Number> const& values)
    {
        out_ += '"';
        out_ += name;
        out_ += "\":[";
        for (std::size_t i = 0; i < values.size(); ++i) {
            if (i > 0)
                out_ += ',';
            number(values[i]);
        }
        out_ += ']';
    }

    /// Ids as the first, then each less the one before.
    void gap_column(std::string_view name, std::vector<std::uint64_t> const& ids)
    {
        out_ += '"';
        out_ += name;
        out_ += "\":[";
        std::uint64_t last = 0;
        for (std::size_t i = 0; i < ids.size(); ++i) {
            if (i > 0)
                out_ += ',';
            number(ids[i] - last);
            last = ids[i];
        }
        out_ += ']';
    }

    /// Doubles, a run of equal ones written by copying the first's text (a scene's bodies
    /// mostly share radius and mass: shortest-form conversion is the costly part).
    void constant_column(std::string_view name, std::vector<double> const& values)
    {
        out_ += '"';
        out_ += name;
        out_ += "\":[";
        std::size_t text_start = 0, text_size = 0;
        for (std::size_t i = 0; i < values.size(); ++i) {
            if (i > 0)
                out_ += ',';
            if (i > 0 && std::bit_cast<std::uint64_t>(values[i]) ==
                             std::bit_cast<std::uint64_t>(values[i - 1])) {
                out_.append(out_, text_start, text_size);
                continue;
            }
            text_start = out_.size();
            number(values[i]);
            text_size = out_.size() - text_start;
        }
        out_ += ']';
    }

    std::string take() { return std::move(out_); }

private:
    std::string out_;
};


std::string old_encode(snapshot const& message)
{
    body_columns const& b = message.bodies;
    snapshot_writer w(b.size());
    w.raw(R"({"type":"snapshot","tick":)");
    w.number(message.tick);
    w.raw(R"(,"time":)");
    w.number(message.time);
    w.raw(message.paused ? R"(,"paused":true)" : R"(,"paused":false)");
    if (message.faults > 0) {
        w.raw(R"(,"faults":)");
        w.number(message.faults);
    }
    w.raw(R"(,"bodies":{)");
    w.column("id", b.id);
    w.raw(",");
    w.column("position", b.position);
    w.raw(",");
    w.column("velocity", b.velocity);
    w.raw(",");
    w.column("radius", b.radius);
    if (b.mass) {
        w.raw(",");
        w.column("mass", *b.mass);
    }
    if (b.charge) {
        w.raw(",");
        w.column("charge", *b.charge);
    }
    w.raw("}}");
    return w.take();
}
void write_bodies(snapshot_writer& w, compact_bodies const& b)
{
    w.raw("{");
    w.gap_column("id", b.id);
    w.raw(",");
    w.column("p", b.position);
    w.raw(",");
    w.column("v", b.velocity);
    w.raw(",");
    w.constant_column("radius", b.radius);
    w.raw(",");
    w.constant_column("mass", b.mass);
    if (b.charge) {
        w.raw(",");
        w.constant_column("charge", *b.charge);
    }
    w.raw(",");
    w.column("owner", b.owner);
    w.raw("}");
}


std::string old_encode(compact_snapshot const& message)
{
    std::size_t const bodies = (message.bodies ? message.bodies->size() : 0) +
                               (message.appeared ? message.appeared->size() : 0) +
                               (message.moved ? message.moved->position.size() / 3 : 0);
    snapshot_writer w(bodies / 2);
    w.raw(R"({"type":"snapshot","tick":)");
    w.number(message.tick);
    w.raw(R"(,"form":")");
    w.raw(message.form);
    w.raw("\"");
    if (message.base) {
        w.raw(R"(,"base":)");
        w.number(*message.base);
    }
    w.raw(R"(,"time":)");
    w.number(message.time);
    if (message.paused)
        w.raw(R"(,"paused":true)");
    if (message.faults > 0) {
        w.raw(R"(,"faults":)");
        w.number(message.faults);
    }
    if (message.q) {
        w.raw(R"(,"q":[)");
        w.number((*message.q)[0]);
        w.raw(",");
        w.number((*message.q)[1]);
        w.raw("]");
    }
    if (message.bodies) {
        w.raw(R"(,"bodies":)");
        write_bodies(w, *message.bodies);
    }
    if (message.moved) {
        w.raw(R"(,"moved":{)");
        w.column("runs", message.moved->runs);
        w.raw(",");
        w.column("p", message.moved->position);
        w.raw(",");
        w.column("v", message.moved->velocity);
        w.raw("}");
    }
    if (message.appeared) {
        w.raw(R"(,"appeared":)");
        write_bodies(w, *message.appeared);
    }
    if (message.vanished) {
        w.raw(",");
        w.gap_column("vanished", *message.vanished);
    }
    w.raw("}");
    return w.take();
}


} // namespace old_writer

/// A snapshot of n bodies with every kind of number a snapshot can hold.
snapshot random_snapshot(std::mt19937_64& rng, std::size_t n, bool charges)
{
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    std::uniform_int_distribution<int> kind(0, 5);
    auto const value = [&]() -> double {
        switch (kind(rng)) {
        case 0: return 0.0;
        case 1: return std::round(u(rng) * 100.0); // whole: written with ".0"
        case 2: return u(rng) * 1e-7;
        case 3: return u(rng) * 1e21;
        case 4: return -std::numeric_limits<double>::denorm_min();
        default: return u(rng) * 10.0;
        }
    };
    snapshot s{.tick = rng() % 1000000, .time = std::abs(u(rng)) * 1e4, .paused = rng() % 2 == 0,
               .faults = rng() % 3, .bodies = {}};
    std::uint64_t id = 0;
    s.bodies.mass.emplace();
    if (charges)
        s.bodies.charge.emplace();
    for (std::size_t i = 0; i < n; ++i) {
        id += 1 + rng() % 5;
        s.bodies.id.push_back(id);
        for (int k = 0; k < 3; ++k) {
            s.bodies.position.push_back(value());
            s.bodies.velocity.push_back(value());
        }
        bool const same = i > 0 && rng() % 4 != 0; // runs of equal constants, as in a scene
        s.bodies.radius.push_back(same ? s.bodies.radius.back() : std::abs(value()));
        s.bodies.mass->push_back(same ? s.bodies.mass->back() : std::abs(value()) + 1.0);
        if (charges)
            s.bodies.charge->push_back(same ? s.bodies.charge->back() : value());
    }
    return s;
}

TEST(SnapshotWriter, FullFormIsTheOldWritersTextByteForByte)
{
    std::mt19937_64 rng(7);
    for (std::size_t n : {0U, 1U, 2U, 17U, 1000U}) {
        for (bool charges : {false, true}) {
            snapshot s = random_snapshot(rng, n, charges);
            EXPECT_EQ(encode(s), old_writer::old_encode(s)) << n << " bodies";
            s.bodies.mass.reset(); // optional in the format
            EXPECT_EQ(encode(s), old_writer::old_encode(s)) << n << " bodies, no masses";
        }
    }
}

TEST(SnapshotWriter, CompactFormsAreTheOldWritersTextByteForByte)
{
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> step(-0.2, 0.2);
    for (std::size_t n : {0U, 1U, 3U, 40U, 2000U}) {
        for (bool charges : {false, true}) {
            snapshot s = random_snapshot(rng, n, charges);
            std::vector<body_owner> owners;
            for (std::size_t i = 0; i < n; i += 3)
                owners.push_back({s.bodies.id[i], 1 + rng() % 1000});
            quanta const q{1e-3, 1e-2};
            compact_state const base = quantize(s, owners, q);
            compact_snapshot const key = keyframe(base);
            EXPECT_EQ(encode(key), old_writer::old_encode(key)) << n << " bodies";
            EXPECT_EQ(encode_keyframe(base), old_writer::old_encode(key)) << n << " bodies";

            // The next snapshot: most bodies moved a little, some not at all, some replaced.
            snapshot next = s;
            next.tick += 2;
            next.time += 1.0 / 30.0;
            for (std::size_t k = 0; k < next.bodies.position.size(); ++k) {
                if (rng() % 5 == 0)
                    continue;
                next.bodies.position[k] += step(rng);
                next.bodies.velocity[k] += step(rng) * 10.0;
            }
            if (n > 2) {
                next.bodies.id[1] = next.bodies.id.back() + 7; // one vanished, one appeared
            }
            compact_state const now = quantize(next, owners, q);
            auto const d = delta(base, now);
            ASSERT_TRUE(d || n > 2) << n << " bodies"; // a keyframe when most were replaced
            if (d) {
                EXPECT_EQ(encode(*d), old_writer::old_encode(*d)) << n << " bodies";
            }
        }
    }
}

// The writer makes an integer below 10^8 as one word of eight digits: every length from one
// to sixteen digits, each at its edges (10^k − 1, 10^k, 10^k + 1) and with both signs, in
// the positions and velocities of a keyframe at quanta of 1, written as the old writer did.
TEST(SnapshotWriter, IntegersOfEveryLengthAreTheOldWritersText)
{
    snapshot s{.tick = 1, .time = 0.0, .paused = false, .faults = 0, .bodies = {}};
    s.bodies.mass.emplace();
    std::uint64_t id = 0;
    double power = 1.0;
    for (int k = 0; k <= 16; ++k, power *= 10.0) {
        for (double const edge : {power - 1.0, power, power + 1.0}) {
            s.bodies.id.push_back(++id);
            for (int d = 0; d < 3; ++d) {
                s.bodies.position.push_back(d == 1 ? -edge : edge);
                s.bodies.velocity.push_back(d == 2 ? -edge : edge);
            }
            s.bodies.radius.push_back(1.0);
            s.bodies.mass->push_back(1.0);
        }
    }
    compact_snapshot const key = keyframe(quantize(s, {}, quanta{1.0, 1.0}));
    std::string const text = encode(key);
    EXPECT_EQ(text, old_writer::old_encode(key));
    for (char const* number : {"[0,", ",-9,", ",99999999,", ",-100000000,", ",10000001,"})
        EXPECT_NE(text.find(number), std::string::npos) << number;
}

} // namespace
} // namespace kugel::protocol
