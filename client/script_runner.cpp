#include "script_runner.hpp"

#include "body_check.hpp"
#include "connection.hpp"
#include "protocol/codec.hpp"
#include "url.hpp"
#include "variables.hpp"

#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <thread>
#include <type_traits>

namespace kugel::client {

namespace {

using json = nlohmann::json;
using std::chrono::milliseconds;

/// A step that did not hold: what it expected and what arrived instead.
struct step_failed
{
    std::string expected;
    std::string arrived;
};

/// An answer as the codec wrote it (for messages) and as JSON (for checks).
struct answer
{
    json value;
    std::string text;
};

answer answer_of(reply const& r)
{
    std::string text = std::visit([](auto const& m) { return protocol::encode(m); }, r);
    return {json::parse(text), std::move(text)};
}

std::string describe(close_info const& info)
{
    std::string text = info.code != 0 ? "closed with " + std::to_string(info.code) : "ended";
    if (!info.reason.empty())
        text += " (" + info.reason + ")";
    return text + (info.by_server ? " by the server" : "");
}

/// Two expected-field values are equal: numbers by value (7 and 7.0 are the same), the
/// rest as JSON.
bool same(json const& got, json const& wanted)
{
    if (got.is_number() && wanted.is_number())
        return got.get<double>() == wanted.get<double>();
    return got == wanted;
}

class script_runner
{
public:
    script_runner(script const& s, run_options const& options, std::ostream& log)
        : script_(s), options_(options), log_(log)
    {
        for (auto const& [name, value] : s.variables)
            vars_.set(name, value);
    }

    run_result run()
    {
        run_result result;
        for (step const& s : script_.steps) {
            std::string failure;
            try {
                std::string const detail = perform(s);
                log_ << "ok   " << label_of(s) << (detail.empty() ? "" : ": " + detail) << '\n';
                continue;
            } catch (step_failed const& f) {
                failure = "FAIL " + label_of(s) + "\n  expected: " + f.expected +
                          "\n  arrived:  " + f.arrived;
            } catch (substitution_error const& e) {
                failure = "FAIL " + label_of(s) + "\n  cannot resolve a value: " + e.what();
            } catch (connection_error const& e) {
                failure = "FAIL " + label_of(s) + "\n  connection: " + e.what();
            } catch (url_error const& e) {
                failure = "FAIL " + label_of(s) + "\n  url: " + e.what();
            }
            failure += "\n  step:     " + kugel::client::describe(s.source);
            log_ << failure << '\n';
            result.failed_step = s.number;
            result.failure = std::move(failure);
            clean_up();
            close_all();
            return result;
        }
        clean_up();
        close_all();
        log_ << "passed: " << script_.steps.size() << " steps\n";
        result.passed = true;
        return result;
    }

private:
    /// With cleanup, each client that is still connected removes the bodies it spawned.
    void clean_up()
    {
        if (!options_.cleanup && !script_.cleanup)
            return;
        for (auto& [name, c] : clients_) {
            if (!c.link || c.link->closed_with())
                continue;
            try {
                std::size_t const spawned = c.link->spawned().size();
                std::size_t const removed = c.link->remove_spawned(options_.timeout);
                log_ << "     client " << name << " removed " << removed << " of the " << spawned
                     << " bodies it spawned\n";
            } catch (connection_error const& e) {
                log_ << "     client " << name << " could not clean up: " << e.what() << '\n';
            }
        }
    }

    /// What was sent by one send or send_text step. Answers stay with it once they have
    /// arrived, so that several expects may look at the same send.
    struct sent
    {
        std::vector<std::uint64_t> refs; ///< one per repetition; empty for text
        bool text = false;
        std::optional<answer> text_answer;
    };

    struct client_state
    {
        std::unique_ptr<connection> link;
        std::shared_ptr<sent> latest;
        std::map<std::string, std::shared_ptr<sent>> labelled;
        std::map<std::uint64_t, answer> answers; ///< by ref, as they were awaited
    };

    std::string perform(step const& s)
    {
        client_state& c = client(s);
        return std::visit([&](auto const& action) { return perform(action, c); }, s.action);
    }

