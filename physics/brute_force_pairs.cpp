#include "broadphase.hpp"

namespace kugel::physics {

// Lecture: "n Objekte: Welche überschneiden sich? (Brute force: n^2 Tests)". Every one of the
// n(n-1)/2 pairs is tested with the 1D interval rule on all three axes. The loops visit
// (a, b) in ascending order, so the output needs no sort. This is the reference the other
// broadphases are tested against.
void brute_force_pairs(std::span<aabb const> boxes, std::vector<box_pair>& out)
{
    out.clear();
    auto const n = static_cast<std::uint32_t>(boxes.size());
    for (std::uint32_t a = 0; a < n; ++a) {
        aabb const& box_a = boxes[a];
        for (std::uint32_t b = a + 1; b < n; ++b) {
            if (overlaps(box_a, boxes[b]))
                out.push_back({a, b});
        }
    }
}

} // namespace kugel::physics
