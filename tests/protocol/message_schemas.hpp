#pragma once

// The published JSON Schemas of protocol/schema/, one per message type, so the tests hold
// the codec, the schemas and PROTOCOL.md to the same rules.

#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <valijson/adapters/nlohmann_json_adapter.hpp>
#include <valijson/schema.hpp>
#include <valijson/schema_parser.hpp>
#include <valijson/validation_results.hpp>
#include <valijson/validator.hpp>
#include <vector>

namespace kugel::protocol::testing {

inline std::filesystem::path const source_dir = KUGEL_SOURCE_DIR;
inline std::filesystem::path const schema_dir = source_dir / "protocol" / "schema";

inline std::string read_file(std::filesystem::path const& path)
{
    std::ifstream in(path);
    std::ostringstream out;
    out << in.rdbuf();
    return out.str();
}

class message_schemas
{
  public:
    message_schemas()
    {
        std::string const suffix = ".schema.json";
        for (auto const& entry : std::filesystem::directory_iterator(schema_dir)) {
            std::string const file = entry.path().filename().string();
            if (!file.ends_with(suffix))
                continue;
            auto const doc = nlohmann::json::parse(read_file(entry.path()));
            auto schema = std::make_unique<valijson::Schema>();
            valijson::SchemaParser parser;
            valijson::adapters::NlohmannJsonAdapter adapter(doc);
            parser.populateSchema(adapter, *schema);
            schemas_.emplace(file.substr(0, file.size() - suffix.size()), std::move(schema));
        }
    }

    /// The message types that have a schema.
    std::vector<std::string> types() const
    {
        std::vector<std::string> out;
        for (auto const& [type, _] : schemas_)
            out.push_back(type);
        return out;
    }

    /// Empty when the schema of the message's `type` accepts it, otherwise why not.
    std::string refusal(nlohmann::json const& message) const
    {
        if (!message.is_object() || !message.contains("type") || !message["type"].is_string())
            return "no string type";
        auto const found = schemas_.find(message["type"].get<std::string>());
        if (found == schemas_.end())
            return "no schema for type " + message["type"].dump();
        valijson::Validator validator;
        valijson::ValidationResults results;
        valijson::adapters::NlohmannJsonAdapter adapter(message);
        if (validator.validate(*found->second, adapter, &results))
            return {};
        std::string why;
        valijson::ValidationResults::Error e;
        while (results.popError(e)) {
            for (auto const& part : e.context)
                why += part;
            why += ": " + e.description + "\n";
        }
        return why.empty() ? "refused" : why;
    }

    bool accepts(nlohmann::json const& message) const { return refusal(message).empty(); }

  private:
    std::map<std::string, std::unique_ptr<valijson::Schema>> schemas_;
};

inline message_schemas const& schemas()
{
    static message_schemas const instance;
    return instance;
}

} // namespace kugel::protocol::testing
