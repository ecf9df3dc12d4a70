#include "connection.hpp"

#include "protocol/codec.hpp"
#include "protocol/compact.hpp"
#include "url.hpp"

#include <algorithm>
#include <atomic>
#include <charconv>
#include <boost/asio/connect.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>
#include <cmath>
#include <condition_variable>
#include <deque>
#include <mutex>
#include <optional>
#include <string_view>
#include <thread>
#include <set>
#include <unordered_map>
#include <vector>

namespace kugel::client {

namespace beast = boost::beast;
namespace websocket = beast::websocket;
namespace net = boost::asio;
using tcp = net::ip::tcp;

std::optional<std::uint64_t> ref_of(reply const& r)
{
    return std::visit([](auto const& m) -> std::optional<std::uint64_t> { return m.ref; }, r);
}

/// The WebSocket and everything the I/O thread and the user's threads share. The I/O side
/// is Beast's chain of do_x/on_x handlers; it holds mutex_ only to hand results over, and
/// runs no user code. The user side waits on changed_.
class connection::session : public std::enable_shared_from_this<session>
{
public:
    session(net::io_context& io, connection_options options)
        : options_(std::move(options)), resolver_(io), ws_(io)
    {
    }

    // I/O side --------------------------------------------------------------------------

    void start(websocket_url url)
    {
        url_ = std::move(url);
        resolver_.async_resolve(
            url_.host, std::to_string(url_.port),
            beast::bind_front_handler(&session::on_resolve, shared_from_this()));
    }

    void on_resolve(beast::error_code ec, tcp::resolver::results_type results)
    {
        if (ec)
            return fail_to_connect("cannot resolve " + url_.host + ": " + ec.message());
        beast::get_lowest_layer(ws_).expires_after(options_.connect_timeout);
        beast::get_lowest_layer(ws_).async_connect(
            results, beast::bind_front_handler(&session::on_connect, shared_from_this()));
    }

    void on_connect(beast::error_code ec, tcp::endpoint)
    {
        if (ec)
            return fail_to_connect("cannot connect to " + to_string(url_) + ": " + ec.message());
        // The stream's own timer is for connecting; from here the websocket's timeouts rule.
        beast::get_lowest_layer(ws_).expires_never();
        // Commands are small and wanted at once: no waiting to fill a segment (Nagle).
        beast::error_code ignored;
        beast::get_lowest_layer(ws_).socket().set_option(tcp::no_delay(true), ignored);
        ws_.set_option(websocket::stream_base::timeout::suggested(beast::role_type::client));
        ws_.set_option(websocket::stream_base::decorator([](websocket::request_type& request) {
            request.set(beast::http::field::user_agent, "kugel-client");
        }));
        ws_.read_message_max(options_.max_message_bytes);
        ws_.text(true);
        bool const ipv6 = url_.host.find(':') != std::string::npos;
        std::string const host =
            (ipv6 ? "[" + url_.host + "]" : url_.host) + ":" + std::to_string(url_.port);
        ws_.async_handshake(upgrade_response_, host, url_.target,
                            beast::bind_front_handler(&session::on_handshake, shared_from_this()));
    }

    void on_handshake(beast::error_code ec)
    {
        if (ec == websocket::error::upgrade_declined)
            return fail_to_connect(
                "the server refused the WebSocket upgrade on " + url_.target + ": " +
                std::to_string(upgrade_response_.result_int()) + " " +
                std::string(upgrade_response_.reason()) +
                (upgrade_response_.result_int() == 404 ? " (no such room?)" : ""));
        if (ec)
            return fail_to_connect("WebSocket handshake with " + to_string(url_) +
                                   " failed: " + ec.message());
        if (!options_.name.empty() || options_.snapshots || !options_.players ||
            options_.resume_token || options_.events || options_.interest) {
            {
                std::lock_guard lock(mutex_);
                ++unsent_; // on_write counts every message down
                resume_pending_ = options_.resume_token.has_value();
            }
            protocol::hello hello{.protocol = protocol::protocol_version};
            // The resume first (the server takes it before the name, which then names the
            // player resumed).
            hello.resume = options_.resume_token;
            if (!options_.name.empty())
                hello.name = options_.name;
            hello.snapshots = options_.snapshots;
            if (!options_.players)
                hello.players = false;
            hello.events = options_.events;
            hello.interest = options_.interest;
            queue_write(std::make_shared<std::string const>(protocol::encode(hello)));
        }
        do_read();
    }

