#pragma once

#include "checkpoint.hpp"
#include "encoded_snapshot.hpp"
#include "interest.hpp"
#include "metrics.hpp"
#include "network.hpp"
#include "options.hpp"

#include "physics/thread_pool.hpp"
#include "physics/world.hpp"
#include "protocol/messages.hpp"
#include "scene/scene.hpp"

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <unordered_map>
#include <vector>

namespace kugel::server {

class websocket_session;

/// What a room tells the world outside its strand (tests, logs, /healthz): read atomically.
struct room_counters
{
    std::atomic<std::uint64_t> ticks{0};      ///< ticks completed
    std::atomic<std::uint64_t> late_ticks{0}; ///< ticks dropped because the room fell behind
    std::atomic<std::uint64_t> bodies{0};
    std::atomic<std::uint64_t> sessions{0};
    std::atomic<std::uint64_t> players{0}; ///< one per session, and the away players kept for a resume
    std::atomic<std::uint64_t> snapshots{0};  ///< snapshots encoded and sent
    /// Snapshots due while the last was still being encoded: not taken (room::send_snapshot)
    std::atomic<std::uint64_t> snapshots_skipped{0};
    /// Steps that failed (a singular force, a state beyond a double) and were recovered from
    /// by removing the bodies at fault (room::step_world)
    std::atomic<std::uint64_t> step_faults{0};
    /// Nanoseconds the room's steps spent in each phase (physics/step_timings.hpp)
    std::array<std::atomic<std::uint64_t>, physics::step_phase_count> phase_nanoseconds{};
    /// Discrete mode: bodies that moved farther than collisions.sweep_fraction of their radius
    /// in a step and were swept, and those that were not (each a contact that may have been
    /// missed; zero while the sweep is on): physics::collision_stats, summed over the room's worlds
    std::atomic<std::uint64_t> swept_bodies{0};
    std::atomic<std::uint64_t> unswept_fast_bodies{0};
    /// The continuous mode's events (and the sweep's), and the steps (or sweeps) that reached
    /// an event cap and were finished in discrete mode: not exact there
    std::atomic<std::uint64_t> collision_events{0};
    std::atomic<std::uint64_t> capped_steps{0};
};

/// One world and the clients watching it. Everything here runs on the room's strand: the
/// world is touched by nothing else. Sessions hand it commands by posting (submit), and it
/// answers them and sends snapshots by posting back.
///
/// One tick (DESIGN.md): apply the commands that arrived since the last tick in arrival
/// order, step the world, send a snapshot when one is due (copied on the tick, encoded once
/// off it, the same bytes to every session), record the tick's cost. Ticks follow a steady
/// clock at tick_rate; a room that falls more than a few ticks behind drops them instead of
/// spiralling.
class room : public std::enable_shared_from_this<room>
{
public:
    struct settings
    {
        double tick_rate = 60.0;     ///< Hz
        double snapshot_rate = 30.0; ///< Hz
        std::size_t max_bodies = 20'000;
        client_limits client;
        /// Where checkpoints go (DIR/ROOM.json); empty: none are taken.
        std::filesystem::path state_dir;
        std::chrono::milliseconds checkpoint_interval{5000};
        /// Threads that step the world, the room's own tick thread counted: more than one
        /// lends the world a thread_pool for its discrete-collision and drift loops. The
        /// result is the same bit for bit; only the time a step takes changes.
        std::size_t physics_threads = 1;
        /// Bodies from which the world uses those threads (world::set_parallel_for).
        std::size_t physics_threads_from = physics::world::bodies_worth_sharing;
        /// m and m/s: the compact form's quanta; 0 chooses them from the scene (room.cpp,
        /// default_quanta).
        double position_quantum = 0.0;
        double velocity_quantum = 0.0;
        /// s: a compact stream has a keyframe at least this often, besides those a client
        /// needs (it joined, or skipped a delta's base).
        double keyframe_interval = 10.0;
        /// s and the rule for scenes that set no `players` of their own (the scene's wins).
        double resume_grace = 0.0;
        bool remove_bodies_on_leave = false;
    };

