#include "room.hpp"

#include "resume_token.hpp"
#include "websocket_session.hpp"

#include "physics/obb.hpp"
#include "physics/time_of_impact.hpp"
#include "protocol/codec.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <fmt/ranges.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <ctime>

namespace kugel::server {

namespace {

using protocol::error_code;

protocol::vec3 to_wire(physics::vec3 const& v) { return {v.x(), v.y(), v.z()}; }
physics::vec3 from_wire(protocol::vec3 const& v) { return {v[0], v[1], v[2]}; }

/// The static part of every welcome: what the room's scene looks like.
protocol::welcome make_welcome(std::string const& room_name, scene::scene const& s,
                               physics::world const& w, room::settings const& config)
{
    protocol::welcome welcome;
    welcome.room = room_name;
    welcome.tick_rate = config.tick_rate;
    welcome.dt = s.dt;
    welcome.snapshot_rate = config.snapshot_rate;
    welcome.scene.name = s.name;
    for (physics::wall const& wall : w.walls())
        welcome.scene.walls.push_back({to_wire(wall.surface.normal), wall.surface.offset,
                                       wall.damping, wall.friction});
    for (physics::obstacle const& o : w.obstacles()) {
        protocol::obstacle box;
        box.centre = to_wire(o.box.centre);
        box.half_extents = to_wire(o.box.half_extents);
        for (int k = 0; k < 3; ++k)
            box.axes[static_cast<std::size_t>(k)] = to_wire(o.box.axes.col(k));
        welcome.scene.obstacles.push_back(box);
    }
    physics::sphere const bounds = scene::scene_bounds(s, w);
    welcome.scene.bounds = {to_wire(bounds.centre), bounds.radius};
    welcome.limits = {config.client.max_message_bytes, config.max_bodies,
                      static_cast<std::uint64_t>(config.client.commands_per_second)};
    welcome.limits.max_queued_events = config.client.max_queued_events;
    welcome.permissions = {std::string(scene::name(s.permissions.push)),
                           std::string(scene::name(s.permissions.remove))};
    return welcome;
}

std::shared_ptr<std::string const> share(std::string text)
{
    return std::make_shared<std::string const>(std::move(text));
}

/// Answers a command that cannot apply with an error, and counts and logs the refusal.
void refuse(traffic_counters& traffic, websocket_session& to, std::uint64_t ref, error_code code,
            std::string message)
{
    traffic.count_rejected(code);
    spdlog::info("client {}: refused ref {}: {} ({})", to.client_id(), ref,
                 protocol::name(code), message);
    to.send_reply(share(protocol::encode(protocol::error{ref, code, std::move(message)})));
}

std::string describe(protocol::vec3 const& v) { return fmt::format("[{}, {}, {}]", v[0], v[1], v[2]); }

/// The processor time the calling thread has used.
std::chrono::nanoseconds thread_processor_time()
{
    timespec t{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return std::chrono::seconds(t.tv_sec) + std::chrono::nanoseconds(t.tv_nsec);
}

} // namespace

room::room(net::io_context& ticks, net::any_io_executor background, std::string name,
           scene::scene const& s, settings config, std::string scene_fingerprint,
           std::vector<std::string> scene_overrides, std::optional<checkpoint> restored)
    : name_(std::move(name)), settings_(std::move(config)), strand_(net::make_strand(ticks)),
      background_(std::move(background)),
      timer_(strand_),
      period_(std::chrono::duration_cast<clock::duration>(
          std::chrono::duration<double>(1.0 / settings_.tick_rate))),
      checkpoint_timer_(strand_), scene_name_(s.name),
      scene_fingerprint_(std::move(scene_fingerprint)),
      scene_overrides_(std::move(scene_overrides)),
      loaded_scene_(restored ? restored->loaded_scene : std::nullopt),
      scene_(restored ? restored_scene(s, *restored, checkpoint_file().string()) : s),
      physics_threads_(settings_.physics_threads > 1
                           ? std::make_unique<physics::thread_pool>(settings_.physics_threads)
                           : nullptr),
      world_(restored ? restored_world(scene_, *restored, checkpoint_file().string())
                      : scene::build_world(scene_)),
      dt_(scene_.dt), send_charges_(scene_.forces.coulomb.has_value())
{
    world_.set_parallel_for(physics_threads_.get(), settings_.physics_threads_from);
    world_.time_phases(true); // for /metrics
    // A restored room frames its scene as a fresh one does: the bounds are the scene's, not
    // those of wherever the bodies went before the checkpoint (one flung far away would
    // leave the camera looking at nothing).
    welcome_ = restored ? make_welcome(name_, scene_, scene::build_world(scene_), settings_)
                        : make_welcome(name_, scene_, world_, settings_);
    quanta_ = quanta_for(scene_, welcome_);
    use_player_rules(scene_);
    auto const ids = world_.bodies().ids();
    for (std::size_t slot = 0; slot < ids.size(); ++slot) {
        physics::body_id const id = ids[slot];
        // A restored body keeps its wire id; the scene's bodies get 1, 2, 3, ...
        std::uint64_t const wire_id = restored ? restored->bodies[slot].wire_id : next_wire_id_++;
        if (wire_id_of_index_.size() <= id.index)
            wire_id_of_index_.resize(id.index + 1, 0);
        wire_id_of_index_[id.index] = wire_id;
        body_of_wire_id_.emplace(wire_id, id);
    }
    if (restored) {
        next_wire_id_ = restored->next_wire_id;
        counters_.ticks = restored->tick;
        for (std::size_t slot = 0; slot < ids.size(); ++slot)
            if (!restored->bodies[slot].tag.empty())
                tag_body(restored->bodies[slot].wire_id, ids[slot], restored->bodies[slot].tag, scene_);
    } else {
        tag_scene_bodies(scene_);
    }
    counters_.bodies = world_.bodies().size();
}

void room::tag_scene_bodies(scene::scene const& s)
{
    // build_world adds the scene's bodies first, in order, to a world not yet stepped: the
    // world's first slots are the scene's bodies.
    auto const ids = world_.bodies().ids();
    for (std::size_t i = 0; i < s.body_tags.size() && i < ids.size(); ++i)
        if (!s.body_tags[i].empty())
            tag_body(wire_id_of_index_[ids[i].index], ids[i], s.body_tags[i], s);
}

void room::tag_body(std::uint64_t wire_id, physics::body_id id, std::string const& tag, scene::scene const& s)
{
    tag_of_wire_id_[wire_id] = tag;
    // A body whose tag a contacts rule names is reported by the world (and no other: a scene
    // without rules pays nothing).
    if (std::any_of(s.contacts.begin(), s.contacts.end(),
                    [&](scene::contact_rule const& r) { return r.tags[0] == tag || r.tags[1] == tag; }))
        world_.report_contacts(id, true);
}

checkpoint room::take_checkpoint() const
{
    physics::body_storage const& bodies = world_.bodies();
    checkpoint c;
    c.room = name_;
    c.scene_name = scene_name_;
    c.scene_fingerprint = scene_fingerprint_;
    c.scene_overrides = scene_overrides_;
    c.loaded_scene = loaded_scene_;
    c.tick = counters_.ticks;
    c.time = world_.time();
    c.time_compensation = world_.time_compensation();
    c.steps = world_.steps();
    c.next_wire_id = next_wire_id_;
    c.bodies.reserve(bodies.size());
    for (std::size_t slot = 0; slot < bodies.size(); ++slot) {
        std::uint64_t const wire_id = wire_id_of_index_[bodies.ids()[slot].index];
        auto const tag = tag_of_wire_id_.find(wire_id);
        c.bodies.push_back({wire_id, bodies.describe(slot), tag != tag_of_wire_id_.end() ? tag->second : std::string()});
    }
    return c;
}

bool room::write_checkpoint()
{
    if (settings_.state_dir.empty())
        return false;
    auto const started = clock::now();
    checkpoint const c = take_checkpoint();
    return write(c, clock::now() - started);
}

std::filesystem::path room::checkpoint_file() const
{
    return checkpoint_path(settings_.state_dir, name_);
}

bool room::write(checkpoint const& c, clock::duration take_cost)
{
    std::filesystem::path const file = checkpoint_file();
    try {
        // A world the room could not step again is never written over the last good one.
        // (step_world keeps the world finite; this is the guard should anything slip by.)
        for (checkpoint::body const& b : c.bodies)
            if (!(b.desc.position.allFinite() && b.desc.velocity.allFinite()))
                throw std::runtime_error(fmt::format("body {} is not finite; the last good "
                                                     "checkpoint stays", b.wire_id));
        auto const started = clock::now();
        std::string const text = encode_checkpoint(c);
        auto const encoded = clock::now();
        write_file_atomically(file, text);
        using ms = std::chrono::duration<double, std::milli>;
        spdlog::debug("room '{}': checkpoint of tick {} ({} bodies, {} bytes): take {:.2f} ms on "
                      "the strand, then encode {:.2f} ms, write and fsync {:.2f} ms",
                      name_, c.tick, c.bodies.size(), text.size(), ms(take_cost).count(),
                      ms(encoded - started).count(), ms(clock::now() - encoded).count());
        if (checkpoint_failing_.exchange(false))
            spdlog::info("room '{}': checkpoints to {} work again", name_, file.string());
        return true;
    } catch (std::exception const& e) {
        // The room goes on; the last good checkpoint stays in place.
        if (!checkpoint_failing_.exchange(true))
            spdlog::error("room '{}': cannot write checkpoint {}: {}", name_, file.string(), e.what());
        return false;
    }
}

void room::schedule_next_checkpoint()
{
    if (!running_ || settings_.state_dir.empty())
        return;
    checkpoint_timer_.expires_after(settings_.checkpoint_interval);
    checkpoint_timer_.async_wait(beast::bind_front_handler(&room::on_checkpoint_timer, shared_from_this()));
}

void room::on_checkpoint_timer(beast::error_code ec)
{
    if (ec || !running_)
        return;
    // Only the copy is taken here, between two ticks (0.2 ms for 10,000 bodies); encoding
    // and fsync (the most of the cost) run in the background, so the tick does not wait. One
    // write at a time: when the last is still under way, this interval's is skipped.
    if (!checkpoint_writing_.exchange(true)) {
        auto const started = clock::now();
        checkpoint c = take_checkpoint();
        auto const take_cost = clock::now() - started;
        net::post(background_,
                  [self = shared_from_this(), c = std::move(c), take_cost] {
                      self->write(c, take_cost);
                      self->checkpoint_writing_ = false;
                  });
    }
    schedule_next_checkpoint();
}

void room::start()
{
    net::dispatch(strand_, [self = shared_from_this()] {
        self->running_ = true;
        self->next_tick_at_ = clock::now();
        self->report_started_ = self->next_tick_at_;
        self->schedule_next_tick();
        self->schedule_next_checkpoint();
    });
}

void room::stop()
{
    net::dispatch(strand_, [self = shared_from_this()] {
        self->running_ = false;
        self->timer_.cancel();
        self->checkpoint_timer_.cancel();
        for (member const& m : self->sessions_)
            if (auto session = m.session.lock())
                session->shut_down();
    });
}

void room::join(std::shared_ptr<websocket_session> session)
{
    net::post(strand_, [self = shared_from_this(), session = std::move(session)] {
        // Counted before the welcome goes out, so a client that has its welcome is counted.
        member joined{session->client_id(), session};
        joined.connection = session->connection_id();
        try {
            joined.resume_token = new_resume_token();
        } catch (std::exception const& e) { // the kernel gave no random bytes: no resume for it
            spdlog::error("room '{}': no resume token for client {}: {}", self->name_,
                          joined.connection, e.what());
        }
        self->sessions_.push_back(std::move(joined));
        self->count_players();
        session->send_reply(self->welcome_for(self->sessions_.back()));
        session->send_players(share(protocol::encode(self->current_roster())));
        self->tell_players({.change = "joined", .id = session->client_id(), .name = std::nullopt},
                           session->client_id());
    });
}

void room::rename(std::shared_ptr<websocket_session> session, std::string name)
{
    net::post(strand_, [self = shared_from_this(), session = std::move(session), name = std::move(name)] {
        for (member& m : self->sessions_)
            if (m.connection == session->connection_id() && m.name != name) {
                m.name = name;
                self->tell_players({.change = "renamed", .id = m.client_id, .name = name}, 0);
            }
    });
}

void room::send_roster(std::shared_ptr<websocket_session> session)
{
    net::post(strand_, [self = shared_from_this(), session = std::move(session)] {
        for (member const& m : self->sessions_)
            if (m.connection == session->connection_id() && m.hears_players)
                session->send_players(share(protocol::encode(self->current_roster())));
    });
}

void room::hear_players(std::shared_ptr<websocket_session> session, bool hears)
{
    net::post(strand_, [self = shared_from_this(), session = std::move(session), hears] {
        for (member& m : self->sessions_)
            if (m.connection == session->connection_id() && m.hears_players != hears) {
                m.hears_players = hears;
                if (hears)
                    session->send_players(share(protocol::encode(self->current_roster())));
            }
    });
}

void room::leave(std::uint64_t connection_id)
{
    net::post(strand_, [self = shared_from_this(), connection_id] {
        auto const gone =
            std::find_if(self->sessions_.begin(), self->sessions_.end(),
                         [&](member const& m) { return m.connection == connection_id; });
        if (gone == self->sessions_.end())
            return; // its player was resumed on another connection
        member const m = std::move(*gone);
        self->sessions_.erase(gone);
        if (self->resume_grace_ > 0.0 && !m.resume_token.empty()) {
            // Kept for a resume until its grace ends (end_graces): away, not yet left.
            self->away_.push_back({m.client_id, m.name, m.resume_token,
                                   self->counters_.ticks + self->grace_ticks_});
            self->tell_players({.change = "away", .id = m.client_id, .name = m.name}, m.client_id);
        } else {
            self->tell_players({.change = "left", .id = m.client_id, .name = m.name}, m.client_id);
            if (self->remove_bodies_on_leave_)
                self->leaving_bodies_.push_back(m.client_id);
        }
        self->count_players();
    });
}

void room::resume(std::shared_ptr<websocket_session> session, std::string token)
{
    net::post(strand_, [self = shared_from_this(), session = std::move(session),
                        token = std::move(token)] { self->take_up_player(*session, token); });
}

void room::take_up_player(websocket_session& session, std::string const& token)
{
    auto const find_member = [&] {
        return std::find_if(sessions_.begin(), sessions_.end(), [&](member const& m) {
            return m.connection == session.connection_id();
        });
    };
    auto const here = find_member();
    if (here == sessions_.end())
        return; // the session ended meanwhile
    std::uint64_t const fresh = here->client_id;
    // The token is never written anywhere: not in the answer, not in the log.
    auto const refuse_resume = [&](std::string const& why) {
        traffic_.count_rejected(error_code::bad_resume);
        // The first ten, then one in a hundred: guessing must not flood the log.
        if (++resume_refusals_ <= 10 || resume_refusals_ % 100 == 0)
            spdlog::info("room '{}': client {} refused a resume ({} refusals so far): {}", name_,
                         session.connection_id(), resume_refusals_, why);
        session.send_notice(share(protocol::encode(
            protocol::error{std::nullopt, error_code::bad_resume, "/resume: " + why})));
    };
    if (!(resume_grace_ > 0.0))
        return refuse_resume(fmt::format("this room keeps no player for a resume (its resume_grace "
                                         "is 0); this connection stays player {}", fresh));
    if (here->resumed)
        return refuse_resume(fmt::format("this connection resumed player {} already, and a "
                                         "connection resumes once; open a new one to resume again",
                                         fresh));
    if (is_resume_token(token, here->resume_token))
        return refuse_resume(fmt::format("that is this connection's own token: it is player {} "
                                         "already", fresh));
    // Every token the room holds is compared in full, each in constant time.
    std::optional<std::size_t> away_at;
    for (std::size_t i = 0; i < away_.size(); ++i)
        if (is_resume_token(token, away_[i].resume_token))
            away_at = i;
    std::optional<std::size_t> open_at;
    for (std::size_t i = 0; i < sessions_.size(); ++i)
        if (sessions_[i].connection != session.connection_id() &&
            is_resume_token(token, sessions_[i].resume_token))
            open_at = i;
    if (!away_at && !open_at)
        return refuse_resume(fmt::format("no player of this room holds this token (it is wrong, of "
                                         "another room, used already, or its player's grace "
                                         "ended); this connection stays player {}", fresh));

    std::uint64_t player = 0;
    std::optional<std::string> name;
    if (away_at) {
        player = away_[*away_at].client_id;
        name = away_[*away_at].name;
        away_.erase(away_.begin() + static_cast<std::ptrdiff_t>(*away_at));
    } else {
        // Still connected (a connection the client has given up on, which the server has not
        // noticed yet): that connection is closed, and this one takes its place.
        member const old = std::move(sessions_[*open_at]);
        sessions_.erase(sessions_.begin() + static_cast<std::ptrdiff_t>(*open_at));
        player = old.client_id;
        name = old.name;
        if (auto const old_session = old.session.lock())
            old_session->replace();
    }
    member& m = *find_member(); // the erase above may have moved it
    // The player this connection was until now is gone for the others; its bodies, if any,
    // follow the room's rule as any player's that leaves.
    tell_players({.change = "left", .id = fresh, .name = m.name}, fresh);
    if (remove_bodies_on_leave_)
        leaving_bodies_.push_back(fresh);
    m.client_id = player;
    m.name = std::move(name);
    m.resumed = true;
    try {
        m.resume_token = new_resume_token(); // the used one is spent
    } catch (std::exception const& e) {
        m.resume_token.clear();
        spdlog::error("room '{}': no new resume token for client {}: {}", name_, m.connection,
                      e.what());
    }
    session.become(player);
    tell_players({.change = "back", .id = player, .name = m.name}, player);
    session.send_notice(welcome_for(m));
    if (m.hears_players)
        session.send_players(share(protocol::encode(current_roster())));
    count_players();
    spdlog::info("room '{}': client {} resumed player {}{}", name_, m.connection, player,
                 open_at ? " (closing its other connection)" : "");
}

void room::end_graces()
{
    std::uint64_t const tick = counters_.ticks + 1; // the tick being applied
    std::size_t const before = away_.size();
    for (auto it = away_.begin(); it != away_.end();) {
        if (it->until_tick > tick) {
            ++it;
            continue;
        }
        tell_players({.change = "left", .id = it->client_id, .name = it->name}, it->client_id);
        if (remove_bodies_on_leave_)
            leaving_bodies_.push_back(it->client_id);
        it = away_.erase(it);
    }
    for (std::uint64_t const client : std::exchange(leaving_bodies_, {}))
        remove_bodies_of(client);
    if (away_.size() != before)
        count_players();
}

void room::remove_bodies_of(std::uint64_t client_id)
{
    std::vector<std::uint64_t> owned;
    for (auto const& [wire_id, owner] : owner_of_wire_id_)
        if (owner == client_id)
            owned.push_back(wire_id);
    for (std::uint64_t const wire_id : owned) {
        if (auto const body = body_of_wire_id_.find(wire_id); body != body_of_wire_id_.end())
            world_.remove_body(body->second);
        forget_body(wire_id);
    }
    if (!owned.empty())
        spdlog::info("room '{}': player {} left; its {} bodies were removed", name_, client_id,
                     owned.size());
}

void room::count_players()
{
    counters_.sessions = sessions_.size();
    counters_.players = sessions_.size() + away_.size();
}

void room::use_player_rules(scene::scene const& s)
{
    resume_grace_ = s.players.resume_grace.value_or(settings_.resume_grace);
    remove_bodies_on_leave_ =
        s.players.remove_bodies_on_leave.value_or(settings_.remove_bodies_on_leave);
    double const ticks = std::ceil(resume_grace_ * settings_.tick_rate);
    grace_ticks_ =
        resume_grace_ > 0.0 ? std::max<std::uint64_t>(1, static_cast<std::uint64_t>(ticks)) : 0;
}

void room::tell_players(protocol::player_notice const& notice, std::uint64_t except)
{
    auto const bytes = std::make_shared<std::string const>(protocol::encode(notice));
    for (member const& m : sessions_)
        if (m.client_id != except && m.hears_players)
            if (auto session = m.session.lock())
                session->send_player_notice(bytes);
}

protocol::roster room::current_roster() const
{
    protocol::roster roster;
    roster.players.reserve(sessions_.size());
    for (member const& m : sessions_)
        roster.players.push_back({m.client_id, m.name});
    for (away_player const& a : away_)
        roster.players.push_back({a.client_id, a.name, true});
    std::sort(roster.players.begin(), roster.players.end(),
              [](protocol::player const& a, protocol::player const& b) { return a.id < b.id; });
    return roster;
}

void room::grant_admin(std::shared_ptr<websocket_session> session)
{
    net::post(strand_, [self = shared_from_this(), session = std::move(session)] {
        for (member& m : self->sessions_)
            if (m.connection == session->connection_id()) {
                m.admin = true;
                session->send_notice(self->welcome_for(m));
            }
    });
}

protocol::quanta room::quanta_for(scene::scene const& s, protocol::welcome const& w) const
{
    // The server's option wins, then the scene's. Otherwise a position quantum of 1/10,000
    // of the scene's size, to the decade above (1 mm for a scene of a few metres): far below
    // what a screen shows; and a velocity quantum that moves a body about one position
    // quantum between two snapshots, to the nearest decade: what a client's interpolation
    // needs.
    auto const first_set = [](double option, double scene_value, auto chosen) {
        return option > 0.0 ? option : scene_value > 0.0 ? scene_value : chosen();
    };
    double const position = first_set(settings_.position_quantum, s.snapshots.position_quantum, [&] {
        double const size = std::max(w.scene.bounds.radius, 1e-3);
        return std::pow(10.0, std::ceil(std::log10(size))) * 1e-4;
    });
    double const velocity = first_set(settings_.velocity_quantum, s.snapshots.velocity_quantum, [&] {
        return std::pow(10.0, std::round(std::log10(position * settings_.snapshot_rate)));
    });
    return {position, velocity};
}

void room::request_snapshots(std::shared_ptr<websocket_session> session,
                             protocol::snapshot_request request)
{
    net::post(strand_, [self = shared_from_this(), session = std::move(session), request] {
        for (member& m : self->sessions_) {
            if (m.connection != session->connection_id())
                continue;
            if (request.form)
                m.compact = *request.form == "compact";
            m.every = 1;
            if (request.rate) {
                // The whole share of the room's snapshots nearest below the rate asked for;
                // at most one a minute's worth of skipping.
                double const ratio = self->settings_.snapshot_rate / *request.rate;
                double const cap = std::max(1.0, 60.0 * self->settings_.snapshot_rate);
                m.every = static_cast<std::uint64_t>(std::clamp(std::ceil(ratio - 1e-9), 1.0, cap));
            }
            m.asked = true;
            // One turn of the session's strand: a snapshot posted meanwhile cannot come
            // between the new form and the welcome that announces it.
            session->use_snapshots(m.compact, m.every, self->welcome_for(m));
        }
    });
}

void room::subscribe_events(std::shared_ptr<websocket_session> session, protocol::event_request request)
{
    net::post(strand_, [self = shared_from_this(), session = std::move(session), request = std::move(request)] {
        if (request.on && request.filter.sensors) {
            auto const& known = self->scene_.sensors;
            auto const& asked = *request.filter.sensors;
            for (std::size_t i = 0; i < asked.size(); ++i) {
                bool const found = std::any_of(known.begin(), known.end(), [&](scene::sensor_settings const& s) {
                    return s.name == asked[i];
                });
                if (found)
                    continue;
                std::vector<std::string> names;
                for (auto const& s : known)
                    names.push_back("\"" + s.name + "\"");
                std::string const message = fmt::format(
                    "/events/sensors/{}: the room's scene has no sensor \"{}\" ({})", i, asked[i],
                    names.empty() ? std::string("it has no sensors")
                                  : fmt::format("its sensors: {}", fmt::join(names, ", ")));
                self->traffic_.count_rejected(error_code::bad_value);
                spdlog::info("client {}: refused an event subscription: {}", session->client_id(), message);
                session->send_notice(share(protocol::encode(protocol::error{std::nullopt, error_code::bad_value, message})));
                return;
            }
        }
        for (member& m : self->sessions_)
            if (m.connection == session->connection_id())
                m.events = request.on ? std::optional(request.filter) : std::nullopt;
    });
}

bool room::wants(protocol::event_filter const& filter, protocol::event const& e)
{
    auto const in = [](std::optional<std::vector<std::string>> const& list, std::string const& value) {
        return !list || std::find(list->begin(), list->end(), value) != list->end();
    };
    if (!in(filter.kinds, e.kind))
        return false;
    if (filter.sensors && !(e.sensor && in(filter.sensors, *e.sensor)))
        return false; // a contact names no sensor
    if (!filter.tags)
        return true;
    if (e.tags) // a contact: either body's tag
        return std::any_of(e.tags->begin(), e.tags->end(), [&](std::string const& t) { return in(filter.tags, t); });
    return e.tag && in(filter.tags, *e.tag);
}

void room::send_events()
{
    auto const crossings = world_.sensor_events();
    auto const contacts = world_.contact_events();
    if (crossings.empty() && contacts.empty())
        return; // a scene without sensors or contacts, or a quiet step: nothing more
    bool const heard = std::any_of(sessions_.begin(), sessions_.end(),
                                   [](member const& m) { return m.events.has_value(); });
    if (!heard)
        return; // nobody subscribes: no event is built
    // Each event is built and encoded once, then handed to every member it matches. The
    // world lists each kind by time; so does the room, crossings first at equal times.
    std::vector<protocol::event> built;
    built.reserve(crossings.size() + contacts.size());
    for (physics::sensor_event const& c : crossings) {
        if (c.sensor >= scene_.sensors.size() || c.body.index >= wire_id_of_index_.size())
            continue; // cannot happen: the world's sensors are the scene's, its bodies the room's
        protocol::event e;
        e.tick = counters_.ticks;
        e.time = c.time;
        e.kind = c.entered ? "entered" : "left";
        e.sensor = scene_.sensors[c.sensor].name;
        std::uint64_t const body = wire_id_of_index_[c.body.index];
        e.body = body;
        if (auto const tag = tag_of_wire_id_.find(body); tag != tag_of_wire_id_.end())
            e.tag = tag->second;
        if (auto const owner = owner_of_wire_id_.find(body); owner != owner_of_wire_id_.end())
            e.owner = owner->second;
        built.push_back(std::move(e));
    }
    for (physics::contact_event const& c : contacts) {
        if (c.a.index >= wire_id_of_index_.size() || c.b.index >= wire_id_of_index_.size())
            continue; // cannot happen: the world's bodies are the room's
        std::array ids{wire_id_of_index_[c.a.index], wire_id_of_index_[c.b.index]};
        if (ids[1] < ids[0])
            std::swap(ids[0], ids[1]);
        auto const tag_a = tag_of_wire_id_.find(ids[0]), tag_b = tag_of_wire_id_.find(ids[1]);
        if (tag_a == tag_of_wire_id_.end() || tag_b == tag_of_wire_id_.end())
            continue; // cannot happen: only tagged bodies are reported
        if (std::none_of(scene_.contacts.begin(), scene_.contacts.end(), [&](scene::contact_rule const& r) {
                return r.matches(tag_a->second, tag_b->second);
            }))
            continue; // two reported bodies whose tags no rule pairs ("ball" and "ball" under a ball–post rule)
        protocol::event e;
        e.tick = counters_.ticks;
        e.time = c.time;
        e.kind = "contact";
        e.bodies = std::vector<std::uint64_t>{ids[0], ids[1]};
        e.tags = std::vector<std::string>{tag_a->second, tag_b->second};
        built.push_back(std::move(e));
    }
    std::stable_sort(built.begin(), built.end(),
                     [](protocol::event const& a, protocol::event const& b) { return a.time < b.time; });
    std::vector<queued_event> events;
    events.reserve(built.size());
    for (protocol::event& e : built) {
        auto bytes = share(protocol::encode(e));
        events.push_back({std::make_shared<protocol::event const>(std::move(e)), std::move(bytes)});
    }
    for (member const& m : sessions_) {
        if (!m.events)
            continue;
        auto session = m.session.lock();
        if (!session)
            continue; // it ended: its leave() is on its way
        std::vector<queued_event> matching;
        for (queued_event const& e : events)
            if (wants(*m.events, *e.message))
                matching.push_back(e);
        if (!matching.empty())
            session->send_events(std::move(matching));
    }
}

std::shared_ptr<std::string const> room::welcome_for(member const& m) const
{
    protocol::welcome welcome = welcome_;
    welcome.client = m.client_id;
    welcome.admin = m.admin;
    if (m.asked)
        welcome.snapshots = protocol::snapshot_stream{
            .form = m.compact ? "compact" : "full",
            .rate = settings_.snapshot_rate / static_cast<double>(m.every),
            .position_quantum = quanta_.position,
            .velocity_quantum = quanta_.velocity,
            .keyframe_interval = settings_.keyframe_interval};
    if (!m.admin && settings_.client.max_bodies_per_client > 0)
        welcome.limits.max_bodies_per_client = settings_.client.max_bodies_per_client;
    welcome.resume_grace = resume_grace_;
    welcome.bodies_on_leave = remove_bodies_on_leave_ ? "remove" : "stay";
    if (resume_grace_ > 0.0 && !m.resume_token.empty())
        welcome.resume_token = m.resume_token;
    return share(protocol::encode(welcome));
}

void room::submit(std::shared_ptr<websocket_session> from, protocol::client_message message,
                  bool admin)
{
    net::post(strand_, [self = shared_from_this(), from = std::move(from),
                        message = std::move(message), admin]() mutable {
        if (auto const* ping = std::get_if<protocol::ping>(&message)) {
            protocol::pong pong{ping->ref, self->counters_.ticks, std::nullopt};
            if (self->counters_.ticks > 0)
                pong.tick_ms = std::chrono::duration<double, std::milli>(self->last_tick_cost_).count();
            from->send_reply(share(protocol::encode(pong)));
            return;
        }
        self->pending_commands_.push_back({from, std::move(message), admin});
    });
}

void room::on_tick(beast::error_code ec)
{
    if (ec || !running_)
        return;
    auto const started = clock::now();
    auto const started_on_processor = thread_processor_time();
    lateness_.record(started - next_tick_at_, period_);    // against its due time
    apply_commands(std::exchange(pending_commands_, {})); // 1. in arrival order
    end_graces();                                          //    then players that left
    auto const applied = clock::now();
    if (step_world())                                      // 2. physics
        send_events();                                     //    its sensor events, ahead of
    auto const stepped = clock::now();                     //    the snapshot
    if (snapshot_due())
        send_snapshot();                   // 3. copied here, encoded once off the tick
    record({applied - started, stepped - applied, clock::now() - stepped, // 4. cost
            thread_processor_time() - started_on_processor});
    schedule_next_tick();
}

void room::apply_commands(std::vector<command> commands)
{
    for (command& c : commands) {
        auto from = c.from.lock();
        if (!from || from->replaced())
            continue; // the client left (or its player moved to another connection); nobody hears
        std::visit(
            [&]<class M>(M const& m) {
                if constexpr (std::is_same_v<M, protocol::interest>)
                    apply_interest(m.filter(), *from, c.answered ? std::optional(m.ref) : std::nullopt);
                else if constexpr (requires { apply(m, *from, c.admin); })
                    apply(m, *from, c.admin);
            },
            c.message);
    }
}

void room::apply(protocol::spawn const& spawn, websocket_session& from, bool admin)
{
    protocol::body_spec const& body = spawn.body;
    auto const refuse_spawn = [&](error_code code, std::string message) {
        refuse(traffic_, from, spawn.ref, code, std::move(message));
    };
    if (body.is_static && !admin)
        return refuse_spawn(error_code::forbidden, "/body/static: only an admin may spawn a static body "
                                                   "(an obstacle nothing moves)");
    if (world_.bodies().size() >= settings_.max_bodies)
        return refuse_spawn(error_code::room_full, "the room holds its limit of " +
                                                 std::to_string(settings_.max_bodies) + " bodies");
    std::size_t const cap = settings_.client.max_bodies_per_client;
    if (!admin && cap > 0) {
        auto const own = bodies_of_client_.find(from.client_id());
        if (own != bodies_of_client_.end() && own->second >= cap)
            return refuse_spawn(error_code::too_many_bodies,
                                fmt::format("/: this client has {} bodies in the room, the most "
                                            "one client may have; remove one to spawn another",
                                            own->second));
    }
    if (auto refusal = placement_refusal(body.position, body.radius, "/body/position"))
        return refuse_spawn(refusal->code, std::move(refusal->message));
    physics::body_desc desc;
    desc.position = from_wire(body.position);
    desc.velocity = from_wire(body.velocity);
    desc.radius = body.radius;
    desc.charge = body.charge;
    desc.mass = protocol::mass_of(body); // usable: the decoder checked it
    desc.is_static = body.is_static;     // an admin's: the decoder checked it does not move
    // No force may be one no step can hold: beyond a double, or a change of speed by c in
    // one step. A step that still fails is recovered from (step_world), but it costs the
    // bodies that made it fail.
    if (auto const refusal = world_.check_addition(desc, {protocol::speed_of_light / dt_}))
        return refuse_spawn(error_code::singular_force,
                            fmt::format("/body: its {} with body {} ({} m away, softening {} m) "
                                        "would be a force of {} N, accelerating at {} m/s², "
                                        "which no step of {} s can hold (the speed would change "
                                        "by c or more, or the force is beyond a double)",
                                        refusal->model, wire_id_of_slot(refusal->other),
                                        refusal->distance, refusal->softening, refusal->force,
                                        refusal->acceleration, dt_));
    std::uint64_t id = 0;
    try {
        id = add_body(desc);
    } catch (std::invalid_argument const& e) {
        return refuse_spawn(error_code::bad_value, std::string("/body: ") + e.what());
    }
    owner_of_wire_id_.emplace(id, from.client_id());
    ++bodies_of_client_[from.client_id()];
    if (body.tag)
        tag_body(id, body_of_wire_id_.find(id)->second, *body.tag, scene_);
    from.send_reply(share(protocol::encode(protocol::ack{spawn.ref, counters_.ticks + 1, id})));
}

void room::apply(protocol::impulse const& impulse, websocket_session& from, bool admin)
{
    auto const body = find_body(impulse.id, impulse.ref, from);
    if (!body)
        return;
    if (auto why = permission_refusal(impulse.id, from.client_id(), admin, true))
        return refuse(traffic_, from, impulse.ref, error_code::forbidden, std::move(*why));
    physics::vec3 const j = from_wire(impulse.impulse);
    std::size_t const slot = *world_.bodies().slot_of(*body);
    physics::vec3 const v =
        world_.bodies().velocities()[slot] + world_.bodies().inverse_masses()[slot] * j;
    // A finite impulse on a light body can give an infinite speed, and a merely huge one
    // an infinite position some ticks later: both would reach every client as non-numbers.
    if (!(v.norm() < protocol::speed_of_light))
        return refuse(traffic_, from, impulse.ref, error_code::bad_value,
                      fmt::format("/impulse: {} N·s would give body {} a speed of {} m/s, not "
                                  "below the speed of light",
                                  describe(impulse.impulse), impulse.id, v.norm()));
    world_.apply_impulse(*body, j);
    from.send_reply(share(protocol::encode(protocol::ack{impulse.ref, counters_.ticks + 1, {}})));
}

void room::apply(protocol::remove const& remove, websocket_session& from, bool admin)
{
    auto const body = find_body(remove.id, remove.ref, from);
    if (!body)
        return;
    if (auto why = permission_refusal(remove.id, from.client_id(), admin, false))
        return refuse(traffic_, from, remove.ref, error_code::forbidden, std::move(*why));
    world_.remove_body(*body);
    forget_body(remove.id);
    from.send_reply(share(protocol::encode(protocol::ack{remove.ref, counters_.ticks + 1, {}})));
}

void room::apply(protocol::set const& set, websocket_session& from, bool admin)
{
    auto const body = find_body(set.id, set.ref, from);
    if (!body)
        return;
    if (auto why = permission_refusal(set.id, from.client_id(), admin, true))
        return refuse(traffic_, from, set.ref, error_code::forbidden, std::move(*why));
    std::size_t const slot = *world_.bodies().slot_of(*body);
    bool const is_static = world_.bodies().inverse_masses()[slot] == 0.0;
    if (set.velocity && is_static && *set.velocity != protocol::vec3{})
        return refuse(traffic_, from, set.ref, error_code::bad_value,
                      fmt::format("/velocity: body {} is static: it never moves, so its velocity "
                                  "stays [0, 0, 0]", set.id));
    // Where spawn may put a sphere of this radius, this body may go; only itself is not in
    // its way.
    if (set.position)
        if (auto refusal = placement_refusal(*set.position, world_.bodies().radii()[slot], "/position", slot))
            return refuse(traffic_, from, set.ref, refusal->code, std::move(refusal->message));
    std::optional<physics::vec3> position, velocity;
    if (set.position)
        position = from_wire(*set.position);
    if (set.velocity)
        velocity = from_wire(*set.velocity);
    try {
        world_.set_state(*body, position, velocity);
    } catch (std::invalid_argument const& e) { // the decoder and the checks above leave none
        return refuse(traffic_, from, set.ref, error_code::bad_value, std::string("/: ") + e.what());
    }
    from.send_reply(share(protocol::encode(protocol::ack{set.ref, counters_.ticks + 1, {}})));
}

void room::set_interest(std::shared_ptr<websocket_session> session, protocol::interest_filter filter)
{
    net::post(strand_, [self = shared_from_this(), session = std::move(session), filter = std::move(filter)] {
        protocol::interest stated{.ref = 0, .box = filter.box, .around = filter.around, .tags = filter.tags};
        self->pending_commands_.push_back({session, std::move(stated), false, false});
    });
}

void room::apply_interest(protocol::interest_filter filter, websocket_session& from,
                          std::optional<std::uint64_t> ref)
{
    auto const here = std::find_if(sessions_.begin(), sessions_.end(), [&](member const& m) {
        return m.connection == from.connection_id();
    });
    if (here == sessions_.end())
        return; // it left
    if (filter.around) {
        std::uint64_t const id = filter.around->body;
        auto const body = body_of_wire_id_.find(id);
        if (body == body_of_wire_id_.end()) {
            // A hello's interest is no command: its refusal answers nothing and has no ref.
            std::string message = fmt::format("{}/around/body: no body {} in this room to follow",
                                              ref ? "" : "/interest", id);
            if (ref)
                return refuse(traffic_, from, *ref, error_code::unknown_body, std::move(message));
            traffic_.count_rejected(error_code::unknown_body);
            from.send_notice(share(protocol::encode(protocol::error{std::nullopt, error_code::unknown_body,
                                                                    std::move(message)})));
            return;
        }
        followed_at_[id] = to_wire(world_.bodies().positions()[*world_.bodies().slot_of(body->second)]);
    }
    if (filter.everything())
        here->interest.reset();
    else
        here->interest = normalized(std::move(filter));
    if (ref)
        from.send_reply(share(protocol::encode(protocol::ack{*ref, counters_.ticks + 1, {}})));
}

// The admin commands. The session refuses them from anyone else before they are queued; the
// check here keeps the room right should another caller ever submit one.

void room::apply(protocol::pause const& pause, websocket_session& from, bool admin)
{
    if (!admin)
        return refuse(traffic_, from, pause.ref, error_code::forbidden, "/type: pause is an admin command");
    if (!paused_)
        spdlog::info("room '{}': paused by client {} at tick {}", name_, from.client_id(), counters_.ticks.load());
    paused_ = true;
    from.send_reply(share(protocol::encode(protocol::ack{pause.ref, counters_.ticks + 1, {}})));
}

void room::apply(protocol::resume const& resume, websocket_session& from, bool admin)
{
    if (!admin)
        return refuse(traffic_, from, resume.ref, error_code::forbidden, "/type: resume is an admin command");
    if (paused_)
        spdlog::info("room '{}': resumed by client {} at tick {}", name_, from.client_id(), counters_.ticks.load());
    paused_ = false;
    from.send_reply(share(protocol::encode(protocol::ack{resume.ref, counters_.ticks + 1, {}})));
}

void room::apply(protocol::reset const& reset, websocket_session& from, bool admin)
{
    if (!admin)
        return refuse(traffic_, from, reset.ref, error_code::forbidden, "/type: reset is an admin command");
    try {
        replace_world(scene_);
    } catch (std::exception const& e) {
        // The scene built this room once, so it builds again; should it not, nothing changed.
        return refuse(traffic_, from, reset.ref, error_code::bad_value,
                      std::string("/: the scene cannot be rebuilt: ") + e.what());
    }
    spdlog::info("room '{}': reset to scene '{}' by client {}", name_, scene_.name, from.client_id());
    from.send_reply(share(protocol::encode(protocol::ack{reset.ref, counters_.ticks + 1, {}})));
}

void room::apply(protocol::load_scene const& load, websocket_session& from, bool admin)
{
    if (!admin)
        return refuse(traffic_, from, load.ref, error_code::forbidden, "/type: load_scene is an admin command");
    scene::scene s;
    try {
        // The loader's messages start with the source; "/scene" makes them point into the
        // command: "/scene: /bodies/0/radius: must be >= 0, got -1".
        s = scene::parse_scene(load.scene.text, "/scene");
    } catch (scene::scene_error const& e) {
        return refuse(traffic_, from, load.ref, error_code::bad_value, e.what());
    }
    if (s.body_count() > settings_.max_bodies)
        return refuse(traffic_, from, load.ref, error_code::room_full,
                      fmt::format("/scene: it has {} bodies, and the room holds at most {}",
                                  s.body_count(), settings_.max_bodies));
    std::string const old_name = scene_.name;
    try {
        replace_world(std::move(s));
    } catch (std::exception const& e) {
        return refuse(traffic_, from, load.ref, error_code::bad_value,
                      std::string("/scene: cannot be built: ") + e.what());
    }
    // Kept as the loader read it, so that a checkpoint rebuilds exactly this scene.
    loaded_scene_ = embedded_scene{scene_.name, scene_fingerprint(load.scene.text), load.scene.text};
    spdlog::info("room '{}': scene '{}' replaced by '{}' ({} bodies, dt {} s) by client {}", name_,
                 old_name, scene_.name, world_.bodies().size(), dt_, from.client_id());
    from.send_reply(share(protocol::encode(protocol::ack{load.ref, counters_.ticks + 1, {}})));
    // Every client learns the new geometry and dt, each in its own welcome.
    for (member const& m : sessions_)
        if (auto session = m.session.lock())
            session->send_notice(welcome_for(m));
}

void room::replace_world(scene::scene s)
{
    // Built aside first: a scene that fails to build leaves the room as it was.
    physics::world fresh = scene::build_world(s);
    fresh.restore_clock(world_.time(), world_.time_compensation(), world_.steps());
    protocol::welcome welcome = make_welcome(name_, s, fresh, settings_);

    world_ = std::move(fresh);
    world_.time_phases(true);
    phase_seconds_seen_ = world_.timings();
    collisions_seen_ = world_.collisions();
    world_.set_parallel_for(physics_threads_.get(), settings_.physics_threads_from);
    welcome_ = std::move(welcome);
    quanta_ = quanta_for(s, welcome_);
    use_player_rules(s);
    dt_ = s.dt;
    send_charges_ = s.forces.coulomb.has_value();
    wire_id_of_index_.clear();
    body_of_wire_id_.clear();
    owner_of_wire_id_.clear();
    bodies_of_client_.clear();
    tag_of_wire_id_.clear();
    // New ids for every body: an id names one body for the life of the room.
    for (physics::body_id const id : world_.bodies().ids()) {
        std::uint64_t const wire_id = next_wire_id_++;
        if (wire_id_of_index_.size() <= id.index)
            wire_id_of_index_.resize(id.index + 1, 0);
        wire_id_of_index_[id.index] = wire_id;
        body_of_wire_id_.emplace(wire_id, id);
    }
    tag_scene_bodies(s);
    counters_.bodies = world_.bodies().size();
    scene_ = std::move(s);
}

std::optional<physics::body_id> room::find_body(std::uint64_t wire_id, std::uint64_t ref,
                                                websocket_session& from)
{
    auto const body = body_of_wire_id_.find(wire_id);
    if (body != body_of_wire_id_.end())
        return body->second;
    refuse(traffic_, from, ref, error_code::unknown_body, fmt::format("/id: no body {} in this room", wire_id));
    return std::nullopt;
}

std::uint64_t room::wire_id_of_slot(std::size_t slot) const
{
    return wire_id_of_index_[world_.bodies().ids()[slot].index];
}

std::optional<std::uint64_t> room::overlapped_sphere(physics::vec3 const& x, double radius,
                                                     std::optional<std::size_t> self) const
{
    if (!(radius > 0.0) || world_.settings().collisions.mode == physics::collision_mode::off)
        return std::nullopt; // point masses never collide; nor does anything with collisions off
    auto const positions = world_.bodies().positions();
    auto const radii = world_.bodies().radii();
    for (std::size_t i = 0; i < positions.size(); ++i)
        if (i != self && radii[i] > 0.0 && physics::spheres_overlap(x, radius, positions[i], radii[i]))
            return wire_id_of_slot(i);
    return std::nullopt;
}

std::optional<protocol::error> room::placement_refusal(protocol::vec3 const& position, double radius,
                                                       std::string_view pointer,
                                                       std::optional<std::size_t> self) const
{
    auto const refusal = [](error_code code, std::string message) {
        return protocol::error{std::nullopt, code, std::move(message)};
    };
    physics::vec3 const x = from_wire(position);
    for (std::size_t k = 0; k < world_.walls().size(); ++k) {
        physics::plane const& p = world_.walls()[k].surface;
        double const height = p.normal.dot(x) - p.offset; // m above the wall
        if (height < 0.0)
            return refusal(error_code::outside_world, fmt::format("{}: {} is behind wall {} (by {} m)",
                                                                  pointer, describe(position), k, -height));
        if (height < radius)
            return refusal(error_code::overlaps_wall,
                           fmt::format("{}: a sphere of radius {} m at {} crosses wall {}", pointer,
                                       radius, describe(position), k));
    }
    if (radius > 0.0) {
        for (std::size_t k = 0; k < world_.obstacles().size(); ++k)
            if (physics::sphere_vs_obb(x, radius, world_.obstacles()[k].box).touching)
                return refusal(error_code::overlaps_wall,
                               fmt::format("{}: a sphere of radius {} m at {} overlaps obstacle {}",
                                           pointer, radius, describe(position), k));
    }
    if (auto const other = overlapped_sphere(x, radius, self))
        return refusal(error_code::overlaps_body,
                       fmt::format("{}: a sphere of radius {} m at {} overlaps body {}; spheres "
                                   "collide here, and one inside another cannot be",
                                   pointer, radius, describe(position), *other));
    return std::nullopt;
}

std::optional<std::string> room::permission_refusal(std::uint64_t wire_id, std::uint64_t client,
                                                    bool admin, bool push) const
{
    if (admin)
        return std::nullopt; // whatever the rules
    auto const owner = owner_of_wire_id_.find(wire_id);
    bool const own = owner != owner_of_wire_id_.end() && owner->second == client;
    std::string_view const whose = owner == owner_of_wire_id_.end() ? "came with the scene"
                                   : own                            ? "is this client's"
                                                                    : "was spawned by another client";
    if (push) {
        switch (scene_.permissions.push) {
        case scene::push_rule::anyone:
            return std::nullopt;
        case scene::push_rule::owner:
            if (own)
                return std::nullopt;
            return fmt::format("/id: body {} {}; this room's push rule is \"owner\": only the client "
                               "that spawned a body (or an admin) may push it (impulse, set)",
                               wire_id, whose);
        case scene::push_rule::admins:
            break;
        }
        return std::string("/id: this room's push rule is \"admins\": only an admin may push a body "
                           "(impulse, set)");
    }
    if (scene_.permissions.remove == scene::remove_rule::admins)
        return std::string("/id: this room's remove rule is \"admins\": only an admin may remove a body");
    if (own)
        return std::nullopt;
    return fmt::format("/id: body {} {}; this room's remove rule is \"owner\": a client may remove "
                       "only the bodies it spawned (an admin may remove any)",
                       wire_id, whose);
}

void room::forget_body(std::uint64_t wire_id)
{
    body_of_wire_id_.erase(wire_id);
    tag_of_wire_id_.erase(wire_id);
    auto const owner = owner_of_wire_id_.find(wire_id);
    if (owner != owner_of_wire_id_.end()) {
        auto const count = bodies_of_client_.find(owner->second);
        if (count != bodies_of_client_.end() && --count->second == 0)
            bodies_of_client_.erase(count);
        owner_of_wire_id_.erase(owner);
    }
    counters_.bodies = world_.bodies().size();
}

std::uint64_t room::add_body(physics::body_desc const& desc)
{
    physics::body_id const id = world_.add_body(desc);
    if (wire_id_of_index_.size() <= id.index)
        wire_id_of_index_.resize(id.index + 1, 0);
    std::uint64_t const wire_id = next_wire_id_++;
    wire_id_of_index_[id.index] = wire_id;
    body_of_wire_id_.emplace(wire_id, id);
    counters_.bodies = world_.bodies().size();
    return wire_id;
}

bool room::step_world()
{
    if (paused_) { // the tick goes on, the world stands still
        ++counters_.ticks;
        return false;
    }
    // A step that fails changes nothing (world::step); the newer of the two bodies it names
    // (or the one an adaptive integrator could not follow) is removed and the step is taken
    // again, a few times at most in one tick, so that the room keeps its rate. A step that leaves a body's state non-finite (an overflow no check foresaw)
    // loses that body. Either way the world that goes on is finite, and every snapshot,
    // /healthz and /metrics count the fault.
    constexpr int max_attempts = 4;
    bool stepped = false;
    for (int attempt = 1; attempt <= max_attempts; ++attempt) {
        try {
            world_.step(dt_);
            stepped = true;
            break;
        } catch (physics::singular_force_error const& e) {
            // Of the two, the body that came last goes: a client's body that runs into the
            // scene's costs only that client.
            auto const newer = [&](physics::body_id id) {
                return world_.bodies().contains(id) ? wire_id_of_index_[id.index] : 0;
            };
            remove_after_fault({newer(e.first) > newer(e.second) ? e.first : e.second}, e.what());
        } catch (physics::step_control_error const& e) {
            // The adaptive integrator could not meet its tolerance: the body whose error was
            // the largest goes, as a body in a singular pair does.
            remove_after_fault({world_.bodies().ids()[e.body_slot]}, e.what());
        }
    }
    if (auto const broken = world_.non_finite_bodies(); !broken.empty())
        remove_after_fault(broken, "the step left their position or velocity beyond the range of a double");
    count_phase_times();
    ++counters_.ticks;
    return stepped;
}

void room::count_phase_times()
{
    // The world's timings are totals since it was made; a world made anew (a reset) starts
    // from zero, and its first step's share is then not counted.
    physics::step_timings const& now = world_.timings();
    for (std::size_t p = 0; p < physics::step_phase_count; ++p) {
        double const added = now.seconds[p] - phase_seconds_seen_.seconds[p];
        if (added > 0.0)
            counters_.phase_nanoseconds[p] += static_cast<std::uint64_t>(added * 1e9);
    }
    phase_seconds_seen_ = now;
    physics::collision_stats const& collisions = world_.collisions();
    counters_.swept_bodies += collisions.swept_bodies - collisions_seen_.swept_bodies;
    counters_.unswept_fast_bodies += collisions.unswept_fast_bodies - collisions_seen_.unswept_fast_bodies;
    counters_.collision_events += collisions.events - collisions_seen_.events;
    counters_.capped_steps += collisions.capped_steps - collisions_seen_.capped_steps;
    collisions_seen_ = collisions;
}

void room::remove_after_fault(std::vector<physics::body_id> const& bodies, std::string const& why)
{
    std::vector<std::uint64_t> removed;
    for (physics::body_id const id : bodies) {
        if (!world_.remove_body(id))
            continue; // named twice
        std::uint64_t const wire_id = wire_id_of_index_[id.index];
        forget_body(wire_id);
        removed.push_back(wire_id);
    }
    ++counters_.step_faults;
    std::string text = fmt::format("tick {}: the world could not step ({}); removed {} {}",
                                   counters_.ticks.load() + 1, why,
                                   removed.size() == 1 ? "body" : "bodies", fmt::join(removed, ", "));
    // One line per fault for the first few, then one in a hundred: a fault a tick must not
    // flood the log.
    if (counters_.step_faults <= 10 || counters_.step_faults % 100 == 0)
        spdlog::error("room '{}': {} ({} faults so far)", name_, text, counters_.step_faults.load());
    std::lock_guard const lock(last_fault_mutex_);
    last_fault_ = std::move(text);
}

std::string room::last_fault() const
{
    std::lock_guard const lock(last_fault_mutex_);
    return last_fault_;
}

bool room::snapshot_due()
{
    snapshot_phase_ += settings_.snapshot_rate;
    if (snapshot_phase_ < settings_.tick_rate)
        return false;
    snapshot_phase_ -= settings_.tick_rate;
    return true;
}

protocol::snapshot room::copy_snapshot() const
{
    physics::body_storage const& bodies = world_.bodies();
    std::size_t const n = bodies.size();
    protocol::snapshot snapshot;
    snapshot.tick = counters_.ticks;
    snapshot.time = world_.time();
    snapshot.paused = paused_;
    snapshot.faults = counters_.step_faults;
    protocol::body_columns& columns = snapshot.bodies;
    columns.id.reserve(n);
    columns.position.reserve(3 * n);
    columns.velocity.reserve(3 * n);
    columns.radius.assign(bodies.radii().begin(), bodies.radii().end());
    for (std::size_t i = 0; i < n; ++i) {
        columns.id.push_back(wire_id_of_index_[bodies.ids()[i].index]);
        for (int k = 0; k < 3; ++k) {
            columns.position.push_back(bodies.positions()[i][k]);
            columns.velocity.push_back(bodies.velocities()[i][k]);
        }
    }
    columns.mass.emplace(bodies.masses().begin(), bodies.masses().end()); // for J = m·Δv
    if (send_charges_) {
        if (bodies.charges().empty())
            columns.charge.emplace(n, 0.0); // no body carries a charge
        else
            columns.charge.emplace(bodies.charges().begin(), bodies.charges().end());
    }
    if (!tag_of_wire_id_.empty()) { // the column only when some body has a tag
        columns.tag.emplace(n);
        for (std::size_t i = 0; i < n; ++i)
            if (auto const tag = tag_of_wire_id_.find(columns.id[i]); tag != tag_of_wire_id_.end())
                (*columns.tag)[i] = tag->second;
    }
    return snapshot;
}

std::uint64_t room::view_of(protocol::interest_filter const& interest)
{
    for (auto const& [known, view] : view_of_interest_)
        if (known == interest)
            return view;
    view_of_interest_.emplace_back(interest, next_view_);
    return next_view_++;
}

resolved_interest room::resolve(protocol::interest_filter const& interest)
{
    resolved_interest r{.box = interest.box, .ball = std::nullopt, .tags = interest.tags};
    if (interest.around) {
        std::uint64_t const id = interest.around->body;
        if (auto const body = body_of_wire_id_.find(id); body != body_of_wire_id_.end())
            followed_at_[id] = to_wire(world_.bodies().positions()[*world_.bodies().slot_of(body->second)]);
        if (auto const at = followed_at_.find(id); at != followed_at_.end())
            r.ball = interest_ball{at->second, interest.around->radius};
        else
            r.nothing = true; // cannot be: a followed body is noted when the interest is set
    }
    return r;
}

void room::forget_unused_views(std::vector<snapshot_view> const& used)
{
    auto const in_use = [&](std::uint64_t view) {
        return std::any_of(used.begin(), used.end(), [&](snapshot_view const& v) { return v.id == view; });
    };
    std::erase_if(view_of_interest_, [&](auto const& entry) { return !in_use(entry.second); });
    std::erase_if(followed_at_, [&](auto const& entry) {
        return std::none_of(sessions_.begin(), sessions_.end(), [&](member const& m) {
            return m.interest && m.interest->around && m.interest->around->body == entry.first;
        });
    });
}

void room::send_snapshot()
{
    // The sessions still alive are this snapshot's audience (one that ended is forgotten
    // when its leave() comes), each in the view of the world it is sent: every body, or
    // what its interest holds. Sessions with the same interest share one view.
    std::vector<snapshot_view> views;
    for (member const& m : sessions_) {
        auto session = m.session.lock();
        if (!session)
            continue; // it ended: its leave() is on its way
        std::uint64_t const id = m.interest ? view_of(*m.interest) : 0;
        auto view = std::find_if(views.begin(), views.end(), [&](snapshot_view const& v) { return v.id == id; });
        if (view == views.end()) {
            views.push_back({id, m.interest ? std::optional(resolve(*m.interest)) : std::nullopt, false, {}, {}});
            view = views.end() - 1;
        }
        view->audience.push_back(std::move(session));
        if (!m.compact)
            view->any_full = true;
        else if (std::find(view->every.begin(), view->every.end(), m.every) == view->every.end())
            view->every.push_back(m.every);
    }
    if (!view_of_interest_.empty() || !followed_at_.empty())
        forget_unused_views(views); // a room without interests never gets here
    if (views.empty())
        return; // nobody to send it to: nothing to encode
    // Only the copy is made on the tick (about 0.2 ms for 10,000 bodies). Encoding (6 to 9 ms
    // for 10,000 bodies in full, bench/README.md) runs on the sessions' threads, one snapshot
    // at a time and in tick order: a snapshot due while the last is still being encoded is
    // skipped, as a slow client skips snapshots. Its audience then hears the next one. The
    // compact chains never see a skipped snapshot, so their deltas stay consecutive.
    if (snapshot_encoding_.exchange(true)) {
        ++counters_.snapshots_skipped;
        return;
    }
    std::vector<protocol::body_owner> owners;
    owners.reserve(owner_of_wire_id_.size());
    for (auto const& [wire_id, client] : owner_of_wire_id_)
        owners.push_back({wire_id, client});
    std::sort(owners.begin(), owners.end(),
              [](auto const& l, auto const& r) { return l.id < r.id; });
    net::post(background_, [self = shared_from_this(), index = snapshot_index_++,
                            snapshot = copy_snapshot(), owners = std::move(owners),
                            q = quanta_, views = std::move(views)]() mutable {
        // Each view encoded once for all its sessions: the interests' views first, each the
        // bodies of the whole snapshot its interest holds; then the whole snapshot itself
        // goes to the view of every body (the only one, in a room without interests).
        std::vector<std::shared_ptr<encoded_snapshot const>> forms(views.size());
        std::size_t bytes = 0;
        for (std::size_t v = 0; v < views.size(); ++v)
            if (views[v].interest)
                forms[v] = self->encode_view(index, views[v], inside(snapshot, *views[v].interest),
                                             owners, q, bytes);
        for (std::size_t v = 0; v < views.size(); ++v)
            if (!views[v].interest)
                forms[v] = self->encode_view(index, views[v], std::move(snapshot), std::move(owners), q, bytes);
        // A view no session is sent any more is forgotten with its chains.
        std::erase_if(self->chains_, [&](auto const& chains) {
            return std::none_of(views.begin(), views.end(),
                                [&](snapshot_view const& v) { return v.id == chains.first; });
        });
        // Counted before any session can send it: a client that has a snapshot finds it
        // in the count (/metrics, tests).
        self->report_bytes_ += bytes;
        ++self->counters_.snapshots;
        for (std::size_t v = 0; v < views.size(); ++v)
            for (auto const& session : views[v].audience)
                session->send_snapshot(forms[v]);
        self->snapshot_encoding_ = false; // after the sends: the next is queued behind them
    });
}

std::shared_ptr<encoded_snapshot const> room::encode_view(std::uint64_t index, snapshot_view const& view,
                                                          protocol::snapshot part,
                                                          std::vector<protocol::body_owner> owners,
                                                          protocol::quanta q, std::size_t& bytes)
{
    // Quantized only for a compact client: a room of full-form clients never pays for it.
    auto forms = std::make_shared<encoded_snapshot>(
        index, view.id, std::move(part), std::move(owners), q,
        std::shared_ptr<snapshot_form_counters>(shared_from_this(), &traffic_.encoded));
    auto chains = std::find_if(chains_.begin(), chains_.end(), [&](auto const& c) { return c.first == view.id; });
    if (chains == chains_.end()) {
        chains_.emplace_back(view.id, snapshot_chains{});
        chains = chains_.end() - 1;
    }
    chains->second.encode(*forms, view.every, settings_.keyframe_interval, settings_.snapshot_rate);
    if (view.any_full)
        bytes += forms->full()->size();
    return forms;
}

void room::record(tick_phases const& phases)
{
    clock::duration const cost = phases.total();
    last_tick_cost_ = cost;
    tick_durations_.record(cost);
    ++report_ticks_;
    report_cost_ += cost;
    if (cost > report_worst_.total())
        report_worst_ = phases;
    auto const now = clock::now();
    if (now - report_started_ < std::chrono::seconds(5))
        return;
    // The worst tick's steps say which of them to look at when a tick runs long.
    using ms = std::chrono::duration<double, std::milli>;
    double const seconds = std::chrono::duration<double>(now - report_started_).count();
    spdlog::info("room '{}': {} ticks in {:.1f} s, tick {:.2f} ms mean / {:.2f} ms worst (commands "
                 "{:.2f}, step {:.2f}, snapshot copy {:.2f} ms; on the processor {:.2f} ms), {} "
                 "bodies, {} clients, {:.0f} snapshot bytes/s, {} late ticks in all",
                 name_, report_ticks_, seconds,
                 ms(report_cost_).count() / static_cast<double>(report_ticks_),
                 ms(report_worst_.total()).count(), ms(report_worst_.commands).count(),
                 ms(report_worst_.step).count(), ms(report_worst_.snapshot).count(),
                 ms(report_worst_.on_processor).count(),
                 world_.bodies().size(), sessions_.size(),
                 static_cast<double>(report_bytes_.exchange(0)) / seconds,
                 counters_.late_ticks.load());
    report_started_ = now;
    report_ticks_ = 0;
    report_cost_ = {};
    report_worst_ = {};
}

void room::schedule_next_tick()
{
    if (!running_)
        return;
    // Catch up on a late tick or two, but a room more than max_behind ticks behind (too
    // many bodies for the tick rate) drops the backlog and slows down instead of spiralling.
    constexpr int max_behind = 4;
    next_tick_at_ += period_;
    auto const now = clock::now();
    if (now - next_tick_at_ > max_behind * period_) {
        auto const dropped = static_cast<std::uint64_t>((now - next_tick_at_) / period_);
        counters_.late_ticks += dropped;
        lateness_.record_backlog(now - next_tick_at_);
        if (now - last_late_warning_ > std::chrono::seconds(10)) {
            last_late_warning_ = now;
            spdlog::warn("room '{}': {} ticks late, dropped them (a tick costs more than {:.1f} ms)",
                         name_, dropped, std::chrono::duration<double, std::milli>(period_).count());
        }
        next_tick_at_ = now;
    }
    timer_.expires_at(next_tick_at_);
    timer_.async_wait(beast::bind_front_handler(&room::on_tick, shared_from_this()));
}

} // namespace kugel::server
