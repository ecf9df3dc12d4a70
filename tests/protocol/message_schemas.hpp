#pragma once

// The published JSON Schemas of protocol/schema/, one per message type, so the tests hold
// the codec, the schemas and PROTOCOL.md to the same rules. Compiled once
// (message_schemas.cpp, in kugel_test_schemas): valijson's templates cost each file that
// instantiated them about 35 s under the sanitizers.

#include <filesystem>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace valijson {
class Schema;
}

namespace kugel::protocol::testing {

inline std::filesystem::path const source_dir = KUGEL_SOURCE_DIR;
inline std::filesystem::path const schema_dir = source_dir / "protocol" / "schema";

/// The whole file's text ("" when it cannot be read).
std::string read_file(std::filesystem::path const& path);

class message_schemas
{
  public:
    message_schemas();
    ~message_schemas();
    message_schemas(message_schemas const&) = delete;
    message_schemas& operator=(message_schemas const&) = delete;

    /// The message types that have a schema.
    std::vector<std::string> types() const;

    /// Empty when the schema of the message's `type` accepts it, otherwise why not.
    std::string refusal(nlohmann::json const& message) const;

    bool accepts(nlohmann::json const& message) const { return refusal(message).empty(); }

  private:
    std::map<std::string, std::unique_ptr<valijson::Schema>> schemas_;
};

/// The schemas of protocol/schema/, read once.
message_schemas const& schemas();

} // namespace kugel::protocol::testing