    /// Builds the scene's world, or (given a checkpoint of this scene) the checkpoint's
    /// world, ids and tick, in the scene an admin loaded when the checkpoint carries one.
    /// `scene_fingerprint`, of the text of `s` and of the overrides `scene_overrides` it was
    /// made with (scene_fingerprint()), is written into this room's checkpoints with them.
    /// Throws physics::singular_force_error if it cannot start, checkpoint_error for a
    /// checkpoint body the world refuses or a loaded scene the scene loader refuses.
    /// `ticks` runs the room's strand (its ticks, commands and snapshots' copies);
    /// `background` runs what must not hold up a tick (encoding snapshots, writing a
    /// checkpoint).
    room(net::io_context& ticks, net::any_io_executor background, std::string name,
         scene::scene const& s, settings config, std::string scene_fingerprint = {},
         std::vector<std::string> scene_overrides = {}, std::optional<checkpoint> restored = {});

    std::string const& name() const { return name_; }
    room_counters const& counters() const { return counters_; }
    /// What the last step fault was and which bodies it cost; empty while there was none.
    /// Any thread.
    std::string last_fault() const;
    /// Counted by the room's sessions on their strands, read by /metrics from any thread.
    traffic_counters& traffic() { return traffic_; }
    traffic_counters const& traffic() const { return traffic_; }
    tick_histogram const& tick_durations() const { return tick_durations_; }
    /// How late the ticks started against their schedule.
    tick_lateness const& lateness() const { return lateness_; }

    /// Starts ticking. The room keeps itself alive while it ticks.
    void start();
    /// Stops ticking and closes every session with 1001 (going away).
    void stop();

    /// Adds a session; it is sent `welcome` first, then every snapshot. A session leaves
    /// by ending: the room holds it weakly, and its destructor calls leave().
    void join(std::shared_ptr<websocket_session> session);
    /// Queues a command for the next tick (ping is answered at once). `admin`: the sender
    /// proved itself an admin before sending it (the session refuses admin commands from
    /// anyone else; the room checks what only it can: whose body a remove names).
    void submit(std::shared_ptr<websocket_session> from, protocol::client_message command,
                bool admin = false);
    /// The session's hello gave a name: the room's players are told (player "renamed").
    void rename(std::shared_ptr<websocket_session> session, std::string name);
    /// Sends the session the room's players now (it had too many notices unsent).
    void send_roster(std::shared_ptr<websocket_session> session);
    /// The session's hello said whether it wants player messages; turned on again, it is sent
    /// the roster.
    void hear_players(std::shared_ptr<websocket_session> session, bool hears);
    /// The session ended (its destructor; `connection_id` is its connection_id()): the other
    /// players are told it left, or, while the room keeps players for a resume, that it is
    /// away.
    void leave(std::uint64_t connection_id);
    /// The session's hello carried a resume token: when it is a player's the room keeps (away,
    /// or connected elsewhere, whose connection is then closed), the session becomes that
    /// player and is sent a welcome saying so; otherwise it is answered bad_resume.
    void resume(std::shared_ptr<websocket_session> session, std::string token);
    /// The session proved itself an admin: it is sent a welcome saying so.
    void grant_admin(std::shared_ptr<websocket_session> session);
    /// The session's hello asked for a snapshot form or rate: from the next snapshot on it
    /// gets them, and it is sent a welcome saying what it gets (welcome.snapshots).
    void request_snapshots(std::shared_ptr<websocket_session> session,
                           protocol::snapshot_request request);
    /// The session's hello asked for sensor events: from the next tick on it is sent those
    /// that match. A sensor name the room's scene does not have is answered bad_value, and the
    /// session keeps what it had.
    void subscribe_events(std::shared_ptr<websocket_session> session, protocol::event_request request);
    /// The session's hello stated an interest: applied at the next tick, in arrival order with
    /// its commands, as the interest command is; answered only when refused (an error without
    /// a ref).
    void set_interest(std::shared_ptr<websocket_session> session, protocol::interest_filter filter);

    /// The room's state now. Call it on the room's strand, or while nothing runs the room
    /// (before start, after the server's threads ended).
    checkpoint take_checkpoint() const;
    /// Takes a checkpoint and writes it atomically to the state directory (when there is
    /// one); a failure is logged, not thrown: false. Same threading rule as take_checkpoint.
    bool write_checkpoint();

private:
    using clock = std::chrono::steady_clock;

    struct command
    {
        std::weak_ptr<websocket_session> from;
        protocol::client_message message;
        bool admin = false; ///< the sender is an admin
        bool answered = true; ///< false: a hello's interest, answered only when refused
    };
    struct member;

