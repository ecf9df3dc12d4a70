// /metrics, /readyz and /healthz of an in-process server: the text parses as Prometheus'
// exposition format, and after known traffic each counter has moved by exactly what was sent.

#include "metrics.hpp"
#include "server.hpp"

#include "support/http_get.hpp"
#include "support/in_process_server.hpp"
#include "support/scene_files.hpp"
#include "support/ws_client.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <chrono>
#include <thread>

namespace kugel::server {
namespace {

using nlohmann::json;
using test_support::http_get;
using test_support::ws_client;
namespace fs = std::filesystem;

/// Every sample of a scrape, by its series (`name{labels}` as written); fails the test for
/// a line that is neither a sample, a # HELP or a # TYPE, for a sample whose family has no
/// # TYPE before it, and for a family described twice.
std::map<std::string, double> parse_metrics(std::string const& text)
{
    static std::regex const comment(R"(# (HELP|TYPE) ([a-zA-Z_:][a-zA-Z0-9_:]*) (.+))");
    static std::regex const sample(
        R"(([a-zA-Z_:][a-zA-Z0-9_:]*)(\{[a-zA-Z_][a-zA-Z0-9_]*="(?:[^"\\]|\\.)*"(?:,[a-zA-Z_][a-zA-Z0-9_]*="(?:[^"\\]|\\.)*")*\})? ([-+]?(?:[0-9.eE+-]+|Inf|NaN)))");
    static std::set<std::string> const types{"counter", "gauge", "histogram", "summary", "untyped"};
    std::map<std::string, double> samples;
    std::set<std::string> typed;
    std::set<std::string> described;
    std::istringstream in(text);
    std::string line;
    EXPECT_TRUE(text.empty() || text.back() == '\n') << "the text must end in a newline";
    while (std::getline(in, line)) {
        std::smatch m;
        if (std::regex_match(line, m, comment)) {
            EXPECT_TRUE(described.insert(m[1].str() + " " + m[2].str()).second) << "twice: " << line;
            if (m[1] == "TYPE") {
                EXPECT_TRUE(types.contains(m[3].str())) << line;
                typed.insert(m[2].str());
            }
        } else if (std::regex_match(line, m, sample)) {
            std::string name = m[1].str();
            bool has_type = typed.contains(name);
            for (std::string const suffix : {"_bucket", "_sum", "_count"})
                if (name.ends_with(suffix))
                    has_type = has_type || typed.contains(name.substr(0, name.size() - suffix.size()));
            EXPECT_TRUE(has_type) << "no # TYPE before " << line;
            std::string const value = m[3].str();
            double const x = value == "+Inf" ? HUGE_VAL : std::stod(value);
            EXPECT_TRUE(samples.emplace(m[1].str() + m[2].str(), x).second) << "twice: " << line;
        } else {
            ADD_FAILURE() << "not exposition format: '" << line << "'";
        }
    }
    return samples;
}

std::map<std::string, double> scrape(std::uint16_t port)
{
    auto const reply = http_get(port, "/metrics");
    EXPECT_EQ(reply.status, 200U);
    EXPECT_EQ(reply.content_type, metrics_content_type);
    return parse_metrics(reply.body);
}

fs::path write_scene(std::string const& name, json const& scene)
{
    return test_support::write_scene(fs::path(testing::TempDir()) / ("kugel_metrics_test_" + name + ".json"), scene);
}

json still_scene(int generated = 0) { return test_support::still_scene(generated); }

server_options lab(int generated = 0)
{
    server_options o;
    o.rooms.push_back({"lab", write_scene("lab" + std::to_string(generated), still_scene(generated))});
    return o;
}

std::string rejected(std::string const& code)
{
    return R"(kugel_commands_rejected_total{room="lab",code=")" + code + R"("})";
}

/// The next message that is not a snapshot; counts the snapshots passed on the way.
json next_answer(ws_client& c, int& snapshots)
{
    for (;;) {
        json message = c.read_json();
        if (message.at("type") != "snapshot")
            return message;
        ++snapshots;
    }
}

TEST(Metrics, CountersMoveByExactlyTheTrafficSent)
{
    server_options options = lab();
    options.client.command_burst = 4;
    options.client.commands_per_second = 0.001; // no token accrues during the test
    options.client.max_message_bytes = 1024;
    test_support::in_process_server s(options);

    auto const before = scrape(s.port());
    ASSERT_TRUE(before.contains(rejected("bad_json")));

    ws_client c(s.port(), "/ws/lab");
    int snapshots = 0;
    ASSERT_EQ(next_answer(c, snapshots).at("type"), "welcome");
    for (int i = 0; i < 3; ++i)
        c.send(std::string("{bad"));
    for (int i = 0; i < 2; ++i)
        c.send(json{{"type", "remove"}, {"ref", i}, {"id", 424242}});
    for (int i = 0; i < 6; ++i) // 2 pass (the removes took 2 of the burst of 4), 4 are refused
        c.send(json{{"type", "ping"}, {"ref", 100 + i}});
    std::map<std::string, int> answers;
    for (int i = 0; i < 11; ++i) {
        json const a = next_answer(c, snapshots);
        ++answers[a.at("type") == "error" ? a.at("code").get<std::string>() : a.at("type").get<std::string>()];
    }
    EXPECT_EQ(answers, (std::map<std::string, int>{{"bad_json", 3}, {"unknown_body", 2}, {"pong", 2}, {"rate_limited", 4}}));

    ws_client big(s.port(), "/ws/lab");
    ASSERT_EQ(next_answer(big, snapshots).at("type"), "welcome");
    // Its roster read first: a reply still queued when the oversized frame closes the
    // session is never handed to the socket, and so never counted.
    big.hear_players();
    big.next("players");
    big.send(std::string(2000, ' '));
    while (big.read()) {
    }
    ASSERT_EQ(big.close_code(), 1009);
    // The first client is told big joined and left: player notices, counted as replies.
    c.hear_players();
    for (json notice = c.next("player"); notice.at("change") != "left"; notice = c.next("player")) {
    }

    // Beast sends the 1009 close before it hands the read's error to the session, which
    // only then counts the frame: the client can see the close first, so wait for the count.
    // Two scrapes in a row, the earlier one for the tick counters' bounds below.
    auto earlier = scrape(s.port());
    auto after = scrape(s.port());
    auto const counted_by = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (after.at(rejected("message_too_large")) == before.at(rejected("message_too_large")) &&
           std::chrono::steady_clock::now() < counted_by) {
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
        earlier = std::move(after);
        after = scrape(s.port());
    }
    auto const moved = [&](std::string const& series) { return after.at(series) - before.at(series); };
    EXPECT_EQ(moved(rejected("bad_json")), 3);
    EXPECT_EQ(moved(rejected("unknown_body")), 2);
    EXPECT_EQ(moved(rejected("rate_limited")), 4);
    EXPECT_EQ(moved(rejected("message_too_large")), 1);
    EXPECT_EQ(moved(rejected("bad_value")), 0);
    EXPECT_EQ(moved(R"(kugel_messages_in_total{room="lab"})"), 3 + 2 + 6 + 1);
    // Two welcomes, two rosters, big's joined and left notices to the first client, and the
    // eleven answers; every snapshot the clients read was counted.
    EXPECT_EQ(moved(R"(kugel_messages_out_total{room="lab",kind="reply"})"), 2 + 2 + 2 + 11);
    EXPECT_GE(moved(R"(kugel_messages_out_total{room="lab",kind="snapshot"})"), snapshots);
    EXPECT_GT(moved(R"(kugel_bytes_out_total{room="lab"})"), 0);
    EXPECT_EQ(after.at(R"(kugel_bodies{room="lab"})"), 1);
    EXPECT_GE(after.at(R"(kugel_clients{room="lab"})"), 1); // c stays; big has left (c heard it)

    // The histogram: cumulative buckets, +Inf equal to the count, one record per tick. At any
    // instant the count is the ticks completed, or one less while a tick's record is pending.
    // A scrape reads the histogram before the tick counter, and ticks go on in between (under
    // load a reader can be descheduled for several ticks), so the bounds are taken from two
    // scrapes: the count cannot exceed the ticks read after it, nor fall more than one below
    // the ticks an earlier scrape read.
    double const ticks = after.at(R"(kugel_ticks_total{room="lab"})");
    double const count = after.at(R"(kugel_tick_duration_seconds_count{room="lab"})");
    EXPECT_GT(ticks, 0);
    EXPECT_LE(count, ticks);
    EXPECT_GE(count, earlier.at(R"(kugel_ticks_total{room="lab"})") - 1);
    EXPECT_EQ(after.at(R"(kugel_tick_duration_seconds_bucket{room="lab",le="+Inf"})"), count);
    double previous = 0;
    for (double const bound : tick_histogram::upper_bounds) {
        std::ostringstream series;
        series << R"(kugel_tick_duration_seconds_bucket{room="lab",le=")" << bound << R"("})";
        ASSERT_TRUE(after.contains(series.str())) << series.str();
        EXPECT_GE(after.at(series.str()), previous);
        previous = after.at(series.str());
    }
    EXPECT_LE(previous, count);
    EXPECT_GT(after.at(R"(kugel_tick_duration_seconds_sum{room="lab"})"), 0);

    // Every tick started is in the lateness histogram, recorded as it starts: at any instant
    // the ticks completed or one more. A scrape reads it before the tick counter, so it is at
    // most one above the ticks read after it and at least the ticks an earlier scrape read.
    // The count of ticks behind and the largest lateness are there.
    double const started = after.at(R"(kugel_tick_lateness_seconds_count{room="lab"})");
    EXPECT_GE(started, earlier.at(R"(kugel_ticks_total{room="lab"})"));
    EXPECT_LE(started, ticks + 1);
    EXPECT_EQ(after.at(R"(kugel_tick_lateness_seconds_bucket{room="lab",le="+Inf"})"), started);
    EXPECT_LE(after.at(R"(kugel_ticks_behind_total{room="lab"})"), started);
    EXPECT_GE(after.at(R"(kugel_tick_lateness_max_seconds{room="lab"})"), 0);
    EXPECT_EQ(after.at(R"(kugel_stalled_clients_total{room="lab"})"), 0);
}

/// Snapshots and bytes a client read, by form ("full", "keyframe", "delta").
struct read_by_form
{
    std::map<std::string, double> snapshots, bytes;

    void read_snapshots(ws_client& c, int n)
    {
        for (int got = 0; got < n;) {
            auto const text = c.read();
            ASSERT_TRUE(text) << "no snapshot in time";
            json const m = json::parse(*text);
            if (m.at("type") != "snapshot")
                continue;
            std::string const form = !m.contains("form") ? "full" : m.at("form") == "key" ? "keyframe" : "delta";
            snapshots[form] += 1;
            bytes[form] += static_cast<double>(text->size());
            ++got;
        }
    }
};

std::string by_form(std::string const& family, std::string const& form)
{
    return family + R"({room="lab",form=")" + form + R"("})";
}

TEST(Metrics, SnapshotsAndTheirBytesAreCountedByForm)
{
    test_support::in_process_server s(lab(20));
    ws_client full(s.port(), "/ws/lab");
    ws_client compact(s.port(), "/ws/lab");
    full.next("welcome");
    compact.next("welcome");
    compact.send(json{{"type", "hello"}, {"snapshots", {{"form", "compact"}}}});
    compact.next("welcome");
    read_by_form seen;
    seen.read_snapshots(full, 10);
    seen.read_snapshots(compact, 10);
    ASSERT_FALSE(HasFatalFailure());
    EXPECT_GE(seen.snapshots["keyframe"], 1);
    EXPECT_GE(seen.snapshots["delta"], 5);

    auto const m = scrape(s.port());
    for (std::string const form : {"full", "keyframe", "delta"}) {
        // Counted before it is handed to the socket: whatever a client read is in the count.
        EXPECT_GE(m.at(by_form("kugel_snapshots_sent_total", form)), seen.snapshots[form]) << form;
        EXPECT_GE(m.at(by_form("kugel_snapshot_bytes_sent_total", form)), seen.bytes[form]) << form;
        // Each form encoded once for every client: never more encodings than snapshots sent.
        EXPECT_GE(m.at(by_form("kugel_snapshots_encoded_total", form)), 1) << form;
        EXPECT_GT(m.at(by_form("kugel_snapshot_bytes_encoded_total", form)), 0) << form;
    }
    // A still scene: a delta is its head alone, a keyframe every body.
    EXPECT_LT(m.at(by_form("kugel_snapshot_bytes_sent_total", "delta")) / m.at(by_form("kugel_snapshots_sent_total", "delta")),
              m.at(by_form("kugel_snapshot_bytes_sent_total", "keyframe")) / m.at(by_form("kugel_snapshots_sent_total", "keyframe")) / 4);
}

TEST(Metrics, SentByFormAddsUpToTheSnapshotsSent)
{
    test_support::in_process_server s(lab(5));
    {
        ws_client full(s.port(), "/ws/lab");
        ws_client compact(s.port(), "/ws/lab");
        compact.next("welcome");
        compact.send(json{{"type", "hello"}, {"snapshots", {{"form", "compact"}}}});
        read_by_form seen;
        seen.read_snapshots(compact, 5);
        seen.read_snapshots(full, 5);
    }
    // Once the room has forgotten both clients, nothing more is sent: the counters stand.
    auto m = scrape(s.port());
    auto const until = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (m.at(R"(kugel_clients{room="lab"})") > 0 && std::chrono::steady_clock::now() < until) {
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
        m = scrape(s.port());
    }
    ASSERT_EQ(m.at(R"(kugel_clients{room="lab"})"), 0);
    std::this_thread::sleep_for(std::chrono::milliseconds(200)); // sends already posted land
    m = scrape(s.port());
    double snapshots = 0, bytes = 0;
    for (std::string const form : {"full", "keyframe", "delta"}) {
        snapshots += m.at(by_form("kugel_snapshots_sent_total", form));
        bytes += m.at(by_form("kugel_snapshot_bytes_sent_total", form));
    }
    EXPECT_EQ(snapshots, m.at(R"(kugel_messages_out_total{room="lab",kind="snapshot"})"));
    EXPECT_GE(snapshots, 10);
    EXPECT_LT(bytes, m.at(R"(kugel_bytes_out_total{room="lab"})")); // the replies are the rest
}

TEST(Metrics, ARoomOfFullFormClientsEncodesNoCompactForm)
{
    test_support::in_process_server s(lab(20));
    ws_client full(s.port(), "/ws/lab");
    full.next("welcome");
    read_by_form seen;
    seen.read_snapshots(full, 10);
    auto m = scrape(s.port());
    EXPECT_GE(m.at(by_form("kugel_snapshots_encoded_total", "full")), 10);
    for (std::string const form : {"keyframe", "delta"}) {
        EXPECT_EQ(m.at(by_form("kugel_snapshots_encoded_total", form)), 0) << form;
        EXPECT_EQ(m.at(by_form("kugel_snapshots_sent_total", form)), 0) << form;
    }

    // Asking for the compact form later: a keyframe first (quantized when first needed),
    // then deltas, which the client can apply.
    full.send(json{{"type", "hello"}, {"snapshots", {{"form", "compact"}}}});
    full.next("welcome");
    seen = {};
    seen.read_snapshots(full, 10);
    EXPECT_GE(seen.snapshots["keyframe"], 1);
    EXPECT_GE(seen.snapshots["delta"], 5);
    m = scrape(s.port());
    EXPECT_GE(m.at(by_form("kugel_snapshots_encoded_total", "keyframe")), 1);
}

TEST(Metrics, TickLatenessCountsTicksMoreThanOnePeriodLate)
{
    using std::chrono::milliseconds;
    tick_lateness l;
    milliseconds const period(16);
    l.record(milliseconds(-1), period); // early by timer rounding: on time
    l.record(milliseconds(3), period);
    l.record(period, period);           // exactly one period: not behind
    EXPECT_EQ(l.behind(), 0U);
    l.record(milliseconds(17), period);
    EXPECT_EQ(l.behind(), 1U);
    EXPECT_DOUBLE_EQ(l.max_seconds(), 0.017);
    l.record_backlog(milliseconds(90)); // a dropped backlog raises the largest, not the count
    EXPECT_EQ(l.behind(), 1U);
    EXPECT_DOUBLE_EQ(l.max_seconds(), 0.09);
    tick_histogram::reading const h = l.histogram().read();
    EXPECT_EQ(h.count(), 4U);
    EXPECT_EQ(h.cumulative[0], 1U); // the early one, as 0
    EXPECT_DOUBLE_EQ(h.sum, 0.036);
}

TEST(Metrics, ASlowClientsReplacedSnapshotsAreCountedAsDropped)
{
    server_options options = lab(2000); // snapshots of about 250 kB fill a socket fast
    options.client.write_stall = std::chrono::milliseconds(60'000);
    test_support::in_process_server s(options);
    ws_client stalled(s.port(), "/ws/lab"); // never reads
    std::string const series = R"(kugel_snapshots_dropped_total{room="lab"})";
    auto const deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    double dropped = 0;
    while ((dropped = scrape(s.port()).at(series)) == 0 && std::chrono::steady_clock::now() < deadline)
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
    EXPECT_GT(dropped, 0);
}

TEST(Metrics, AClientThatStopsReadingIsCountedWhenItIsDropped)
{
    server_options options = lab(2000); // snapshots of about 250 kB fill a socket fast
    options.client.write_stall = std::chrono::milliseconds(500);
    test_support::in_process_server s(options);
    ws_client stalled(s.port(), "/ws/lab"); // never reads
    std::string const series = R"(kugel_stalled_clients_total{room="lab"})";
    auto const deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    double count = 0;
    while ((count = scrape(s.port()).at(series)) == 0 && std::chrono::steady_clock::now() < deadline)
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
    EXPECT_EQ(count, 1);
    while (stalled.read(std::chrono::seconds(10))) {
    }
    EXPECT_TRUE(stalled.closed());
    EXPECT_EQ(scrape(s.port()).at(series), 1);
}

TEST(Metrics, LabelValuesAreEscaped)
{
    metrics_text m;
    m.begin({"kugel_example", "gauge", "An example."});
    m.sample("kugel_example", {{"room", "a\"b\\c\nd"}}, std::uint64_t{7});
    EXPECT_EQ(m.text(), "# HELP kugel_example An example.\n# TYPE kugel_example gauge\n"
                        "kugel_example{room=\"a\\\"b\\\\c\\nd\"} 7\n");
    parse_metrics(m.text());
}

TEST(Readiness, ReadyzIs200OnceEveryRoomTicksAndHealthzStays)
{
    server_options options = lab();
    options.rooms.push_back({"other", write_scene("other", still_scene())});
    test_support::in_process_server s(options);
    ws_client c(s.port(), "/ws/other");
    while (c.read_json().at("type") != "snapshot") {
    }
    ws_client d(s.port(), "/ws/lab");
    while (d.read_json().at("type") != "snapshot") {
    } // both rooms have ticked

    auto const ready = http_get(s.port(), "/readyz");
    EXPECT_EQ(ready.status, 200U) << ready.body;
    EXPECT_EQ(ready.content_type, "application/json");
    json const body = json::parse(ready.body);
    EXPECT_EQ(body.at("status"), "ready");
    EXPECT_EQ(body.at("ready"), true);
    EXPECT_EQ(body.at("rooms").at("lab").at("ready"), true);
    EXPECT_EQ(body.at("rooms").at("other").at("ready"), true);

    auto const health = http_get(s.port(), "/healthz");
    EXPECT_EQ(health.status, 200U);
    EXPECT_EQ(json::parse(health.body).at("status"), "ok");
}

TEST(Metrics, StepPhasesAreTimedAndOnlyThoseTheSceneUsesGrow)
{
    // The pile: discrete collisions under gravity, so free motion and every discrete phase
    // run on every tick, and the continuous mode never does.
    server_options o;
    o.rooms.push_back({"pile", fs::path(KUGEL_SOURCE_DIR) / "scenes" / "pile.json"});
    test_support::in_process_server s(o);
    room const& r = *s.get().find_room("pile");
    while (r.counters().ticks.load() < 20)
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    auto const samples = scrape(s.port());
    auto const phase = [&](std::string const& name) {
        auto const found = samples.find(R"(kugel_step_phase_seconds_total{room="pile",phase=")" + name + R"("})");
        EXPECT_NE(found, samples.end()) << name;
        return found == samples.end() ? -1.0 : found->second;
    };
    for (char const* used : {"free_motion", "walls", "cells", "velocity_passes", "position_passes",
                             "write_back"})
        EXPECT_GT(phase(used), 0.0) << used;
    EXPECT_EQ(phase("obstacles"), 0.0) << "the pile has no boxes";
    EXPECT_EQ(phase("continuous"), 0.0);
    EXPECT_EQ(phase("reorder"), 0.0) << "500 spheres are too few to be worth reordering";
}

// A continuous-mode room counts its events, and the steps it could not take exactly: 1,000
// spheres at up to 50 m/s in a box they fill to a tenth take some 4,000 events a step, so a
// cap of 100 events is reached in every step (each then finished in discrete mode), where
// the same gas without a cap takes every step whole. A room without collisions counts none.
TEST(Metrics, ContinuousEventsAndCappedStepsAreCounted)
{
    json gas = json::parse(std::ifstream(fs::path(KUGEL_SOURCE_DIR) / "scenes" / "gas.json"));
    json const box = {{"min", {-0.868, -0.868, -0.868}}, {"max", {0.868, 0.868, 0.868}}};
    gas["box"] = box;
    gas["generators"][0]["count"] = 1000;
    gas["generators"][0]["max_speed"] = 50.0;
    gas["generators"][0]["region"] = box;
    json capped = gas;
    capped["collisions"]["max_events_per_step"] = 100;
    server_options o;
    o.rooms.push_back({"whole", write_scene("gas_whole", gas)});
    o.rooms.push_back({"capped", write_scene("gas_capped", capped)});
    o.rooms.push_back({"lab", write_scene("lab0", still_scene())});
    test_support::in_process_server s(o);
    for (char const* name : {"whole", "capped", "lab"}) {
        room const& r = *s.get().find_room(name);
        while (r.counters().ticks.load() < 5)
            std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    auto const samples = scrape(s.port());
    auto const value = [&](std::string const& metric, std::string const& room_name) {
        auto const found = samples.find(metric + R"({room=")" + room_name + R"("})");
        EXPECT_NE(found, samples.end()) << metric << " " << room_name;
        return found == samples.end() ? -1.0 : found->second;
    };
    auto const ticks = [&](std::string const& room_name) { return value("kugel_ticks_total", room_name); };
    EXPECT_GT(value("kugel_collision_events_total", "whole"), 100.0 * ticks("whole"));
    EXPECT_EQ(value("kugel_capped_steps_total", "whole"), 0.0);
    EXPECT_GE(value("kugel_capped_steps_total", "capped"), 5.0);
    EXPECT_LE(value("kugel_capped_steps_total", "capped"), ticks("capped") + 1.0); // a tick may end after the scrape read its ticks
    EXPECT_GT(value("kugel_collision_events_total", "capped"), 0.0);
    EXPECT_EQ(value("kugel_collision_events_total", "lab"), 0.0);
    EXPECT_EQ(value("kugel_capped_steps_total", "lab"), 0.0);
}

} // namespace
} // namespace kugel::server