    /// The step's client, connected on first use.
    client_state& client(step const& s)
    {
        auto& c = clients_[s.client];
        if (!c.link) {
            connection_options o;
            o.name = "kugel-client run (" + s.client + ")";
            o.connect_timeout = options_.timeout;
            o.snapshots = options_.snapshots;
            c.link = std::make_unique<connection>(options_.url, std::move(o));
            // The welcome that answers the hello's snapshots names the quanta.
            auto const until = std::chrono::steady_clock::now() + options_.timeout;
            while (options_.snapshots && !c.link->welcome().snapshots && c.link->is_open() &&
                   std::chrono::steady_clock::now() < until)
                std::this_thread::sleep_for(std::chrono::milliseconds(5));
            protocol::welcome const w = c.link->welcome();
            vars_.set("dt", w.dt);
            vars_.set("tick_rate", w.tick_rate);
            vars_.set("snapshot_rate", w.snapshot_rate);
            if (w.snapshots && w.snapshots->form == "compact") {
                vars_.set("position_quantum", w.snapshots->position_quantum);
                vars_.set("velocity_quantum", w.snapshots->velocity_quantum);
            }
            log_ << "     client " << s.client << " joined room '" << w.room << "' (scene '"
                 << w.scene.name << "', client id " << w.client << ")\n";
        }
        return c;
    }

    std::string perform(send_step const& send, client_state& c)
    {
        json message = vars_.resolve(send.message);
        bool const has_ref = message["type"] != "hello";
        if (has_ref)
            message["ref"] = 0; // replaced by the connection's own
        auto decoded = protocol::decode(message.dump());
        if (decoded.failure)
            throw step_failed{"a message the protocol accepts (send_text sends anything)",
                              std::string(protocol::name(decoded.failure->code)) + ": " +
                                  decoded.failure->message};
        auto record = std::make_shared<sent>();
        for (std::uint64_t i = 0; i < send.repeat; ++i) {
            std::visit(
                [&](auto const& m) {
                    if constexpr (std::is_same_v<std::decay_t<decltype(m)>, protocol::hello>)
                        c.link->send(m);
                    else
                        record->refs.push_back(c.link->send(command(m)));
                },
                *decoded.message);
        }
        remember(c, send.label, record);
        std::string detail = "sent " + message["type"].get<std::string>();
        auto const& refs = record->refs;
        if (refs.size() == 1)
            detail += ", ref " + std::to_string(refs.front());
        else if (!refs.empty())
            detail += " ×" + std::to_string(refs.size()) + ", refs " +
                      std::to_string(refs.front()) + "-" + std::to_string(refs.back());
        return detail;
    }

    std::string perform(send_text_step const& send, client_state& c)
    {
        std::string text = vars_.interpolate(send.text);
        if (text.size() < send.pad_to_bytes)
            text.append(send.pad_to_bytes - text.size(), ' ');
        std::size_t const bytes = text.size();
        c.link->send_text(std::move(text));
        auto record = std::make_shared<sent>();
        record->text = true;
        remember(c, send.label, std::move(record));
        return "sent " + std::to_string(bytes) + " bytes of text";
    }

    void remember(client_state& c, std::string const& label, std::shared_ptr<sent> record)
    {
        c.latest = record;
        if (!label.empty())
            c.labelled[label] = record;
    }

    std::string perform(expect_step const& e, client_state& c)
    {
        sent* target = nullptr;
        if (e.to.empty()) {
            if (!c.latest)
                throw step_failed{"an answer to an earlier send", "this client has sent nothing"};
            target = c.latest.get();
        } else {
            auto const it = c.labelled.find(e.to);
            if (it == c.labelled.end())
                throw step_failed{"an answer to the send labelled \"" + e.to + "\"",
                                  "this client sent nothing with \"as\": \"" + e.to + "\""};
            target = it->second.get();
        }
        std::string const wanted = expected_text(e);
        auto const deadline = std::chrono::steady_clock::now() + options_.timeout;
        auto const remaining = [&] {
            return std::max(milliseconds(0), std::chrono::duration_cast<milliseconds>(
                                                 deadline - std::chrono::steady_clock::now()));
        };
        auto const await = [&](std::optional<std::uint64_t> ref) -> answer {
            if (ref) {
                if (auto const it = c.answers.find(*ref); it != c.answers.end())
                    return it->second;
            } else if (target->text_answer) {
                return *target->text_answer;
            }
            auto r = ref ? c.link->await_reply(*ref, remaining())
                         : c.link->next_unmatched_reply(remaining());
            if (r) {
                answer got = answer_of(*r);
                if (ref)
                    c.answers.emplace(*ref, got);
                else
                    target->text_answer = got;
                return got;
            }
            std::string const what = ref ? "no answer to ref " + std::to_string(*ref)
                                         : std::string("no answer to the text");
            auto const closed = c.link->closed_with();
            throw step_failed{wanted, closed
                                          ? what + ": the connection " + describe(*closed)
                                          : what + " within " +
                                                std::to_string(options_.timeout.count()) + " ms"};
        };

        if (target->text) {
            answer const got = await(std::nullopt);
            if (mismatch(e, got.value))
                throw step_failed{wanted, got.text};
            keep(e.keep, got.value);
            return got.text;
        }
        std::vector<std::uint64_t> refs = target->refs;
        if (e.of == expect_step::which::last || refs.size() == 1)
            refs = {refs.back()};
        std::optional<answer> first_miss;
        std::optional<answer> match;
        std::size_t matches = 0;
        for (std::uint64_t const ref : refs) {
            answer got = await(ref);
            if (mismatch(e, got.value)) {
                if (!first_miss)
                    first_miss = std::move(got);
                continue;
            }
            ++matches;
            if (!match)
                match = std::move(got);
        }
        if (e.of == expect_step::which::all && first_miss)
            throw step_failed{wanted + " for all " + std::to_string(refs.size()) + " answers",
                              std::to_string(refs.size() - matches) +
                                  " did not match, the first: " + first_miss->text};
        if (!match)
            throw step_failed{
                refs.size() > 1 ? wanted + " for any of " + std::to_string(refs.size()) + " answers"
                                : wanted,
                refs.size() > 1 ? "none did; the first: " + first_miss->text : first_miss->text};
        keep(e.keep, match->value);
        return refs.size() > 1 ? std::to_string(matches) + " of " + std::to_string(refs.size()) +
                                     " answers matched, the first: " + match->text
                               : match->text;
    }