    void on_tick(beast::error_code ec);
    void apply_commands(std::vector<command> commands);
    void apply(protocol::spawn const& spawn, websocket_session& from, bool admin);
    void apply(protocol::impulse const& impulse, websocket_session& from, bool admin);
    void apply(protocol::remove const& remove, websocket_session& from, bool admin);
    void apply(protocol::set const& set, websocket_session& from, bool admin);
    void apply(protocol::pause const& pause, websocket_session& from, bool admin);
    void apply(protocol::resume const& resume, websocket_session& from, bool admin);
    void apply(protocol::reset const& reset, websocket_session& from, bool admin);
    void apply(protocol::load_scene const& load, websocket_session& from, bool admin);
    /// The connection's interest from this tick's snapshot on; `ref` nothing: a hello's,
    /// answered only when refused.
    void apply_interest(protocol::interest_filter filter, websocket_session& from,
                        std::optional<std::uint64_t> ref);
    /// Replaces the world by `s`'s, fresh: new wire ids for its bodies (the counter goes on),
    /// no spawned bodies, the clock going on from where it stood.
    void replace_world(scene::scene s);
    /// The resume the session asked for, on the strand.
    void take_up_player(websocket_session& session, std::string const& token);
    /// The room's rules for players (its scene's `players`, else the server's).
    void use_player_rules(scene::scene const& s);
    /// At a tick: the players whose grace ended leave, and the bodies of those that left go
    /// when the rules say so.
    void end_graces();
    void remove_bodies_of(std::uint64_t client_id);
    void count_players();
    /// Sends a player notice to every session but `except`'s (0: to all).
    void tell_players(protocol::player_notice const& notice, std::uint64_t except);
    /// The players in the room now, by id.
    protocol::roster current_roster() const;
    /// What `m` is told in its welcome: the room's, with its id, admin flag and caps.
    std::shared_ptr<std::string const> welcome_for(member const& m) const;
    /// Steps the world (unless paused): true when a step was taken.
    bool step_world();
    /// The last step's sensor events, to the members whose subscriptions they match.
    void send_events();
    /// Adds what the last step spent in each phase to counters_.phase_nanoseconds, and the
    /// bodies it swept (or did not) to counters_.
    void count_phase_times();
    bool snapshot_due();
    /// The world now, as a snapshot's columns.
    protocol::snapshot copy_snapshot() const;
    /// Copies a snapshot for the sessions in the room and has it encoded and sent off the
    /// room's strand (on `background`), once for each view of it its sessions are sent (every
    /// body, and each interest some session has); none when nobody listens.
    void send_snapshot();
    /// One view of a snapshot and the sessions sent it.
    struct snapshot_view
    {
        std::uint64_t id = 0; ///< 0: every body; else an interest's (view_of)
        std::optional<resolved_interest> interest; ///< where it stands at this snapshot
        bool any_full = false;            ///< a session of the full form is sent it
        std::vector<std::uint64_t> every; ///< of its compact sessions, each once
        std::vector<std::shared_ptr<websocket_session>> audience;
    };
    /// The view number of an interest: the same while some session has it, never reused.
    std::uint64_t view_of(protocol::interest_filter const& interest);
    /// The interest's region where it stands now: a followed body's place is noted, and a
    /// followed body that is gone keeps its last.
    resolved_interest resolve(protocol::interest_filter const& interest);
    /// Forgets the views and followed places no session has any more.
    void forget_unused_views(std::vector<snapshot_view> const& used);
    /// Encodes one view of a snapshot on the encoder (its chains' deltas, the full form when
    /// a full-form session is sent it); `bytes` grows by the full form's size.
    std::shared_ptr<encoded_snapshot const> encode_view(std::uint64_t index, snapshot_view const& view,
                                                        protocol::snapshot part,
                                                        std::vector<protocol::body_owner> owners,
                                                        protocol::quanta q, std::size_t& bytes);
    /// What one tick spent on each of its steps.
    struct tick_phases
    {
        clock::duration commands{}; ///< applying the commands
        clock::duration step{};     ///< world.step
        clock::duration snapshot{}; ///< copying a due snapshot for the encoder
        /// the room's thread's processor time over the three: far below their sum, the thread
        /// waited for a core (other threads had it) rather than worked
        clock::duration on_processor{};
        clock::duration total() const { return commands + step + snapshot; }
    };
    void record(tick_phases const& phases);
    void schedule_next_tick();
    void schedule_next_checkpoint();
    void on_checkpoint_timer(beast::error_code ec);
    /// Where this room's checkpoint lives: DIR/ROOM.json.
    std::filesystem::path checkpoint_file() const;
    /// Encodes and writes a taken checkpoint; any thread, one write at a time.
    bool write(checkpoint const& c, clock::duration take_cost);

