#include "scene.hpp"

#include "physics/forces.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <initializer_list>
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

std::string describe(json const& value)
{
    std::string text = value.dump();
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
    if (mass)
        return is_static ? number_at_least(*mass, at / "mass", 0.0, false)
                         : number_at_least(*mass, at / "mass", 0.0, true);
    if (density) {
        double const rho = number_at_least(*density, at / "density", 0.0, true);
        if (radius <= 0.0)
            (at / "density").fail("needs a radius > 0 (a point mass has no volume; give mass)");
        double const m = physics::mass_from_density(rho, radius);
        if (!std::isfinite(m) || (!is_static && !(m > 0.0)))
            (at / "density").fail("gives a mass of " + format(m) + " kg, not a usable mass");
        return m;
    }
    if (is_static)
        return 0.0;
    at.fail("needs a mass (kg) or a density (kg/m^3)");
}

physics::body_desc read_body(json const& value, location const& at)
{
    object(value, at, {"position", "velocity", "radius", "mass", "density", "charge", "static"});
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
           {"count", "seed", "region", "max_speed", "radius", "mass", "density", "charge"});
    body_generator g;
    g.count = whole_number(required(value, "count", at), at / "count", 0, max_scene_bodies);
    g.seed = optional_field(value, "seed", at, std::uint64_t{1}, [](json const& v, location const& l) {
        return whole_number(v, l, 0, std::uint64_t{1} << 53U);
    });
    location const region_at = at / "region";
    json const& region = object(required(value, "region", at), region_at, {"min", "max"});
    g.region.min = vector3(required(region, "min", region_at), region_at / "min");
    g.region.max = vector3(required(region, "max", region_at), region_at / "max");
    if (!(g.region.min.array() <= g.region.max.array()).all())
        (region_at / "max").fail("must be >= min on every axis");
    g.max_speed = optional_field(value, "max_speed", at, 0.0, [](json const& v, location const& l) {
        return number_at_least(v, l, 0.0, false);
    });
    g.radius = optional_field(value, "radius", at, 0.0, [](json const& v, location const& l) {
        return number_at_least(v, l, 0.0, false);
    });
    g.charge = optional_field(value, "charge", at, 0.0, number);
    g.mass = read_mass(value, at, g.radius, false);
    return g;
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
        object(*g, at / "gravity", {"G", "softening"});
        gravity_settings s;
        s.G = optional_field(*g, "G", at / "gravity", s.G, non_negative);
        s.softening = optional_field(*g, "softening", at / "gravity", s.softening, non_negative);
        f.gravity = s;
    }
    if (auto const* c = find(value, "coulomb")) {
        object(*c, at / "coulomb", {"k", "softening"});
        coulomb_settings s;
        s.k = optional_field(*c, "k", at / "coulomb", s.k, non_negative);
        s.softening = optional_field(*c, "softening", at / "coulomb", s.softening, non_negative);
        f.coulomb = s;
    }
    return f;
}

scene read_scene(json const& doc, location const& at)
{
    object(doc, at,
           {"$schema", "name", "description", "dt", "substeps", "integrator", "forces", "bodies",
            "generators"});
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
    if (auto const* forces = find(doc, "forces"))
        s.forces = read_forces(*forces, at / "forces");
    if (auto const* bodies = find(doc, "bodies")) {
        if (!bodies->is_array())
            (at / "bodies").fail("must be an array of bodies, got " + describe(*bodies));
        for (std::size_t i = 0; i < bodies->size(); ++i)
            s.bodies.push_back(read_body((*bodies)[i], at / "bodies" / i));
    }
    if (auto const* generators = find(doc, "generators")) {
        if (!generators->is_array())
            (at / "generators").fail("must be an array of generators, got " + describe(*generators));
        for (std::size_t i = 0; i < generators->size(); ++i)
            s.generators.push_back(read_generator((*generators)[i], at / "generators" / i));
    }
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

physics::world build_world(scene const& s)
{
    physics::world w({s.integrator, s.substeps});
    if (s.forces.uniform_field)
        w.add_force(std::make_unique<physics::uniform_field>(s.forces.uniform_field->g));
    if (s.forces.gravity)
        w.add_force(std::make_unique<physics::newtonian_gravity>(s.forces.gravity->G,
                                                                 s.forces.gravity->softening));
    if (s.forces.coulomb)
        w.add_force(
            std::make_unique<physics::coulomb>(s.forces.coulomb->k, s.forces.coulomb->softening));

    for (auto const& body : s.bodies)
        w.add_body(body);
    for (auto const& g : s.generators) {
        std::mt19937_64 rng(g.seed);
        physics::vec3 const size = g.region.max - g.region.min;
        for (std::uint64_t i = 0; i < g.count; ++i) {
            physics::body_desc b;
            b.position = g.region.min + size.cwiseProduct(physics::vec3(
                                            unit_random(rng), unit_random(rng), unit_random(rng)));
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

} // namespace kugel::scene
