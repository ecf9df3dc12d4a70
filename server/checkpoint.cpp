#include "checkpoint.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <fcntl.h>
#include <fstream>
#include <set>
#include <sstream>
#include <system_error>
#include <unistd.h>

namespace kugel::server {

namespace {

using nlohmann::json;

constexpr std::string_view format_name = "kugel-checkpoint";

/// What is wrong, at a JSON pointer of the file.
[[noreturn]] void refuse(std::string const& file, std::string_view where, std::string_view what)
{
    throw checkpoint_error(fmt::format("checkpoint {}: {}: {}", file, where, what));
}

json const& field(json const& object, char const* key, std::string const& file,
                  std::string const& where)
{
    auto const it = object.find(key);
    if (it == object.end())
        refuse(file, where + "/" + key, "missing");
    return *it;
}

std::uint64_t unsigned_field(json const& object, char const* key, std::string const& file)
{
    json const& v = field(object, key, file, "");
    if (!v.is_number_unsigned())
        refuse(file, std::string("/") + key, "must be a non-negative integer, got " + v.dump());
    return v.get<std::uint64_t>();
}

double number_field(json const& object, char const* key, std::string const& file)
{
    json const& v = field(object, key, file, "");
    if (!v.is_number())
        refuse(file, std::string("/") + key, "must be a number, got " + v.dump());
    return v.get<double>();
}

/// A column of bodies: an array of `per_body` * n numbers (or booleans).
json const& column(json const& bodies, char const* key, std::size_t n, std::string const& file)
{
    std::string const where = std::string("/bodies/") + key;
    json const& c = field(bodies, key, file, "/bodies");
    if (!c.is_array() || c.size() != n)
        refuse(file, where, fmt::format("must be an array of {} values", n));
    return c;
}

double number_at(json const& c, std::size_t i, char const* key, std::string const& file)
{
    if (!c[i].is_number())
        refuse(file, fmt::format("/bodies/{}/{}", key, i), "must be a number, got " + c[i].dump());
    return c[i].get<double>();
}

/// The scene an admin loaded, its text checked against its fingerprint: an edit to either
/// shows.
embedded_scene decode_loaded_scene(json const& loaded, std::string const& file)
{
    if (!loaded.is_object())
        refuse(file, "/loaded_scene", "must be an object");
    auto const string_at = [&](char const* key) {
        json const& v = field(loaded, key, file, "/loaded_scene");
        if (!v.is_string())
            refuse(file, std::string("/loaded_scene/") + key, "must be a string, got " + v.dump());
        return v.get<std::string>();
    };
    embedded_scene s{string_at("name"), string_at("fingerprint"), string_at("text")};
    if (std::string const actual = scene_fingerprint(s.text); actual != s.fingerprint)
        refuse(file, "/loaded_scene",
               fmt::format("its text's fingerprint is {}, not the {} recorded: the scene an admin "
                           "loaded was changed in the file, or the file is corrupt",
                           actual, s.fingerprint));
    return s;
}

std::system_error last_error(std::string const& what, std::filesystem::path const& path)
{
    return {errno, std::generic_category(), what + " " + path.string()};
}

} // namespace

std::string scene_fingerprint(std::string_view scene_text, std::span<std::string const> overrides)
{
    std::uint64_t h = 14695981039346656037ULL; // FNV-1a, 64 bits
    auto const add = [&h](char c) { h = (h ^ static_cast<unsigned char>(c)) * 1099511628211ULL; };
    for (char c : scene_text)
        add(c);
    // Each override after a NUL, which neither a scene's JSON text nor a command-line
    // argument can hold: no text and overrides can run into those of another.
    for (std::string const& o : overrides) {
        add('\0');
        for (char c : o)
            add(c);
    }
    return fmt::format("fnv1a64:{:016x}", h);
}

std::string encode_checkpoint(checkpoint const& c)
{
    std::size_t const n = c.bodies.size();
    json id = json::array(), position = json::array(), velocity = json::array(),
         mass = json::array(), radius = json::array(), charge = json::array(),
         is_static = json::array();
    id.get_ref<json::array_t&>().reserve(n);
    position.get_ref<json::array_t&>().reserve(3 * n);
    velocity.get_ref<json::array_t&>().reserve(3 * n);
    for (checkpoint::body const& b : c.bodies) {
        id.push_back(b.wire_id);
        for (int k = 0; k < 3; ++k) {
            position.push_back(b.desc.position[k]);
            velocity.push_back(b.desc.velocity[k]);
        }
        mass.push_back(b.desc.mass);
        radius.push_back(b.desc.radius);
        charge.push_back(b.desc.charge);
        is_static.push_back(b.desc.is_static);
    }
    json document{
        {"format", std::string(format_name)},
        {"version", checkpoint_format_version},
        {"room", c.room},
        {"scene", {{"name", c.scene_name}, {"fingerprint", c.scene_fingerprint}}},
        {"tick", c.tick},
        {"time", c.time},
        {"time_compensation", c.time_compensation},
        {"steps", c.steps},
        {"next_id", c.next_wire_id},
        {"bodies",
         {{"id", std::move(id)},
          {"position", std::move(position)},
          {"velocity", std::move(velocity)},
          {"mass", std::move(mass)},
          {"radius", std::move(radius)},
          {"charge", std::move(charge)},
          {"static", std::move(is_static)}}}};
    // The tags only when some body has one, as snapshots carry them.
    if (std::any_of(c.bodies.begin(), c.bodies.end(), [](checkpoint::body const& b) { return !b.tag.empty(); })) {
        json tag = json::array();
        for (checkpoint::body const& b : c.bodies)
            tag.push_back(b.tag);
        document["bodies"]["tag"] = std::move(tag);
    }
    if (!c.scene_overrides.empty())
        document["scene"]["overrides"] = c.scene_overrides;
    if (c.loaded_scene)
        document["loaded_scene"] = {{"name", c.loaded_scene->name},
                                    {"fingerprint", c.loaded_scene->fingerprint},
                                    {"text", c.loaded_scene->text}};
    // nlohmann writes the shortest text that reads back as the same double: exact.
    return document.dump() + "\n";
}

checkpoint decode_checkpoint(std::string_view text, std::string const& file)
{
    json document;
    try {
        document = json::parse(text);
    } catch (json::parse_error const& e) {
        throw checkpoint_error(fmt::format("checkpoint {}: not valid JSON (truncated or corrupt): {}",
                                           file, e.what()));
    }
    if (!document.is_object())
        refuse(file, "/", "must be an object");
    if (!document.contains("format") || !document["format"].is_string() ||
        document["format"].get<std::string>() != format_name)
        refuse(file, "/format", fmt::format("must be \"{}\": not a Kugel checkpoint", format_name));
    // Version 1 is version 2 without loaded_scene, and 2 is 3 without tags: read as they
    // always were.
    json const& version = field(document, "version", file, "");
    if (version != 1 && version != 2 && version != checkpoint_format_version)
        refuse(file, "/version",
               fmt::format("format version {} is not a version this server reads (1 to {})",
                           version.dump(), checkpoint_format_version));

    checkpoint c;
    json const& room = field(document, "room", file, "");
    json const& scene = field(document, "scene", file, "");
    if (!room.is_string())
        refuse(file, "/room", "must be a string");
    if (!scene.is_object() || !scene.contains("name") || !scene.at("name").is_string() ||
        !scene.contains("fingerprint") || !scene.at("fingerprint").is_string())
        refuse(file, "/scene", "must be an object with string fields name and fingerprint");
    c.room = room.get<std::string>();
    c.scene_name = scene.at("name").get<std::string>();
    c.scene_fingerprint = scene.at("fingerprint").get<std::string>();
    if (scene.contains("overrides")) {
        json const& overrides = scene.at("overrides");
        if (!overrides.is_array() ||
            !std::ranges::all_of(overrides, [](json const& o) { return o.is_string(); }))
            refuse(file, "/scene/overrides", "must be an array of strings, got " + overrides.dump());
        c.scene_overrides = overrides.get<std::vector<std::string>>();
    }
    c.tick = unsigned_field(document, "tick", file);
    c.time = number_field(document, "time", file);
    c.time_compensation = number_field(document, "time_compensation", file);
    c.steps = unsigned_field(document, "steps", file);
    c.next_wire_id = unsigned_field(document, "next_id", file);
    if (version != 1 && document.contains("loaded_scene"))
        c.loaded_scene = decode_loaded_scene(document.at("loaded_scene"), file);

    json const& bodies = field(document, "bodies", file, "");
    if (!bodies.is_object())
        refuse(file, "/bodies", "must be an object of columns");
    json const& id = field(bodies, "id", file, "/bodies");
    if (!id.is_array())
        refuse(file, "/bodies/id", "must be an array");
    std::size_t const n = id.size();
    json const& position = column(bodies, "position", 3 * n, file);
    json const& velocity = column(bodies, "velocity", 3 * n, file);
    json const& mass = column(bodies, "mass", n, file);
    json const& radius = column(bodies, "radius", n, file);
    json const& charge = column(bodies, "charge", n, file);
    json const& is_static = column(bodies, "static", n, file);
    json const* tag = version == checkpoint_format_version && bodies.contains("tag") ? &column(bodies, "tag", n, file) : nullptr;
    std::set<std::uint64_t> seen;
    c.bodies.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
        checkpoint::body& b = c.bodies[i];
        if (!id[i].is_number_unsigned() || id[i].get<std::uint64_t>() == 0)
            refuse(file, fmt::format("/bodies/id/{}", i), "must be a positive integer, got " + id[i].dump());
        b.wire_id = id[i].get<std::uint64_t>();
        if (b.wire_id >= c.next_wire_id)
            refuse(file, fmt::format("/bodies/id/{}", i),
                   fmt::format("id {} is not below next_id {}", b.wire_id, c.next_wire_id));
        if (!seen.insert(b.wire_id).second)
            refuse(file, fmt::format("/bodies/id/{}", i), fmt::format("id {} is given twice", b.wire_id));
        for (int k = 0; k < 3; ++k) {
            std::size_t const at = 3 * i + static_cast<std::size_t>(k);
            b.desc.position[k] = number_at(position, at, "position", file);
            b.desc.velocity[k] = number_at(velocity, at, "velocity", file);
        }
        b.desc.mass = number_at(mass, i, "mass", file);
        b.desc.radius = number_at(radius, i, "radius", file);
        b.desc.charge = number_at(charge, i, "charge", file);
        if (!is_static[i].is_boolean())
            refuse(file, fmt::format("/bodies/static/{}", i), "must be true or false");
        b.desc.is_static = is_static[i].get<bool>();
        if (tag) {
            json const& t = (*tag)[i];
            bool const control = t.is_string() && std::any_of(t.get_ref<std::string const&>().begin(),
                                                               t.get_ref<std::string const&>().end(), [](char ch) {
                                                                   auto const u = static_cast<unsigned char>(ch);
                                                                   return u < 0x20 || u == 0x7f;
                                                               });
            if (!t.is_string() || t.get_ref<std::string const&>().size() > scene::max_tag_bytes || control)
                refuse(file, fmt::format("/bodies/tag/{}", i),
                       fmt::format("must be \"\" or a tag of 1 to {} bytes without control characters, got {}",
                                   scene::max_tag_bytes, t.dump()));
            b.tag = t.get<std::string>();
        }
        // The rest (finite values, positive masses) the world checks as it adds the body.
    }
    return c;
}