    std::uint64_t add_body(physics::body_desc const& desc); ///< the new body's wire id
    std::uint64_t wire_id_of_slot(std::size_t slot) const;
    /// The sphere that a sphere at x of this radius would overlap, when spheres collide; the
    /// body in slot `self` (one being moved) is not looked at.
    std::optional<std::uint64_t> overlapped_sphere(physics::vec3 const& x, double radius,
                                                   std::optional<std::size_t> self = std::nullopt) const;
    /// Why a sphere of this radius cannot be at x (spawn's checks, for a spawn and a set):
    /// behind a wall (outside_world), across one or in an obstacle (overlaps_wall), in
    /// another sphere but the one in slot `self` (overlaps_body); `pointer` names the field
    /// in the message. Nothing when it can.
    std::optional<protocol::error> placement_refusal(protocol::vec3 const& position, double radius,
                                                     std::string_view pointer,
                                                     std::optional<std::size_t> self = std::nullopt) const;
    /// Why `client` may not push (impulse, set; push) or remove (push false) body `wire_id`
    /// under the scene's permissions: the message of a `forbidden`. Nothing when it may.
    std::optional<std::string> permission_refusal(std::uint64_t wire_id, std::uint64_t client,
                                                  bool admin, bool push) const;
    /// The tags of the scene's bodies, as build_world put them in the world's first slots.
    void tag_scene_bodies(scene::scene const& s);
    /// Gives a body its tag; the world reports its contacts when a rule of `s.contacts` names
    /// the tag.
    void tag_body(std::uint64_t wire_id, physics::body_id id, std::string const& tag, scene::scene const& s);
    /// Drops a body the world no longer holds from the ids, owners and counts.
    void forget_body(std::uint64_t wire_id);
    /// Removes the bodies a failed step names, and records the fault.
    void remove_after_fault(std::vector<physics::body_id> const& bodies, std::string const& why);
    /// The body a command names, or nothing after answering it with unknown_body.
    std::optional<physics::body_id> find_body(std::uint64_t wire_id, std::uint64_t ref,
                                              websocket_session& from);

    std::string name_;
    settings settings_;
    net::strand<net::io_context::executor_type> strand_;
    net::any_io_executor background_;
    net::steady_timer timer_;
    clock::duration period_;
    clock::time_point next_tick_at_;
    bool running_ = false;
    net::steady_timer checkpoint_timer_;
    std::string scene_name_;        ///< the room's own scene (its file)
    std::string scene_fingerprint_; ///< of the room's own scene's text and overrides
    std::vector<std::string> scene_overrides_; ///< PATH=VALUE, the room's own scene's
    /// The scene an admin loaded, in no file: every checkpoint carries it, so that a restart
    /// rebuilds it. None while the room runs its own scene.
    std::optional<embedded_scene> loaded_scene_;
    std::atomic<bool> checkpoint_failing_{false}; ///< the last write failed; logged once per streak
    std::atomic<bool> checkpoint_writing_{false}; ///< a periodic write is under way off the strand
    std::atomic<bool> snapshot_encoding_{false};  ///< a snapshot is being encoded off the strand

    scene::scene scene_;               ///< the scene it runs, as loaded: what reset goes back to
    /// Lent to world_ (and to each world that replaces it) when physics_threads > 1; declared
    /// first, so that it outlives the world it is lent to.
    std::unique_ptr<physics::thread_pool> physics_threads_;
    physics::world world_;
    physics::step_timings phase_seconds_seen_; ///< world_.timings() at the last count_phase_times()
    physics::collision_stats collisions_seen_; ///< world_.collisions() at the last count_phase_times()
    double dt_;                        ///< s per tick
    bool paused_ = false;              ///< an admin paused the room: ticks go on, no steps
    protocol::welcome welcome_;        ///< all but the client id
    bool send_charges_; ///< the scene has Coulomb forces: snapshots carry charges

