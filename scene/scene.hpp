#pragma once

#include "physics/aabb.hpp"
#include "physics/body_storage.hpp"
#include "physics/bounding_sphere.hpp"
#include "physics/collisions.hpp"
#include "physics/integrators.hpp"
#include "physics/world.hpp"

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace kugel::scene {

/// A scene that cannot be loaded. what() names the source, the field (a JSON pointer such as
/// /bodies/3/radius) and the reason: "kepler.json: /bodies/1/mass: must be > 0, got -2".
class scene_error : public std::runtime_error
{
public:
    using std::runtime_error::runtime_error;
};

struct uniform_field_settings
{
    physics::vec3 g{0.0, 0.0, -9.81}; ///< m/s²
};

/// How a pairwise law is summed: every pair (exact, O(n²)) or through a Barnes–Hut tree
/// (O(n log n), error set by the opening angle θ).
enum class force_method {
    direct,
    tree,
};

struct gravity_settings
{
    double G = 6.6743e-11;  ///< m³/(kg·s²)
    double softening = 0.0; ///< m, Plummer ε
    force_method method = force_method::direct;
    double theta = 0.5; ///< the tree's opening angle, in (0, 1]; only with method tree
};

struct coulomb_settings
{
    double k = 8.9875517923e9; ///< N·m²/C²
    double softening = 0.0;    ///< m
    force_method method = force_method::direct;
    double theta = 0.5; ///< as for gravity
};

/// "direct" or "tree".
std::string_view name(force_method method);

/// The force models a scene names; only these are built.
struct force_settings
{
    std::optional<uniform_field_settings> uniform_field;
    std::optional<gravity_settings> gravity;
    std::optional<coulomb_settings> coulomb;
};

enum class placement {
    random,  ///< uniform in the region; spheres may overlap
    lattice, ///< on a cubic lattice filling the region, no two spheres overlapping
    plummer, ///< a Plummer sphere in equilibrium under the scene's gravity (no region)
};

/// N bodies placed in a box, each with a velocity drawn uniformly from the ball of radius
/// max_speed; or (placement plummer) a Plummer sphere around `centre`, positions and
/// velocities drawn from its equilibrium under the scene's G. Seeded: the same scene always
/// gives the same bodies.
struct body_generator
{
    std::uint64_t count = 0;
    placement where = placement::random;
    std::uint64_t seed = 1;
    physics::aabb region;   ///< m; random and lattice
    double max_speed = 0.0; ///< m/s; random and lattice
    physics::vec3 centre = physics::vec3::Zero(); ///< m; plummer
    double scale_radius = 0.0;                    ///< m, a > 0; plummer
    double radius = 0.0;    ///< m
    double mass = 1.0;      ///< kg, from `mass` or from `density`
    double charge = 0.0;    ///< C
};

/// A static box that spheres collide with: given directly, or fitted to points (PCA).
struct obstacle_settings
{
    physics::obb box;
    double damping = 0.0;
    double friction = 0.0;
};

/// How a server sends the scene's state (protocol/PROTOCOL.md, compact snapshots): the steps
/// positions and velocities are quantized to. 0 leaves the choice to the server (from the
/// scene's size and the snapshot rate); a server option given overrides either.
struct snapshot_settings
{
    double position_quantum = 0.0; ///< m; 0, or in [min_quantum, max_quantum]
    double velocity_quantum = 0.0; ///< m/s; 0, or in [min_quantum, max_quantum]

    /// Quanta outside these are typos: below, a position needs more than 2^50 quanta within
    /// a kilometre; above, a body's state is lost in one step.
    static constexpr double min_quantum = 1e-9;
    static constexpr double max_quantum = 1e6;
};

/// Who may push (impulse, set) a body: anyone, its owner (the client that spawned it; a
/// scene's bodies have none), or only admins. An admin always may.
enum class push_rule {
    anyone,
    owner,
    admins,
};

/// Who may remove a body: its owner, or only admins. An admin always may.
enum class remove_rule {
    owner,
    admins,
};

std::string_view name(push_rule rule);   ///< "anyone", "owner", "admins"
std::string_view name(remove_rule rule); ///< "owner", "admins"

/// A scene's `permissions`: the defaults are a room's rules without any.
struct room_permissions
{
    push_rule push = push_rule::anyone;
    remove_rule remove = remove_rule::owner;
};

/// The longest tag a body may carry, in bytes of UTF-8 (as the protocol's spawn.body.tag).
inline constexpr std::size_t max_tag_bytes = 32;

/// What a server does when a player's connection ends (protocol/PROTOCOL.md, resume). A field
/// the scene leaves out is the server's choice (kugel-server --resume-grace,
/// --bodies-on-leave); one it gives wins, so that a demo gets the rules it was written for.
struct player_settings
{
    /// s the room keeps a player whose connection ended, for a hello.resume; 0: none.
    std::optional<double> resume_grace;
    /// "remove": true, the player's bodies go when it leaves for good; "stay": false.
    std::optional<bool> remove_bodies_on_leave;

    static constexpr double max_resume_grace = 86'400.0; ///< s: a day; more is a typo
};

/// The longest sensor name, in bytes of UTF-8 (an event names its sensor).
inline constexpr std::size_t max_sensor_name_bytes = 32;

/// A named sensor (physics/sensors.hpp): a goal, a zone. Events name it.
struct sensor_settings
{
    std::string name; ///< 1 to max_sensor_name_bytes bytes, no control characters, unique
    physics::sensor volume;
};

/// The most `contacts` rules a scene may hold.
inline constexpr std::size_t max_contact_rules = 32;

/// A rule of `contacts`: the contacts between a body tagged `tags[0]` and one tagged `tags[1]`
/// are reported (physics/contact_events.hpp); the order does not matter, and both may be the
/// same tag.
struct contact_rule
{
    std::array<std::string, 2> tags;

    /// Whether bodies with these two tags are the rule's pair, in either order.
    bool matches(std::string const& a, std::string const& b) const
    {
        return (a == tags[0] && b == tags[1]) || (a == tags[1] && b == tags[0]);
    }
};

/// A validated scene: everything a world needs, in engine units.
struct scene
{
    std::string name;
    std::string description;
    double dt = 0.0; ///< s per step, > 0
    int substeps = 1;
    physics::integrator_kind integrator = physics::integrator_kind::velocity_verlet;
    physics::step_control adaptive; ///< the tolerance of an adaptive integrator
    force_settings forces;
    physics::collision_settings collisions;
    std::vector<physics::wall> walls; ///< including the six of `box`
    std::optional<physics::aabb> box; ///< the `box` shortcut's region, when given
    std::vector<obstacle_settings> obstacles;
    /// The world's sensors, in this order (sensor i of the world is sensors[i]).
    std::vector<sensor_settings> sensors;
    /// The pairs of tags whose contacts are reported (a room's `event` messages).
    std::vector<contact_rule> contacts;
    std::vector<physics::body_desc> bodies;
    /// bodies[i]'s tag, "" for none (the world's first bodies, in this order, are these)
    std::vector<std::string> body_tags;
    std::vector<body_generator> generators;
    snapshot_settings snapshots;
    room_permissions permissions;
    player_settings players;

    /// Explicit bodies plus every generator's count.
    std::uint64_t body_count() const;
};

/// The most bodies one scene may create: a typo in a count fails fast, not out of memory.
inline constexpr std::uint64_t max_scene_bodies = 10'000'000;

/// Parses and validates a scene from JSON text. `source` names it in error messages (usually
/// the file name). Each override is "PATH=VALUE" as for `--set` (see apply_override) and is
/// applied to the document before validation, so an override is checked like the file.
scene parse_scene(std::string_view text, std::string const& source,
                  std::span<std::string const> overrides = {});

/// Reads and parses a scene file; throws scene_error when it cannot be read or is invalid.
scene load_scene(std::filesystem::path const& file, std::span<std::string const> overrides = {});

/// Creates the world a scene describes: its settings, force models, sensors (in order) and
/// bodies, generators expanded in order after the explicit bodies.
physics::world build_world(scene const& s);

/// The sphere that holds every body, obstacle and the `box`: what a client frames its
/// camera on.
physics::sphere scene_bounds(scene const& s, physics::world const& w);

} // namespace kugel::scene