scene::scene restored_scene(scene::scene const& own, checkpoint const& c, std::string const& file)
{
    if (!c.loaded_scene)
        return own;
    scene::scene loaded;
    try {
        // Its messages then read "checkpoint FILE: /loaded_scene/text: /bodies/0/radius: ...".
        loaded = scene::parse_scene(c.loaded_scene->text,
                                    fmt::format("checkpoint {}: /loaded_scene/text", file));
    } catch (scene::scene_error const& e) {
        throw checkpoint_error(e.what());
    }
    if (loaded.name != c.loaded_scene->name)
        refuse(file, "/loaded_scene/name",
               fmt::format("'{}' is not the name of the scene in its text, '{}'",
                           c.loaded_scene->name, loaded.name));
    return loaded;
}

physics::world restored_world(scene::scene const& s, checkpoint const& c, std::string const& file)
{
    scene::scene without_bodies = s;
    without_bodies.bodies.clear();
    without_bodies.generators.clear();
    physics::world w = scene::build_world(without_bodies);
    for (std::size_t i = 0; i < c.bodies.size(); ++i) {
        try {
            w.add_body(c.bodies[i].desc);
        } catch (std::invalid_argument const& e) {
            refuse(file, fmt::format("/bodies (body {}, id {})", i, c.bodies[i].wire_id), e.what());
        }
    }
    try {
        w.restore_clock(c.time, c.time_compensation, c.steps);
    } catch (std::invalid_argument const& e) {
        refuse(file, "/time", e.what());
    }
    return w;
}

