#pragma once

#include "metrics.hpp"

#include "protocol/compact.hpp"
#include "protocol/messages.hpp"

#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace kugel::server {

/// One snapshot in every form a session may be sent, each encoded at most once and its bytes
/// shared by every session that sends it (DESIGN.md, one tick):
///  - full: every body in full (protocol 1's form; encoded when the room has a client of
///    that form, or when a session first asks);
///  - keyframe: the compact form of every body, encoded only when a session needs one;
///    the quantized state behind it and the deltas is made only when a compact client
///    listens (or a session that just switched to compact asks for the keyframe);
///  - deltas: the compact bodies that changed since the room's previous snapshot of a chain
///    (chains_, by how many of the room's snapshots a client's rate skips), encoded by the
///    room's encoder in tick order.
///  - catch-up deltas: for a client that skipped snapshots (slow, or its unsent one was
///    replaced), the delta from the state it holds, encoded on first demand and shared by
///    every client holding that same state (a few bases per snapshot at most): a client
///    that falls a snapshot behind is not sent a keyframe many times a delta's size, which
///    would put it further behind.
/// A session picks the form at the moment it writes, never earlier: a delta only against
/// the state the client holds (the last compact snapshot it was sent), else the keyframe.
/// So a client that skips snapshots never gets a delta it cannot apply. Thread-safe.
///
/// A snapshot is made for one view of the world (`view`): 0 holds every body, the others the
/// bodies one interest holds (interest.hpp), each view with its own chains. Deltas go only
/// between snapshots of one view: a client whose interest changed holds another view's state.
class encoded_snapshot
{
public:
    struct delta_form
    {
        std::uint64_t base = 0; ///< the tick the delta applies to
        std::shared_ptr<std::string const> bytes;
    };

    /// What the compact forms are made of: `owners` (sorted by id) name who spawned which
    /// body, `q` the quanta. Each form encoded is counted in `encoded` (when given).
    encoded_snapshot(std::uint64_t index, std::uint64_t view, protocol::snapshot full,
                     std::vector<protocol::body_owner> owners, protocol::quanta q,
                     std::shared_ptr<snapshot_form_counters> encoded = nullptr);

    /// The room's count of snapshots encoded before this one: a client that takes every
    /// n-th snapshot takes those whose index is a multiple of n.
    std::uint64_t index() const { return index_; }
    /// The view of the world it shows: 0 every body; another number, the bodies of one
    /// interest (never reused by the room for another).
    std::uint64_t view() const { return view_; }
    std::uint64_t tick() const { return full_snapshot_.tick; }

    std::shared_ptr<std::string const> const& full() const;
    /// The quantized state (protocol::quantize), made on the first call.
    std::shared_ptr<protocol::compact_state const> const& compact() const;
    std::shared_ptr<std::string const> const& keyframe() const;
    /// Set by the encoder before the snapshot is offered to any session.
    void add_delta(delta_form d);
    /// A delta against `base`, if one was encoded; null otherwise.
    std::shared_ptr<std::string const> delta_from(std::uint64_t base) const;
    /// Set by the encoder: this snapshot is a forced keyframe of the chain of `every`.
    void force_keyframe(std::uint64_t every);
    /// The delta for a client of the chain of `every` that holds `held` (a state of this
    /// view): the encoder's, or a catch-up delta. Null when the client is to get the
    /// keyframe: its chain's keyframe is due, a keyframe serves better (protocol::delta),
    /// or most_catch_up_bases other bases were asked for already.
    std::shared_ptr<std::string const> delta_for(protocol::compact_state const& held,
                                                 std::uint64_t every) const;
    /// Counts an encoding made for one session alone (a delta between two views).
    void count_encoded(snapshot_form form, std::size_t bytes) const;

private:
    std::uint64_t index_;
    std::uint64_t view_;
    protocol::snapshot full_snapshot_;
    std::vector<protocol::body_owner> owners_;
    protocol::quanta quanta_;
    std::shared_ptr<snapshot_form_counters> encoded_;
    std::vector<delta_form> deltas_;
    std::vector<std::uint64_t> forced_keyframes_; ///< the chains (by `every`) it is a keyframe of
    /// Catch-up deltas encoded so far, by base tick (null: a keyframe serves better).
    static constexpr std::size_t most_catch_up_bases = 8;
    mutable std::mutex catch_up_mutex_;
    mutable std::vector<delta_form> catch_up_;
    mutable std::once_flag compact_once_;
    mutable std::shared_ptr<protocol::compact_state const> compact_;
    mutable std::once_flag full_once_;
    mutable std::shared_ptr<std::string const> full_;
    mutable std::once_flag keyframe_once_;
    mutable std::shared_ptr<std::string const> keyframe_;
};

/// What the room's encoder keeps between snapshots: the last compact state of each chain. A
/// chain of n takes every n-th snapshot; its clients get deltas between consecutive ones.
/// Used by one encoding at a time (room::send_snapshot runs them one after the other).
class snapshot_chains
{
public:
    /// Adds to `s` a delta for every chain in `every` that takes it, against that chain's
    /// last state, and makes `s`'s compact state their last. A chain's delta is left out (its clients get
    /// the keyframe) when `keyframe_every` of its snapshots have passed since its last
    /// keyframe, when the quanta changed, or when most bodies were replaced. Chains not in
    /// `every` are forgotten.
    void encode(encoded_snapshot& s, std::vector<std::uint64_t> const& every, double keyframe_seconds,
                double room_snapshot_rate);

private:
    struct chain
    {
        std::uint64_t every = 1;
        std::shared_ptr<protocol::compact_state const> last;
        std::uint64_t since_keyframe = 0; ///< deltas since the last forced keyframe
    };
    std::vector<chain> chains_;
};

} // namespace kugel::server
