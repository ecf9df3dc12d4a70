// kugel-server: steps a scene's world. With --headless it runs a fixed number of steps
// without networking and prints one JSON summary on stdout; logs go to stderr.

#include "headless.hpp"
#include "scene/scene.hpp"

#include <CLI/CLI.hpp>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <iostream>
#include <string>
#include <vector>

namespace {

int run_headless_command(std::string const& scene_file, std::vector<std::string> const& overrides,
                         std::uint64_t steps)
{
    using namespace kugel;
    scene::scene s;
    try {
        s = scene::load_scene(scene_file, overrides);
    } catch (scene::scene_error const& e) {
        spdlog::error("{}", e.what());
        return 2;
    }
    spdlog::info("scene '{}': {} bodies, dt {} s, integrator {}, {} steps", s.name, s.body_count(),
                 s.dt, physics::info(s.integrator).name, steps);
    nlohmann::ordered_json summary;
    try {
        summary = server::run_headless(s, steps);
    } catch (physics::singular_force_error const& e) {
        spdlog::error("the scene's initial state is singular: {}", e.what());
        return 1;
    }
    std::cout << summary.dump() << '\n';
    if (summary.contains("error")) {
        spdlog::error("{}", summary["error"].get<std::string>());
        return 1;
    }
    spdlog::info("{} steps in {:.1f} ms, energy drift {}", steps, summary["wall_ms"].get<double>(),
                 summary["energy_rel_drift"].dump());
    return 0;
}

} // namespace

int main(int argc, char** argv)
{
    spdlog::set_default_logger(spdlog::stderr_color_mt("kugel"));

    CLI::App app{"kugel-server: an authoritative physics server for point masses and spheres.\n"
                 "Steps a scene's world at a fixed dt; --headless runs it without networking and "
                 "prints one JSON summary on stdout (logs go to stderr)."};
    std::string scene_file;
    bool headless = false;
    std::uint64_t steps = 1000;
    std::vector<std::string> overrides;
    std::string log_level = "info";
    app.add_option("--scene", scene_file, "Scene file (JSON), see scenes/README.md")
        ->check(CLI::ExistingFile);
    app.add_flag("--headless", headless,
                 "Step the scene without networking and print a JSON summary on stdout");
    app.add_option("--steps", steps, "Steps to run with --headless")
        ->check(CLI::Range(std::uint64_t{0}, std::uint64_t{1'000'000'000}))
        ->capture_default_str();
    app.add_option("--set", overrides,
                   "Override a scene field before validation, PATH=VALUE (repeatable), e.g.\n"
                   "--set integrator=rk4 --set dt=0.001 --set generators.0.count=100000\n"
                   "--set forces.gravity.softening=0.01. VALUE is JSON, or a plain string.")
        ->take_all();
    app.add_option("--log-level", log_level, "trace, debug, info, warn, error, critical or off")
        ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error", "critical", "off"}))
        ->capture_default_str();
    CLI11_PARSE(app, argc, argv);
    spdlog::set_level(spdlog::level::from_str(log_level));

    if (!headless) {
        spdlog::error("serving over the network is not built yet; run a scene with --headless");
        return 2;
    }
    if (scene_file.empty()) {
        spdlog::error("--headless needs --scene FILE");
        return 2;
    }
    return run_headless_command(scene_file, overrides, steps);
}
