#include "encoded_snapshot.hpp"

#include "protocol/codec.hpp"

#include <algorithm>
#include <cmath>

namespace kugel::server {

encoded_snapshot::encoded_snapshot(std::uint64_t index, std::uint64_t view, protocol::snapshot full,
                                   std::vector<protocol::body_owner> owners, protocol::quanta q,
                                   std::shared_ptr<snapshot_form_counters> encoded)
    : index_(index), view_(view), full_snapshot_(std::move(full)), owners_(std::move(owners)), quanta_(q),
      encoded_(std::move(encoded))
{
}

void encoded_snapshot::add_delta(delta_form d)
{
    if (encoded_)
        encoded_->count(snapshot_form::delta, d.bytes->size());
    deltas_.push_back(std::move(d));
}

std::shared_ptr<protocol::compact_state const> const& encoded_snapshot::compact() const
{
    std::call_once(compact_once_, [&] {
        compact_ = std::make_shared<protocol::compact_state const>(
            protocol::quantize(full_snapshot_, owners_, quanta_));
    });
    return compact_;
}

std::shared_ptr<std::string const> const& encoded_snapshot::full() const
{
    std::call_once(full_once_, [&] {
        full_ = std::make_shared<std::string const>(protocol::encode(full_snapshot_));
        if (encoded_)
            encoded_->count(snapshot_form::full, full_->size());
    });
    return full_;
}

std::shared_ptr<std::string const> const& encoded_snapshot::keyframe() const
{
    std::call_once(keyframe_once_, [&] {
        keyframe_ = std::make_shared<std::string const>(protocol::encode_keyframe(*compact()));
        if (encoded_)
            encoded_->count(snapshot_form::keyframe, keyframe_->size());
    });
    return keyframe_;
}

std::shared_ptr<std::string const> encoded_snapshot::delta_from(std::uint64_t base) const
{
    for (delta_form const& d : deltas_)
        if (d.base == base)
            return d.bytes;
    return nullptr;
}

void encoded_snapshot::force_keyframe(std::uint64_t every)
{
    forced_keyframes_.push_back(every);
}

std::shared_ptr<std::string const> encoded_snapshot::delta_for(protocol::compact_state const& held,
                                                               std::uint64_t every) const
{
    if (auto bytes = delta_from(held.tick))
        return bytes;
    if (std::find(forced_keyframes_.begin(), forced_keyframes_.end(), every) != forced_keyframes_.end())
        return nullptr;
    std::lock_guard const lock(catch_up_mutex_);
    for (delta_form const& d : catch_up_)
        if (d.base == held.tick)
            return d.bytes;
    if (catch_up_.size() >= most_catch_up_bases)
        return nullptr;
    std::shared_ptr<std::string const> bytes;
    if (auto const d = protocol::delta(held, *compact())) {
        bytes = std::make_shared<std::string const>(protocol::encode(*d));
        count_encoded(snapshot_form::delta, bytes->size());
    }
    catch_up_.push_back({held.tick, bytes});
    return bytes;
}

void encoded_snapshot::count_encoded(snapshot_form form, std::size_t bytes) const
{
    if (encoded_)
        encoded_->count(form, bytes);
}

void snapshot_chains::encode(encoded_snapshot& s, std::vector<std::uint64_t> const& every,
                             double keyframe_seconds, double room_snapshot_rate)
{
    std::erase_if(chains_, [&](chain const& c) {
        return std::find(every.begin(), every.end(), c.every) == every.end();
    });
    for (std::uint64_t const n : every)
        if (std::none_of(chains_.begin(), chains_.end(), [&](chain const& c) { return c.every == n; }))
            chains_.push_back({n, nullptr, 0});
    for (chain& c : chains_) {
        if (s.index() % c.every != 0)
            continue;
        std::shared_ptr<protocol::compact_state const> const& now = s.compact();
        // Snapshots of this chain between forced keyframes: at least one.
        double const per_keyframe = keyframe_seconds * room_snapshot_rate / static_cast<double>(c.every);
        bool const keyframe_due =
            static_cast<double>(c.since_keyframe + 1) >= std::max(per_keyframe, 1.0);
        bool delta_sent = false;
        if (c.last && !keyframe_due) {
            delta_sent = s.delta_from(c.last->tick) != nullptr; // another chain's, same base
            if (!delta_sent)
                if (auto const d = protocol::delta(*c.last, *now)) {
                    s.add_delta({c.last->tick, std::make_shared<std::string const>(protocol::encode(*d))});
                    delta_sent = true;
                }
        }
        if (c.last && keyframe_due)
            s.force_keyframe(c.every);
        c.since_keyframe = delta_sent ? c.since_keyframe + 1 : 0;
        c.last = now;
    }
}

} // namespace kugel::server
