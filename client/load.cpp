#include "load.hpp"

#include "stalled_connection.hpp"

#include <sys/resource.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <future>
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
            last_ref_ = link_.send(protocol::ping{});
        } else if (!body_) {
            spawn_ref_ = link_.send(spawn());
            last_ref_ = spawn_ref_;
            pushes_ = 0;
        } else if (pushes_ < pushes_per_body) {
            ++pushes_;
            last_ref_ = link_.send(protocol::impulse{0, *body_, direction(0.01)});
        } else {
            last_ref_ = link_.send(protocol::remove{0, *std::exchange(body_, std::nullopt)});
        }
    }

    /// Getting ready to leave, called until it returns true: once its spawn is answered it
    /// removes the body it holds, and it is ready when the last command it sent is answered
    /// (a room applies a client's commands in order, and skips those of a client that has
    /// gone, so closing earlier could leave a body behind).
    bool leave()
    {
        take_spawn_answer();
        if (spawn_ref_)
            return false;
        if (body_)
            last_ref_ = link_.send(protocol::remove{0, *std::exchange(body_, std::nullopt)});
        if (last_ref_) {
            if (!link_.await_reply(*last_ref_, std::chrono::milliseconds(0)))
                return false;
            last_ref_.reset();
        }
        return true;
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
        protocol::welcome const w = link_.welcome();
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
    std::optional<std::uint64_t> last_ref_;  ///< the last command sent, until leave() saw its answer
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
    if (!(o.reconnects_per_second >= 0.0 && o.reconnects_per_second <= max_reconnects_per_second))
        throw std::invalid_argument("reconnects per second must be from 0 to " +
                                    std::to_string(static_cast<int>(max_reconnects_per_second)));
    if (o.stalled > max_stalled_clients)
        throw std::invalid_argument("stalled clients must be at most " +
                                    std::to_string(max_stalled_clients));
}

/// Raises the soft limit on open files to what the clients need, as far as the hard limit
/// allows; throws std::invalid_argument naming the figure when that is not enough.
void ensure_file_descriptors(load_options const& o)
{
    // Reconnects overlap a little: the old connection closes while the new one opens.
    rlim_t const needed =
        static_cast<rlim_t>((o.clients + o.stalled) * file_descriptors_per_client + 64);
    rlimit limit{};
    if (getrlimit(RLIMIT_NOFILE, &limit) != 0 || limit.rlim_cur >= needed)
        return;
    if (limit.rlim_max == RLIM_INFINITY || limit.rlim_max >= needed) {
        limit.rlim_cur = needed;
        if (setrlimit(RLIMIT_NOFILE, &limit) == 0)
            return;
    }
    throw std::invalid_argument(std::to_string(o.clients + o.stalled) + " clients need about " +
                                std::to_string(needed) + " open files, and the limit is " +
                                std::to_string(limit.rlim_max) + ": raise it (ulimit -n " +
                                std::to_string(needed) + ", as root or in limits.conf)");
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

/// Adds one connection's counters to a total (tick gaps: the extremes).
void add(connection_stats& total, connection_stats const& s)
{
    total.messages_received += s.messages_received;
    total.messages_sent += s.messages_sent;
    total.snapshots += s.snapshots;
    total.snapshots_dropped += s.snapshots_dropped;
    total.bytes_received += s.bytes_received;
    total.bytes_sent += s.bytes_sent;
    total.commands_sent += s.commands_sent;
    total.acks += s.acks;
    total.pongs += s.pongs;
    total.late_snapshots += s.late_snapshots;
    total.ignored += s.ignored;
    total.undecodable += s.undecodable;
    total.events += s.events;
    total.events_missed += s.events_missed;
    for (auto const& [code, count] : s.errors)
        total.errors[code] += count;
    total.ack_latency.merge(s.ack_latency);
    total.pong_latency.merge(s.pong_latency);
    if (s.tick_gaps > 0) {
        total.tick_gap_min =
            total.tick_gaps == 0 ? s.tick_gap_min : std::min(total.tick_gap_min, s.tick_gap_min);
        total.tick_gap_max = std::max(total.tick_gap_max, s.tick_gap_max);
        total.tick_gaps += s.tick_gaps;
    }
}

/// The counters of every client added up.
connection_stats total_of(load_report const& report)
{
    connection_stats total;
    for (auto const& c : report.clients)
        if (c.connected())
            add(total, c.stats);
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
            {"undecodable", s.undecodable},
            {"events", s.events},
            {"events_missed", s.events_missed}};
}

} // namespace

