// Fuzz target: scene loading. Any text given as a scene file, optionally with one --set
// override: an input whose first line starts with "set:" uses the rest of that line as
// "PATH=VALUE" and the remaining lines as the scene.
//
// Properties checked on every input:
//  - parse_scene() either returns a scene or throws scene_error (any other exception, a
//    crash or a sanitizer report is a bug);
//  - a scene it accepts with at most 500 bodies builds a world (continuous mode capped at
//    1,000 events per step), and five steps either
//    complete with every position and velocity finite or stop on a singular force (the
//    documented outcome of two coincident bodies without softening).

#include "physics/forces.hpp"
#include "scene/scene.hpp"

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>
#include <vector>

namespace {

void require(bool ok)
{
    if (!ok)
        std::abort(); // the fuzzer reports the input
}

constexpr std::uint64_t largest_world_stepped = 500;

} // namespace

extern "C" int LLVMFuzzerTestOneInput(std::uint8_t const* data, std::size_t size)
{
    std::string_view text(reinterpret_cast<char const*>(data), size);
    std::vector<std::string> overrides;
    if (text.starts_with("set:")) {
        auto const end = text.find('\n');
        overrides.emplace_back(text.substr(4, end == std::string_view::npos ? text.npos : end - 4));
        text = end == std::string_view::npos ? std::string_view{} : text.substr(end + 1);
    }

    kugel::scene::scene loaded;
    try {
        loaded = kugel::scene::parse_scene(text, "fuzz input", overrides);
    } catch (kugel::scene::scene_error const&) {
        return 0; // refused with a message: what bad input should get
    }
    if (loaded.body_count() > largest_world_stepped)
        return 0;
    // A legal scene may allow 10^5 events per step, which under the sanitizers takes seconds
    // a step; a lower cap reaches the same code (the capped step ends in discrete mode).
    loaded.collisions.max_events_per_step = std::min<std::uint64_t>(loaded.collisions.max_events_per_step, 1'000);

    auto world = kugel::scene::build_world(loaded);
    for (int step = 0; step < 5; ++step) {
        try {
            world.step(loaded.dt);
        } catch (kugel::physics::singular_force_error const&) {
            break;
        }
    }
    auto const& bodies = world.bodies();
    for (std::size_t i = 0; i < bodies.size(); ++i)
        require(bodies.positions()[i].allFinite() && bodies.velocities()[i].allFinite());
    return 0;
}
