#include "metrics.hpp"

#include "room.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>

namespace kugel::server {

namespace {

std::string number_text(double x)
{
    if (std::isnan(x))
        return "NaN";
    if (std::isinf(x))
        return x > 0 ? "+Inf" : "-Inf";
    std::array<char, 32> buffer{};
    auto const [end, ec] = std::to_chars(buffer.data(), buffer.data() + buffer.size(), x,
                                                std::chars_format::general); // 0.0001, not 1e-04
    return std::string(buffer.data(), end);
}

/// A label value in the exposition format: backslash, double quote and newline escaped.
void append_escaped(std::string& out, std::string_view value)
{
    for (char const c : value) {
        if (c == '\\')
            out += "\\\\";
        else if (c == '"')
            out += "\\\"";
        else if (c == '\n')
            out += "\\n";
        else
            out += c;
    }
}

} // namespace

void snapshot_form_counters::count(snapshot_form form, std::size_t message_bytes)
{
    bump(snapshots[static_cast<std::size_t>(form)]);
    bump(bytes[static_cast<std::size_t>(form)], message_bytes);
}

void tick_histogram::record(std::chrono::steady_clock::duration cost)
{
    double const seconds = std::chrono::duration<double>(cost).count();
    std::size_t bucket = 0;
    while (bucket < upper_bounds.size() && seconds > upper_bounds[bucket])
        ++bucket;
    bump(counts_[bucket]);
    bump(sum_ns_, static_cast<std::uint64_t>(
                      std::chrono::duration_cast<std::chrono::nanoseconds>(cost).count()));
}

tick_histogram::reading tick_histogram::read() const
{
    reading r;
    std::uint64_t total = 0;
    for (std::size_t i = 0; i < counts_.size(); ++i) {
        total += counts_[i].load(std::memory_order_relaxed);
        r.cumulative[i] = total;
    }
    r.sum = static_cast<double>(sum_ns_.load(std::memory_order_relaxed)) * 1e-9;
    return r;
}

void tick_lateness::record(std::chrono::steady_clock::duration lateness,
                           std::chrono::steady_clock::duration period)
{
    lateness = std::max(lateness, std::chrono::steady_clock::duration::zero());
    histogram_.record(lateness);
    if (lateness > period)
        bump(behind_);
    keep_max(lateness);
}

void tick_lateness::record_backlog(std::chrono::steady_clock::duration lateness)
{
    keep_max(lateness);
}

void tick_lateness::keep_max(std::chrono::steady_clock::duration lateness)
{
    // Only the room's strand writes: a plain load and store keep the largest.
    auto const ns = std::chrono::duration_cast<std::chrono::nanoseconds>(lateness).count();
    if (ns > max_ns_.load(std::memory_order_relaxed))
        max_ns_.store(ns, std::memory_order_relaxed);
}

double tick_lateness::max_seconds() const
{
    return static_cast<double>(max_ns_.load(std::memory_order_relaxed)) * 1e-9;
}

void traffic_counters::count_rejected(protocol::error_code code)
{
    bump(rejected[static_cast<std::size_t>(code)]);
}

void metrics_text::begin(family const& f)
{
    out_ += "# HELP ";
    out_ += f.name;
    out_ += ' ';
    out_ += f.help;
    out_ += "\n# TYPE ";
    out_ += f.name;
    out_ += ' ';
    out_ += f.type;
    out_ += '\n';
}

void metrics_text::labels(std::initializer_list<std::pair<std::string_view, std::string_view>> labels)
{
    if (labels.size() == 0)
        return;
    out_ += '{';
    bool first = true;
    for (auto const& [name, value] : labels) {
        if (!first)
            out_ += ',';
        first = false;
        out_ += name;
        out_ += "=\"";
        append_escaped(out_, value);
        out_ += '"';
    }
    out_ += '}';
}

void metrics_text::sample(std::string_view name,
                          std::initializer_list<std::pair<std::string_view, std::string_view>> labels,
                          double value)
{
    out_ += name;
    this->labels(labels);
    out_ += ' ';
    out_ += number_text(value);
    out_ += '\n';
}

void metrics_text::sample(std::string_view name,
                          std::initializer_list<std::pair<std::string_view, std::string_view>> labels,
                          std::uint64_t value)
{
    out_ += name;
    this->labels(labels);
    out_ += ' ';
    out_ += std::to_string(value);
    out_ += '\n';
}

std::string prometheus_metrics(std::vector<std::shared_ptr<room const>> const& rooms)
{
    metrics_text m;
    auto const load = [](std::atomic<std::uint64_t> const& counter) {
        return counter.load(std::memory_order_relaxed);
    };
    // One family at a time, a series per room: the format wants a family's lines together.
    auto const per_room = [&](metrics_text::family const& f, auto value_of) {
        m.begin(f);
        for (auto const& r : rooms)
            m.sample(f.name, {{"room", r->name()}}, value_of(*r));
    };

    auto const histogram = [&](metrics_text::family const& f, auto histogram_of) {
        m.begin(f);
        std::string const bucket = std::string(f.name) + "_bucket";
        for (auto const& r : rooms) {
            tick_histogram::reading const h = histogram_of(*r).read();
            for (std::size_t i = 0; i < tick_histogram::upper_bounds.size(); ++i)
                m.sample(bucket, {{"room", r->name()}, {"le", number_text(tick_histogram::upper_bounds[i])}},
                         h.cumulative[i]);
            m.sample(bucket, {{"room", r->name()}, {"le", "+Inf"}}, h.count());
            m.sample(std::string(f.name) + "_sum", {{"room", r->name()}}, h.sum);
            m.sample(std::string(f.name) + "_count", {{"room", r->name()}}, h.count());
        }
    };

    histogram({"kugel_tick_duration_seconds", "histogram",
               "Wall-clock time a room's tick took: commands, physics step, copying a snapshot's columns (encoding runs off the tick)."},
              [](room const& r) -> tick_histogram const& { return r.tick_durations(); });
    histogram({"kugel_tick_lateness_seconds", "histogram",
               "How long after it was due a room's tick started (due: the previous tick's due time plus one period)."},
              [](room const& r) -> tick_histogram const& { return r.lateness().histogram(); });
    per_room({"kugel_tick_lateness_max_seconds", "gauge",
              "The latest a room's tick has started after it was due, since the server started (dropped backlogs included)."},
             [&](room const& r) { return r.lateness().max_seconds(); });
    per_room({"kugel_ticks_behind_total", "counter",
              "Ticks a room started more than one tick period after they were due."},
             [&](room const& r) { return r.lateness().behind(); });
    per_room({"kugel_ticks_total", "counter", "Ticks a room has completed."},
             [&](room const& r) { return load(r.counters().ticks); });
    per_room({"kugel_late_ticks_total", "counter",
              "Ticks a room dropped because it fell more than 4 ticks behind its clock."},
             [&](room const& r) { return load(r.counters().late_ticks); });
    per_room({"kugel_step_faults_total", "counter",
              "Steps a room could not take (a singular force, a state beyond a double), each recovered from by removing the bodies at fault."},
             [&](room const& r) { return load(r.counters().step_faults); });
    m.begin({"kugel_step_phase_seconds_total", "counter",
             "Wall-clock time a room's steps spent in each phase (free motion, the discrete mode's passes, the continuous mode, reordering); a scene pays only for the phases its models use."});
    for (auto const& r : rooms)
        for (std::size_t p = 0; p < physics::step_phase_count; ++p)
            m.sample("kugel_step_phase_seconds_total", {{"room", r->name()}, {"phase", physics::step_phase_names[p]}},
                     static_cast<double>(load(r->counters().phase_nanoseconds[p])) * 1e-9);
    per_room({"kugel_swept_bodies_total", "counter",
              "Discrete mode: bodies that moved farther than collisions.sweep_fraction of their radius in a step and were swept through its events."},
             [&](room const& r) { return load(r.counters().swept_bodies); });
    per_room({"kugel_unswept_fast_bodies_total", "counter",
              "Discrete mode: bodies that moved that far and were not swept to the end of their step (the sweep off, an event cap): each a contact that may have been missed. Zero while the sweep is on."},
             [&](room const& r) { return load(r.counters().unswept_fast_bodies); });
    per_room({"kugel_collision_events_total", "counter",
              "Continuous mode (and the discrete mode's sweep): collision events taken in time order."},
             [&](room const& r) { return load(r.counters().collision_events); });
    per_room({"kugel_capped_steps_total", "counter",
              "Continuous steps (or discrete sweeps) that reached an event cap (collisions.max_events_per_step or max_events_per_body) and were finished in discrete mode: not exact there."},
             [&](room const& r) { return load(r.counters().capped_steps); });
    per_room({"kugel_clients", "gauge", "WebSocket clients in a room."},
             [&](room const& r) { return load(r.counters().sessions); });
    per_room({"kugel_players", "gauge", "Players in a room (a connection each)."},
             [&](room const& r) { return load(r.counters().players); });
    per_room({"kugel_bodies", "gauge", "Bodies in a room's world."},
             [&](room const& r) { return load(r.counters().bodies); });
    per_room({"kugel_messages_in_total", "counter", "WebSocket frames read from a room's clients."},
             [&](room const& r) { return load(r.traffic().messages_in); });
    m.begin({"kugel_messages_out_total", "counter",
             "Messages handed to a room's client sockets: kind reply (welcome, ack, error, pong) or snapshot."});
    for (auto const& r : rooms) {
        m.sample("kugel_messages_out_total", {{"room", r->name()}, {"kind", "reply"}}, load(r->traffic().replies_out));
        m.sample("kugel_messages_out_total", {{"room", r->name()}, {"kind", "snapshot"}},
                 load(r->traffic().snapshots_out));
    }
    per_room({"kugel_bytes_out_total", "counter", "Payload bytes of the messages handed to a room's client sockets."},
             [&](room const& r) { return load(r.traffic().bytes_out); });
    auto const by_form = [&](metrics_text::family const& f, auto counts_of) {
        m.begin(f);
        for (auto const& r : rooms)
            for (std::size_t i = 0; i < snapshot_form_names.size(); ++i)
                m.sample(f.name, {{"room", r->name()}, {"form", snapshot_form_names[i]}},
                         load(counts_of(*r)[i]));
    };
    by_form({"kugel_snapshots_sent_total", "counter",
             "Snapshots handed to a room's client sockets, by form: full, or the compact form's keyframe or delta."},
            [](room const& r) -> auto const& { return r.traffic().sent.snapshots; });
    by_form({"kugel_snapshot_bytes_sent_total", "counter",
             "Payload bytes of the snapshots handed to a room's client sockets, by form."},
            [](room const& r) -> auto const& { return r.traffic().sent.bytes; });
    by_form({"kugel_snapshots_encoded_total", "counter",
             "Snapshots a room encoded, by form: each form of a snapshot is encoded at most once, its bytes shared by every client sent it."},
            [](room const& r) -> auto const& { return r.traffic().encoded.snapshots; });
    by_form({"kugel_snapshot_bytes_encoded_total", "counter",
             "Bytes of the snapshots a room encoded, by form."},
            [](room const& r) -> auto const& { return r.traffic().encoded.bytes; });
    per_room({"kugel_snapshots_dropped_total", "counter",
              "Snapshots replaced before they were sent, because a client read slower than they came."},
             [&](room const& r) { return load(r.traffic().snapshots_dropped); });
    per_room({"kugel_snapshots_skipped_total", "counter",
              "Snapshots not taken because the room's previous snapshot was still being encoded."},
             [&](room const& r) { return load(r.counters().snapshots_skipped); });
    per_room({"kugel_stalled_clients_total", "counter",
              "Clients disconnected because a send to them was pending longer than the write-stall bound (they stopped reading)."},
             [&](room const& r) { return load(r.traffic().stalled_clients); });
    per_room({"kugel_player_notices_merged_total", "counter",
              "Times a client's unsent player notices were replaced by one roster of the room's players."},
             [&](room const& r) { return load(r.traffic().player_messages_merged); });
    per_room({"kugel_events_sent_total", "counter",
              "Sensor events (event messages) handed to a room's client sockets."},
             [&](room const& r) { return load(r.traffic().events_out); });
    per_room({"kugel_events_dropped_total", "counter",
              "Sensor events not sent because the client had as many unsent as it may (the next one it is sent says how many it missed)."},
             [&](room const& r) { return load(r.traffic().events_dropped); });
    m.begin({"kugel_commands_rejected_total", "counter",
             "Messages refused with an error, by error code (protocol/PROTOCOL.md)."});
    for (auto const& r : rooms)
        for (protocol::error_code const code : protocol::all_error_codes)
            m.sample("kugel_commands_rejected_total", {{"room", r->name()}, {"code", protocol::name(code)}},
                     load(r->traffic().rejected[static_cast<std::size_t>(code)]));
    return m.text();
}

} // namespace kugel::server
