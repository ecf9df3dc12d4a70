#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry> // cross products

namespace kugel::physics {

/// A point or a vector in world space. Units are SI unless a scene says otherwise: m, m/s, m/s².
using vec3 = Eigen::Vector3d;

} // namespace kugel::physics
