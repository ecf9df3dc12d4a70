#include "message_schemas.hpp"
#include "protocol/codec.hpp"
#include "sample_messages.hpp"

#include <algorithm>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <utility>
#include <variant>
#include <vector>

namespace kugel::protocol {
namespace {

using nlohmann::json;
using testing::read_file;
using testing::schemas;

template <class Variant> std::set<std::string> type_names()
{
    std::set<std::string> out;
    [&]<std::size_t... I>(std::index_sequence<I...>)
    {
        (out.insert(std::string(std::variant_alternative_t<I, Variant>::type)), ...);
    }
    (std::make_index_sequence<std::variant_size_v<Variant>>{});
    return out;
}

std::set<std::string> all_type_names()
{
    auto out = type_names<client_message>();
    out.merge(type_names<server_message>());
    return out;
}

TEST(Schemas, OneForEveryMessageType)
{
    auto const types = schemas().types();
    EXPECT_EQ(std::set<std::string>(types.begin(), types.end()), all_type_names());
}

TEST(Schemas, AcceptEveryEncodedMessage)
{
    for (auto const& message : samples::client_messages()) {
        std::string const text = encode(message);
        EXPECT_EQ(schemas().refusal(json::parse(text)), "") << text;
    }
    for (auto const& message : samples::server_messages()) {
        std::string const text = encode(message);
        EXPECT_EQ(schemas().refusal(json::parse(text)), "") << text;
    }
}

/// A sample server message with one mistake a server could make.
struct broken_case
{
    char const* what;
    json message;
};

void PrintTo(broken_case const& c, std::ostream* out)
{
    *out << c.what;
}

class BrokenServerMessage : public ::testing::TestWithParam<broken_case>
{
};

TEST_P(BrokenServerMessage, IsRefusedByItsSchema)
{
    EXPECT_FALSE(schemas().accepts(GetParam().message)) << GetParam().message.dump();
}

json encoded(server_message const& message)
{
    return json::parse(encode(message));
}

json sample_snapshot()
{
    return encoded(samples::server_messages().at(6));
}

std::vector<broken_case> broken_server_messages()
{
    std::vector<broken_case> out;
    auto const add = [&](char const* what, json message, auto&& change) {
        change(message);
        out.push_back({what, std::move(message)});
    };
    json const welcome_doc = encoded(samples::sample_welcome());
    add("welcome_without_dt", welcome_doc, [](json& m) { m.erase("dt"); });
    add("welcome_zero_tick_rate", welcome_doc, [](json& m) { m["tick_rate"] = 0; });
    add("welcome_protocol_2", welcome_doc, [](json& m) { m["protocol"] = 2; });
    add("welcome_misspelt_field", welcome_doc, [](json& m) { m["tickrate"] = 60; });
    add("wall_normal_of_two", welcome_doc, [](json& m) {
        m["scene"]["walls"][0]["normal"] = json::array({0, 1});
    });
    add("wall_damping_above_one", welcome_doc,
        [](json& m) { m["scene"]["walls"][0]["damping"] = 1.5; });
    add("obstacle_with_two_axes", welcome_doc,
        [](json& m) { m["scene"]["obstacles"][0]["axes"].erase(2); });
    add("bounds_as_array", welcome_doc, [](json& m) {
        m["scene"]["bounds"] = json::array({0, 0, 0, 1});
    });
    add("limits_negative", welcome_doc, [](json& m) { m["limits"]["max_bodies"] = -1; });
    add("client_id_as_string", welcome_doc, [](json& m) { m["client"] = "3"; });
    add("welcome_bodies_on_leave_unknown", welcome_doc, [](json& m) { m["bodies_on_leave"] = "vanish"; });
    add("welcome_negative_resume_grace", welcome_doc, [](json& m) { m["resume_grace"] = -1; });
    add("welcome_empty_resume_token", welcome_doc, [](json& m) { m["resume_token"] = ""; });

    json const snapshot_doc = sample_snapshot();
    add("snapshot_position_of_strings", snapshot_doc,
        [](json& m) { m["bodies"]["position"][0] = "0"; });
    add("snapshot_bodies_as_rows", snapshot_doc, [](json& m) {
        m["bodies"] = json::array({{{"id", 1}, {"position", {0, 0, 0}}}});
    });
    add("snapshot_without_radius", snapshot_doc, [](json& m) { m["bodies"].erase("radius"); });
    add("snapshot_negative_radius", snapshot_doc, [](json& m) { m["bodies"]["radius"][0] = -1; });
    add("snapshot_id_beyond_2_to_53", snapshot_doc,
        [](json& m) { m["bodies"]["id"][0] = 9007199254740992ULL; });
    add("snapshot_fractional_tick", snapshot_doc, [](json& m) { m["tick"] = 1.5; });

    add("ack_negative_tick", encoded(ack{.ref = 1, .tick = 2}), [](json& m) { m["tick"] = -2; });
    add("ack_without_ref", encoded(ack{.ref = 1, .tick = 2}), [](json& m) { m.erase("ref"); });
    add("error_unknown_code", encoded(error{.code = error_code::bad_json, .message = "x"}),
        [](json& m) { m["code"] = "teapot"; });
    add("error_without_message", encoded(error{.code = error_code::bad_json, .message = "x"}),
        [](json& m) { m.erase("message"); });
    add("pong_with_extra_field", encoded(pong{.ref = 1, .tick = 2}),
        [](json& m) { m["time"] = 0.5; });
    return out;
}

INSTANTIATE_TEST_SUITE_P(Cases, BrokenServerMessage, ::testing::ValuesIn(broken_server_messages()));

TEST(Schemas, ErrorCodeEnumListsEveryCode)
{
    json const schema = json::parse(read_file(testing::schema_dir / "error.schema.json"));
    std::vector<std::string> names;
    for (auto const code : all_error_codes)
        names.emplace_back(name(code));
    EXPECT_EQ(schema["properties"]["code"]["enum"].get<std::vector<std::string>>(), names);
}

// PROTOCOL.md ---------------------------------------------------------------------------

std::string const protocol_doc = read_file(testing::source_dir / "protocol" / "PROTOCOL.md");

/// The text of every ```json block.
std::vector<std::string> json_examples(std::string const& markdown)
{
    std::vector<std::string> out;
    std::string const open = "```json\n";
    std::string const close = "\n```";
    for (auto start = markdown.find(open); start != std::string::npos;
         start = markdown.find(open, start)) {
        start += open.size();
        auto const end = markdown.find(close, start);
        if (end == std::string::npos)
            break;
        out.push_back(markdown.substr(start, end - start));
        start = end + close.size();
    }
    return out;
}

TEST(ProtocolDoc, EveryJsonExampleDecodesAndMatchesItsSchema)
{
    auto const examples = json_examples(protocol_doc);
    std::set<std::string> shown;
    auto const client_types = type_names<client_message>();
    for (std::string const& example : examples) {
        SCOPED_TRACE(example);
        json doc;
        ASSERT_NO_THROW(doc = json::parse(example));
        EXPECT_EQ(schemas().refusal(doc), "");
        std::string const type = doc.value("type", "");
        shown.insert(type);
        auto const failure = client_types.contains(type) ? decode(example).failure
                                                         : decode_server_message(example).failure;
        EXPECT_FALSE(failure) << encode(*failure);
    }
    EXPECT_EQ(shown, all_type_names()) << "every message type has an example";
}

TEST(ProtocolDoc, DescribesEveryErrorCode)
{
    for (auto const code : all_error_codes) {
        std::string const row = "| `" + std::string(name(code)) + "` |";
        EXPECT_NE(protocol_doc.find(row), std::string::npos) << "no row for " << name(code);
    }
}

TEST(ProtocolDoc, ErrorExamplesAreWhatDecodeSays)
{
    // Rows of the examples table: | `message` | `code` | `message text` |
    std::string const marker = "| message | code | message text |";
    auto pos = protocol_doc.find(marker);
    ASSERT_NE(pos, std::string::npos);
    pos = protocol_doc.find('\n', protocol_doc.find('\n', pos) + 1) + 1; // skip the rule
    int rows = 0;
    while (protocol_doc.compare(pos, 3, "| `") == 0) {
        auto const line_end = protocol_doc.find('\n', pos);
        std::string const line = protocol_doc.substr(pos, line_end - pos);
        pos = line_end + 1;
        // Cells are `code`-quoted; split on "` | `".
        std::vector<std::string> cells;
        std::size_t from = 3;
        for (auto to = line.find("` | `", from); to != std::string::npos;
             to = line.find("` | `", from)) {
            cells.push_back(line.substr(from, to - from));
            from = to + 5;
        }
        cells.push_back(line.substr(from, line.rfind("` |") - from));
        ASSERT_EQ(cells.size(), 3U) << line;
        if (cells[0].ends_with("..."))
            continue; // shortened in the table
        ++rows;
        SCOPED_TRACE(cells[0]);
        auto const decoded = decode(cells[0]);
        ASSERT_TRUE(decoded.failure);
        EXPECT_EQ(name(decoded.failure->code), cells[1]);
        EXPECT_EQ(decoded.failure->message, cells[2]);
    }
    EXPECT_GE(rows, 4);
}

} // namespace
} // namespace kugel::protocol
