#include "aabb.hpp"

namespace kugel::physics {

aabb aabb_of_points(std::span<vec3 const> points)
{
    if (points.empty())
        return {};
    aabb box{points[0], points[0]};
    for (vec3 const& p : points.subspan(1)) {
        box.min = box.min.cwiseMin(p);
        box.max = box.max.cwiseMax(p);
    }
    return box;
}

} // namespace kugel::physics
