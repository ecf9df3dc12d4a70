#include "scene.hpp"

#include "physics/barnes_hut.hpp"
#include "physics/forces.hpp"
#include "physics/plummer_sphere.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>
#include <initializer_list>
#include <limits>
#include <numbers>
#include <random>
#include <sstream>

namespace kugel::scene {

using nlohmann::json;

namespace {

/// Where we are in the document, for messages: the source and a JSON pointer.
struct location
{
    std::string const& source;
    std::string pointer;

    location operator/(std::string_view key) const
    {
        return {source, pointer + "/" + std::string(key)};
    }
    location operator/(std::size_t index) const
    {
        return {source, pointer + "/" + std::to_string(index)};
    }

    [[noreturn]] void fail(std::string_view reason) const
    {
        throw scene_error(source + ": " + (pointer.empty() ? "/" : pointer) + ": " +
                          std::string(reason));
    }
};

/// The value's type and its start, for a message: bytes that are not UTF-8 (a --set value
/// is kept as the string it was given when it is not JSON) print as U+FFFD.
std::string describe(json const& value)
{
    std::string text = value.dump(-1, ' ', false, json::error_handler_t::replace);
    if (text.size() > 40)
        text = text.substr(0, 37) + "...";
    return std::string(value.type_name()) + " " + text;
}

std::string join(std::initializer_list<std::string_view> words)
{
    std::string out;
    for (auto w : words)
        out += (out.empty() ? "" : ", ") + std::string(w);
    return out;
}

/// An object whose keys must all be known; a typo is an error, not a silent default.
json const& object(json const& value, location const& at, std::initializer_list<std::string_view> known)
{
    if (!value.is_object())
        at.fail("must be an object, got " + describe(value));
    for (auto const& [key, _] : value.items())
        if (std::find(known.begin(), known.end(), key) == known.end())
            (at / key).fail("unknown field (known here: " + join(known) + ")");
    return value;
}

json const* find(json const& obj, std::string_view key)
{
    auto it = obj.find(key);
    return it == obj.end() ? nullptr : &*it;
}

json const& required(json const& obj, std::string_view key, location const& at)
{
    if (auto const* v = find(obj, key))
        return *v;
    (at / key).fail("missing (required)");
}

double number(json const& value, location const& at)
{
    if (!value.is_number())
        at.fail("must be a number, got " + describe(value));
    double const x = value.get<double>();
    if (!std::isfinite(x))
        at.fail("must be finite");
    return x;
}

std::string format(double x)
{
    std::ostringstream out;
    out << x;
    return out.str();
}

double number_at_least(json const& value, location const& at, double minimum, bool strict)
{
    double const x = number(value, at);
    if (strict ? !(x > minimum) : !(x >= minimum))
        at.fail(std::string("must be ") + (strict ? "> " : ">= ") + format(minimum) + ", got " +
                format(x));
    return x;
}

std::uint64_t whole_number(json const& value, location const& at, std::uint64_t minimum,
                           std::uint64_t maximum)
{
    double const x = number(value, at);
    if (x != std::floor(x))
        at.fail("must be a whole number, got " + format(x));
    if (x < static_cast<double>(minimum) || x > static_cast<double>(maximum))
        at.fail("must be between " + std::to_string(minimum) + " and " + std::to_string(maximum) +
                ", got " + format(x));
    return value.is_number_unsigned() ? value.get<std::uint64_t>() : static_cast<std::uint64_t>(x);
}

physics::vec3 vector3(json const& value, location const& at)
{
    if (!value.is_array() || value.size() != 3)
        at.fail("must be an array of 3 numbers [x, y, z], got " + describe(value));
    return {number(value[0], at / 0), number(value[1], at / 1), number(value[2], at / 2)};
}

std::string text(json const& value, location const& at)
{
    if (!value.is_string())
        at.fail("must be a string, got " + describe(value));
    return value.get<std::string>();
}

bool boolean(json const& value, location const& at)
{
    if (!value.is_boolean())
        at.fail("must be true or false, got " + describe(value));
    return value.get<bool>();
}

template <class T, class Read>
T optional_field(json const& obj, std::string_view key, location const& at, T fallback, Read read)
{
    if (auto const* v = find(obj, key))
        return read(*v, at / key);
    return fallback;
}

/// The mass of a body or generator: exactly one of `mass` (kg, > 0) or `density` (kg/m³, > 0,
/// needs radius > 0). Static bodies may give neither (mass 0: they attract nothing).
double read_mass(json const& obj, location const& at, double radius, bool is_static)
{
    json const* mass = find(obj, "mass");
    json const* density = find(obj, "density");
    if (mass && density)
        at.fail("give either mass or density, not both");
    // A dynamic body moves by 1/m: a mass so small that 1/m overflows (5e-324 kg) has none.
    auto const usable = [&](double m, location const& where, std::string const& what) {
        if (!is_static && !std::isfinite(1.0 / m))
            where.fail(what + format(m) + " kg, too small for a moving body: 1/m overflows");
        return m;
    };
    if (mass)
        return is_static ? number_at_least(*mass, at / "mass", 0.0, false)
                         : usable(number_at_least(*mass, at / "mass", 0.0, true), at / "mass", "is ");
    if (density) {
        double const rho = number_at_least(*density, at / "density", 0.0, true);
        if (radius <= 0.0)
            (at / "density").fail("needs a radius > 0 (a point mass has no volume; give mass)");
        double const m = physics::mass_from_density(rho, radius);
        if (!std::isfinite(m) || (!is_static && !(m > 0.0)))
            (at / "density").fail("gives a mass of " + format(m) + " kg, not a usable mass");
        return usable(m, at / "density", "gives a mass of ");
    }
    if (is_static)
        return 0.0;
    at.fail("needs a mass (kg) or a density (kg/m^3)");
}

/// A label every client is shown (a body's tag, a sensor's name): 1 to `most` bytes of UTF-8
/// without control characters, as the protocol has it. `what` names it in the message.
std::string read_label(json const& value, location const& at, char const* what, std::size_t most)
{
    std::string const label = text(value, at);
    if (label.empty() || label.size() > most)
        at.fail(std::string(what) + " must be 1 to " + std::to_string(most) + " bytes of UTF-8, got " +
                std::to_string(label.size()));
    for (char const ch : label)
        if (auto const c = static_cast<unsigned char>(ch); c < 0x20 || c == 0x7f)
            at.fail(std::string(what) + " must not hold control characters (found the byte " +
                    std::to_string(static_cast<unsigned>(c)) + ")");
    return label;
}

/// A body's tag (the protocol's rule for spawn.body.tag).
std::string read_tag(json const& value, location const& at)
{
    return read_label(value, at, "a body's tag", max_tag_bytes);
}

physics::body_desc read_body(json const& value, location const& at, std::string& tag)
{
    object(value, at, {"position", "velocity", "radius", "mass", "density", "charge", "static", "tag"});
    tag = optional_field(value, "tag", at, std::string(), read_tag);
    physics::body_desc b;
    b.position = vector3(required(value, "position", at), at / "position");
    b.is_static = optional_field(value, "static", at, false, boolean);
    b.velocity = optional_field(value, "velocity", at, physics::vec3(physics::vec3::Zero()), vector3);
    if (b.is_static && !b.velocity.isZero(0.0))
        (at / "velocity").fail("a static body cannot move; remove the velocity or the static flag");
    b.radius = optional_field(value, "radius", at, 0.0, [](json const& v, location const& l) {
        return number_at_least(v, l, 0.0, false);
    });
    b.charge = optional_field(value, "charge", at, 0.0, number);
    b.mass = read_mass(value, at, b.radius, b.is_static);
    return b;
}

body_generator read_generator(json const& value, location const& at)
{
    object(value, at,
           {"count", "seed", "placement", "region", "max_speed", "centre", "scale_radius", "radius",
            "mass", "density", "charge"});
    body_generator g;
    if (auto const* where = find(value, "placement")) {
        std::string const name = text(*where, at / "placement");
        if (name == "lattice")
            g.where = placement::lattice;
        else if (name == "plummer")
            g.where = placement::plummer;
        else if (name != "random")
            (at / "placement").fail("unknown placement '" + name + "' (known: random, lattice, plummer)");
    }
    g.count = whole_number(required(value, "count", at), at / "count", 0, max_scene_bodies);
    g.seed = optional_field(value, "seed", at, std::uint64_t{1}, [](json const& v, location const& l) {
        return whole_number(v, l, 0, std::uint64_t{1} << 53U);
    });
    if (g.where == placement::plummer) {
        for (char const* key : {"region", "max_speed"})
            if (find(value, key))
                (at / key).fail("a plummer sphere is placed by centre and scale_radius, its speeds "
                                "drawn from its equilibrium; remove this field");
        g.centre = optional_field(value, "centre", at, g.centre, vector3);
        g.scale_radius = number_at_least(required(value, "scale_radius", at), at / "scale_radius", 0.0, true);
    } else {
        for (char const* key : {"centre", "scale_radius"})
            if (find(value, key))
                (at / key).fail("only used with placement plummer; give a region instead");
        location const region_at = at / "region";
        json const& region = object(required(value, "region", at), region_at, {"min", "max"});
        g.region.min = vector3(required(region, "min", region_at), region_at / "min");
        g.region.max = vector3(required(region, "max", region_at), region_at / "max");
        if (!(g.region.min.array() <= g.region.max.array()).all())
            (region_at / "max").fail("must be >= min on every axis");
        g.max_speed = optional_field(value, "max_speed", at, 0.0, [](json const& v, location const& l) {
            return number_at_least(v, l, 0.0, false);
        });
    }
    g.radius = optional_field(value, "radius", at, 0.0, [](json const& v, location const& l) {
        return number_at_least(v, l, 0.0, false);
    });
    g.charge = optional_field(value, "charge", at, 0.0, number);
    g.mass = read_mass(value, at, g.radius, false);
    return g;
}

/// Cells per axis of the lattice that places `count` bodies in the region, as near to cubes
/// as the region allows: the largest spacing s such that the cells of size s fit `count`.
std::array<std::uint64_t, 3> lattice_cells(body_generator const& g, double& spacing)
{
    physics::vec3 const size = g.region.max - g.region.min;
    double const volume = std::max(size.prod(), 1e-300);
    spacing = std::cbrt(volume / static_cast<double>(std::max<std::uint64_t>(g.count, 1)));
    for (int attempt = 0; attempt < 10000; ++attempt) {
        std::array<std::uint64_t, 3> cells{};
        std::uint64_t total = 1;
        for (int axis = 0; axis < 3; ++axis) {
            cells[static_cast<std::size_t>(axis)] =
                std::max<std::uint64_t>(1, static_cast<std::uint64_t>(size[axis] / spacing));
            total *= cells[static_cast<std::size_t>(axis)];
        }
        if (total >= g.count)
            return cells;
        spacing *= 0.99;
    }
    return {g.count, 1, 1};
}

void check_lattice_fits(body_generator const& g, location const& at)
{
    if (g.where != placement::lattice || g.count < 2)
        return;
    double spacing = 0.0;
    auto const cells = lattice_cells(g, spacing);
    physics::vec3 const size = g.region.max - g.region.min;
    double gap = std::numeric_limits<double>::infinity();
    for (std::size_t axis = 0; axis < 3; ++axis)
        if (cells[axis] > 1)
            gap = std::min(gap, size[static_cast<int>(axis)] / static_cast<double>(cells[axis]));
    if (gap < 2.0 * g.radius)
        at.fail("a lattice of " + std::to_string(g.count) + " spheres of radius " + format(g.radius) +
                " does not fit in the region without overlaps (spacing " + format(gap) +
                " < diameter); enlarge the region or lower the count");
}

double unit_interval(json const& value, location const& at)
{
    double const x = number(value, at);
    if (x < 0.0 || x > 1.0)
        at.fail("must be between 0 and 1, got " + format(x));
    return x;
}

physics::wall read_wall(json const& value, location const& at)
{
    object(value, at, {"normal", "offset", "damping", "friction"});
    physics::vec3 const normal = vector3(required(value, "normal", at), at / "normal");
    if (normal.isZero(0.0))
        (at / "normal").fail("must not be zero");
    double const offset = number(required(value, "offset", at), at / "offset");
    return {physics::make_plane(normal, offset), optional_field(value, "damping", at, 0.0, unit_interval),
            optional_field(value, "friction", at, 0.0, unit_interval)};
}

/// `box`: six walls around a region, normals pointing in.
std::vector<physics::wall> read_box(json const& value, location const& at, physics::aabb& region)
{
    object(value, at, {"min", "max", "damping", "friction"});
    region.min = vector3(required(value, "min", at), at / "min");
    region.max = vector3(required(value, "max", at), at / "max");
    if (!(region.min.array() < region.max.array()).all())
        (at / "max").fail("must be > min on every axis");
    double const damping = optional_field(value, "damping", at, 0.0, unit_interval);
    double const friction = optional_field(value, "friction", at, 0.0, unit_interval);
    return physics::box_walls(region, damping, friction);
}

/// A sensor: a name and exactly one of `box` {min, max} or `ball` {centre, radius}; the
/// engine's own checks (sensor::invalid) name the volume that fails them.
sensor_settings read_sensor(json const& value, location const& at)
{
    object(value, at, {"name", "box", "ball"});
    sensor_settings out;
    out.name = read_label(required(value, "name", at), at / "name", "a sensor's name", max_sensor_name_bytes);
    auto const* box = find(value, "box");
    auto const* ball = find(value, "ball");
    if ((box != nullptr) == (ball != nullptr))
        at.fail("a sensor needs exactly one of \"box\" ({min, max}) or \"ball\" ({centre, radius})");
    location const volume_at = at / (box ? "box" : "ball");
    if (box) {
        object(*box, volume_at, {"min", "max"});
        physics::aabb b;
        b.min = vector3(required(*box, "min", volume_at), volume_at / "min");
        b.max = vector3(required(*box, "max", volume_at), volume_at / "max");
        out.volume = physics::sensor::of_box(b);
    } else {
        object(*ball, volume_at, {"centre", "radius"});
        physics::vec3 const c = vector3(required(*ball, "centre", volume_at), volume_at / "centre");
        double const r = number(required(*ball, "radius", volume_at), volume_at / "radius");
        out.volume = physics::sensor::of_ball(c, r);
    }
    if (auto why = out.volume.invalid())
        volume_at.fail(std::string(*why) + (box ? "" : ", got a radius of " + format(out.volume.radius)));
    return out;
}

obstacle_settings read_obstacle(json const& value, location const& at)
{
    object(value, at, {"centre", "half_extents", "rotation", "points", "damping", "friction"});
    obstacle_settings o;
    o.damping = optional_field(value, "damping", at, 0.0, unit_interval);
    o.friction = optional_field(value, "friction", at, 0.0, unit_interval);
    if (auto const* points = find(value, "points")) {
        for (char const* key : {"centre", "half_extents", "rotation"})
            if (find(value, key))
                (at / key).fail("give either points or centre/half_extents/rotation, not both");
        if (!points->is_array() || points->empty())
            (at / "points").fail("must be a non-empty array of [x, y, z] points");
        std::vector<physics::vec3> cloud;
        for (std::size_t i = 0; i < points->size(); ++i)
            cloud.push_back(vector3((*points)[i], at / "points" / i));
        o.box = physics::obb_of_points(cloud);
        return o;
    }
    physics::vec3 const centre = vector3(required(value, "centre", at), at / "centre");
    physics::vec3 const half = vector3(required(value, "half_extents", at), at / "half_extents");
    if (!(half.array() >= 0.0).all())
        (at / "half_extents").fail("must be >= 0 on every axis");
    Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
    if (auto const* r = find(value, "rotation")) {
        location const r_at = at / "rotation";
        object(*r, r_at, {"axis", "degrees"});
        physics::vec3 const axis = vector3(required(*r, "axis", r_at), r_at / "axis");
        if (axis.isZero(0.0))
            (r_at / "axis").fail("must not be zero");
        double const degrees = number(required(*r, "degrees", r_at), r_at / "degrees");
        rotation = Eigen::AngleAxisd(degrees * std::numbers::pi / 180.0, axis.normalized())
                       .toRotationMatrix();
    }
    o.box = physics::obb_from_box(centre, half, rotation);
    return o;
}

physics::collision_settings read_collisions(json const& value, location const& at)
{
    object(value, at,
           {"mode", "broadphase", "restitution", "friction", "rest_speed", "sleep", "sleep_speed", "sleep_time",
            "velocity_iterations", "position_iterations", "position_slop", "support_sweeps",
            "max_events_per_step", "max_events_per_body", "sweep", "sweep_fraction"});
    physics::collision_settings c;
    c.mode = physics::collision_mode::discrete; // naming collisions turns them on
    if (auto const* mode = find(value, "mode")) {
        std::string const name = text(*mode, at / "mode");
        auto const kind = physics::collision_mode_from_name(name);
        if (!kind)
            (at / "mode").fail("unknown collision mode '" + name + "' (known: off, discrete, continuous)");
        c.mode = *kind;
    }
    if (auto const* broadphase = find(value, "broadphase")) {
        std::string const name = text(*broadphase, at / "broadphase");
        auto const kind = physics::broadphase_from_name(name);
        if (!kind)
            (at / "broadphase")
                .fail("unknown broadphase '" + name + "' (known: brute_force, sweep_and_prune, grid)");
        c.broadphase = *kind;
    }
    c.restitution = optional_field(value, "restitution", at, c.restitution, unit_interval);
    c.friction = optional_field(value, "friction", at, c.friction, unit_interval);
    if (auto const* rest = find(value, "rest_speed"))
        c.rest_speed = number_at_least(*rest, at / "rest_speed", 0.0, false);
    c.sleep = optional_field(value, "sleep", at, c.sleep, boolean);
    // A sleep speed of 0 would let nothing sleep: "sleep": false says that.
    c.sleep_speed = optional_field(value, "sleep_speed", at, c.sleep_speed, [](json const& v, location const& l) {
        return number_at_least(v, l, 0.0, true);
    });
    c.sleep_time = optional_field(value, "sleep_time", at, c.sleep_time, [](json const& v, location const& l) {
        return number_at_least(v, l, 0.0, false);
    });
    c.velocity_iterations = static_cast<int>(optional_field(
        value, "velocity_iterations", at, std::uint64_t{4},
        [](json const& v, location const& l) { return whole_number(v, l, 1, 100); }));
    c.position_iterations = static_cast<int>(optional_field(
        value, "position_iterations", at, std::uint64_t{4},
        [](json const& v, location const& l) { return whole_number(v, l, 0, 100); }));
    // Past a tenth of r_a + r_b, resting spheres would sink into each other where one can see it.
    c.position_slop = optional_field(value, "position_slop", at, c.position_slop, [](json const& v, location const& l) {
        double const x = number_at_least(v, l, 0.0, false);
        if (x > 0.1)
            l.fail("must be at most 0.1 (a share of the two radii), got " + format(x));
        return x;
    });
    c.support_sweeps = static_cast<int>(optional_field(
        value, "support_sweeps", at, std::uint64_t{16},
        [](json const& v, location const& l) { return whole_number(v, l, 1, 64); }));
    c.max_events_per_step = optional_field(
        value, "max_events_per_step", at, c.max_events_per_step,
        [](json const& v, location const& l) { return whole_number(v, l, 1, std::uint64_t{1} << 40U); });
    c.max_events_per_body = optional_field(
        value, "max_events_per_body", at, c.max_events_per_body,
        [](json const& v, location const& l) { return whole_number(v, l, 1, std::uint64_t{1} << 40U); });
    c.sweep = optional_field(value, "sweep", at, c.sweep, boolean);
    // Above one radius per step, spheres below the threshold could pass through each other,
    // which the sweep is there to prevent; at 0 every body would be swept ("mode": "continuous").
    c.sweep_fraction = optional_field(value, "sweep_fraction", at, c.sweep_fraction, [](json const& v, location const& l) {
        double const x = number_at_least(v, l, 0.0, true);
        if (x > 1.0)
            l.fail("must be at most 1 (a share of the radius), got " + format(x));
        return x;
    });
    return c;
}

/// `method` and `theta` of a pairwise law; theta only with the tree, where it is used.
void read_method(json const& value, location const& at, force_method& method, double& theta)
{
    if (auto const* m = find(value, "method")) {
        std::string const name = text(*m, at / "method");
        if (name == "tree")
            method = force_method::tree;
        else if (name != "direct")
            (at / "method").fail("unknown method '" + name + "' (known: direct, tree)");
    }
    if (auto const* t = find(value, "theta")) {
        if (method != force_method::tree)
            (at / "theta").fail("is the tree's opening angle; it needs \"method\": \"tree\" "
                                "(the method here is direct)");
        double const x = number(*t, at / "theta");
        if (!(x > 0.0 && x <= physics::max_opening_angle))
            (at / "theta").fail("must be > 0 and <= 1, got " + format(x) +
                                " (0 would be exact: use method direct)");
        theta = x;
    }
}

force_settings read_forces(json const& value, location const& at)
{
    object(value, at, {"uniform_field", "gravity", "coulomb"});
    force_settings f;
    auto const non_negative = [](json const& v, location const& l) {
        return number_at_least(v, l, 0.0, false);
    };
    if (auto const* u = find(value, "uniform_field")) {
        object(*u, at / "uniform_field", {"g"});
        f.uniform_field = uniform_field_settings{};
        f.uniform_field->g = optional_field(*u, "g", at / "uniform_field", f.uniform_field->g, vector3);
    }
    if (auto const* g = find(value, "gravity")) {
        object(*g, at / "gravity", {"G", "softening", "method", "theta"});
        gravity_settings s;
        s.G = optional_field(*g, "G", at / "gravity", s.G, non_negative);
        s.softening = optional_field(*g, "softening", at / "gravity", s.softening, non_negative);
        read_method(*g, at / "gravity", s.method, s.theta);
        f.gravity = s;
    }
    if (auto const* c = find(value, "coulomb")) {
        object(*c, at / "coulomb", {"k", "softening", "method", "theta"});
        coulomb_settings s;
        s.k = optional_field(*c, "k", at / "coulomb", s.k, non_negative);
        s.softening = optional_field(*c, "softening", at / "coulomb", s.softening, non_negative);
        read_method(*c, at / "coulomb", s.method, s.theta);
        f.coulomb = s;
    }
    return f;
}

/// A quantum of the snapshots: a number in [min_quantum, max_quantum].
double quantum(json const& value, location const& at)
{
    double const x = number_at_least(value, at, 0.0, true);
    if (!(x >= snapshot_settings::min_quantum && x <= snapshot_settings::max_quantum))
        at.fail("must be between " + format(snapshot_settings::min_quantum) + " and " +
                format(snapshot_settings::max_quantum) + ", got " + format(x));
    return x;
}

snapshot_settings read_snapshots(json const& value, location const& at)
{
    object(value, at, {"position_quantum", "velocity_quantum"});
    snapshot_settings s;
    s.position_quantum = optional_field(value, "position_quantum", at, 0.0, quantum);
    s.velocity_quantum = optional_field(value, "velocity_quantum", at, 0.0, quantum);
    return s;
}

room_permissions read_permissions(json const& value, location const& at)
{
    object(value, at, {"push", "remove"});
    room_permissions p;
    if (auto const* push = find(value, "push")) {
        std::string const rule = text(*push, at / "push");
        if (rule == "owner")
            p.push = push_rule::owner;
        else if (rule == "admins")
            p.push = push_rule::admins;
        else if (rule != "anyone")
            (at / "push").fail("unknown rule '" + rule + "' (known: anyone, owner, admins)");
    }
    if (auto const* remove = find(value, "remove")) {
        std::string const rule = text(*remove, at / "remove");
        if (rule == "admins")
            p.remove = remove_rule::admins;
        else if (rule != "owner")
            (at / "remove").fail("unknown rule '" + rule + "' (known: owner, admins)");
    }
    return p;
}

player_settings read_players(json const& value, location const& at)
{
    object(value, at, {"resume_grace", "bodies_on_leave"});
    player_settings p;
    if (auto const* grace = find(value, "resume_grace")) {
        double const x = number_at_least(*grace, at / "resume_grace", 0.0, false);
        if (x > player_settings::max_resume_grace)
            (at / "resume_grace")
                .fail("must be at most " + format(player_settings::max_resume_grace) +
                      " s (a day), got " + format(x));
        p.resume_grace = x;
    }
    if (auto const* rule = find(value, "bodies_on_leave")) {
        std::string const wanted = text(*rule, at / "bodies_on_leave");
        if (wanted != "stay" && wanted != "remove")
            (at / "bodies_on_leave").fail("must be \"stay\" or \"remove\", got \"" + wanted + "\"");
        p.remove_bodies_on_leave = wanted == "remove";
    }
    return p;
}

scene read_scene(json const& doc, location const& at)
{
    object(doc, at,
           {"$schema", "name", "description", "dt", "substeps", "integrator", "tolerance", "forces",
             "collisions", "walls", "box", "obstacles", "bodies", "generators", "snapshots", "permissions",
             "players", "sensors", "contacts"});
    scene s;
    s.name = optional_field(doc, "name", at, std::string("unnamed"), text);
    s.description = optional_field(doc, "description", at, std::string(), text);
    s.dt = number_at_least(required(doc, "dt", at), at / "dt", 0.0, true);
    s.substeps = static_cast<int>(optional_field(doc, "substeps", at, std::uint64_t{1},
                                                 [](json const& v, location const& l) {
                                                     return whole_number(v, l, 1, 1000);
                                                 }));
    if (auto const* name = find(doc, "integrator")) {
        std::string const wanted = text(*name, at / "integrator");
        auto const kind = physics::integrator_from_name(wanted);
        if (!kind) {
            std::string known;
            for (auto const& entry : physics::integrator_table())
                known += (known.empty() ? "" : ", ") + std::string(entry.name);
            (at / "integrator").fail("unknown integrator '" + wanted + "' (known: " + known + ")");
        }
        s.integrator = *kind;
    }
    if (auto const* tolerance = find(doc, "tolerance")) {
        location const where = at / "tolerance";
        if (!physics::info(s.integrator).adaptive)
            where.fail("is the adaptive integrator's; this scene's integrator " +
                       std::string(physics::info(s.integrator).name) +
                       " takes fixed steps (give \"integrator\": \"dormand_prince\", or remove it)");
        double const t = number(*tolerance, where);
        if (!(t >= physics::step_control::min_tolerance && t < 1.0))
            where.fail("must be >= " + format(physics::step_control::min_tolerance) +
                       " (below, rounding outweighs the error it measures) and < 1, got " + format(t));
        s.adaptive.tolerance = t;
    }
    if (auto const* forces = find(doc, "forces"))
        s.forces = read_forces(*forces, at / "forces");
    if (auto const* collisions = find(doc, "collisions"))
        s.collisions = read_collisions(*collisions, at / "collisions");
    if (auto const* walls = find(doc, "walls")) {
        if (!walls->is_array())
            (at / "walls").fail("must be an array of walls, got " + describe(*walls));
        for (std::size_t i = 0; i < walls->size(); ++i)
            s.walls.push_back(read_wall((*walls)[i], at / "walls" / i));
    }
    if (auto const* box = find(doc, "box")) {
        physics::aabb region;
        auto const six = read_box(*box, at / "box", region);
        s.walls.insert(s.walls.end(), six.begin(), six.end());
        s.box = region;
    }
    if (auto const* obstacles = find(doc, "obstacles")) {
        if (!obstacles->is_array())
            (at / "obstacles").fail("must be an array of boxes, got " + describe(*obstacles));
        for (std::size_t i = 0; i < obstacles->size(); ++i)
            s.obstacles.push_back(read_obstacle((*obstacles)[i], at / "obstacles" / i));
    }
    if (auto const* sensors = find(doc, "sensors")) {
        if (!sensors->is_array())
            (at / "sensors").fail("must be an array of sensors, got " + describe(*sensors));
        for (std::size_t i = 0; i < sensors->size(); ++i) {
            location const s_at = at / "sensors" / i;
            s.sensors.push_back(read_sensor((*sensors)[i], s_at));
            for (std::size_t j = 0; j < i; ++j)
                if (s.sensors[j].name == s.sensors.back().name)
                    (s_at / "name").fail("sensor names must be unique: '" + s.sensors.back().name +
                                         "' is also /sensors/" + std::to_string(j));
        }
    }
    if (auto const* contacts = find(doc, "contacts")) {
        if (!contacts->is_array() || contacts->size() > max_contact_rules)
            (at / "contacts").fail("must be an array of at most " + std::to_string(max_contact_rules) +
                                   " pairs of tags, got " + describe(*contacts));
        for (std::size_t i = 0; i < contacts->size(); ++i) {
            location const c_at = at / "contacts" / i;
            json const& pair = (*contacts)[i];
            if (!pair.is_array() || pair.size() != 2)
                c_at.fail("must be a pair of body tags, [\"ball\", \"post\"], got " + describe(pair));
            s.contacts.push_back({{read_tag(pair[0], c_at / std::size_t{0}), read_tag(pair[1], c_at / std::size_t{1})}});
        }
    }
    if (auto const* bodies = find(doc, "bodies")) {
        if (!bodies->is_array())
            (at / "bodies").fail("must be an array of bodies, got " + describe(*bodies));
        for (std::size_t i = 0; i < bodies->size(); ++i) {
            std::string tag;
            s.bodies.push_back(read_body((*bodies)[i], at / "bodies" / i, tag));
            s.body_tags.push_back(std::move(tag));
        }
    }
    if (auto const* generators = find(doc, "generators")) {
        if (!generators->is_array())
            (at / "generators").fail("must be an array of generators, got " + describe(*generators));
        for (std::size_t i = 0; i < generators->size(); ++i) {
            location const g_at = at / "generators" / i;
            s.generators.push_back(read_generator((*generators)[i], g_at));
            check_lattice_fits(s.generators.back(), g_at);
            if (s.generators.back().where == placement::plummer &&
                !(s.forces.gravity && s.forces.gravity->G > 0.0))
                (g_at / "placement")
                    .fail("a plummer sphere needs forces.gravity with G > 0: its velocities "
                          "balance its own gravity");
        }
    }
    if (auto const* snapshots = find(doc, "snapshots"))
        s.snapshots = read_snapshots(*snapshots, at / "snapshots");
    if (auto const* permissions = find(doc, "permissions"))
        s.permissions = read_permissions(*permissions, at / "permissions");
    if (auto const* players = find(doc, "players"))
        s.players = read_players(*players, at / "players");
    if (s.body_count() > max_scene_bodies)
        at.fail("creates " + std::to_string(s.body_count()) + " bodies, more than the limit of " +
                std::to_string(max_scene_bodies));
    return s;
}

/// "a.b.0.c=VALUE": sets the field at that path, creating objects on the way. VALUE is read as
/// JSON when it parses (numbers, true, [1,2,3], "quoted") and as a plain string otherwise, so
/// `integrator=rk4` needs no quotes.
void apply_override(json& doc, std::string const& assignment, std::string const& source)
{
    auto fail = [&](std::string const& reason) {
        throw scene_error(source + ": --set " + assignment + ": " + reason);
    };
    auto const eq = assignment.find('=');
    if (eq == std::string::npos || eq == 0)
        fail("expected PATH=VALUE, e.g. dt=0.001 or generators.0.count=1000");
    try { // a scene is JSON text, which is UTF-8; so is every string a scene holds
        (void)json(assignment).dump();
    } catch (json::type_error const&) {
        fail("not UTF-8 text");
    }
    std::string const path = assignment.substr(0, eq);
    std::string const raw = assignment.substr(eq + 1);
    json value = json::parse(raw, nullptr, /*allow_exceptions=*/false);
    if (value.is_discarded())
        value = raw;

    json* node = &doc;
    std::size_t start = 0;
    while (true) {
        auto const dot = path.find('.', start);
        std::string const key = path.substr(start, dot == std::string::npos ? dot : dot - start);
        if (key.empty())
            fail("empty path component");
        json* next = nullptr;
        if (node->is_array()) {
            if (key.find_first_not_of("0123456789") != std::string::npos)
                fail("'" + key + "' is not an index into an array");
            std::size_t const index = std::stoul(key);
            if (index >= node->size())
                fail("index " + key + " is out of range (the array has " +
                     std::to_string(node->size()) + " entries)");
            next = &(*node)[index];
        } else {
            if (node->is_null())
                *node = json::object();
            if (!node->is_object())
                fail("'" + key + "' is inside a value that is neither object nor array");
            next = &(*node)[key];
        }
        if (dot == std::string::npos) {
            *next = std::move(value);
            return;
        }
        node = next;
        start = dot + 1;
    }
}

/// A double in [0, 1) from 53 random bits: the same on every standard library, unlike
/// std::uniform_real_distribution.
double unit_random(std::mt19937_64& rng)
{
    return static_cast<double>(rng() >> 11U) * 0x1.0p-53;
}

} // namespace

std::string_view name(force_method method)
{
    return method == force_method::tree ? "tree" : "direct";
}

std::uint64_t scene::body_count() const
{
    std::uint64_t n = bodies.size();
    for (auto const& g : generators)
        n += g.count;
    return n;
}

scene parse_scene(std::string_view text, std::string const& source,
                  std::span<std::string const> overrides)
{
    json doc;
    try {
        doc = json::parse(text);
    } catch (json::exception const& e) {
        throw scene_error(source + ": not valid JSON: " + e.what());
    }
    for (auto const& assignment : overrides)
        apply_override(doc, assignment, source);
    std::string const where = overrides.empty() ? source : source + " (with --set overrides)";
    return read_scene(doc, location{where, ""});
}

scene load_scene(std::filesystem::path const& file, std::span<std::string const> overrides)
{
    std::ifstream in(file, std::ios::binary);
    if (!in)
        throw scene_error(file.string() + ": cannot open the scene file");
    std::ostringstream buffer;
    buffer << in.rdbuf();
    return parse_scene(buffer.str(), file.string(), overrides);
}

std::string_view name(push_rule rule)
{
    switch (rule) {
    case push_rule::owner:
        return "owner";
    case push_rule::admins:
        return "admins";
    case push_rule::anyone:
        break;
    }
    return "anyone";
}

std::string_view name(remove_rule rule)
{
    return rule == remove_rule::admins ? "admins" : "owner";
}

physics::world build_world(scene const& s)
{
    physics::world w(
        {.integrator = s.integrator, .substeps = s.substeps, .adaptive = s.adaptive, .collisions = s.collisions});
    for (auto const& wall : s.walls)
        w.add_wall(wall);
    for (auto const& o : s.obstacles)
        w.add_obstacle({o.box, o.damping, o.friction});
    for (auto const& sensor : s.sensors)
        w.add_sensor(sensor.volume);
    if (s.forces.uniform_field)
        w.add_force(std::make_unique<physics::uniform_field>(s.forces.uniform_field->g));
    if (auto const& g = s.forces.gravity) {
        if (g->method == force_method::tree)
            w.add_force(std::make_unique<physics::tree_gravity>(g->G, g->softening, g->theta));
        else
            w.add_force(std::make_unique<physics::newtonian_gravity>(g->G, g->softening));
    }
    if (auto const& c = s.forces.coulomb) {
        if (c->method == force_method::tree)
            w.add_force(std::make_unique<physics::tree_coulomb>(c->k, c->softening, c->theta));
        else
            w.add_force(std::make_unique<physics::coulomb>(c->k, c->softening));
    }

    std::size_t total = s.bodies.size();
    for (auto const& g : s.generators)
        total += static_cast<std::size_t>(g.count);
    w.reserve(total);
    for (auto const& body : s.bodies)
        w.add_body(body);
    for (auto const& g : s.generators) {
        if (g.where == placement::plummer) { // checked at load: the scene has gravity, G > 0
            if (g.count == 0)
                continue;
            auto const sphere = physics::plummer_sphere(
                {.count = g.count, .total_mass = g.mass * static_cast<double>(g.count),
                 .scale_radius = g.scale_radius, .G = s.forces.gravity->G, .seed = g.seed});
            for (auto b : sphere) {
                b.position += g.centre;
                b.radius = g.radius;
                b.mass = g.mass;
                b.charge = g.charge;
                w.add_body(b);
            }
            continue;
        }
        std::mt19937_64 rng(g.seed);
        physics::vec3 const size = g.region.max - g.region.min;
        double spacing = 0.0;
        auto const cells = g.where == placement::lattice ? lattice_cells(g, spacing)
                                                          : std::array<std::uint64_t, 3>{};
        for (std::uint64_t i = 0; i < g.count; ++i) {
            physics::body_desc b;
            if (g.where == placement::lattice) {
                std::uint64_t const cell[3] = {i % cells[0], (i / cells[0]) % cells[1],
                                               i / (cells[0] * cells[1])};
                for (int axis = 0; axis < 3; ++axis) {
                    auto const n = static_cast<double>(cells[static_cast<std::size_t>(axis)]);
                    b.position[axis] = g.region.min[axis] +
                                       size[axis] * (static_cast<double>(cell[axis]) + 0.5) / n;
                }
            } else {
                b.position = g.region.min + size.cwiseProduct(physics::vec3(
                                                unit_random(rng), unit_random(rng), unit_random(rng)));
            }
            physics::vec3 direction;
            do { // uniform in the unit ball, by rejection
                direction = {2.0 * unit_random(rng) - 1.0, 2.0 * unit_random(rng) - 1.0,
                             2.0 * unit_random(rng) - 1.0};
            } while (direction.squaredNorm() > 1.0);
            b.velocity = g.max_speed * direction;
            b.radius = g.radius;
            b.mass = g.mass;
            b.charge = g.charge;
            w.add_body(b);
        }
    }
    return w;
}

physics::sphere scene_bounds(scene const& s, physics::world const& w)
{
    // The bodies' centres where they are (a copy was 24 MB at 10⁶ bodies, the peak of a
    // headless run's summary), the corners beside them.
    std::vector<physics::vec3> corners;
    corners.reserve(8 * s.obstacles.size() + 8);
    double largest_radius = 0.0;
    for (double r : w.bodies().radii())
        largest_radius = std::max(largest_radius, r);
    for (auto const& o : s.obstacles) {
        for (int corner = 0; corner < 8; ++corner) {
            physics::vec3 const sign((corner & 1) ? 1.0 : -1.0, (corner & 2) ? 1.0 : -1.0,
                                     (corner & 4) ? 1.0 : -1.0);
            corners.push_back(o.box.centre + o.box.axes * sign.cwiseProduct(o.box.half_extents));
        }
    }
    if (s.box) {
        for (int corner = 0; corner < 8; ++corner)
            corners.emplace_back((corner & 1) ? s.box->max.x() : s.box->min.x(),
                                 (corner & 2) ? s.box->max.y() : s.box->min.y(),
                                 (corner & 4) ? s.box->max.z() : s.box->min.z());
    }
    physics::sphere bounds = physics::minimum_bounding_sphere(w.bodies().positions(), corners);
    bounds.radius += largest_radius;
    return bounds;
}

} // namespace kugel::scene