    void do_read()
    {
        ws_.async_read(buffer_, beast::bind_front_handler(&session::on_read, shared_from_this()));
    }

    void on_read(beast::error_code ec, std::size_t)
    {
        if (ec) {
            // A close frame that came in is the reason, even when answering it then failed
            // (a server that closes with 1009 does not wait for the answer).
            if (ws_.reason().code != websocket::close_code::none)
                return end({ws_.reason().code, std::string(ws_.reason().reason), !close_started_});
            return end({0, ec.message(), !close_started_});
        }
        handle_message(beast::buffers_to_string(buffer_.data()));
        buffer_.consume(buffer_.size());
        do_read();
    }

    /// Decodes one message (outside the lock: a snapshot may be large) and hands it over.
    void handle_message(std::string const& text)
    {
        if (options_.snapshot_ticks_only)
            if (auto const tick = snapshot_tick(text)) {
                std::lock_guard lock(mutex_);
                ++stats_.messages_received;
                stats_.bytes_received += text.size();
                count_snapshot(*tick);
                return;
            }
        auto decoded = protocol::decode_server_message(text);
        // A compact snapshot is applied to the state held here (on the I/O thread only, and
        // outside the lock: it is as large as the room) and handed over in the full form.
        std::optional<protocol::snapshot> expanded;
        std::string compact_failure;
        if (decoded.message)
            if (auto const* compact = std::get_if<protocol::compact_snapshot>(&*decoded.message)) {
                auto applied = protocol::apply_compact(*compact, compact_held_ ? &*compact_held_ : nullptr);
                if (applied.state) {
                    expanded = protocol::to_snapshot(*applied.state);
                    compact_held_ = std::move(applied.state);
                } else {
                    compact_held_.reset(); // what the server sends next can only be a keyframe
                    compact_failure = "compact snapshot: " + applied.failure;
                }
            }
        auto const now = clock::now();
        std::lock_guard lock(mutex_);
        ++stats_.messages_received;
        stats_.bytes_received += text.size();
        if (decoded.failure) {
            // A later protocol may add message types: a client ignores what it does not know.
            if (decoded.failure->code == protocol::error_code::unknown_type) {
                ++stats_.ignored;
            } else {
                ++stats_.undecodable;
                stats_.last_undecodable = decoded.failure->message;
            }
            return;
        }
        if (std::holds_alternative<protocol::compact_snapshot>(*decoded.message)) {
            if (expanded) {
                take(std::move(*expanded), now);
            } else {
                ++stats_.undecodable;
                stats_.last_undecodable = std::move(compact_failure);
            }
        } else {
            std::visit([&](auto& m) { take(std::move(m), now); }, *decoded.message);
        }
        changed_.notify_all();
    }

    void take(protocol::compact_snapshot const&, clock::time_point) {} // expanded above

    void take(protocol::welcome welcome, clock::time_point now)
    {
        // The newest welcome holds (after a hello that made this an admin, after an admin
        // loaded another scene); the connection opened with the first.
        double const ratio =
            welcome.tick_rate / (welcome.snapshots ? welcome.snapshots->rate : welcome.snapshot_rate);
        expected_tick_gap_ =
            std::max<std::uint64_t>(1, static_cast<std::uint64_t>(std::ceil(ratio - 1e-9)));
        if (!welcome_)
            stats_.opened = now;
        // A resume is answered by a welcome naming another player than the first welcome did.
        if (resume_pending_ && welcome_ && welcome.client != welcome_->client) {
            resume_pending_ = false;
            resumed_ = true;
        }
        welcome_ = std::move(welcome);
    }

    /// The tick of a snapshot's text, found by a search rather than a parse (the server writes
    /// `{"type":"snapshot","tick":N,...`); nullopt for any other message, or text of
    /// another shape, which is then decoded as usual.
    static std::optional<std::uint64_t> snapshot_tick(std::string_view text)
    {
        constexpr std::string_view head = R"({"type":"snapshot",)";
        constexpr std::string_view key = R"("tick":)";
        if (!text.starts_with(head))
            return std::nullopt;
        auto const at = text.find(key, head.size());
        if (at == std::string_view::npos)
            return std::nullopt;
        std::uint64_t tick = 0;
        char const* first = text.data() + at + key.size();
        auto const [end, ec] = std::from_chars(first, text.data() + text.size(), tick);
        if (ec != std::errc{} || end == first)
            return std::nullopt;
        return tick;
    }

