#pragma once

// One or more filled-in messages of every type, with every optional field both present and
// absent somewhere, for round trips and schema checks.

#include "protocol/messages.hpp"

#include <cmath>
#include <numbers>
#include <string>
#include <vector>

namespace kugel::protocol::samples {

inline std::vector<client_message> client_messages()
{
    return {
        hello{},
        hello{.protocol = protocol_version, .name = "orbit-viewer"},
        hello{.name = "operator", .admin_token = "s3cret-token"},
        hello{.protocol = protocol_version, .snapshots = snapshot_request{.form = "compact", .rate = 10.0}},
        hello{.snapshots = snapshot_request{}},
        hello{.players = false},
        hello{.name = "ann", .resume = "6f1c0e9a52d84b37a0c4e1f2d3b5a697"},
        hello{.events = event_request{}},
        hello{.events = event_request{.on = false}},
        hello{.events = event_request{.filter = {.sensors = std::vector<std::string>{"goal", "zone 🎯"},
                                                 .tags = std::vector<std::string>{"ball"},
                                                 .kinds = std::vector<std::string>{"entered"}}}},
        hello{.name = "watcher", .events = event_request{.filter = {.kinds = std::vector<std::string>{"left", "entered"}}}},
        spawn{.ref = 1, .body = {.position = {0.0, 0.0, 2.0}, .radius = 0.1, .mass = 2.5}},
        spawn{.ref = 2,
              .body = {.position = {1.0, -2.0, 3.5},
                       .velocity = {1.5, 0.0, -0.25},
                       .radius = 0.05,
                       .density = 7800.0,
                       .charge = -1e-6}},
        spawn{.ref = 11,
              .body = {.position = {0.0, 1.0, 0.5}, .radius = 0.5, .mass = 100.0, .tag = "post 🎱", .is_static = true}},
        spawn{.ref = 12, .body = {.position = {0.0, 1.0, 0.5}, .radius = 0.1, .mass = 1.0, .tag = R"(say "hi" \ bye)"}},
        impulse{.ref = 3, .id = 17, .impulse = {0.0, 0.0, 0.25}},
        set{.ref = 13, .id = 17, .position = vec3{1.0, 2.0, 3.0}, .velocity = vec3{0.0, -0.5, 0.0}},
        set{.ref = 14, .id = 18, .position = vec3{1.0, 2.0, 3.0}},
        set{.ref = 15, .id = 19, .velocity = vec3{0.0, 0.0, 0.0}},
        remove{.ref = 4, .id = 0},
        ping{.ref = max_safe_integer},
        pause{.ref = 6},
        resume{.ref = 7},
        reset{.ref = 8},
        load_scene{.ref = 9,
                   .scene = {R"({"name":"drop","dt":0.01,"bodies":[{"position":[0,0,1],)"
                             R"("radius":0.1,"mass":1}],"nested":{"a":[1,2.5,"x",null,true]}})"}},
        load_scene{.ref = 10, .scene = {"{}"}},
    };
}

inline welcome sample_welcome()
{
    double const c = std::cos(0.3);
    double const s = std::sin(0.3);
    return {
        .client = 3,
        .room = "default",
        .tick_rate = 60.0,
        .dt = 1.0 / 60.0,
        .snapshot_rate = 30.0,
        .scene =
            {.name = "pile",
             .walls = {{.normal = {0.0, 0.0, 1.0}, .offset = 0.0, .damping = 0.2, .friction = 0.1},
                       {.normal = {-1.0, 0.0, 0.0}, .offset = -5.0}},
             .obstacles = {{.centre = {0.0, 0.0, 0.5},
                            .half_extents = {1.0, 0.5, 0.25},
                            .axes = {{{c, s, 0.0}, {-s, c, 0.0}, {0.0, 0.0, 1.0}}}}},
             .bounds = {.centre = {0.0, 0.0, 2.0}, .radius = 5.0}},
        .limits = {.max_message_bytes = 65536, .max_bodies = 10000, .commands_per_second = 100},
    };
}

inline std::vector<server_message> server_messages()
{
    return {
        sample_welcome(),
        welcome{.client = 0,
                .room = "empty",
                .tick_rate = 1000.0,
                .dt = 1e-3,
                .snapshot_rate = 7.5,
                .scene = {.name = "", .bounds = {.radius = 0.0}},
                .limits = {.max_message_bytes = 1,
                           .max_bodies = 0,
                           .commands_per_second = 0,
                           .max_bodies_per_client = 50,
                           .max_queued_events = 256},
                .admin = true,
                .permissions = {.push = "owner", .remove = "admins"},
                .snapshots = snapshot_stream{.form = "compact",
                                             .rate = 15.0,
                                             .position_quantum = 1e-3,
                                             .velocity_quantum = 1e-2,
                                             .keyframe_interval = 10.0},
                .resume_grace = 30.0,
                .bodies_on_leave = "remove",
                .resume_token = "6f1c0e9a52d84b37a0c4e1f2d3b5a697"},
        ack{.ref = 1, .tick = 1204, .id = 17},
        ack{.ref = 3, .tick = 1210},
        error{.ref = 1,
              .code = error_code::bad_value,
              .message = "/body/radius: must be >= 0, got -1"},
        error{.code = error_code::rate_limited, .message = "slow down"},
        snapshot{.tick = 1204,
                 .time = 1204.0 / 60.0,
                 .bodies = {.id = {4, 17, max_safe_integer},
                            .position = {0.0, 0.0, 0.1, 0.5, -0.25, 1.75, 1e300, -1e-300, 0.0},
                            .velocity = {0.0, 0.0, 0.0, 1.5, 0.0, -3.2, 0.1, 0.2, 0.3},
                            .radius = {0.1, 0.1, 0.0}}},
        snapshot{.tick = 7,
                 .time = 0.07,
                 .paused = true,
                 .bodies = {.id = {0, 1},
                            .position = {1.0, 2.0, 3.0, 4.0, 5.0, 6.0},
                            .velocity = {-1.0, -2.0, -3.0, -4.0, -5.0, -6.0},
                            .radius = {0.0, 0.5},
                            .mass = std::vector{1.0, std::numbers::pi},
                            .charge = std::vector{-1.6e-19, 1.6e-19}}},
        snapshot{.tick = 8,
                 .time = 0.08,
                 .bodies = {.id = {1, 2},
                            .position = {1.0, 2.0, 3.0, 4.0, 5.0, 6.0},
                            .velocity = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
                            .radius = {0.5, 0.5},
                            .mass = std::vector{1.0, 2.0},
                            .tag = std::vector<std::string>{"", R"(goal "A" \ 🎱)"}}},
        snapshot{},
        roster{.players = {{.id = 3, .name = "ann", .away = true}, {.id = 7, .name = std::nullopt},
                           {.id = max_safe_integer, .name = "Zoë 🎱"}}},
        roster{},
        player_notice{.change = "joined", .id = 8},
        player_notice{.change = "renamed", .id = 8, .name = "bob"},
        player_notice{.change = "left", .id = 3, .name = "ann"},
        player_notice{.change = "away", .id = 3, .name = "ann"},
        player_notice{.change = "back", .id = 3},
        event{.tick = 1204, .time = 20.0583, .kind = "entered", .sensor = "goal", .body = 17},
        event{.tick = max_safe_integer, .time = -1e-300, .kind = "left", .sensor = R"(zone "B" \ 🎯)", .body = 4,
              .tag = "ball", .missed = 12},
        pong{.ref = 5, .tick = 1207},
        pong{.ref = 6, .tick = 1208, .tick_ms = 0.42},
        compact_snapshot{.tick = 1204,
                         .form = "key",
                         .time = 1204.0 / 60.0,
                         .q = std::array{1e-3, 1e-2},
                         .bodies = compact_bodies{.id = {4, 17, max_safe_integer},
                                                  .position = {0, 0, 100, 500, -250, 1750,
                                                               9007199254740991, -9007199254740991, 0},
                                                  .velocity = {0, 0, 0, 150, 0, -320, 1, 2, 3},
                                                  .radius = {0.1, 0.1, 0.0},
                                                  .mass = {32.67, 32.67, 1.0},
                                                  .owner = {0, 3, 3}}},
        compact_snapshot{.tick = 1205,
                         .form = "key",
                         .time = 1205.0 / 60.0,
                         .q = std::array{1e-3, 1e-2},
                         .bodies = compact_bodies{.id = {4, 17},
                                                  .position = {0, 0, 100, 500, -250, 1750},
                                                  .velocity = {0, 0, 0, 150, 0, -320},
                                                  .radius = {0.1, 0.1},
                                                  .mass = {32.67, 32.67},
                                                  .owner = {0, 3},
                                                  .tag = std::vector<std::string>{"goal", ""}}},
        compact_snapshot{.tick = 1206,
                         .form = "delta",
                         .base = 1204,
                         .time = 1206.0 / 60.0,
                         .paused = true,
                         .faults = 2,
                         .moved = compact_moves{.runs = {1, 1}, .position = {0, -1, 2}, .velocity = {0, 0, -33}},
                         .appeared = compact_bodies{.id = {20},
                                                    .position = {1, 2, 3},
                                                    .velocity = {0, 0, 0},
                                                    .radius = {0.2},
                                                    .mass = {4.0},
                                                    .charge = std::vector{1e-6},
                                                    .owner = {7},
                                                    .tag = std::vector<std::string>{"red"}},
                         .vanished = std::vector<std::uint64_t>{4, max_safe_integer}},
        compact_snapshot{.tick = 2, .form = "delta", .base = 0},
    };
}

} // namespace kugel::protocol::samples
