// The load generator in this process against a server in this process. It asserts what
// every client saw, never how fast anything was.

#include "client/load.hpp"
#include "server.hpp"
#include "support/in_process_server.hpp"

#include <filesystem>
#include <gtest/gtest.h>
#include <sstream>

namespace kugel::client {
namespace {

TEST(Load, EveryClientSeesSnapshotsAndGetsItsCommandsAnswered)
{
    server::server_options o;
    o.rooms = {{"still", std::filesystem::path(KUGEL_SOURCE_DIR) / "client" / "examples" /
                             "scenes" / "still.json"}};
    test_support::in_process_server s(o);

    load_options options;
    options.url = s.url("still");
    options.clients = 3;
    options.duration = 2.0;
    options.commands_per_second = 10.0;
    load_report const report = run_load(options);

    EXPECT_TRUE(report.ok());
    EXPECT_FALSE(report.stopped_early);
    EXPECT_EQ(report.tick_rate, 60.0);
    ASSERT_EQ(report.clients.size(), 3U);
    for (auto const& c : report.clients) {
        EXPECT_TRUE(c.connected()) << c.connect_error;
        EXPECT_GT(c.snapshots_per_second(), 0.0) << "client " << c.number;
        EXPECT_GT(c.stats.commands_sent, 0U) << "client " << c.number;
        EXPECT_GT(c.stats.acks, 0U) << "client " << c.number;
        EXPECT_TRUE(c.stats.errors.empty()) << "client " << c.number;
        EXPECT_FALSE(c.disconnected) << "client " << c.number;
    }

    nlohmann::json const json = report_json(report);
    EXPECT_EQ(json["per_client"].size(), 3U);
    EXPECT_TRUE(json["ok"].get<bool>());
    EXPECT_GT(json["total"]["snapshots_per_second"].get<double>(), 0.0);
    EXPECT_TRUE(json["total"]["ack_latency"].contains("p99_ms"));

    std::ostringstream table;
    print_report(report, table);
    EXPECT_NE(table.str().find(" total "), std::string::npos) << table.str();

    s.stop();
}

TEST(Load, RefusesCountsAndTimesOutOfBounds)
{
    load_options options;
    options.url = "ws://127.0.0.1:1/ws";
    options.clients = 0;
    EXPECT_THROW(run_load(options), std::invalid_argument);
    options.clients = max_load_clients + 1;
    EXPECT_THROW(run_load(options), std::invalid_argument);
    options.clients = 1;
    options.duration = 0.0;
    EXPECT_THROW(run_load(options), std::invalid_argument);
    options.duration = 1.0;
    options.commands_per_second = -1.0;
    EXPECT_THROW(run_load(options), std::invalid_argument);
}

} // namespace
} // namespace kugel::client
