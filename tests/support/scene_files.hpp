#pragma once

// Test support: scenes written to files for servers under test.

#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <string>

#include <unistd.h>

namespace kugel::test_support {

/// Nothing moves unless pushed: no forces, no collisions, walls at ±10 m. One body of
/// 2 kg at the origin, a power of two so that J/m is exact.
inline nlohmann::json still_scene()
{
    return {{"name", "still"},
            {"dt", 1.0 / 64.0},
            {"integrator", "semi_implicit_euler"},
            {"collisions", {{"mode", "off"}}},
            {"box", {{"min", {-10, -10, -10}}, {"max", {10, 10, 10}}}},
            {"bodies", nlohmann::json::array({{{"position", {0, 0, 0}}, {"radius", 0.5}, {"mass", 2.0}}})}};
}

/// The still scene and `generated` more spheres (r = 0.05 m, 1 kg) at rest on a lattice.
inline nlohmann::json still_scene(int generated)
{
    nlohmann::json scene = still_scene();
    if (generated > 0)
        scene["generators"] = nlohmann::json::array({{{"count", generated},
                                                      {"placement", "lattice"},
                                                      {"radius", 0.05},
                                                      {"mass", 1.0},
                                                      {"max_speed", 0.0},
                                                      {"region", {{"min", {-9, -9, -9}}, {"max", {9, 9, 9}}}}}});
    return scene;
}

/// A scene that differs from the still scene in every way a welcome shows: gravity, a
/// smaller box, another dt and integrator, two bodies.
inline nlohmann::json drop_scene()
{
    return {{"name", "drop"},
            {"dt", 0.01},
            {"integrator", "velocity_verlet"},
            {"forces", {{"uniform_field", {{"g", {0, 0, -9.81}}}}}},
            {"box", {{"min", {-2, -2, 0}}, {"max", {2, 2, 4}}}},
            {"bodies", nlohmann::json::array({{{"position", {0, 0, 3}}, {"radius", 0.2}, {"mass", 1}},
                                              {{"position", {1, 0, 3}}, {"radius", 0.2}, {"mass", 1}}})}};
}

/// Writes `scene` to `file` (indented JSON) and returns the path. The tests run at the same
/// time, each in a process of its own, and several write the same file: so it is written
/// beside and renamed into place, and a reader sees the whole file or the one before, never
/// a half-written one.
inline std::filesystem::path write_scene(std::filesystem::path const& file, nlohmann::json const& scene)
{
    std::filesystem::path const part = file.string() + "." + std::to_string(::getpid()) + ".part";
    std::ofstream(part) << scene.dump(2);
    std::filesystem::rename(part, file);
    return file;
}

} // namespace kugel::test_support