    static std::string describe_json(json const& value) { return kugel::client::describe(value); }

    std::string expected_text(expect_step const& e) const
    {
        std::string text = *e.type;
        if (e.code)
            text += " " + *e.code;
        if (!e.fields.empty())
            text += " with " + describe_json(vars_.resolve(e.fields));
        if (e.message_contains)
            text += ", its message containing \"" + *e.message_contains + "\"";
        return text;
    }

    /// Why `got` is not the answer `e` expects, or nullopt when it is.
    std::optional<std::string> mismatch(expect_step const& e, json const& got) const
    {
        if (got.at("type") != *e.type)
            return "type";
        if (e.code && got.at("code") != *e.code)
            return "code";
        for (auto const& [where, wanted] : e.fields.items()) {
            json const resolved = vars_.resolve(wanted);
            try {
                if (!same(value_at(got, where), resolved))
                    return where;
            } catch (substitution_error const&) {
                return where; // the field is absent
            }
        }
        if (e.message_contains) {
            auto const it = got.find("message");
            if (it == got.end() || !it->is_string() ||
                it->get<std::string>().find(*e.message_contains) == std::string::npos)
                return "message";
        }
        return std::nullopt;
    }

    void keep(keep_map const& names, json const& from)
    {
        for (auto const& [name, where] : names)
            vars_.set(name, value_at(from, where));
    }

    /// Wall-clock time a wait of `ticks` ticks may take: twice their worth, plus the timeout.
    milliseconds allowance(client_state const& c, std::uint64_t ticks) const
    {
        double const seconds = 2.0 * static_cast<double>(ticks) / c.link->welcome().tick_rate;
        return options_.timeout +
               milliseconds(static_cast<std::int64_t>(std::ceil(seconds * 1000.0)));
    }

    std::string perform(wait_ticks_step const& w, client_state& c)
    {
        std::uint64_t const ticks = vars_.whole_number(w.ticks, "wait_ticks");
        std::uint64_t base = c.link->latest_tick();
        if (base == 0) {
            auto const first = c.link->take_latest_snapshot(options_.timeout);
            if (!first)
                throw step_failed{"a first snapshot", "none within " +
                                                          std::to_string(options_.timeout.count()) +
                                                          " ms"};
            base = first->tick;
        }
        return wait_until(c, base + ticks);
    }

    std::string perform(wait_until_tick_step const& w, client_state& c)
    {
        return wait_until(c, vars_.whole_number(w.tick, "wait_until_tick"));
    }

    std::string wait_until(client_state& c, std::uint64_t tick)
    {
        std::uint64_t const now = c.link->latest_tick();
        auto const result = c.link->wait_for_snapshot(
            [tick](protocol::snapshot const& s) { return s.tick >= tick; },
            std::numeric_limits<std::uint64_t>::max() / 2,
            allowance(c, tick > now ? tick - now : 0));
        if (result.outcome != wait_outcome::matched)
            throw step_failed{"a snapshot of tick " + std::to_string(tick) + " or later",
                              why_not(c, result)};
        return "tick " + std::to_string(result.snapshot->tick);
    }