std::filesystem::path checkpoint_path(std::filesystem::path const& dir, std::string const& room)
{
    return dir / (room + ".json");
}

void write_file_atomically(std::filesystem::path const& file, std::string_view text)
{
    std::filesystem::path const temporary = file.string() + ".tmp";
    int const fd = ::open(temporary.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd < 0)
        throw last_error("cannot create", temporary);
    for (std::size_t written = 0; written < text.size();) {
        ssize_t const n = ::write(fd, text.data() + written, text.size() - written);
        if (n < 0 && errno == EINTR)
            continue;
        if (n < 0) {
            auto error = last_error("cannot write", temporary);
            ::close(fd);
            throw error;
        }
        written += static_cast<std::size_t>(n);
    }
    // The data reaches the disk before the name points at it: a crash never leaves ROOM.json
    // naming a file whose blocks were not written.
    if (::fsync(fd) != 0) {
        auto error = last_error("cannot fsync", temporary);
        ::close(fd);
        throw error;
    }
    if (::close(fd) != 0)
        throw last_error("cannot close", temporary);
    if (::rename(temporary.c_str(), file.c_str()) != 0)
        throw last_error("cannot rename over", file);
    // And the rename itself is durable once the directory is.
    std::filesystem::path const dir = file.has_parent_path() ? file.parent_path() : ".";
    int const dir_fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (dir_fd < 0)
        throw last_error("cannot open directory", dir);
    int const synced = ::fsync(dir_fd);
    auto error = last_error("cannot fsync directory", dir);
    ::close(dir_fd);
    if (synced != 0)
        throw error;
}

