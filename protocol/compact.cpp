#include "compact.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>
#include <utility>
#include <vector>

namespace kugel::protocol {

namespace {

/// floor(y) for |y| < 2^62, without a library call: truncation toward zero, one less for a
/// negative y that is not whole. Exact: every double there truncates to a representable
/// integer, and converting it back compares exactly.
std::int64_t floor_to_integer(double y)
{
    auto const k = static_cast<std::int64_t>(y);
    return static_cast<double>(k) > y ? k - 1 : k;
}

/// A tag column of bodies none of which has a tag is left off: the column is there only
/// when some body has a tag (PROTOCOL.md), so that equal states compare equal.
void drop_empty_tags(compact_bodies& b)
{
    if (b.tag && std::all_of(b.tag->begin(), b.tag->end(), [](std::string const& t) { return t.empty(); }))
        b.tag.reset();
}

} // namespace

std::int64_t quantize(double x, double quantum)
{
    double const y = x / quantum + 0.5;
    auto const limit = static_cast<double>(max_quantized);
    if (y > -limit && y < limit) // floor(y) from -limit to limit - 1
        return floor_to_integer(y);
    if (y >= limit)
        return max_quantized;
    return y <= -limit ? -max_quantized : 0; // 0 for NaN, which no server state holds
}

compact_state quantize(snapshot const& full, std::span<body_owner const> owners, quanta q)
{
    body_columns const& b = full.bodies;
    std::size_t const n = b.size();
    compact_state s{.tick = full.tick, .time = full.time, .paused = full.paused,
                    .faults = full.faults, .q = q, .bodies = {}};
    compact_bodies& c = s.bodies;
    // Id order: the world's slots are mostly in it already (bodies are appended with rising
    // ids); a removal or a reordering of the slots breaks it.
    if (std::is_sorted(b.id.begin(), b.id.end())) {
        c.id = b.id;
        c.position.reserve(3 * n); // appended, not zero-filled first
        for (double const x : b.position)
            c.position.push_back(quantize(x, q.position));
        c.velocity.reserve(3 * n);
        for (double const v : b.velocity)
            c.velocity.push_back(quantize(v, q.velocity));
        c.radius = b.radius;
        c.mass = b.mass ? *b.mass : std::vector<double>(n, 0.0);
        c.charge = b.charge;
        if (b.tag && b.tag->size() == n)
            c.tag = b.tag;
    } else {
        std::vector<std::uint32_t> order(n);
        std::iota(order.begin(), order.end(), 0U);
        std::sort(order.begin(), order.end(),
                  [&](std::uint32_t l, std::uint32_t r) { return b.id[l] < b.id[r]; });
        c.position.resize(3 * n);
        c.velocity.resize(3 * n);
        c.id.resize(n);
        c.radius.resize(n);
        c.mass.resize(n);
        if (b.charge)
            c.charge.emplace(n);
        bool const tags = b.tag && b.tag->size() == n;
        if (tags)
            c.tag.emplace(n);
        for (std::size_t k = 0; k < n; ++k) {
            std::size_t const i = order[k];
            c.id[k] = b.id[i];
            for (std::size_t d = 0; d < 3; ++d) {
                c.position[3 * k + d] = quantize(b.position[3 * i + d], q.position);
                c.velocity[3 * k + d] = quantize(b.velocity[3 * i + d], q.velocity);
            }
            c.radius[k] = b.radius[i];
            c.mass[k] = b.mass ? (*b.mass)[i] : 0.0;
            if (b.charge)
                (*c.charge)[k] = (*b.charge)[i];
            if (tags)
                (*c.tag)[k] = (*b.tag)[i];
        }
    }
    drop_empty_tags(c);
    c.owner.assign(n, 0);
    std::size_t next_owner = 0;
    for (std::size_t k = 0; k < n && next_owner < owners.size(); ++k) {
        while (next_owner < owners.size() && owners[next_owner].id < c.id[k])
            ++next_owner;
        if (next_owner < owners.size() && owners[next_owner].id == c.id[k])
            c.owner[k] = owners[next_owner].client;
    }
    return s;
}

double prediction_factor(double base_time, double time, quanta q)
{
    return (time - base_time) * q.velocity / q.position / 2.0;
}

std::int64_t predicted_position(std::int64_t base_position, std::int64_t base_velocity,
                                std::int64_t velocity, double half_steps)
{
    double const moved = static_cast<double>(base_velocity + velocity) * half_steps;
    if (!(std::abs(moved) < static_cast<double>(max_quantized)))
        return base_position; // no prediction that far (or after a hostile base)
    return base_position + floor_to_integer(moved + 0.5);
}

compact_snapshot keyframe_head(compact_state const& state)
{
    return {.tick = state.tick,
            .form = "key",
            .base = std::nullopt,
            .time = state.time,
            .paused = state.paused,
            .faults = state.faults,
            .q = std::array{state.q.position, state.q.velocity},
            .bodies = std::nullopt,
            .moved = std::nullopt,
            .appeared = std::nullopt,
            .vanished = std::nullopt};
}

compact_snapshot keyframe(compact_state const& state)
{
    compact_snapshot k = keyframe_head(state);
    k.bodies = state.bodies;
    return k;
}

namespace {

/// Appends body i of `from` to `to`, constants and all.
void append_body(compact_bodies& to, compact_bodies const& from, std::size_t i)
{
    to.id.push_back(from.id[i]);
    for (std::size_t d = 0; d < 3; ++d) {
        to.position.push_back(from.position[3 * i + d]);
        to.velocity.push_back(from.velocity[3 * i + d]);
    }
    to.radius.push_back(from.radius[i]);
    to.mass.push_back(from.mass[i]);
    to.owner.push_back(from.owner[i]);
    if (to.charge && from.charge)
        to.charge->push_back((*from.charge)[i]);
    // The tag column starts with the first tagged body ("" for those before it).
    std::string const none;
    std::string const& tag = from.tag && i < from.tag->size() ? (*from.tag)[i] : none;
    if (!to.tag && !tag.empty())
        to.tag.emplace(to.id.size() - 1);
    if (to.tag)
        to.tag->push_back(tag);
}

void reserve(compact_bodies& b, std::size_t n, bool charges)
{
    b.id.reserve(n);
    b.position.reserve(3 * n);
    b.velocity.reserve(3 * n);
    b.radius.reserve(n);
    b.mass.reserve(n);
    b.owner.reserve(n);
    if (charges) {
        b.charge.emplace();
        b.charge->reserve(n);
    }
}

} // namespace

std::optional<compact_snapshot> delta(compact_state const& base, compact_state const& now)
{
    if (base.q != now.q || !(base.tick < now.tick))
        return std::nullopt;
    compact_bodies const& from = base.bodies;
    compact_bodies const& to = now.bodies;
    bool const charges = to.charge.has_value();
    double const half_steps = prediction_factor(base.time, now.time, now.q);

    compact_moves moved;
    moved.position.reserve(3 * to.size());
    moved.velocity.reserve(3 * to.size());
    compact_bodies appeared;
    if (charges)
        appeared.charge.emplace();
    std::vector<std::uint64_t> vanished;
    std::uint64_t skip = 0, take = 0; // the run being counted: base bodies kept, then moved
    auto const still = [&] {
        if (take > 0) {
            moved.runs.push_back(skip);
            moved.runs.push_back(take);
            skip = take = 0;
        }
        ++skip;
    };
    std::size_t i = 0, j = 0;
    while (i < from.size() || j < to.size()) {
        if (j == to.size() || (i < from.size() && from.id[i] < to.id[j])) {
            vanished.push_back(from.id[i++]);
            still();
        } else if (i == from.size() || to.id[j] < from.id[i]) {
            append_body(appeared, to, j++);
        } else {
            bool const same = std::equal(&from.position[3 * i], &from.position[3 * i] + 3,
                                         &to.position[3 * j]) &&
                              std::equal(&from.velocity[3 * i], &from.velocity[3 * i] + 3,
                                         &to.velocity[3 * j]);
            if (same) {
                still();
            } else {
                ++take;
                for (std::size_t d = 0; d < 3; ++d) {
                    std::int64_t const v = to.velocity[3 * j + d];
                    std::int64_t const vb = from.velocity[3 * i + d];
                    moved.position.push_back(to.position[3 * j + d] -
                                             predicted_position(from.position[3 * i + d], vb, v,
                                                                half_steps));
                }
                for (std::size_t d = 0; d < 3; ++d)
                    moved.velocity.push_back(to.velocity[3 * j + d] - from.velocity[3 * i + d]);
            }
            ++i;
            ++j;
        }
    }
    if (take > 0) {
        moved.runs.push_back(skip);
        moved.runs.push_back(take);
    }
    // A reset or a new scene replaces every body: then a keyframe is smaller.
    if (appeared.size() + vanished.size() > to.size() / 2 + 8)
        return std::nullopt;
    compact_snapshot out{.tick = now.tick,
                         .form = "delta",
                         .base = base.tick,
                         .time = now.time,
                         .paused = now.paused,
                         .faults = now.faults,
                         .q = std::nullopt,
                         .bodies = std::nullopt,
                         .moved = std::nullopt,
                         .appeared = std::nullopt,
                         .vanished = std::nullopt};
    if (!moved.runs.empty())
        out.moved = std::move(moved);
    drop_empty_tags(appeared);
    if (appeared.size() > 0)
        out.appeared = std::move(appeared);
    if (!vanished.empty())
        out.vanished = std::move(vanished);
    return out;
}

namespace {

apply_result refused(std::string why)
{
    return {std::nullopt, std::move(why)};
}

bool safe(std::int64_t x)
{
    auto const limit = static_cast<std::int64_t>(max_safe_integer);
    return x >= -limit && x <= limit;
}

} // namespace

apply_result apply_compact(compact_snapshot const& message, compact_state const* held)
{
    if (message.form == "key") {
        if (!message.bodies || !message.q)
            return refused("a keyframe without bodies or q");
        compact_state s{.tick = message.tick, .time = message.time, .paused = message.paused,
                        .faults = message.faults,
                        .q = {(*message.q)[0], (*message.q)[1]}, .bodies = *message.bodies};
        drop_empty_tags(s.bodies);
        return {std::move(s), {}};
    }
    if (message.form != "delta" || !message.base)
        return refused("neither a keyframe nor a delta");
    if (!held)
        return refused("a delta against tick " + std::to_string(*message.base) +
                       ", and no keyframe came before it");
    if (held->tick != *message.base)
        return refused("a delta against tick " + std::to_string(*message.base) +
                       ", but the state held is of tick " + std::to_string(held->tick));

    compact_bodies const& from = held->bodies;
    bool const charges = from.charge.has_value();
    compact_moves const no_moves;
    compact_moves const& moved = message.moved ? *message.moved : no_moves;
    std::vector<std::uint64_t> const no_ids;
    std::vector<std::uint64_t> const& vanished = message.vanished ? *message.vanished : no_ids;
    double const half_steps = prediction_factor(held->time, message.time, held->q);

    compact_state s{.tick = message.tick, .time = message.time, .paused = message.paused,
                    .faults = message.faults, .q = held->q, .bodies = {}};
    compact_bodies kept;
    reserve(kept, from.size(), charges);
    std::size_t run = 0;          // index into moved.runs
    std::uint64_t run_left = 0;   // bodies left in the current run
    std::size_t next_move = 0;    // moved body being read
    std::size_t next_vanished = 0;
    auto advance_runs = [&] {
        while (run_left == 0 && run < moved.runs.size())
            run_left = moved.runs[run++];
    };
    for (std::size_t i = 0; i < from.size(); ++i) {
        advance_runs();
        bool const is_moved = run_left > 0 && run % 2 == 0; // run was incremented past a take
        if (run_left > 0)
            --run_left;
        if (next_vanished < vanished.size() && vanished[next_vanished] == from.id[i]) {
            ++next_vanished;
            if (is_moved)
                return refused("body " + std::to_string(from.id[i]) + " both moved and vanished");
            continue;
        }
        append_body(kept, from, i);
        if (!is_moved)
            continue;
        if (3 * next_move + 3 > moved.position.size() || 3 * next_move + 3 > moved.velocity.size())
            return refused("moved.runs name more bodies than moved.p and moved.v hold");
        std::size_t const k = kept.size() - 1;
        for (std::size_t d = 0; d < 3; ++d) {
            std::int64_t const vb = from.velocity[3 * i + d];
            std::int64_t const v = vb + moved.velocity[3 * next_move + d];
            std::int64_t const p =
                predicted_position(from.position[3 * i + d], vb, v, half_steps) +
                moved.position[3 * next_move + d];
            if (!safe(v) || !safe(p))
                return refused("body " + std::to_string(from.id[i]) + " moves beyond 2^53 quanta");
            kept.velocity[3 * k + d] = v;
            kept.position[3 * k + d] = p;
        }
        ++next_move;
    }
    advance_runs();
    if (run_left > 0 || run < moved.runs.size())
        return refused("moved.runs reach past the base's " + std::to_string(from.size()) + " bodies");
    if (next_vanished < vanished.size())
        return refused("vanished body " + std::to_string(vanished[next_vanished]) +
                       " is not in the base (or not in id order)");

    // The bodies kept and those that appeared, merged in id order.
    compact_bodies const no_bodies;
    compact_bodies const& added = message.appeared ? *message.appeared : no_bodies;
    if (message.appeared && added.charge.has_value() != charges)
        return refused("appeared bodies have charges where the keyframe's have none, or none "
                       "where it has them");
    compact_bodies& out = s.bodies;
    reserve(out, kept.size() + added.size(), charges);
    std::size_t a = 0, b = 0;
    while (a < kept.size() || b < added.size()) {
        if (b == added.size() || (a < kept.size() && kept.id[a] < added.id[b])) {
            append_body(out, kept, a++);
        } else if (a == kept.size() || added.id[b] < kept.id[a]) {
            append_body(out, added, b++);
        } else {
            return refused("appeared body " + std::to_string(added.id[b]) + " is already held");
        }
    }
    drop_empty_tags(out);
    return {std::move(s), {}};
}

snapshot to_snapshot(compact_state const& state)
{
    compact_bodies const& c = state.bodies;
    snapshot s{.tick = state.tick, .time = state.time, .paused = state.paused,
               .faults = state.faults, .bodies = {}};
    body_columns& b = s.bodies;
    b.id = c.id;
    b.position.resize(c.position.size());
    b.velocity.resize(c.velocity.size());
    for (std::size_t k = 0; k < c.position.size(); ++k) {
        b.position[k] = static_cast<double>(c.position[k]) * state.q.position;
        b.velocity[k] = static_cast<double>(c.velocity[k]) * state.q.velocity;
    }
    b.radius = c.radius;
    b.mass = c.mass;
    b.charge = c.charge;
    b.tag = c.tag;
    return s;
}

} // namespace kugel::protocol
