#include "aabb.hpp"

namespace kugel::physics {

void boxes_of_spheres(std::span<vec3 const> x, std::span<double const> radius, std::vector<aabb>& boxes,
                      std::vector<std::uint32_t>& members, double margin)
{
    boxes.clear();
    members.clear();
    boxes.reserve(x.size()); // grown once, not doubled on the way
    members.reserve(x.size());
    for (std::size_t i = 0; i < x.size(); ++i) {
        if (radius[i] > 0.0) {
            boxes.push_back(aabb_of_sphere(x[i], radius[i] + margin));
            members.push_back(static_cast<std::uint32_t>(i));
        }
    }
}

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
