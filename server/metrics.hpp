#pragma once

#include "protocol/error_code.hpp"

#include <array>
#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace kugel::server {

/// Tick durations (a tick's cost, or how late it started) as a Prometheus histogram.
/// Written on the room's strand, read by any thread: every field is an atomic counter, updated with relaxed ordering (a scrape may see
/// one tick half recorded, which a monitoring system cannot tell from a tick a moment later).
class tick_histogram
{
public:
    /// Upper bounds of the buckets, s. A tick at 60 Hz has 16.7 ms.
    static constexpr std::array<double, 11> upper_bounds{0.0001, 0.00025, 0.0005, 0.001, 0.0025, 0.005,
                                                         0.01,   0.0167,  0.025,  0.05,  0.1};

    void record(std::chrono::steady_clock::duration cost);

    struct reading
    {
        std::array<std::uint64_t, upper_bounds.size() + 1> cumulative{}; ///< the last is +Inf
        double sum = 0.0;                                                 ///< s
        std::uint64_t count() const { return cumulative.back(); }
    };
    reading read() const;

private:
    std::array<std::atomic<std::uint64_t>, upper_bounds.size() + 1> counts_{}; ///< per bucket, not cumulative
    std::atomic<std::uint64_t> sum_ns_{0};
};

/// How late a room's ticks start against their schedule (due = the previous due time plus
/// one period): timer slack, busy threads, and the backlog of ticks that cost more than a
/// period. A tick more than one period late has let the world fall a whole tick behind the
/// clock. Written on the room's strand, read by any thread (relaxed atomics).
class tick_lateness
{
public:
    /// A tick that started `lateness` after it was due (negative counts as 0), at a tick
    /// period of `period`.
    void record(std::chrono::steady_clock::duration lateness, std::chrono::steady_clock::duration period);
    /// Ticks not run at all (the room dropped a backlog `lateness` behind): the largest
    /// lateness only; the dropped ticks are room_counters::late_ticks.
    void record_backlog(std::chrono::steady_clock::duration lateness);

    tick_histogram const& histogram() const { return histogram_; }
    /// Ticks that started more than one period after they were due.
    std::uint64_t behind() const { return behind_.load(std::memory_order_relaxed); }
    /// The largest lateness seen, s.
    double max_seconds() const;

private:
    void keep_max(std::chrono::steady_clock::duration lateness);

    tick_histogram histogram_;
    std::atomic<std::uint64_t> behind_{0};
    std::atomic<std::int64_t> max_ns_{0};
};

/// The forms a snapshot is sent in: the full form, and the compact form's keyframes and
/// deltas (protocol/PROTOCOL.md).
enum class snapshot_form : std::size_t { full, keyframe, delta };
inline constexpr std::array<std::string_view, 3> snapshot_form_names{"full", "keyframe", "delta"};

/// Snapshots and their bytes by form: a relaxed atomic count each.
struct snapshot_form_counters
{
    std::array<std::atomic<std::uint64_t>, snapshot_form_names.size()> snapshots{};
    std::array<std::atomic<std::uint64_t>, snapshot_form_names.size()> bytes{};

    void count(snapshot_form form, std::size_t message_bytes);
};

/// What a room's sessions send and receive, for /metrics. Each session adds to its room's
/// counters from its own strand (relaxed atomics: counts, not synchronisation).
struct traffic_counters
{
    std::atomic<std::uint64_t> messages_in{0};       ///< frames read from clients
    std::atomic<std::uint64_t> replies_out{0};       ///< welcome, ack, error, pong handed to a socket
    std::atomic<std::uint64_t> snapshots_out{0};     ///< snapshots handed to a socket
    std::atomic<std::uint64_t> bytes_out{0};         ///< their payload bytes
    std::atomic<std::uint64_t> snapshots_dropped{0}; ///< replaced unsent in a slow client's slot
    std::atomic<std::uint64_t> stalled_clients{0};   ///< disconnected: a send pending past write_stall
    /// unsent player notices replaced by one roster (a crowd joined faster than a client read)
    std::atomic<std::uint64_t> player_messages_merged{0};
    std::atomic<std::uint64_t> events_out{0};     ///< sensor events handed to a socket
    /// sensor events dropped because a client had max_queued_events unsent
    std::atomic<std::uint64_t> events_dropped{0};
    snapshot_form_counters sent;    ///< snapshots handed to a socket, by form
    snapshot_form_counters encoded; ///< snapshots encoded (once for all sessions), by form
    std::array<std::atomic<std::uint64_t>, protocol::all_error_codes.size()> rejected{};

    void count_rejected(protocol::error_code code);
};

/// Adds `n` to a counter, relaxed.
inline void bump(std::atomic<std::uint64_t>& counter, std::uint64_t n = 1)
{
    counter.fetch_add(n, std::memory_order_relaxed);
}

/// Writes Prometheus' text exposition format (version 0.0.4): # HELP and # TYPE once per
/// metric, then one `name{labels} value` line per series.
class metrics_text
{
public:
    struct family
    {
        std::string_view name;
        std::string_view type; ///< counter, gauge, histogram
        std::string_view help;
    };

    /// Starts a metric; its samples follow.
    void begin(family const& f);
    /// `name{labels} value`; labels as pairs, their values escaped here.
    void sample(std::string_view name,
                std::initializer_list<std::pair<std::string_view, std::string_view>> labels,
                double value);
    void sample(std::string_view name,
                std::initializer_list<std::pair<std::string_view, std::string_view>> labels,
                std::uint64_t value);

    std::string const& text() const { return out_; }

private:
    void labels(std::initializer_list<std::pair<std::string_view, std::string_view>> labels);
    std::string out_;
};

/// The content type of metrics_text.
inline constexpr std::string_view metrics_content_type = "text/plain; version=0.0.4; charset=utf-8";

class room;

/// The body of GET /metrics: every room's ticks, clients, bodies and traffic.
std::string prometheus_metrics(std::vector<std::shared_ptr<room const>> const& rooms);

} // namespace kugel::server