    /// A snapshot's tick into the counts: gaps, late ones.
    void count_snapshot(std::uint64_t tick)
    {
        if (stats_.snapshots == 0) {
            stats_.first_tick = tick;
        } else if (tick > stats_.last_tick) {
            std::uint64_t const gap = tick - stats_.last_tick;
            stats_.tick_gap_min = stats_.tick_gaps == 0 ? gap : std::min(stats_.tick_gap_min, gap);
            stats_.tick_gap_max = std::max(stats_.tick_gap_max, gap);
            ++stats_.tick_gaps;
            if (gap > expected_tick_gap_)
                ++stats_.late_snapshots;
        }
        ++stats_.snapshots;
        stats_.last_tick = tick;
    }

    void take(protocol::snapshot snapshot, clock::time_point)
    {
        auto shared = std::make_shared<protocol::snapshot const>(std::move(snapshot));
        count_snapshot(shared->tick);
        if (snapshots_.size() >= std::max<std::size_t>(options_.snapshot_queue, 1)) {
            snapshots_.pop_front();
            ++stats_.snapshots_dropped;
        }
        snapshots_.push_back(shared);
        for_callback_ = shared;
        latest_ = std::move(shared);
    }

    void take(protocol::ack ack, clock::time_point now)
    {
        ++stats_.acks;
        if (spawn_refs_.erase(ack.ref) > 0 && ack.id)
            spawned_.push_back(*ack.id);
        auto const sent = answered(ack.ref);
        if (sent)
            stats_.ack_latency.record(std::chrono::duration<double>(now - *sent).count());
        file(std::move(ack), sent.has_value());
    }

    void take(protocol::pong pong, clock::time_point now)
    {
        ++stats_.pongs;
        auto const sent = answered(pong.ref);
        if (sent)
            stats_.pong_latency.record(std::chrono::duration<double>(now - *sent).count());
        file(std::move(pong), sent.has_value());
    }

    void take(protocol::roster roster, clock::time_point)
    {
        players_.clear();
        for (protocol::player& p : roster.players)
            players_.insert_or_assign(p.id, std::move(p));
    }

    void take(protocol::player_notice notice, clock::time_point)
    {
        if (notice.change == "left")
            players_.erase(notice.id);
        else // away: kept for a resume, marked so as in a roster
            players_.insert_or_assign(
                notice.id, protocol::player{notice.id, notice.name,
                                            notice.change == "away" ? std::optional(true) : std::nullopt});
        notices_.push_back(std::move(notice));
        while (notices_.size() > std::max<std::size_t>(options_.kept_player_notices, 1))
            notices_.pop_front();
    }

    void take(protocol::event event, clock::time_point)
    {
        ++stats_.events;
        stats_.events_missed += event.missed.value_or(0);
        events_.push_back(std::move(event));
        while (events_.size() > std::max<std::size_t>(options_.kept_events, 1))
            events_.pop_front();
    }

    void take(protocol::error error, clock::time_point)
    {
        ++stats_.errors[std::string(protocol::name(error.code))];
        // The resume's refusal: bad_resume, the rate limit, or a token the server cannot read.
        if (resume_pending_ && !error.ref &&
            (error.code == protocol::error_code::bad_resume ||
             error.code == protocol::error_code::rate_limited ||
             error.message.starts_with("/resume"))) {
            resume_pending_ = false;
            resume_refusal_ = error;
        }
        bool const ours = error.ref && answered(*error.ref);
        file(std::move(error), ours);
    }

    /// When a ref of ours was sent, if it was still waiting for its answer.
    std::optional<clock::time_point> answered(std::uint64_t ref)
    {
        auto const it = pending_.find(ref);
        if (it == pending_.end())
            return std::nullopt;
        auto const sent = it->second;
        pending_.erase(it);
        return sent;
    }