    std::string why_not(client_state const& c, snapshot_wait const& result) const
    {
        std::string const last = result.snapshot ? "the last snapshot was of tick " +
                                                       std::to_string(result.snapshot->tick)
                                                 : std::string("no snapshot came");
        switch (result.outcome) {
        case wait_outcome::closed:
            return last + "; then the connection " + describe(*c.link->closed_with());
        case wait_outcome::timed_out:
            return last + "; then nothing more in time (is the server ticking?)";
        default:
            return last;
        }
    }

    std::string perform(expect_body_step const& e, client_state& c)
    {
        auto const s = c.link->take_latest_snapshot(options_.timeout);
        if (!s)
            throw step_failed{"a snapshot to check",
                              "none within " + std::to_string(options_.timeout.count()) + " ms"};
        body_check const check = check_body(e.body, *s, vars_);
        if (!check.passed)
            throw step_failed{check.expected, check.arrived};
        keep_from_body(e.body, check, vars_);
        return check.arrived;
    }

    std::string perform(wait_for_body_step const& w, client_state& c)
    {
        std::uint64_t const max_ticks = vars_.whole_number(w.max_ticks, "max_ticks");
        std::optional<body_check> last;
        auto const result = c.link->wait_for_snapshot(
            [&](protocol::snapshot const& s) {
                last = check_body(w.body, s, vars_);
                return last->passed;
            },
            max_ticks, allowance(c, max_ticks));
        if (result.outcome == wait_outcome::matched) {
            keep_from_body(w.body, *last, vars_);
            return last->arrived;
        }
        std::string expected = last ? last->expected : "the body as described";
        expected += " within " + std::to_string(max_ticks) + " ticks";
        std::string arrived = last ? "last seen: " + last->arrived : "no snapshot was checked";
        if (result.outcome == wait_outcome::past_limit && result.snapshot)
            arrived += "; the limit passed at tick " + std::to_string(result.snapshot->tick);
        else if (result.outcome != wait_outcome::past_limit)
            arrived += "; " + why_not(c, result);
        throw step_failed{expected, arrived};
    }

    std::string perform(close_step const&, client_state& c)
    {
        c.link->close();
        auto const info = c.link->closed_with();
        return info ? describe(*info) : "closed";
    }

    std::string perform(expect_close_step const& e, client_state& c)
    {
        std::string const wanted = "the server to close the connection" +
                                   (e.code ? " with " + std::to_string(*e.code) : "");
        auto const info = c.link->wait_closed(options_.timeout);
        if (!info)
            throw step_failed{wanted, "still open after " +
                                          std::to_string(options_.timeout.count()) + " ms"};
        if (e.code && info->code != *e.code)
            throw step_failed{wanted, "it " + describe(*info)};
        return describe(*info);
    }

    std::string perform(expect_player_step const& e, client_state& c)
    {
        return expect_message("a player notice", e.fields, e.keep,
                              [&] { return c.link->next_player_notice(options_.timeout); });
    }

    std::string perform(expect_event_step const& e, client_state& c)
    {
        return expect_message("an event", e.fields, e.keep,
                              [&] { return c.link->next_event(options_.timeout); });
    }

    /// The next message `next()` hands out (nothing: none came in time), held to the fields
    /// a step wants and kept as the step says: expect_player and expect_event.
    template <class Next>
    std::string expect_message(char const* what, json const& fields, keep_map const& keep_as, Next next)
    {
        json const wanted = vars_.resolve(fields);
        std::string const expected = what + (wanted.empty() ? std::string() : " with " + describe_json(wanted));
        auto const message = next();
        if (!message)
            throw step_failed{expected, "none within " + std::to_string(options_.timeout.count()) + " ms"};
        json got = json::parse(protocol::encode(*message));
        got.erase("type");
        for (auto const& [field, value] : wanted.items()) {
            json const& have = got.contains(field) ? got[field] : json();
            if (!same(have, value))
                throw step_failed{expected, describe_json(got)};
        }
        keep(keep_as, got);
        return describe_json(got);
    }

    void close_all()
    {
        for (auto& [name, c] : clients_)
            if (c.link)
                c.link->close();
    }

    script const& script_;
    run_options const& options_;
    std::ostream& log_;
    variables vars_;
    std::map<std::string, client_state> clients_;
};

} // namespace

run_result run_script(script const& s, run_options const& options, std::ostream& log)
{
    return script_runner(s, options, log).run();
}

} // namespace kugel::client