double load_client_report::snapshots_per_second() const
{
    return per_second(stats.snapshots, seconds);
}

std::size_t load_report::connections() const
{
    std::size_t n = 0;
    for (auto const& c : clients)
        n += c.connections;
    return n;
}

std::size_t load_report::silent_connections() const
{
    std::size_t n = 0;
    for (auto const& c : clients)
        n += c.silent_connections;
    return n;
}

bool load_report::ok() const
{
    return std::all_of(clients.begin(), clients.end(), [](load_client_report const& c) {
        return c.connected() && !c.disconnected && c.silent_connections == 0;
    });
}

namespace {

/// One client of a load: its connection, its traffic and what it has seen.
struct load_client
{
    std::unique_ptr<connection> link;
    std::unique_ptr<traffic> sender;
    clock::time_point next_send = clock::time_point::max();
    std::optional<clock::time_point> leaving_until; ///< churn: leaving, closed by then at the latest
    std::size_t reconnects = 0;
};

connection_options load_connection_options(std::size_t number, load_options const& options)
{
    connection_options o;
    o.name = "kugel-client load " + std::to_string(number);
    // Unless asked: a thousand load clients told of each other's churn would measure that
    o.players = options.players;
    if (options.events)
        o.events = protocol::event_request{}; // every event; counted, the oldest dropped unread
    o.snapshot_ticks_only = true; // counted on the I/O thread; nobody takes them
    o.snapshots = options.snapshots;
    o.kept_replies = 64;  // only spawn answers and the last command's are looked at, at once
    return o;
}

/// Files what a connection saw into its client's report, before it is closed (so that the
/// close is not taken for a disconnect).
void take_stats(load_client_report& r, connection const& link)
{
    connection_stats const s = link.stats();
    add(r.stats, s);
    if (s.snapshots == 0)
        ++r.silent_connections;
    if (!r.disconnected)
        r.disconnected = link.closed_with(); // it ended by itself: we have not closed it yet
}

} // namespace