    /// Files an answer under its ref when it answers one of our sends, else with the
    /// unmatched ones. Both are bounded: the oldest go first.
    void file(reply r, bool ours)
    {
        if (ours) {
            auto const ref = *ref_of(r);
            replies_.insert_or_assign(ref, std::move(r));
            // Refs count up, so the smallest is the oldest.
            while (replies_.size() > std::max<std::size_t>(options_.kept_replies, 1))
                replies_.erase(replies_.begin());
            return;
        }
        unmatched_.push_back(std::move(r));
        while (unmatched_.size() > std::max<std::size_t>(options_.kept_unmatched_replies, 1))
            unmatched_.pop_front();
    }

    void queue_write(std::shared_ptr<std::string const> bytes)
    {
        {
            std::lock_guard lock(mutex_);
            if (close_started_ || closed_) {
                --unsent_; // never to be written
                return;
            }
        }
        outgoing_.push_back(std::move(bytes));
        if (!writing_)
            do_write();
    }

    void do_write()
    {
        writing_ = true;
        ws_.async_write(net::buffer(*outgoing_.front()),
                        beast::bind_front_handler(&session::on_write, shared_from_this()));
    }

    void on_write(beast::error_code ec, std::size_t bytes)
    {
        writing_ = false;
        outgoing_.pop_front();
        {
            std::lock_guard lock(mutex_);
            --unsent_;
            if (!ec) {
                ++stats_.messages_sent;
                stats_.bytes_sent += bytes;
            }
        }
        if (ec)
            return end({0, "write failed: " + ec.message(), !close_started_});
        if (!outgoing_.empty() && !close_started_)
            do_write();
    }

    void do_close()
    {
        if (close_started_ || ended())
            return;
        close_started_ = true;
        ws_.async_close(websocket::close_code::normal,
                        beast::bind_front_handler(&session::on_close, shared_from_this()));
    }

    void on_close(beast::error_code ec)
    {
        // The read that is still pending ends with the server's close frame, and records
        // the code; this only covers a close that failed.
        if (ec)
            end({0, "close failed: " + ec.message(), false});
    }

    /// Ends whatever is still pending (a resolve, a connect, the stream) once the user has
    /// let go of a connection on shared I/O threads, so that nothing holds it there.
    void abandon()
    {
        resolver_.cancel();
        if (!ended())
            cut();
    }

    /// Cuts the connection without a closing handshake (the server did not answer one).
    void cut()
    {
        beast::error_code ignored;
        beast::get_lowest_layer(ws_).socket().shutdown(tcp::socket::shutdown_both, ignored);
        beast::get_lowest_layer(ws_).close();
        end({0, "cut off: the server did not answer the close", false});
    }

    void fail_to_connect(std::string why)
    {
        std::lock_guard lock(mutex_);
        connect_failure_ = std::move(why);
        changed_.notify_all();
    }

    void end(close_info info)
    {
        std::lock_guard lock(mutex_);
        if (!closed_)
            closed_ = std::move(info);
        pending_.clear();
        changed_.notify_all();
    }

    bool ended()
    {
        std::lock_guard lock(mutex_);
        return closed_.has_value();
    }

    // User side -------------------------------------------------------------------------

    /// Waits for the welcome; throws connection_error when it cannot come.
    void await_welcome()
    {
        std::unique_lock lock(mutex_);
        bool const done = changed_.wait_for(lock, options_.connect_timeout, [&] {
            return welcome_ || connect_failure_ || closed_;
        });
        if (connect_failure_)
            throw connection_error(*connect_failure_);
        if (!welcome_ && closed_)
            throw connection_error("the connection to " + to_string(url_) +
                                   " ended before the welcome: " + describe(*closed_));
        if (!done)
            throw connection_error("no welcome from " + to_string(url_) + " within " +
                                   std::to_string(options_.connect_timeout.count()) + " ms");
    }

    static std::string describe(close_info const& info)
    {
        return info.code != 0 ? "closed with " + std::to_string(info.code) +
                                    (info.reason.empty() ? "" : " (" + info.reason + ")")
                              : info.reason;
    }

    protocol::welcome welcome() const
    {
        std::lock_guard lock(mutex_);
        return *welcome_; // set before the constructor returned; a copy, as a newer may come
    }