std::optional<checkpoint> read_checkpoint(std::filesystem::path const& file,
                                          std::string const& room,
                                          std::string const& scene_name,
                                          std::string const& fingerprint,
                                          std::span<std::string const> overrides)
{
    std::error_code ec;
    if (!std::filesystem::exists(file, ec))
        return std::nullopt;
    std::ifstream in(file, std::ios::binary);
    std::stringstream text;
    text << in.rdbuf();
    if (!in)
        throw checkpoint_error(fmt::format("checkpoint {}: cannot be read", file.string()));
    checkpoint c = decode_checkpoint(text.str(), file.string());
    if (c.room != room)
        refuse(file.string(), "/room",
               fmt::format("it is room '{}''s, not room '{}''s", c.room, room));
    bool const same_overrides = std::ranges::equal(c.scene_overrides, overrides);
    if (c.scene_name != scene_name || c.scene_fingerprint != fingerprint || !same_overrides) {
        // The overrides are said only where some were given, so that a room without any
        // reads as it always did.
        bool const any = !c.scene_overrides.empty() || !overrides.empty();
        auto const described = [any](std::string const& name, std::string const& print,
                                     std::span<std::string const> with) {
            if (!any)
                return fmt::format("'{}' ({})", name, print);
            if (with.empty())
                return fmt::format("'{}' without overrides ({})", name, print);
            json const listed(std::vector<std::string>(with.begin(), with.end()));
            return fmt::format("'{}' with overrides {} ({})", name, listed.dump(), print);
        };
        refuse(file.string(), "/scene",
               fmt::format("it is of scene {}, but the room's scene is {}: {}",
                           described(c.scene_name, c.scene_fingerprint, c.scene_overrides),
                           described(scene_name, fingerprint, overrides),
                           same_overrides ? "another scene, or the scene file changed"
                                          : "the room was started with other overrides "
                                            "(--set ROOM:PATH=VALUE) than the checkpoint's"));
    }
    return c;
}

std::filesystem::path move_aside(std::filesystem::path const& file)
{
    auto const seconds = std::chrono::duration_cast<std::chrono::seconds>(
                             std::chrono::system_clock::now().time_since_epoch())
                             .count();
    std::filesystem::path aside = file.string() + ".bad-" + std::to_string(seconds);
    for (int k = 1; std::filesystem::exists(aside); ++k)
        aside = file.string() + ".bad-" + std::to_string(seconds) + "-" + std::to_string(k);
    std::filesystem::rename(file, aside);
    return aside;
}

} // namespace kugel::server
