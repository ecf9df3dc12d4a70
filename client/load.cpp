#include "load.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <stdexcept>
#include <thread>
#include <utility>

namespace kugel::client {

namespace {

using clock = std::chrono::steady_clock;
using json = nlohmann::json;

/// One client's part of the traffic: spawn a point mass, push it a few times, remove it,
/// spawn again. While a spawn's ack is outstanding it pings instead, so the rate holds.
class traffic
{
public:
    traffic(connection& link, std::uint64_t seed) : link_(link), random_(seed) {}

    void send_next()
    {
        take_spawn_answer();
        if (spawn_ref_) {
            link_.send(protocol::ping{});
        } else if (!body_) {
            spawn_ref_ = link_.send(spawn());
            pushes_ = 0;
        } else if (pushes_ < pushes_per_body) {
            ++pushes_;
            link_.send(protocol::impulse{0, *body_, direction(0.01)});
        } else {
            link_.send(protocol::remove{0, *std::exchange(body_, std::nullopt)});
        }
    }

    /// Removes the body it holds, if any, so that a load leaves the room as it found it.
    /// Returns the remove's ref.
    std::optional<std::uint64_t> remove_body()
    {
        take_spawn_answer();
        if (!body_)
            return std::nullopt;
        return link_.send(protocol::remove{0, *std::exchange(body_, std::nullopt)});
    }

private:
    static constexpr int pushes_per_body = 8;

    /// The answer to the outstanding spawn, if it has come: the body to push from now on.
    void take_spawn_answer()
    {
        if (!spawn_ref_)
            return;
        auto const answer = link_.await_reply(*spawn_ref_, std::chrono::milliseconds(0));
        if (!answer)
            return;
        spawn_ref_.reset();
        if (auto const* ack = std::get_if<protocol::ack>(&*answer); ack && ack->id)
            body_ = *ack->id;
    }

    /// A point mass (radius 0: it never collides, so it disturbs nothing) of 1 kg at rest,
    /// near the middle of the scene.
    protocol::spawn spawn()
    {
        protocol::welcome const& w = link_.welcome();
        protocol::spawn s;
        s.body.position = w.scene.bounds.centre;
        protocol::vec3 const offset = direction(0.25 * w.scene.bounds.radius);
        for (std::size_t k = 0; k < 3; ++k)
            s.body.position[k] += offset[k];
        s.body.radius = 0.0;
        s.body.mass = 1.0;
        return s;
    }

    /// A vector of length `length` in a random direction.
    protocol::vec3 direction(double length)
    {
        std::normal_distribution<double> normal;
        protocol::vec3 v{normal(random_), normal(random_), normal(random_)};
        double const norm = std::hypot(v[0], v[1], v[2]);
        for (double& x : v)
            x = norm > 0.0 ? x / norm * length : 0.0;
        return v;
    }