    /// Waits for the answer to the hello's resume, if it had one; throws connection_error
    /// when none comes in time or the connection ends first.
    void await_resume()
    {
        std::unique_lock lock(mutex_);
        bool const done = changed_.wait_for(lock, options_.connect_timeout,
                                            [&] { return !resume_pending_ || closed_; });
        if (resume_pending_ && closed_)
            throw connection_error("the connection to " + to_string(url_) +
                                   " ended before the answer to its resume: " + describe(*closed_));
        if (!done)
            throw connection_error("no answer to the resume from " + to_string(url_) + " within " +
                                   std::to_string(options_.connect_timeout.count()) + " ms");
    }

    bool resumed() const
    {
        std::lock_guard lock(mutex_);
        return resumed_;
    }

    std::optional<protocol::error> resume_refusal() const
    {
        std::lock_guard lock(mutex_);
        return resume_refusal_;
    }

    /// Counts a message about to be sent; throws when the connection cannot take it.
    void reserve_unsent()
    {
        if (closed_)
            throw connection_error("the connection has ended: " + describe(*closed_));
        if (unsent_ >= std::max<std::size_t>(options_.max_unsent, 1))
            throw connection_error(std::to_string(unsent_) +
                                   " messages not yet written: the server is not reading");
        ++unsent_;
    }

    std::uint64_t send(command c)
    {
        std::uint64_t ref = 0;
        {
            std::lock_guard lock(mutex_);
            reserve_unsent();
            ref = next_ref_++;
            pending_.emplace(ref, clock::now());
            ++stats_.commands_sent;
            if (std::holds_alternative<protocol::spawn>(c))
                spawn_refs_.insert(ref);
        }
        auto bytes = std::make_shared<std::string const>(std::visit(
            [ref](auto m) {
                m.ref = ref;
                return protocol::encode(m);
            },
            std::move(c)));
        post_write(std::move(bytes));
        return ref;
    }

    void send_bytes(std::string text)
    {
        {
            std::lock_guard lock(mutex_);
            reserve_unsent();
        }
        post_write(std::make_shared<std::string const>(std::move(text)));
    }

    void post_write(std::shared_ptr<std::string const> bytes)
    {
        net::post(ws_.get_executor(),
                  [self = shared_from_this(), bytes = std::move(bytes)]() mutable {
                      self->queue_write(std::move(bytes));
                  });
    }

    std::vector<std::uint64_t> spawned() const
    {
        std::lock_guard lock(mutex_);
        return spawned_;
    }

    void forget_spawned(std::uint64_t id)
    {
        std::lock_guard lock(mutex_);
        std::erase(spawned_, id);
    }

    std::optional<reply> await_reply(std::uint64_t ref, std::chrono::milliseconds timeout)
    {
        std::unique_lock lock(mutex_);
        changed_.wait_for(lock, timeout, [&] { return replies_.contains(ref) || closed_; });
        auto const it = replies_.find(ref);
        if (it == replies_.end())
            return std::nullopt;
        reply r = std::move(it->second);
        replies_.erase(it);
        return r;
    }

    std::vector<protocol::player> players() const
    {
        std::lock_guard lock(mutex_);
        std::vector<protocol::player> out;
        out.reserve(players_.size());
        for (auto const& [id, p] : players_)
            out.push_back(p);
        return out;
    }

    std::optional<protocol::player_notice> next_player_notice(std::chrono::milliseconds timeout)
    {
        std::unique_lock lock(mutex_);
        changed_.wait_for(lock, timeout, [&] { return !notices_.empty() || closed_; });
        if (notices_.empty())
            return std::nullopt;
        protocol::player_notice notice = std::move(notices_.front());
        notices_.pop_front();
        return notice;
    }

    std::optional<protocol::event> next_event(std::chrono::milliseconds timeout)
    {
        std::unique_lock lock(mutex_);
        changed_.wait_for(lock, timeout, [&] { return !events_.empty() || closed_; });
        if (events_.empty())
            return std::nullopt;
        protocol::event event = std::move(events_.front());
        events_.pop_front();
        return event;
    }

    std::optional<reply> next_unmatched_reply(std::chrono::milliseconds timeout)
    {
        std::unique_lock lock(mutex_);
        changed_.wait_for(lock, timeout, [&] { return !unmatched_.empty() || closed_; });
        if (unmatched_.empty())
            return std::nullopt;
        reply r = std::move(unmatched_.front());
        unmatched_.pop_front();
        return r;
    }