    // Bodies on the wire have ids 1, 2, 3, ... never reused, so a stale id can never name a
    // new body and every id stays below 2^53 (JavaScript's exact integers).
    std::uint64_t next_wire_id_ = 1;
    std::vector<std::uint64_t> wire_id_of_index_; ///< by physics::body_id::index
    std::unordered_map<std::uint64_t, physics::body_id> body_of_wire_id_;
    // Who spawned what: a client may remove only its own bodies, and hold at most
    // client.max_bodies_per_client of them. Bodies of the scene (or a checkpoint) have no
    // owner. A body outlives its client; its count is dropped when the body goes.
    std::unordered_map<std::uint64_t, std::uint64_t> owner_of_wire_id_; ///< wire id -> client id
    std::unordered_map<std::uint64_t, std::size_t> bodies_of_client_;   ///< client id -> bodies
    /// The tagged bodies' tags (a spawn's or the scene's); sent with their constants.
    std::unordered_map<std::uint64_t, std::string> tag_of_wire_id_; ///< wire id -> tag

    std::vector<command> pending_commands_;
    struct member
    {
        std::uint64_t client_id;
        std::weak_ptr<websocket_session> session; ///< a session leaves when it ends
        std::optional<std::string> name;          ///< the player's, from its hello
        bool hears_players = true;                ///< it is sent player messages
        bool admin = false;
        bool compact = false;    ///< it asked for the compact form
        std::uint64_t every = 1; ///< it takes every n-th of the room's snapshots
        bool asked = false;      ///< its hello asked for snapshots: welcomes say what it gets
        std::uint64_t connection = 0; ///< the session's connection_id(), which never changes
        std::string resume_token;     ///< the player's secret for a resume; never logged
        bool resumed = false;         ///< a resume made it the player it is (once a connection)
        /// Its hello.events: nothing, no events (the start); else the events it matches.
        std::optional<protocol::event_filter> events;
        /// What of the world it is sent (normalized); nothing: every body (the start).
        std::optional<protocol::interest_filter> interest;
    };
    /// Whether an event matches a member's subscription.
    static bool wants(protocol::event_filter const& filter, protocol::event const& e);
    /// A player whose connection ended, kept for a resume until its grace ends.
    struct away_player
    {
        std::uint64_t client_id = 0;
        std::optional<std::string> name;
        std::string resume_token;
        std::uint64_t until_tick = 0; ///< it leaves at the start of this tick
    };
    /// The quanta of the compact form for a scene: the server's, else from the scene's size.
    protocol::quanta quanta_for(scene::scene const& s, protocol::welcome const& w) const;
    std::vector<member> sessions_;
    std::vector<away_player> away_;
    /// Players that left whose bodies go at the next tick (bodies_on_leave "remove").
    std::vector<std::uint64_t> leaving_bodies_;
    double resume_grace_ = 0.0;          ///< s; the scene's, else the server's
    std::uint64_t grace_ticks_ = 0;      ///< resume_grace_ in ticks, rounded up
    bool remove_bodies_on_leave_ = false; ///< the scene's, else the server's
    std::uint64_t resume_refusals_ = 0;  ///< for the log
    double snapshot_phase_ = 0.0; ///< snapshot_rate accumulated per tick, due at tick_rate
    std::uint64_t snapshot_index_ = 0; ///< snapshots handed to the encoder
    protocol::quanta quanta_;     ///< of the compact form, for the scene the room runs
    /// Each view's chains, by view number: used by the encoder only, one snapshot at a time.
    std::vector<std::pair<std::uint64_t, snapshot_chains>> chains_;
    /// The view number of each interest some session has, and the next one to give.
    std::vector<std::pair<protocol::interest_filter, std::uint64_t>> view_of_interest_;
    std::uint64_t next_view_ = 1;
    /// Where each body an interest follows was at the last snapshot (or when the interest was
    /// set): a body that is gone is followed there.
    std::unordered_map<std::uint64_t, protocol::vec3> followed_at_;

    room_counters counters_;
    traffic_counters traffic_;
    tick_histogram tick_durations_;
    tick_lateness lateness_;
    // For the periodic log line.
    clock::time_point report_started_;
    std::uint64_t report_ticks_ = 0;
    clock::duration report_cost_{};
    clock::duration last_tick_cost_{}; ///< the last tick's, for the pong's tick_ms
    tick_phases report_worst_{}; ///< the costliest tick since the last log line
    std::atomic<std::uint64_t> report_bytes_{0}; ///< snapshot bytes, added by the encoder
    clock::time_point last_late_warning_{};
    mutable std::mutex last_fault_mutex_;
    std::string last_fault_; ///< room::last_fault
};

} // namespace kugel::server
