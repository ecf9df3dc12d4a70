#include "client/script.hpp"

#include <filesystem>
#include <gtest/gtest.h>
#include <string>

namespace kugel::client {
namespace {

/// The message of the script_error that parsing `text` throws ("" when it parses).
std::string refusal(std::string const& text)
{
    try {
        parse_script(text);
        return "";
    } catch (script_error const& e) {
        return e.what();
    }
}

/// A script of one step.
std::string one_step(std::string const& step)
{
    return R"({"steps": [)" + step + "]}";
}

TEST(Script, ReadsEveryKindOfStep)
{
    script const s = parse_script(R"({
      "description": "all of them",
      "server": ["--room", "lab=lab.json"],
      "variables": {"g": 9.81},
      "steps": [
        {"name": "drop", "send": {"type": "spawn", "body": {"position": [0, 0, 1], "radius": 0.1, "mass": 1}}, "as": "drop"},
        {"expect": {"to": "drop", "type": "ack", "keep": {"ball": "id"}}},
        {"send_text": "{not json", "pad_to_bytes": 100},
        {"expect": {"code": "bad_json", "message_contains": "JSON"}},
        {"wait_ticks": 10},
        {"wait_until_tick": "= $tick0 + 5"},
        {"client": "other", "expect_body": {"id": "$ball", "position": [0, null, "= 1 - $g"], "tolerance": 1e-9}},
        {"wait_for_body": {"id": "$ball", "exists": false, "max_ticks": 60}},
        {"close": true},
        {"expect_close": {"code": 1009}},
        {"client": "other", "expect_player": {"change": "left", "id": "$ball", "name": null, "keep": {"gone": "id"}}}
      ]})");
    EXPECT_EQ(s.description, "all of them");
    EXPECT_EQ(s.server, (std::vector<std::string>{"--room", "lab=lab.json"}));
    EXPECT_EQ(s.variables.at("g"), 9.81);
    ASSERT_EQ(s.steps.size(), 11U);
    EXPECT_EQ(s.steps[0].kind, "send");
    EXPECT_EQ(std::get<send_step>(s.steps[0].action).label, "drop");
    EXPECT_EQ(std::get<expect_step>(s.steps[1].action).keep.at("ball"), "id");
    EXPECT_EQ(std::get<send_text_step>(s.steps[2].action).pad_to_bytes, 100U);
    EXPECT_EQ(*std::get<expect_step>(s.steps[3].action).type, "error"); // implied by the code
    EXPECT_EQ(s.steps[6].client, "other");
    EXPECT_EQ(s.steps[0].client, "main");
    auto const& body = std::get<expect_body_step>(s.steps[6].action).body;
    EXPECT_TRUE((*body.position)[1].is_null());
    EXPECT_FALSE(std::get<wait_for_body_step>(s.steps[7].action).body.exists);
    EXPECT_EQ(*std::get<expect_close_step>(s.steps[9].action).code, 1009);
    auto const& player = std::get<expect_player_step>(s.steps[10].action);
    EXPECT_EQ(player.fields, (nlohmann::json{{"change", "left"}, {"id", "$ball"}, {"name", nullptr}}));
    EXPECT_EQ(player.keep.at("gone"), "id");
    EXPECT_EQ(label_of(s.steps[0]), "step 1 \"drop\" (send, client main)");
}

TEST(Script, ExpectEventReadsItsFields)
{
    script const s = parse_script(R"({"steps": [
        {"client": "fan", "expect_event": {"kind": "entered", "sensor": "goal", "body": "$ball", "tag": null,
                                           "tick": 12, "keep": {"at": "time"}}},
        {"expect_event": {}},
        {"expect_event": {"kind": "contact", "bodies": [1, "$ball"], "tags": ["post", "ball"]}}]})");
    ASSERT_EQ(s.steps.size(), 3U);
    EXPECT_EQ(s.steps[0].kind, "expect_event");
    auto const& e = std::get<expect_event_step>(s.steps[0].action);
    EXPECT_EQ(e.fields, (nlohmann::json{{"kind", "entered"}, {"sensor", "goal"}, {"body", "$ball"}, {"tag", nullptr},
                                        {"tick", 12}}));
    EXPECT_EQ(e.keep.at("at"), "time");
    EXPECT_TRUE(std::get<expect_event_step>(s.steps[1].action).fields.empty());
    EXPECT_EQ(std::get<expect_event_step>(s.steps[2].action).fields,
              (nlohmann::json{{"kind", "contact"}, {"bodies", {1, "$ball"}}, {"tags", {"post", "ball"}}}));
    EXPECT_NE(refusal(one_step(R"({"expect_event": {"kind": "stayed"}})"))
                  .find(R"(step 1 (expect_event): /expect_event/kind: must be "entered", "left" or "contact")"),
              std::string::npos);
    EXPECT_NE(refusal(one_step(R"({"expect_event": {"bodies": [1]}})")).find("/expect_event/bodies: must be a contact's two body ids"),
              std::string::npos);
    EXPECT_NE(refusal(one_step(R"({"expect_event": {"tags": ["ball", 2]}})")).find("/expect_event/tags/1"),
              std::string::npos);
    EXPECT_NE(refusal(one_step(R"({"expect_event": {"tag": 7}})")).find("/expect_event/tag: must be a string"),
              std::string::npos);
    EXPECT_NE(refusal(one_step(R"({"expect_event": {"sensor": 7}})")).find("/expect_event/sensor"),
              std::string::npos);
    EXPECT_NE(refusal(one_step(R"({"expect_event": {"what": 1}})")).find("unknown field \"what\""),
              std::string::npos);
}