    std::shared_ptr<protocol::snapshot const> next_snapshot(std::chrono::milliseconds timeout)
    {
        std::unique_lock lock(mutex_);
        changed_.wait_for(lock, timeout, [&] { return !snapshots_.empty() || closed_; });
        if (snapshots_.empty())
            return nullptr;
        auto s = std::move(snapshots_.front());
        snapshots_.pop_front();
        return s;
    }

    std::shared_ptr<protocol::snapshot const>
    take_latest_snapshot(std::chrono::milliseconds timeout)
    {
        std::unique_lock lock(mutex_);
        changed_.wait_for(lock, timeout, [&] { return latest_ || closed_; });
        snapshots_.clear();
        return latest_;
    }

    snapshot_wait wait_for_snapshot(std::function<bool(protocol::snapshot const&)> const& predicate,
                                    std::uint64_t max_ticks, std::chrono::milliseconds timeout)
    {
        auto const deadline = clock::now() + timeout;
        std::unique_lock lock(mutex_);
        std::optional<std::uint64_t> limit;
        if (latest_)
            limit = latest_->tick + max_ticks;
        snapshot_wait result;
        for (;;) {
            changed_.wait_until(lock, deadline, [&] { return !snapshots_.empty() || closed_; });
            if (snapshots_.empty()) {
                result.outcome = closed_ ? wait_outcome::closed : wait_outcome::timed_out;
                return result;
            }
            auto s = std::move(snapshots_.front());
            snapshots_.pop_front();
            if (!limit)
                limit = s->tick + max_ticks; // the first snapshot ever is where the count starts
            if (s->tick > *limit) {
                result.outcome = wait_outcome::past_limit;
                if (!result.snapshot)
                    result.snapshot = std::move(s);
                return result;
            }
            lock.unlock(); // the predicate is the user's code: never under our lock
            bool const matched = predicate(*s);
            result.snapshot = std::move(s);
            if (matched) {
                result.outcome = wait_outcome::matched;
                return result;
            }
            lock.lock();
        }
    }

    std::uint64_t latest_tick() const
    {
        std::lock_guard lock(mutex_);
        return latest_ ? latest_->tick : 0;
    }

    std::optional<close_info> wait_closed(std::chrono::milliseconds timeout)
    {
        std::unique_lock lock(mutex_);
        changed_.wait_for(lock, timeout, [&] { return closed_.has_value(); });
        return closed_;
    }

    std::optional<close_info> closed_with() const
    {
        std::lock_guard lock(mutex_);
        return closed_;
    }

    connection_stats stats() const
    {
        std::lock_guard lock(mutex_);
        return stats_;
    }

    /// Runs the user's snapshot callback with the newest snapshot it has not had, until
    /// stop_callbacks(); on its own thread.
    void run_callbacks()
    {
        for (;;) {
            std::shared_ptr<protocol::snapshot const> s;
            {
                std::unique_lock lock(mutex_);
                changed_.wait(lock, [&] { return for_callback_ || stopping_callbacks_; });
                if (stopping_callbacks_)
                    return;
                s = std::exchange(for_callback_, nullptr);
            }
            options_.on_snapshot(s);
        }
    }

    void stop_callbacks()
    {
        std::lock_guard lock(mutex_);
        stopping_callbacks_ = true;
        changed_.notify_all();
    }

    connection_options const& options() const { return options_; }

private:
    connection_options const options_;
    websocket_url url_;

    // I/O thread only.
    tcp::resolver resolver_;
    websocket::stream<beast::tcp_stream> ws_;
    beast::http::response<beast::http::string_body> upgrade_response_;
    beast::flat_buffer buffer_;
    std::deque<std::shared_ptr<std::string const>> outgoing_; ///< front is being written
    bool writing_ = false;
    bool close_started_ = false;

