#pragma once

// The continuous mode's one workspace: the paths, the event queue and the grid, kept from step
// to step so that a step in a steady state allocates nothing.

#include "physics/aabb.hpp"
#include "physics/body_path.hpp"
#include "physics/contact_events.hpp"
#include "physics/broadphase.hpp"
#include "physics/continuous/calendar.hpp"
#include "physics/continuous/event.hpp"
#include "physics/continuous/path_grid.hpp"
#include "physics/vec.hpp"

#include <array>
#include <cstdint>
#include <vector>

namespace kugel::physics::continuous {

struct workspace
{
    std::vector<std::uint32_t> members;  ///< the spheres (radius > 0), in slot order
    std::vector<body_path> paths;        ///< by body: its path in this step, from its last change
    std::vector<aabb> path_box;          ///< by body: its path's box to the slice's end, from its last change
    std::vector<vec3> free_acceleration; ///< by body: its acceleration from free motion alone
    std::vector<std::uint32_t> version;  ///< by body: bumped when its path changes
    std::vector<std::uint32_t> changed;  ///< by body: when its path last changed, as a count of changes in the step (0: not yet)
    std::vector<std::uint64_t> events_of; ///< by body: events it took part in this step
    std::vector<event> queue;            ///< a min-heap by operator>
    std::vector<vec3> start;             ///< by body: the step's start, when its drift was pending
    /// Kept only when keep_segments is set (the discrete sweep's): where each body went in the
    /// step, as its paths from one change to the next.
    struct segment
    {
        std::uint32_t body;
        double until; ///< s, the path's end (its start is path.t)
        body_path path;
    };
    bool keep_segments = false;
    std::vector<segment> segments;
    /// Kept only when keep_contacts is set (a world that reports contacts): each response to a
    /// pair of spheres in the step, and when (s from the step's start).
    bool keep_contacts = false;
    std::vector<pair_touch> touches;
    /// 1/s; set by the discrete sweep alone (0 in continuous mode): a pair of spheres that
    /// would meet moving against each other slower than this times the smaller radius (the
    /// speed below which the sweep leaves a body to the discrete step) is no event: they are
    /// left to the discrete step that follows the sweep, which answers them as it answers
    /// every slow contact. Spheres resting on each other under gravity otherwise meet again
    /// and again at ever smaller speeds (inelastic collapse), and the sweep reached its event
    /// cap in a forming pile.
    double left_to_discrete = 0.0;
    path_grid grid;
    /// Force-free worlds in a closed box: the events kept from step to step instead.
    calendar kept;
    /// Bodies whose boxes overlap at a slice's start, and the events found at a step's or a
    /// slice's start: a list for each part of the work, which lent threads do side by side.
    std::vector<std::vector<std::array<std::uint32_t, 2>>> pairs;
    std::vector<std::vector<event>> found;
    // the boxes too large for the grid's cells, paired among themselves
    std::vector<aabb> listed_boxes;
    std::vector<box_pair> listed_pairs;
    broadphase_workspace broadphase;
};

} // namespace kugel::physics::continuous
