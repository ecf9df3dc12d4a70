#include "protocol/message_schemas.hpp"

#include <valijson/adapters/nlohmann_json_adapter.hpp>
#include <valijson/schema.hpp>
#include <valijson/schema_parser.hpp>
#include <valijson/validation_results.hpp>
#include <valijson/validator.hpp>

#include <fstream>
#include <sstream>

namespace kugel::protocol::testing {

std::string read_file(std::filesystem::path const& path)
{
    std::ifstream in(path);
    std::ostringstream out;
    out << in.rdbuf();
    return out.str();
}

message_schemas::message_schemas()
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

message_schemas::~message_schemas() = default;

std::vector<std::string> message_schemas::types() const
{
    std::vector<std::string> out;
    for (auto const& [type, _] : schemas_)
        out.push_back(type);
    return out;
}

std::string message_schemas::refusal(nlohmann::json const& message) const
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

message_schemas const& schemas()
{
    static message_schemas const instance;
    return instance;
}

} // namespace kugel::protocol::testing
