#pragma once

// A room's state on disk (--state DIR): everything needed to go on where it stopped. The
// file is JSON (docs/architecture.md, Persistence); doubles are written so that they read
// back bit for bit.

#include "physics/body_storage.hpp"
#include "physics/world.hpp"
#include "scene/scene.hpp"

#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace kugel::server {

/// A checkpoint that cannot be used: unreadable, corrupt, of another format version, or of
/// another scene. what() names the file and what is wrong with it.
class checkpoint_error : public std::runtime_error
{
public:
    using std::runtime_error::runtime_error;
};

/// Bumped whenever the file's meaning changes; another version is refused, never guessed at.
/// Version 2 added `loaded_scene`: a server that knew only version 1 would put its bodies in
/// the room's own scene. Version 3 added the bodies' tags (`bodies.tag`): a server that knew
/// only version 2 would drop them, and the contacts and events that follow from them. Older
/// versions (no loaded scene in 1, no tags in 1 and 2) are still read.
inline constexpr int checkpoint_format_version = 3;

/// A scene an admin loaded (load_scene), carried whole: a restart rebuilds the room in it.
struct embedded_scene
{
    std::string name;
    std::string fingerprint; ///< of text (scene_fingerprint())
    std::string text;        ///< the scene's JSON, exactly as the scene loader read it
};

/// One room at one tick.
struct checkpoint
{
    std::string room;
    std::string scene_name;        ///< the room's own scene (its file)
    /// Of the room's own scene's text and overrides (scene_fingerprint()).
    std::string scene_fingerprint;
    /// The overrides (PATH=VALUE, in order) the room's own scene was started with; none
    /// for a room without (then the file has no `overrides`, as before there were any).
    std::vector<std::string> scene_overrides;
    /// The scene the room runs when an admin loaded one; none: it runs its own.
    std::optional<embedded_scene> loaded_scene;
    std::uint64_t tick = 0;        ///< ticks completed
    double time = 0.0;             ///< s, the world's clock
    double time_compensation = 0.0; ///< s, the clock's compensated-sum remainder
    std::uint64_t steps = 0;       ///< the world's step() calls
    std::uint64_t next_wire_id = 1; ///< the room's id counter: no id below it is ever reused

    struct body
    {
        std::uint64_t wire_id = 0;
        physics::body_desc desc;
        std::string tag; ///< "" for none
    };
    std::vector<body> bodies; ///< in slot order, so stepping on gives the same results
};

/// A short, stable fingerprint of a scene's text and the overrides applied to it (PATH=VALUE,
/// in order): "fnv1a64:" and 16 hex digits. Any edit to the scene file, and any override
/// added, removed, changed or moved, changes it. Without overrides it is the text's alone,
/// as it was before rooms took overrides, so their checkpoints still restore.
std::string scene_fingerprint(std::string_view scene_text,
                              std::span<std::string const> overrides = {});

/// The file's text.
std::string encode_checkpoint(checkpoint const& c);

/// Parses a checkpoint's text; `file` names it in errors. Checks the format and version,
/// that every body is well formed and that a loaded scene's text has its fingerprint, but
/// not which room or scene it belongs to.
checkpoint decode_checkpoint(std::string_view text, std::string const& file);

/// The scene a checkpoint's world is rebuilt in: the loaded scene it carries, or else the
/// room's own scene `own`. Throws checkpoint_error (naming `file`) for a loaded scene the
/// scene loader refuses or whose name is not the one recorded.
scene::scene restored_scene(scene::scene const& own, checkpoint const& c, std::string const& file);

/// The world of scene `s` (restored_scene()) with the checkpoint's bodies (in its slot
/// order) instead of the scene's, and its clock. Throws checkpoint_error (naming `file`)
/// for a body the world refuses.
physics::world restored_world(scene::scene const& s, checkpoint const& c, std::string const& file);

/// Where room `room`'s checkpoint lives in `dir`: DIR/ROOM.json.
std::filesystem::path checkpoint_path(std::filesystem::path const& dir, std::string const& room);

/// Replaces `file` atomically: writes `text` to FILE.tmp, fsyncs it, renames it over `file`
/// and fsyncs the directory. A crash at any point leaves either the old or the new file.
/// Throws std::system_error naming the step that failed.
void write_file_atomically(std::filesystem::path const& file, std::string_view text);

/// Reads the checkpoint at `file` when there is one, and checks that it belongs to this
/// room and its own scene, overrides included (also when it carries a loaded scene: a
/// changed scene file or override still refuses it). Throws checkpoint_error when it exists
/// but cannot be used.
std::optional<checkpoint> read_checkpoint(std::filesystem::path const& file,
                                          std::string const& room,
                                          std::string const& scene_name,
                                          std::string const& fingerprint,
                                          std::span<std::string const> overrides = {});

/// Moves a refused checkpoint aside, to FILE.bad-<unix seconds>; returns the new path.
std::filesystem::path move_aside(std::filesystem::path const& file);

} // namespace kugel::server