    // Shared: guarded by mutex_.
    mutable std::mutex mutex_;
    std::condition_variable changed_;
    std::optional<protocol::welcome> welcome_;
    bool resume_pending_ = false; ///< the hello carried a resume not answered yet
    bool resumed_ = false;        ///< a welcome answered it: this connection is that player
    std::optional<protocol::error> resume_refusal_; ///< the error that answered it
    std::optional<std::string> connect_failure_;
    std::optional<close_info> closed_;
    std::uint64_t next_ref_ = 1;
    std::size_t unsent_ = 0;
    std::unordered_map<std::uint64_t, clock::time_point> pending_; ///< refs sent, unanswered
    std::map<std::uint64_t, reply> replies_;                       ///< answers to our refs
    std::set<std::uint64_t> spawn_refs_; ///< refs of spawns not yet acknowledged
    std::vector<std::uint64_t> spawned_; ///< ids of the bodies our spawns made, in ack order
    std::deque<reply> unmatched_;
    std::map<std::uint64_t, protocol::player> players_;  ///< the room's, by id
    std::deque<protocol::player_notice> notices_;        ///< not yet taken
    std::deque<protocol::event> events_;                 ///< sensor events not yet taken
    std::deque<std::shared_ptr<protocol::snapshot const>> snapshots_;
    /// The compact state of the last compact snapshot applied (I/O thread only).
    std::optional<protocol::compact_state> compact_held_;
    std::shared_ptr<protocol::snapshot const> latest_;
    std::shared_ptr<protocol::snapshot const> for_callback_;
    bool stopping_callbacks_ = false;
    std::uint64_t expected_tick_gap_ = 1;
    connection_stats stats_;
};

struct io_threads::pool
{
    std::vector<std::unique_ptr<net::io_context>> contexts; ///< one per thread: no strands needed
    std::vector<net::executor_work_guard<net::io_context::executor_type>> work;
    std::vector<std::thread> threads;
    std::atomic<std::size_t> next{0};
};

io_threads::io_threads(std::size_t count) : pool_(std::make_unique<pool>())
{
    for (std::size_t k = 0; k < std::max<std::size_t>(count, 1); ++k) {
        auto& io = *pool_->contexts.emplace_back(std::make_unique<net::io_context>(1));
        pool_->work.push_back(net::make_work_guard(io));
        pool_->threads.emplace_back([&io] { io.run(); });
    }
}

io_threads::~io_threads()
{
    pool_->work.clear();
    for (auto& io : pool_->contexts)
        io->stop();
    for (auto& t : pool_->threads)
        t.join();
}

/// The session and the callback thread, and the I/O thread with its io_context when the
/// connection has its own. Members are destroyed in reverse order: the threads are joined
/// first (in ~state), then the session is released, then an own io_context destroys the
/// handlers still holding it. On shared threads the session is told to end what it still
/// has pending, and its last handler releases it.
struct connection::state
{
    std::unique_ptr<net::io_context> own_io;
    net::io_context* io = nullptr;
    std::optional<net::executor_work_guard<net::io_context::executor_type>> work;
    std::shared_ptr<session> live;
    std::thread io_thread;
    std::thread callback_thread;

    explicit state(io_threads* shared)
    {
        if (shared) {
            auto& pool = *shared->pool_;
            io = pool.contexts[pool.next++ % pool.contexts.size()].get();
        } else {
            own_io = std::make_unique<net::io_context>(1);
            io = own_io.get();
            work.emplace(net::make_work_guard(*io));
        }
    }