    connection& link_;
    std::mt19937_64 random_;
    std::optional<std::uint64_t> spawn_ref_; ///< a spawn not yet answered
    std::optional<std::uint64_t> body_;      ///< the body it spawned and pushes
    int pushes_ = 0;
};

void check(load_options const& o)
{
    if (o.clients < 1 || o.clients > max_load_clients)
        throw std::invalid_argument("clients must be from 1 to " +
                                    std::to_string(max_load_clients));
    if (!(o.duration > 0.0 && o.duration <= max_load_duration))
        throw std::invalid_argument("duration must be above 0 and at most " +
                                    std::to_string(static_cast<int>(max_load_duration)) + " s");
    if (!(o.commands_per_second >= 0.0 && o.commands_per_second <= max_commands_per_second))
        throw std::invalid_argument("commands per second must be from 0 to " +
                                    std::to_string(static_cast<int>(max_commands_per_second)));
}

bool stop_requested(load_options const& o)
{
    return o.stop_requested && o.stop_requested();
}

double per_second(std::uint64_t count, double seconds)
{
    return seconds > 0.0 ? static_cast<double>(count) / seconds : 0.0;
}

double ms(double seconds)
{
    return seconds * 1000.0;
}

std::uint64_t error_count(connection_stats const& s)
{
    std::uint64_t n = 0;
    for (auto const& [code, count] : s.errors)
        n += count;
    return n;
}

std::string describe(close_info const& info)
{
    std::string text = info.code != 0 ? std::to_string(info.code) : std::string("dropped");
    if (!info.reason.empty())
        text += " (" + info.reason + ")";
    return text;
}

/// The counters of every client added up (tick gaps: the extremes).
connection_stats total_of(load_report const& report)
{
    connection_stats total;
    bool first = true;
    for (auto const& c : report.clients) {
        if (!c.connected())
            continue;
        auto const& s = c.stats;
        total.snapshots += s.snapshots;
        total.bytes_received += s.bytes_received;
        total.bytes_sent += s.bytes_sent;
        total.commands_sent += s.commands_sent;
        total.acks += s.acks;
        total.pongs += s.pongs;
        total.late_snapshots += s.late_snapshots;
        for (auto const& [code, count] : s.errors)
            total.errors[code] += count;
        total.ack_latency.merge(s.ack_latency);
        total.pong_latency.merge(s.pong_latency);
        if (s.tick_gaps > 0) {
            total.tick_gap_min =
                first ? s.tick_gap_min : std::min(total.tick_gap_min, s.tick_gap_min);
            total.tick_gap_max = std::max(total.tick_gap_max, s.tick_gap_max);
            total.tick_gaps += s.tick_gaps;
            first = false;
        }
    }
    return total;
}

json latency_json(latency_histogram const& h)
{
    if (h.count() == 0)
        return nullptr;
    return {{"count", h.count()},
            {"p50_ms", ms(h.quantile(0.5))},
            {"p99_ms", ms(h.quantile(0.99))},
            {"max_ms", ms(h.max())}};
}

json stats_json(connection_stats const& s, double seconds)
{
    return {{"snapshots", s.snapshots},
            {"snapshots_per_second", per_second(s.snapshots, seconds)},
            {"tick_gap_min", s.tick_gap_min},
            {"tick_gap_max", s.tick_gap_max},
            {"late_snapshots", s.late_snapshots},
            {"commands", s.commands_sent},
            {"acks", s.acks},
            {"pongs", s.pongs},
            {"ack_latency", latency_json(s.ack_latency)},
            {"pong_latency", latency_json(s.pong_latency)},
            {"bytes_received_per_second", per_second(s.bytes_received, seconds)},
            {"bytes_sent_per_second", per_second(s.bytes_sent, seconds)},
            {"errors", error_count(s)},
            {"errors_by_code", s.errors},
            {"undecodable", s.undecodable}};
}

} // namespace

double load_client_report::snapshots_per_second() const
{
    return per_second(stats.snapshots, seconds);
}

bool load_report::ok() const
{
    return std::all_of(clients.begin(), clients.end(), [](load_client_report const& c) {
        return c.connected() && !c.disconnected;
    });
}

load_report run_load(load_options options)
{
    check(options);
    load_report report;
    report.options = options;

    // Connect every client (one at a time: each waits for its welcome).
    std::vector<std::unique_ptr<connection>> links(options.clients);
    report.clients.resize(options.clients);
    for (std::size_t i = 0; i < options.clients && !stop_requested(options); ++i) {
        auto& r = report.clients[i];
        r.number = i + 1;
        connection_options o;
        o.name = "kugel-client load " + std::to_string(i + 1);
        o.snapshot_queue = 1; // counted on the I/O thread; nobody takes them
        o.kept_replies = 64;  // only spawn answers are looked at, at once
        try {
            links[i] = std::make_unique<connection>(options.url, std::move(o));
            r.client_id = links[i]->welcome().client;
            if (report.tick_rate == 0.0) {
                report.tick_rate = links[i]->welcome().tick_rate;
                report.snapshot_rate = links[i]->welcome().snapshot_rate;
            }
        } catch (connection_error const& e) {
            r.connect_error = e.what();
        }
    }

    for (std::size_t i = 0; i < options.clients; ++i)
        if (!links[i] && report.clients[i].connect_error.empty()) {
            report.clients[i].number = i + 1;
            report.clients[i].connect_error = "stopped before it connected";
        }

    // Run: send at the given rate, client after client, staggered over one period.
    auto const started = clock::now();
    auto const end = started + std::chrono::duration_cast<clock::duration>(
                                   std::chrono::duration<double>(options.duration));
    std::vector<std::unique_ptr<traffic>> senders(options.clients);
    std::vector<clock::time_point> next_send(options.clients, clock::time_point::max());
    bool const sending = options.commands_per_second > 0.0;
    auto const period = sending
                            ? std::chrono::duration_cast<clock::duration>(
                                  std::chrono::duration<double>(1.0 / options.commands_per_second))
                            : clock::duration::max();
    for (std::size_t i = 0; i < options.clients && sending; ++i) {
        if (!links[i])
            continue;
        senders[i] = std::make_unique<traffic>(*links[i], options.seed + i);
        next_send[i] = started + period * static_cast<long>(i) / static_cast<long>(options.clients);
    }
    for (;;) {
        auto const due = std::min_element(next_send.begin(), next_send.end());
        // Wake at least every 50 ms to notice a stop request.
        auto const wake = std::min({*due, end, clock::now() + std::chrono::milliseconds(50)});
        std::this_thread::sleep_until(wake);
        if (clock::now() >= end || stop_requested(options))
            break;
        if (*due > clock::now())
            continue;
        auto const i = static_cast<std::size_t>(due - next_send.begin());
        try {
            if (links[i]->is_open())
                senders[i]->send_next();
        } catch (connection_error const&) {
            // Ended, or not writing: its report says so; the others go on.
        }
        // Behind by more than a period (a slow machine)? Skip ahead rather than burst.
        next_send[i] = std::max(next_send[i] + period, clock::now() - period);
    }
    auto const finished = clock::now();
    report.stopped_early = finished < end;
    report.seconds = std::chrono::duration<double>(finished - started).count();

    // Count before closing, so that the close is not taken for a disconnect.
    for (std::size_t i = 0; i < options.clients; ++i) {
        if (!links[i])
            continue;
        auto& r = report.clients[i];
        r.stats = links[i]->stats();
        r.seconds = std::chrono::duration<double>(finished - r.stats.opened).count();
        r.disconnected = links[i]->closed_with();
    }
    // Remove the bodies still held (waiting a little for the answers, so that the removes
    // are applied before the connections close), then close.
    std::vector<std::pair<std::size_t, std::uint64_t>> removes;
    for (std::size_t i = 0; i < options.clients; ++i) {
        if (!senders[i] || !links[i]->is_open())
            continue;
        try {
            if (auto const ref = senders[i]->remove_body())
                removes.emplace_back(i, *ref);
        } catch (connection_error const&) {
        }
    }
    auto const patience = clock::now() + std::chrono::seconds(1);
    for (auto const& [i, ref] : removes)
        links[i]->await_reply(ref, std::chrono::duration_cast<std::chrono::milliseconds>(
                                       std::max(clock::duration::zero(), patience - clock::now())));
    for (auto& link : links)
        if (link)
            link->close();
    return report;
}

void print_report(load_report const& report, std::ostream& out)
{
    auto const& o = report.options;
    std::array<char, 512> line{};
    auto const print = [&](char const* format, auto... values) {
        std::snprintf(line.data(), line.size(), format, values...);
        out << line.data();
    };
    if (o.commands_per_second > 0.0)
        print("load: %zu clients for %.1f s on %s, %g commands/s per client\n", o.clients,
              report.seconds, o.url.c_str(), o.commands_per_second);
    else
        print("load: %zu clients for %.1f s on %s, watching only\n", o.clients, report.seconds,
              o.url.c_str());
    if (report.tick_rate > 0.0)
        print("server: %g ticks/s, %g snapshots/s\n", report.tick_rate, report.snapshot_rate);
    if (report.stopped_early)
        out << "stopped early\n";
    print("%6s %6s %9s %8s %7s %5s %8s %6s %22s %10s %10s %6s  %s\n", "client", "id", "snapshots",
          "snaps/s", "gap", "late", "commands", "acks", "ack ms p50/p99/max", "recv kB/s",
          "sent kB/s", "errors", "disconnected");
    auto const row = [&](std::string const& name, std::string const& id, connection_stats const& s,
                         double seconds, std::string const& ended) {
        std::string latency = "-";
        if (s.ack_latency.count() > 0) {
            std::array<char, 64> text{};
            std::snprintf(text.data(), text.size(), "%.1f/%.1f/%.1f",
                          ms(s.ack_latency.quantile(0.5)), ms(s.ack_latency.quantile(0.99)),
                          ms(s.ack_latency.max()));
            latency = text.data();
        }
        std::string const gap =
            s.tick_gaps > 0 ? std::to_string(s.tick_gap_min) + "-" + std::to_string(s.tick_gap_max)
                            : "-";
        print("%6s %6s %9llu %8.2f %7s %5llu %8llu %6llu %22s %10.1f %10.2f %6llu  %s\n",
              name.c_str(), id.c_str(), static_cast<unsigned long long>(s.snapshots),
              per_second(s.snapshots, seconds), gap.c_str(),
              static_cast<unsigned long long>(s.late_snapshots),
              static_cast<unsigned long long>(s.commands_sent),
              static_cast<unsigned long long>(s.acks), latency.c_str(),
              per_second(s.bytes_received, seconds) / 1000.0,
              per_second(s.bytes_sent, seconds) / 1000.0,
              static_cast<unsigned long long>(error_count(s)), ended.c_str());
    };
    for (auto const& c : report.clients) {
        if (!c.connected()) {
            print("%6zu  not connected: %s\n", c.number, c.connect_error.c_str());
            continue;
        }
        row(std::to_string(c.number), std::to_string(c.client_id), c.stats, c.seconds,
            c.disconnected ? describe(*c.disconnected) : "no");
    }
    connection_stats const total = total_of(report);
    std::size_t const connected = static_cast<std::size_t>(std::count_if(
        report.clients.begin(), report.clients.end(), [](auto const& c) { return c.connected(); }));
    std::size_t const dropped = static_cast<std::size_t>(
        std::count_if(report.clients.begin(), report.clients.end(),
                      [](auto const& c) { return c.disconnected.has_value(); }));
    row("total", "", total, report.seconds,
        std::to_string(dropped) + " of " + std::to_string(connected));
    for (auto const& [code, count] : total.errors)
        print("errors %s: %llu\n", code.c_str(), static_cast<unsigned long long>(count));
    if (total.pong_latency.count() > 0)
        print(
            "pong ms p50/p99/max: %.1f/%.1f/%.1f (%llu pings, sent while a spawn was unanswered)\n",
            ms(total.pong_latency.quantile(0.5)), ms(total.pong_latency.quantile(0.99)),
            ms(total.pong_latency.max()), static_cast<unsigned long long>(total.pongs));
}

json report_json(load_report const& report)
{
    json clients = json::array();
    for (auto const& c : report.clients) {
        json entry = {{"client", c.number}, {"connected", c.connected()}};
        if (!c.connected()) {
            entry["connect_error"] = c.connect_error;
        } else {
            entry["id"] = c.client_id;
            entry["seconds"] = c.seconds;
            entry.update(stats_json(c.stats, c.seconds));
            entry["disconnected"] =
                c.disconnected ? json(describe(*c.disconnected)) : json(nullptr);
        }
        clients.push_back(std::move(entry));
    }
    return {{"url", report.options.url},
            {"clients", report.options.clients},
            {"duration", report.options.duration},
            {"commands_per_second", report.options.commands_per_second},
            {"seconds", report.seconds},
            {"stopped_early", report.stopped_early},
            {"tick_rate", report.tick_rate},
            {"snapshot_rate", report.snapshot_rate},
            {"ok", report.ok()},
            {"per_client", std::move(clients)},
            {"total", stats_json(total_of(report), report.seconds)}};
}

} // namespace kugel::client
