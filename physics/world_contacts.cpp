// The world's contact events (contact_events.hpp): after each substep's collisions, which
// reported pairs began to touch. A world that reports no body never comes here.

#include "world.hpp"

#include <algorithm>
#include <tuple>

namespace kugel::physics {

namespace {

bool by_pair(std::pair<body_id, body_id> const& x, std::pair<body_id, body_id> const& y)
{
    return std::tuple(x.first.index, x.first.generation, x.second.index, x.second.generation) <
           std::tuple(y.first.index, y.first.generation, y.second.index, y.second.generation);
}

/// A contact ends when its spheres are apart by more than this share of the smaller radius:
/// far enough that a viewer sees them part, where the discrete mode's answers leave resting
/// spheres apart by up to a step's fall (its contact margin, |Δv|·h) and hovering for a few
/// steps after a stop, which is one contact, not several.
constexpr double parting_share = 0.5;

} // namespace

bool world::report_contacts(body_id id, bool on)
{
    if (!bodies_.contains(id))
        return false;
    if (reports_.size() <= id.index)
        reports_.resize(std::size_t{id.index} + 1, 0);
    if ((reports_[id.index] != 0) != on) {
        reports_[id.index] = on ? 1 : 0;
        on ? ++reporting_ : --reporting_;
        if (!on)
            forget_contacts(id);
    }
    return true;
}

void world::forget_contacts(body_id id)
{
    if (id.index < reports_.size() && reports_[id.index] != 0) {
        reports_[id.index] = 0;
        --reporting_;
    }
    std::erase_if(touching_, [&](auto const& pair) { return pair.first == id || pair.second == id; });
}

void world::keep_touches()
{
    bool const keep = reporting_ > 0;
    collision_workspace_.continuous.keep_contacts = keep;
    collision_workspace_.discrete.swept.keep_contacts = keep;
}

void world::note_touches(double h, double start)
{
    auto const ids = bodies_.ids();
    auto const x = bodies_.positions();
    auto const radius = bodies_.radii();
    auto const reported = [&](std::uint32_t slot) {
        body_id const id = ids[slot];
        return id.index < reports_.size() && reports_[id.index] != 0;
    };
    // Every pair the collisions answered, as an event at the time it did
    touches_.clear();
    auto const met = [&](std::uint32_t i, std::uint32_t j, double t) {
        if (!reported(i) || !reported(j))
            return;
        body_id a = ids[i], b = ids[j];
        if (by_id(b, a))
            std::swap(a, b);
        touches_.push_back({start + t, a, b});
    };
    if (settings_.collisions.mode == collision_mode::continuous) {
        for (pair_touch const& t : collision_workspace_.continuous.touches)
            met(t.a, t.b, t.time);
    } else if (!(gathered_ && active_.empty())) { // discrete: unless no collision step ran
        // the sweep's responses at their times; the overlaps (and speculative contacts) the
        // step answered at its end
        discrete_workspace const& ws = collision_workspace_.discrete;
        auto const slot = [&](std::uint32_t i) { return gathered_ ? active_[i] : i; };
        for (pair_touch const& t : ws.swept.touches)
            met(slot(t.a), slot(t.b), t.time);
        for (contact_slab const& s : ws.slabs)
            for (sphere_pair const& c : s.contacts)
                met(slot(ws.grid.slot(c.a)), slot(ws.grid.slot(c.b)), h);
    }
    std::sort(touches_.begin(), touches_.end(), [](contact_event const& p, contact_event const& q) {
        return std::tuple(p.a.index, p.a.generation, p.b.index, p.b.generation, p.time) <
               std::tuple(q.a.index, q.a.generation, q.b.index, q.b.generation, q.time);
    });

    // A pair that touched and did not touch before begins a contact, at its first touch.
    auto& now = touching_next_; // reused: no allocation per substep once it has grown
    now.clear();
    for (std::size_t k = 0; k < touches_.size(); ++k) {
        contact_event const& e = touches_[k];
        if (k > 0 && touches_[k - 1].a == e.a && touches_[k - 1].b == e.b)
            continue; // the pair's later touches
        std::pair const pair{e.a, e.b};
        now.push_back(pair);
        if (!std::binary_search(touching_.begin(), touching_.end(), pair, by_pair))
            contact_events_.push_back(e);
    }
    // One that touched before and not now goes on touching until its spheres part (a pair at
    // rest, asleep, or a step's answer away). Searched among this substep's touches alone,
    // the sorted part (touches_ is in pair order).
    auto const touched = static_cast<std::ptrdiff_t>(now.size());
    for (auto const& pair : touching_) {
        auto const i = bodies_.slot_of(pair.first), j = bodies_.slot_of(pair.second);
        if (!i || !j || std::binary_search(now.begin(), now.begin() + touched, pair, by_pair))
            continue;
        double const reach = radius[*i] + radius[*j];
        if ((x[*i] - x[*j]).norm() <= reach + parting_share * std::min(radius[*i], radius[*j]))
            now.push_back(pair);
    }
    std::sort(now.begin(), now.end(), by_pair);
    std::swap(touching_, now);
}

} // namespace kugel::physics