load_report run_load(load_options options)
{
    check(options);
    ensure_file_descriptors(options);
    load_report report;
    report.options = options;
    std::size_t const n = options.clients;
    // Declared first, so that every connection (and every close below) ends before it.
    io_threads io(std::max(1U, std::thread::hardware_concurrency()));

    // Connect every client (one at a time: each waits for its welcome).
    std::vector<load_client> clients(n);
    report.clients.resize(n);
    for (std::size_t i = 0; i < n && !stop_requested(options); ++i) {
        auto& r = report.clients[i];
        r.number = i + 1;
        try {
            clients[i].link = std::make_unique<connection>(options.url, load_connection_options(i + 1, options), io);
            r.client_id = clients[i].link->welcome().client;
            r.stats.opened = clients[i].link->stats().opened;
            r.connections = 1;
            if (report.tick_rate == 0.0) {
                report.tick_rate = clients[i].link->welcome().tick_rate;
                report.snapshot_rate = clients[i].link->welcome().snapshot_rate;
            }
        } catch (connection_error const& e) {
            r.connect_error = e.what();
        }
    }
    for (std::size_t i = 0; i < n; ++i)
        if (!clients[i].link && report.clients[i].connect_error.empty()) {
            report.clients[i].number = i + 1;
            report.clients[i].connect_error = "stopped before it connected";
        }

    // The stalled connections: a welcome each, then nothing is read.
    std::vector<std::unique_ptr<stalled_connection>> stalled(options.stalled);
    report.stalled.resize(options.stalled);
    for (std::size_t k = 0; k < options.stalled && !stop_requested(options); ++k) {
        try {
            stalled[k] = std::make_unique<stalled_connection>(options.url, std::chrono::seconds(10));
            report.stalled[k].client_id = stalled[k]->client_id();
        } catch (connection_error const& e) {
            report.stalled[k].connect_error = e.what();
        }
    }

    // Run: send at the given rate, client after client, staggered over one period; churn
    // at its rate, clients in turn.
    auto const started = clock::now();
    auto const end = started + std::chrono::duration_cast<clock::duration>(
                                   std::chrono::duration<double>(options.duration));
    auto const period_of = [](double rate) {
        return rate > 0.0 ? std::chrono::duration_cast<clock::duration>(
                                std::chrono::duration<double>(1.0 / rate))
                          : clock::duration::max();
    };
    bool const sending = options.commands_per_second > 0.0;
    auto const period = period_of(options.commands_per_second);
    auto const start_sending = [&](std::size_t i, clock::time_point first) {
        auto& c = clients[i];
        if (!sending || !c.link)
            return;
        c.sender = std::make_unique<traffic>(*c.link, options.seed + i + n * c.reconnects);
        c.next_send = first;
    };
    for (std::size_t i = 0; i < n && sending; ++i)
        start_sending(i, started + period * static_cast<long>(i) / static_cast<long>(n));

    bool const churning = options.reconnects_per_second > 0.0;
    auto const churn_period = period_of(options.reconnects_per_second);
    auto next_churn = churning ? started + churn_period : clock::time_point::max();
    std::size_t churn_cursor = 0;
    std::vector<std::size_t> leaving;        // clients getting ready to reconnect
    std::vector<std::future<void>> closing; // connections closing off this thread
    constexpr auto leave_patience = std::chrono::seconds(2);

    // Churn, first half: the next client (in turn) whose connection has had a snapshot
    // stops sending and gets ready to leave.
    auto const begin_leaving = [&] {
        for (std::size_t k = 0; k < n; ++k) {
            std::size_t const i = (churn_cursor + k) % n;
            auto& c = clients[i];
            if (!c.link || !c.link->is_open() || c.leaving_until || c.link->stats().snapshots == 0)
                continue;
            c.leaving_until = clock::now() + leave_patience;
            c.next_send = clock::time_point::max();
            leaving.push_back(i);
            churn_cursor = i + 1;
            return;
        }
    };
    // Second half: once ready (or out of patience), closed off this thread and connected
    // again.
    auto const finish_leaving = [&](std::size_t i) {
        auto& c = clients[i];
        auto& r = report.clients[i];
        take_stats(r, *c.link);
        c.sender.reset();
        closing.push_back(std::async(std::launch::async, [link = std::move(c.link)]() mutable {
            link->close();
            link.reset();
        }));
        c.leaving_until.reset();
        ++c.reconnects;
        try {
            c.link = std::make_unique<connection>(options.url, load_connection_options(i + 1, options), io);
            r.client_id = c.link->welcome().client;
            ++r.connections;
            if (sending)
                start_sending(i, clock::now() + period);
        } catch (connection_error const& e) {
            if (!r.disconnected)
                r.disconnected = close_info{0, std::string("reconnect failed: ") + e.what(), true};
        }
        std::erase_if(closing, [](std::future<void>& f) {
            return f.wait_for(std::chrono::seconds(0)) == std::future_status::ready;
        });
    };

    for (;;) {
        auto const due = std::min_element(clients.begin(), clients.end(), [](auto const& a, auto const& b) {
            return a.next_send < b.next_send;
        });
        auto const next_due = due == clients.end() ? clock::time_point::max() : due->next_send;
        // Wake at least every 50 ms to notice a stop request, and every 10 ms while
        // clients are leaving.
        auto const nap = leaving.empty() ? std::chrono::milliseconds(50) : std::chrono::milliseconds(10);
        auto const wake = std::min({next_due, next_churn, end, clock::now() + nap});
        std::this_thread::sleep_until(wake);
        auto const now = clock::now();
        if (now >= end || stop_requested(options))
            break;
        if (next_churn <= now) {
            begin_leaving();
            next_churn = std::max(next_churn + churn_period, now - churn_period);
        }
        std::erase_if(leaving, [&](std::size_t i) {
            bool ready = true;
            try {
                ready = !clients[i].sender || !clients[i].link->is_open() || clients[i].sender->leave();
            } catch (connection_error const&) {
            }
            if (!ready && clock::now() < *clients[i].leaving_until)
                return false;
            finish_leaving(i);
            return true;
        });
        // Every client that is due sends, not only the first: a wake-up late by many
        // periods (a reconnect above waits for its welcome; a busy machine) would otherwise
        // send one command where a hundred were due. The churn above may have taken a
        // client out of sending (next_send at the end of time).
        for (auto& c : clients) {
            if (c.next_send > now)
                continue;
            try {
                if (c.link && c.link->is_open())
                    c.sender->send_next();
            } catch (connection_error const&) {
                // Ended, or not writing: its report says so; the others go on.
            }
            // Behind by more than a period (a slow machine)? Skip ahead rather than burst.
            c.next_send = std::max(c.next_send + period, clock::now() - period);
        }
    }
    auto const finished = clock::now();
    report.stopped_early = finished < end;
    report.seconds = std::chrono::duration<double>(finished - started).count();

    // A connection made late in the run may not have had its first snapshot yet: give each
    // up to 10 s more (the room sends one every 1/snapshot_rate s; a client that gets none
    // in that time is not being served).
    auto const patience = clock::now() + std::chrono::seconds(10);
    for (auto& c : clients)
        while (c.link && c.link->is_open() && c.link->stats().snapshots == 0 &&
               clock::now() < patience && !stop_requested(options))
            std::this_thread::sleep_for(std::chrono::milliseconds(10));

    // Count before closing, so that the close is not taken for a disconnect.
    for (std::size_t i = 0; i < n; ++i) {
        auto& r = report.clients[i];
        if (clients[i].link)
            take_stats(r, *clients[i].link);
        if (r.connections > 0)
            r.seconds = std::chrono::duration<double>(finished - r.stats.opened).count();
    }
    // Was each stalled connection dropped? Read them all at once, up to 5 s.
    {
        std::vector<std::future<bool>> verdicts;
        for (auto& link : stalled)
            verdicts.push_back(std::async(std::launch::async, [&link] {
                return link && link->dropped(std::chrono::seconds(5));
            }));
        for (std::size_t k = 0; k < stalled.size(); ++k)
            report.stalled[k].dropped = verdicts[k].get();
    }
    // Remove the bodies still held (waiting a little for the answers, so that the removes
    // are applied before the connections close), then close.
    std::vector<std::pair<std::size_t, std::uint64_t>> removes;
    for (std::size_t i = 0; i < n; ++i) {
        auto& c = clients[i];
        if (!c.sender || !c.link || !c.link->is_open())
            continue;
        try {
            if (auto const ref = c.sender->remove_body())
                removes.emplace_back(i, *ref);
        } catch (connection_error const&) {
        }
    }
    auto const answer_patience = clock::now() + std::chrono::seconds(1);
    for (auto const& [i, ref] : removes)
        clients[i].link->await_reply(ref, std::chrono::duration_cast<std::chrono::milliseconds>(std::max(
                                              clock::duration::zero(), answer_patience - clock::now())));
    for (auto& c : clients)
        if (c.link)
            c.link->close();
    for (auto& f : closing)
        f.wait();
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
    if (o.reconnects_per_second > 0.0)
        print("churn: %g reconnects/s over all clients\n", o.reconnects_per_second);
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
    if (o.events)
        print("events: %llu received (%.2f/s per client), %llu dropped by the server\n",
              static_cast<unsigned long long>(total.events),
              connected > 0 ? per_second(total.events, report.seconds) / static_cast<double>(connected) : 0.0,
              static_cast<unsigned long long>(total.events_missed));
    print("connections: %zu opened (%zu reconnects), %zu without a snapshot\n",
          report.connections(), report.connections() - connected, report.silent_connections());
    for (auto const& c : report.clients)
        if (c.silent_connections > 0)
            print("client %zu: %zu connections without a snapshot\n", c.number, c.silent_connections);
    if (!report.stalled.empty()) {
        std::size_t const dropped_stalled = static_cast<std::size_t>(
            std::count_if(report.stalled.begin(), report.stalled.end(), [](auto const& c) { return c.dropped; }));
        print("stalled: %zu connections that stopped reading after their welcome, %zu dropped by the server\n",
              report.stalled.size(), dropped_stalled);
        for (auto const& c : report.stalled)
            if (!c.connected())
                print("stalled: not connected: %s\n", c.connect_error.c_str());
    }
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
            entry["connections"] = c.connections;
            entry["silent_connections"] = c.silent_connections;
        }
        clients.push_back(std::move(entry));
    }
    json stalled = json::array();
    for (auto const& c : report.stalled) {
        json entry = {{"connected", c.connected()}, {"dropped", c.dropped}};
        if (c.connected())
            entry["id"] = c.client_id;
        else
            entry["connect_error"] = c.connect_error;
        stalled.push_back(std::move(entry));
    }
    return {{"url", report.options.url},
            {"clients", report.options.clients},
            {"duration", report.options.duration},
            {"commands_per_second", report.options.commands_per_second},
            {"reconnects_per_second", report.options.reconnects_per_second},
            {"players", report.options.players},
            {"events", report.options.events},
            {"connections", report.connections()},
            {"silent_connections", report.silent_connections()},
            {"stalled", std::move(stalled)},
            {"seconds", report.seconds},
            {"stopped_early", report.stopped_early},
            {"tick_rate", report.tick_rate},
            {"snapshot_rate", report.snapshot_rate},
            {"ok", report.ok()},
            {"per_client", std::move(clients)},
            {"total", stats_json(total_of(report), report.seconds)}};
}

} // namespace kugel::client
