#include "static_files.hpp"

#include <algorithm>
#include <string>

namespace kugel::server {

namespace fs = std::filesystem;

namespace {

int hex_digit(char c)
{
    if (c >= '0' && c <= '9')
        return c - '0';
    if (c >= 'a' && c <= 'f')
        return c - 'a' + 10;
    if (c >= 'A' && c <= 'F')
        return c - 'A' + 10;
    return -1;
}

/// One path segment, percent-decoded; nullopt for a bad escape or a byte no file name may
/// hold here ('/', '\\', NUL).
std::optional<std::string> decoded_segment(std::string_view text)
{
    std::string out;
    out.reserve(text.size());
    for (std::size_t i = 0; i < text.size(); ++i) {
        char c = text[i];
        if (c == '%') {
            if (i + 2 >= text.size())
                return std::nullopt;
            int const high = hex_digit(text[i + 1]);
            int const low = hex_digit(text[i + 2]);
            if (high < 0 || low < 0)
                return std::nullopt;
            c = static_cast<char>(high * 16 + low);
            i += 2;
        }
        if (c == '/' || c == '\\' || c == '\0')
            return std::nullopt;
        out.push_back(c);
    }
    return out;
}

bool inside(fs::path const& root, fs::path const& file)
{
    auto const [r, f] = std::mismatch(root.begin(), root.end(), file.begin(), file.end());
    return r == root.end();
}

} // namespace

std::string_view path_of(std::string_view target)
{
    return target.substr(0, target.find_first_of("?#"));
}

std::optional<fs::path> file_for(fs::path const& root, std::string_view target)
{
    std::string_view path = path_of(target);
    if (path.empty() || path.front() != '/')
        return std::nullopt;
    fs::path relative;
    while (!path.empty()) {
        std::size_t const end = std::min(path.find('/'), path.size());
        std::string_view const raw = path.substr(0, end);
        path.remove_prefix(std::min(end + 1, path.size()));
        if (raw.empty())
            continue; // "//" is "/"
        auto const segment = decoded_segment(raw);
        if (!segment || segment->empty() || segment->front() == '.')
            return std::nullopt; // ".", "..", ".git", an encoded '/' or NUL
        relative /= *segment;
    }
    std::error_code ec;
    fs::path file = root / relative;
    if (fs::is_directory(file, ec))
        file /= "index.html";
    // Every link followed: what the open would read, which must lie inside the root.
    fs::path const resolved = fs::canonical(file, ec);
    if (ec || !inside(root, resolved) || !fs::is_regular_file(resolved, ec))
        return std::nullopt;
    return resolved;
}

std::string_view mime_type(std::string_view path)
{
    auto const ends_with = [&](std::string_view ext) { return path.ends_with(ext); };
    if (ends_with(".html") || ends_with(".htm"))
        return "text/html; charset=utf-8";
    if (ends_with(".js") || ends_with(".mjs"))
        return "text/javascript; charset=utf-8";
    if (ends_with(".css"))
        return "text/css; charset=utf-8";
    if (ends_with(".json") || ends_with(".map"))
        return "application/json";
    if (ends_with(".svg"))
        return "image/svg+xml";
    if (ends_with(".png"))
        return "image/png";
    if (ends_with(".ico"))
        return "image/vnd.microsoft.icon";
    if (ends_with(".txt") || ends_with(".md"))
        return "text/plain; charset=utf-8";
    return "application/octet-stream";
}

std::vector<page_place> page_places(std::filesystem::path const& executable,
                                    std::filesystem::path const& source_tree)
{
    std::filesystem::path const bin = executable.parent_path();
    std::vector<page_place> places{
        {bin / "web", "next to the executable"},
        {bin.parent_path() / "share" / "kugel" / "web", "in the install prefix"},
    };
    if (!source_tree.empty())
        places.push_back({source_tree / "web" / "dist", "in the source tree it was built from"});
    return places;
}

std::optional<page_place> find_page(std::vector<page_place> const& places)
{
    for (page_place const& place : places) {
        std::error_code ec;
        if (std::filesystem::is_regular_file(place.root / "index.html", ec))
            return place;
    }
    return std::nullopt;
}

} // namespace kugel::server