TEST(Script, RefusalsNameTheStepAndTheField)
{
    EXPECT_EQ(refusal("{not json").find("not valid JSON"), 0U);
    EXPECT_NE(refusal(R"({"steps": []})").find("/steps"), std::string::npos);
    EXPECT_NE(refusal(R"({"stepz": []})").find("unknown field \"stepz\""), std::string::npos);
    EXPECT_NE(refusal(R"({"cleanup": "yes", "steps": [{"wait_ticks": 1}]})").find("/cleanup: must be true or false"),
              std::string::npos);
    EXPECT_NE(refusal(one_step(R"({"sned": {}})")).find("step 1: no action"), std::string::npos);
    EXPECT_NE(refusal(one_step(R"({"expect_body": {"id": 1, "tag": 7}})"))
                  .find("/expect_body/tag: must be a string (the body's tag) or null (no tag)"),
              std::string::npos);
    EXPECT_NE(refusal(one_step(R"({"expect_body": {"id": 1, "exists": false, "tag": "a"}})"))
                  .find("/expect_body/tag: a body expected not to exist has no tag"),
              std::string::npos);
    EXPECT_NE(refusal(one_step(R"({"send": {"type": "ping"}, "expect": {"type": "pong"}})"))
                  .find("more than one action"),
              std::string::npos);
    EXPECT_NE(refusal(one_step(R"({"send": {"type": "ping", "ref": 3}})"))
                  .find("step 1 (send): /send/ref: refs are chosen by the connection"),
              std::string::npos);
    EXPECT_NE(refusal(one_step(R"({"send": {"ref": 3}})")).find("\"type\""), std::string::npos);
    EXPECT_NE(refusal(one_step(R"({"expect": {}})")).find("say what answer is expected"),
              std::string::npos);
    EXPECT_NE(refusal(one_step(R"({"expect_player": {"change": "kicked"}})"))
                  .find(R"(step 1 (expect_player): /expect_player/change: must be "joined", "renamed" or "left")"),
              std::string::npos);
    EXPECT_NE(refusal(one_step(R"({"expect_player": {"name": 7}})")).find("/expect_player/name: must be a string"),
              std::string::npos);
    EXPECT_NE(refusal(one_step(R"({"expect_player": {"who": 7}})")).find("unknown field \"who\""),
              std::string::npos);
    EXPECT_NE(refusal(one_step(R"({"expect": {"type": "welcome"}})")).find("/expect/type"),
              std::string::npos);
    EXPECT_NE(refusal(one_step(R"({"expect": {"type": "ack", "code": "bad_json"}})"))
                  .find("/expect/code"),
              std::string::npos);
    EXPECT_NE(
        refusal(one_step(R"({"expect": {"type": "ack", "which": "most"}})")).find("/expect/which"),
        std::string::npos);
    EXPECT_NE(refusal(one_step(R"({"expect_body": {"id": 1, "position": [0, 0, 0]}})"))
                  .find("\"tolerance\" is required"),
              std::string::npos);
    EXPECT_NE(refusal(one_step(R"({"expect_body": {"id": 1, "position": [0, 0]}, "tolerance": 0})"))
                  .find("unknown field \"tolerance\""),
              std::string::npos);
    EXPECT_NE(refusal(one_step(R"({"expect_body": {"id": 1, "position": [0, 0], "tolerance": 0}})"))
                  .find("/expect_body/position: must be [x, y, z]"),
              std::string::npos);
    EXPECT_NE(
        refusal(one_step(R"({"expect_body": {"id": 1, "position": [0, "up", 0], "tolerance": 0}})"))
            .find("/expect_body/position/1"),
        std::string::npos);
    EXPECT_NE(
        refusal(one_step(R"({"wait_for_body": {"id": 1}})")).find("\"max_ticks\" is required"),
        std::string::npos);
    EXPECT_NE(refusal(one_step(R"({"send": {"type": "ping"}, "repeat": 0})")).find("/repeat"),
              std::string::npos);
    EXPECT_NE(refusal(one_step(R"({"wait_ticks": "ten"})")).find("/wait_ticks"), std::string::npos);
    EXPECT_NE(refusal(one_step(R"({"close": 1001})")).find("\"close\": true"), std::string::npos);
    EXPECT_NE(refusal(one_step(R"({"expect": {"type": "ack", "keep": {"my id": "id"}}})"))
                  .find("a variable name"),
              std::string::npos);
}

TEST(Script, EveryExampleReads)
{
    std::filesystem::path const examples =
        std::filesystem::path(KUGEL_SOURCE_DIR) / "client" / "examples";
    int read = 0;
    for (auto const& entry : std::filesystem::directory_iterator(examples)) {
        if (entry.path().extension() != ".json")
            continue;
        EXPECT_NO_THROW(load_script(entry.path())) << entry.path();
        ++read;
    }
    EXPECT_GE(read, 4);
}

TEST(Script, LoadNamesTheFile)
{
    try {
        load_script("no/such/script.json");
        FAIL() << "no error";
    } catch (script_error const& e) {
        EXPECT_NE(std::string(e.what()).find("no/such/script.json"), std::string::npos);
    }
}

} // namespace
} // namespace kugel::client