    ~state()
    {
        if (live)
            live->stop_callbacks();
        if (callback_thread.joinable())
            callback_thread.join();
        if (!own_io) {
            if (live)
                net::post(*io, [s = live] { s->abandon(); });
            return;
        }
        work.reset();
        io->stop();
        if (io_thread.joinable())
            io_thread.join();
    }
};

connection::connection(std::string const& url, connection_options options)
    : connection(url, std::move(options), nullptr)
{
}

connection::connection(std::string const& url, connection_options options, io_threads& shared)
    : connection(url, std::move(options), &shared)
{
}

connection::connection(std::string const& url, connection_options options, io_threads* shared)
    : state_(std::make_unique<state>(shared))
{
    websocket_url parsed = parse_websocket_url(url);
    state_->live = std::make_shared<session>(*state_->io, std::move(options));
    net::post(*state_->io, [s = state_->live, parsed = std::move(parsed)]() mutable {
        s->start(std::move(parsed));
    });
    if (state_->own_io)
        state_->io_thread = std::thread([&io = *state_->io] { io.run(); });
    state_->live->await_welcome(); // throws: ~state stops the thread
    state_->live->await_resume();
    if (state_->live->options().on_snapshot)
        state_->callback_thread = std::thread([s = state_->live] { s->run_callbacks(); });
}

connection::~connection()
{
    try {
        close();
    } catch (...) { // a destructor does not throw; close() only could on allocation failure
    }
}

protocol::welcome connection::welcome() const
{
    return state_->live->welcome();
}

std::optional<std::string> connection::resume_token() const
{
    return state_->live->welcome().resume_token;
}

bool connection::resumed() const
{
    return state_->live->resumed();
}

std::optional<protocol::error> connection::resume_refusal() const
{
    return state_->live->resume_refusal();
}

std::uint64_t connection::send(command c)
{
    return state_->live->send(std::move(c));
}

void connection::send(protocol::hello const& h)
{
    state_->live->send_bytes(protocol::encode(h));
}

void connection::send_text(std::string text)
{
    state_->live->send_bytes(std::move(text));
}

std::optional<reply> connection::await_reply(std::uint64_t ref, std::chrono::milliseconds timeout)
{
    return state_->live->await_reply(ref, timeout);
}

std::vector<std::uint64_t> connection::spawned() const
{
    return state_->live->spawned();
}

std::size_t connection::remove_spawned(std::chrono::milliseconds timeout)
{
    auto& live = *state_->live;
    std::vector<std::pair<std::uint64_t, std::uint64_t>> sent; // id, ref
    for (std::uint64_t const id : live.spawned())
        sent.emplace_back(id, live.send(protocol::remove{.ref = 0, .id = id}));
    auto const until = std::chrono::steady_clock::now() + timeout;
    std::size_t removed = 0;
    for (auto const& [id, ref] : sent) {
        auto const left = std::chrono::duration_cast<std::chrono::milliseconds>(until - std::chrono::steady_clock::now());
        auto const answer = live.await_reply(ref, std::max(left, std::chrono::milliseconds(0)));
        if (!answer)
            continue; // no answer in time: it may still be there, and stays on the list
        if (std::holds_alternative<protocol::ack>(*answer))
            ++removed;
        live.forget_spawned(id); // removed now, or gone before (unknown_body)
    }
    return removed;
}

std::vector<protocol::player> connection::players() const
{
    return state_->live->players();
}

std::optional<protocol::player_notice> connection::next_player_notice(std::chrono::milliseconds timeout)
{
    return state_->live->next_player_notice(timeout);
}

std::optional<protocol::event> connection::next_event(std::chrono::milliseconds timeout)
{
    return state_->live->next_event(timeout);
}

std::optional<reply> connection::next_unmatched_reply(std::chrono::milliseconds timeout)
{
    return state_->live->next_unmatched_reply(timeout);
}

std::shared_ptr<protocol::snapshot const>
connection::next_snapshot(std::chrono::milliseconds timeout)
{
    return state_->live->next_snapshot(timeout);
}

std::shared_ptr<protocol::snapshot const>
connection::take_latest_snapshot(std::chrono::milliseconds timeout)
{
    return state_->live->take_latest_snapshot(timeout);
}

snapshot_wait
connection::wait_for_snapshot(std::function<bool(protocol::snapshot const&)> const& predicate,
                              std::uint64_t max_ticks, std::chrono::milliseconds timeout)
{
    return state_->live->wait_for_snapshot(predicate, max_ticks, timeout);
}

std::uint64_t connection::latest_tick() const
{
    return state_->live->latest_tick();
}

void connection::close()
{
    auto& s = state_->live;
    if (s->closed_with())
        return;
    net::post(*state_->io, [s] { s->do_close(); });
    if (s->wait_closed(std::chrono::seconds(1)))
        return;
    net::post(*state_->io, [s] { s->cut(); });
    s->wait_closed(std::chrono::seconds(1));
}

std::optional<close_info> connection::wait_closed(std::chrono::milliseconds timeout)
{
    return state_->live->wait_closed(timeout);
}

bool connection::is_open() const
{
    return !state_->live->closed_with().has_value();
}

std::optional<close_info> connection::closed_with() const
{
    return state_->live->closed_with();
}

connection_stats connection::stats() const
{
    return state_->live->stats();
}

} // namespace kugel::client
