#pragma once

#include <filesystem>
#include <optional>
#include <string_view>
#include <vector>

namespace kugel::server {

/// The file a request target names under `root`, or nullopt for anything that is not a
/// regular file inside the root. `root` must be canonical (std::filesystem::canonical).
///
/// The path (the target up to `?` or `#`) is percent-decoded and split at '/'; empty
/// segments are skipped, as nginx merges slashes. A target that does not start with '/',
/// a bad or encoded '%' sequence, an encoded '/' or NUL, a backslash, and a segment that is
/// "." or ".." or starts with '.' (hidden files) name nothing. What is left is resolved with
/// every symbolic link followed, and must still lie inside the root: a link that leaves the
/// root names nothing. A directory names its index.html.
std::optional<std::filesystem::path> file_for(std::filesystem::path const& root,
                                              std::string_view target);

/// The MIME type for a file name's extension.
std::string_view mime_type(std::string_view path);

/// The target's path: what comes before `?` or `#` (the query string is not the path).
std::string_view path_of(std::string_view target);

/// A place where a server run without --web-root looks for the page.
struct page_place
{
    std::filesystem::path root;
    std::string_view where; ///< for the log: "next to the executable", ...
};

/// Where kugel-server looks for the page when no --web-root is given, in this order: `web`
/// next to the executable, `share/kugel/web` under the install prefix it runs from
/// (PREFIX/bin/kugel-server), and the built page `web/dist` of the source tree it was built
/// from (a build directory's binary), when that is known.
std::vector<page_place> page_places(std::filesystem::path const& executable,
                                    std::filesystem::path const& source_tree);

/// The first place that holds a page (a regular file index.html), or nullopt.
std::optional<page_place> find_page(std::vector<page_place> const& places);

} // namespace kugel::server
