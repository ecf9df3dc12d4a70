// The page: joins a room, buffers its snapshots, draws them a little in the past every frame,
// and turns clicks and drags into spawn and impulse commands. With `?game` in its URL it is
// a player of the game (game.js): it spawns a ball of its own, pushes only that, colours
// every body by its owner and keeps a scoreboard of the room's goals.
//
// window.kugel exposes the page's state (connection, tick, bodies, answers to commands) and
// a few read-only functions, for scripts and for the end-to-end test.
import { colour_bodies, max_charge, round_up, speed_quantile } from './colour_scale.js';
import { Connection, room_url } from './connection.js';
import { colour_by_owner, Game, game_camera, key_direction, key_push, max_speed } from './game.js';
import { Hud } from './hud.js';
import { PointerInput } from './input.js';
import { index_of, PlaybackClock, SnapshotBuffer } from './interpolation.js';
import { choose_room, list_rooms } from './rooms.js';
import { SceneView } from './scene_view.js';

const kept_answers = 20; // acks and errors remembered in window.kugel.state
const speed_scale_hold = 3; // s: the speed legend shrinks only after this long below its maximum

const hud = new Hud(document);
const view = new SceneView(document.getElementById('view'));
const buffer = new SnapshotBuffer();
const number_input = (id) => {
  const input = document.getElementById(id);
  return () => Number(input.value) || Number(input.defaultValue);
};
const settings = {
  radius: number_input('spawn-radius'), // m
  density: number_input('spawn-density'), // kg/m³
  push: number_input('push-strength'), // m/s of Δv per m dragged
};
const colour_mode = document.getElementById('colour-mode');
const parameters = new URLSearchParams(window.location.search);
const game = parameters.has('game')
  ? new Game({ send: (command) => send(command), storage: session_storage(), name: parameters.get('name') })
  : null;

const state = {
  connection: 'connecting',
  room: null,
  rooms: [],
  scene: null,
  bounds: null, // the welcome's scene.bounds: {centre, radius}
  tick: null,
  bodies: null,
  snapshots_per_second: null,
  rtt_ms: null,
  tick_ms: null,
  frames_per_second: null,
  parser: null, // where snapshots are parsed: 'worker' or 'main thread'
  form: null, // the form of the last snapshot read: 'compact' or 'full'
  snapshots: null, // what the server grants this socket: the welcome's `snapshots` (form, rate, quanta)
  room_snapshot_rate: null, // Hz: the room's, from the welcome
  tick_rate: null, // Hz: the room's ticks per second, from the welcome
  asked_rate: null, // Hz: the snapshot rate the page asked for
  bytes_per_second: null, // this page's WebSocket bytes received, over the last second
  bytes_received: 0, // this page's WebSocket bytes received since it joined the room
  bytes_read: 0, // bytes_received as it was when the page read its latest snapshot (the HUD's timer may run late)
  bytes_rate_since: null, // [local s, bytes received]: where bytes_per_second was measured from
  hud_at: null, // local s (performance.now): when the HUD and the counts above were last updated
  snapshots_read: 0, // snapshots turned into columns since the page opened
  keyframes: 0, // compact keyframes among them
  deltas: 0, // compact deltas among them
  refused: [], // the last few snapshots that could not be read: {tick, form, why}
  frames: 0, // frames drawn with bodies in them
  welcomes: 0,
  paused: false, // an admin paused the room: snapshots keep coming, time stands still
  me: null, // this page's player id: its welcome's client
  players: [], // the room's players, by id: {id, name, away} (name null until its hello names it)
  acks: [], // the last few: {ref, tick, id, command}
  errors: [], // the last few: {ref, code, message, command}
};

let connection = null;
let welcome = null;
let clock = null;
let colours = new Float32Array(0);
const commands = new Map(); // ref -> command type, until answered
const snapshot_arrivals = []; // local s, the last second's
const frame_times = []; // local s, the last second's
let speed_scale = { max: 1, since: 0 }; // m/s and when it was last reached
let charge_scale = 0; // C

const input = new PointerInput({
  view,
  settings: () => ({ radius: settings.radius(), density: settings.density(), push: settings.push() }),
  walls: () => welcome?.scene.walls ?? [],
  // kg: the snapshot's (kugel-server always sends masses); a server without them: the panel's density.
  mass_of: (frame, i) => (frame.mass ? frame.mass[i] : settings.density() * (4 / 3) * Math.PI * frame.radius[i] ** 3),
  on_spawn: (position, radius, density) => send({ type: 'spawn', body: { position, radius, density } }),
  on_impulse: (id, impulse, delta_v) => (game ? game.push(delta_v) : send({ type: 'impulse', id, impulse })),
  on_nothing_spawned: (why) => hud.show_notice(`Nothing spawned: ${why}.`),
  label: document.getElementById('push-label'),
  // The game: no spawning by click, only this player's ball is pushed, along the pitch.
  spawns: game === null,
  can_push: (id) => game === null || id === game.ball,
  ground: game !== null,
  max_delta_v: game ? max_speed : Infinity,
});

/** This tab's sessionStorage, or null where the browser allows none. */
function session_storage() {
  try {
    return window.sessionStorage;
  } catch {
    return null;
  }
}

function show_scoreboard() {
  if (game) hud.set_scoreboard(game.scoreboard(state.players));
}

/** The game's keys: arrows or WASD push this player's ball as the camera sees the pitch, space stops it. */
function on_key(event) {
  if (event.target instanceof HTMLInputElement || event.target instanceof HTMLSelectElement) return;
  if (event.ctrlKey || event.metaKey || event.altKey) return;
  if (event.key === ' ') {
    event.preventDefault();
    game.brake();
    return;
  }
  const direction = key_direction(event.key, view.forward());
  if (!direction) return;
  event.preventDefault();
  game.push([key_push * direction[0], key_push * direction[1], 0]);
}

if (game) {
  document.body.classList.add('game');
  for (const id of ['panel', 'legend', 'help']) document.getElementById(id).hidden = true;
  for (const id of ['game', 'game-help']) document.getElementById(id).hidden = false;
  const name_input = document.getElementById('player-name');
  name_input.value = game.name;
  name_input.addEventListener('change', () => {
    const name = name_input.value.trim();
    if (name && name !== game.name) connection?.send_without_ref(game.rename(name));
  });
  window.addEventListener('keydown', on_key);
}

function send(command) {
  const ref = connection?.send(command) ?? null;
  if (ref === null) {
    hud.show_error({ code: 'not_connected', message: 'not connected to the server' }, command.type);
    return null;
  }
  commands.set(ref, command.type);
  if (commands.size > 200) commands.delete(commands.keys().next().value);
  return ref;
}

function remember(list, entry) {
  list.push(entry);
  if (list.length > kept_answers) list.shift();
}

function on_message(message, snapshot) {
  switch (message.type) {
    case 'welcome':
      on_welcome(message);
      break;
    case 'snapshot':
      on_snapshot(message, snapshot);
      break;
    case 'ack': {
      const command = commands.get(message.ref) ?? null;
      commands.delete(message.ref);
      remember(state.acks, { ref: message.ref, tick: message.tick, id: message.id ?? null, command });
      game?.on_ack(message);
      break;
    }
    case 'error': {
      const command = commands.get(message.ref) ?? null;
      commands.delete(message.ref);
      hud.show_error(message, command);
      remember(state.errors, { ref: message.ref ?? null, code: message.code, message: message.message, command });
      game?.on_error(message);
      break;
    }
    case 'event': {
      const scorer = game?.on_event(message) ?? null;
      if (scorer === null) break;
      const player = state.players.find((p) => p.id === scorer);
      const who = scorer === state.me ? 'You' : (player?.name ?? `player ${scorer}`);
      hud.show_notice(`Goal! ${who} scored.`, 'goal');
      show_scoreboard();
      break;
    }
    case 'pong':
      if (typeof message.tick_ms === 'number') state.tick_ms = message.tick_ms;
      break;
    case 'players':
      state.players = message.players.map((p) => ({ id: p.id, name: p.name ?? null, away: p.away === true }));
      hud.set_players(state.players, state.me);
      show_scoreboard();
      break;
    case 'player':
      state.players = state.players.filter((p) => p.id !== message.id);
      if (message.change !== 'left') {
        state.players.push({ id: message.id, name: message.name ?? null, away: message.change === 'away' });
        state.players.sort((a, b) => a.id - b.id);
      }
      hud.set_players(state.players, state.me);
      show_scoreboard();
      break;
    default:
      break; // later protocol versions may add messages: ignored
  }
}

/** The welcome says what the last one said of the world (it answers a hello, or made an admin). */
function same_world(a, b) {
  const world = (w) => JSON.stringify([w.room, w.scene, w.dt, w.tick_rate, w.snapshot_rate]);
  return a !== null && world(a) === world(b);
}

/** The playback delay: two snapshot intervals of the rate the server sends this page. */
function playback_clock(message) {
  const rate = message.dt * message.tick_rate; // simulated s per s
  const snapshot_rate = message.snapshots?.rate ?? message.snapshot_rate;
  return new PlaybackClock({ delay: (2 * rate) / snapshot_rate, rate });
}

function on_welcome(message) {
  state.welcomes++;
  state.me = message.client;
  if (game) {
    game.on_welcome(message);
    show_scoreboard();
  }
  state.snapshots = message.snapshots ?? null;
  state.room_snapshot_rate = message.snapshot_rate;
  state.tick_rate = message.tick_rate;
  state.asked_rate = connection?.asked_rate ?? null;
  if (connection?.socket_welcomes > 1 && same_world(welcome, message) && clock) {
    // Only the snapshots (or admin) changed: keep what is drawn, follow the new rate.
    welcome = message;
    clock.delay = playback_clock(message).delay;
    return;
  }
  // The camera stays where the person left it when the same room comes back after a reconnect.
  const same_scene = welcome?.room === message.room && welcome?.scene.name === message.scene.name;
  welcome = message;
  state.room = message.room;
  state.scene = message.scene.name;
  state.bounds = message.scene.bounds;
  state.tick_ms = null; // until this server's pong says, in case it never does
  buffer.clear();
  clock = playback_clock(message);
  view.set_scene(message.scene, { frame_camera: !same_scene, view: game ? game_camera : undefined });
  hud.set_scene(message.scene.name);
}

function on_snapshot(message, snapshot) {
  const now = snapshot.received_at;
  state.snapshots_read++;
  state.bytes_read = connection?.bytes.total ?? 0;
  state.form = snapshot.form === 'full' ? 'full' : 'compact';
  if (snapshot.form === 'key') state.keyframes++;
  if (snapshot.form === 'delta') state.deltas++;
  state.paused = snapshot.paused;
  game?.on_snapshot(snapshot);
  if (!buffer.push(snapshot)) return;
  clock?.on_snapshot(snapshot.time, now);
  snapshot_arrivals.push(now);
  state.tick = snapshot.tick;
  state.bodies = snapshot.count;
  if (typeof message.tick_ms === 'number') state.tick_ms = message.tick_ms;
  const speed = round_up(speed_quantile(snapshot, 0.98), 0.5);
  if (speed >= speed_scale.max || now - speed_scale.since > speed_scale_hold) speed_scale = { max: speed, since: now };
  const charge = max_charge(snapshot);
  charge_scale = charge > 0 ? round_up(charge) : 0;
}

function connect(room) {
  connection?.close();
  state.room = room;
  hud.set_rooms(room, state.rooms, switch_room);
  const opened = new Connection({
    url: room_url(room),
    worker_url: 'parse_worker.js',
    on_message,
    on_state: (s, detail) => {
      state.connection = s;
      hud.set_connection(s, detail);
    },
    on_attempt_failed: () => check_room(opened, room),
    hello: (first_on_socket) => (game ? game.hello_fields(first_on_socket, room) : { name: 'kugel page' }),
    on_refused: (why, message) => {
      remember(state.refused, { tick: message.tick ?? null, form: message.form ?? 'full', why });
      console.warn(`kugel: snapshot ${message.tick} refused: ${why}`);
      hud.show_notice(`A snapshot from the server could not be read (${why}); ${message.form ? 'reconnecting for a keyframe' : 'it was skipped'}.`);
    },
  });
  connection = opened;
  state.parser = connection.worker ? 'worker' : 'main thread';
  connection.open();
}

let checking_rooms = false; // a /healthz read for check_room is under way

/**
 * After a failed attempt to (re)connect to `room`: a server restarted without that room
 * refuses the upgrade with 404, which the browser reports only as a failed WebSocket, so the
 * page would retry forever. Reads the room list again and, when the server answers without
 * the room, says so and joins the room it would have chosen on load.
 */
async function check_room(opened, room) {
  if (checking_rooms) return;
  checking_rooms = true;
  const rooms = await list_rooms();
  checking_rooms = false;
  // No answer (the server is still down) proves nothing; nor does one for a connection the
  // person has since left by picking another room.
  if (!rooms.length || connection !== opened) return;
  const changed = rooms.join('\n') !== state.rooms.join('\n');
  state.rooms = rooms;
  const chosen = choose_room(rooms, room);
  if (chosen === room) {
    // The room is there (the server is starting, say): keep trying, with the new list.
    if (changed) hud.set_rooms(room, rooms, switch_room);
    return;
  }
  hud.show_notice(`Room "${room}" is no longer on the server; the rooms are ${rooms.join(', ')}. Showing "${chosen}".`);
  switch_room(chosen);
}

function switch_room(room) {
  const url = new URL(window.location.href);
  url.searchParams.set('room', room);
  window.history.replaceState(null, '', url);
  connect(room);
}

function drop_older_than(times, now) {
  while (times.length && times[0] < now - 1) times.shift();
}

function animate(now_ms) {
  const now = now_ms / 1000;
  const t = clock?.time(now) ?? null;
  if (t !== null && buffer.length) {
    const frame = buffer.sample(t);
    if (colours.length < 3 * frame.count) colours = new Float32Array(2 * 3 * frame.count);
    const mode = colour_mode.value;
    if (game) colour_by_owner(frame, game.owners, colours);
    else colour_bodies(frame, mode, mode === 'charge' ? charge_scale || 1 : speed_scale.max, colours);
    view.set_bodies(frame, colours);
    input.update_arrow();
    state.frames++;
  }
  view.render();
  frame_times.push(now);
  requestAnimationFrame(animate);
}

function update_hud() {
  const now = performance.now() / 1000;
  drop_older_than(snapshot_arrivals, now);
  drop_older_than(frame_times, now);
  state.snapshots_per_second = state.connection === 'connected' ? snapshot_arrivals.length : 0;
  state.frames_per_second = frame_times.length;
  state.rtt_ms = connection?.rtt_ms ?? null;
  state.bytes_per_second = connection ? connection.bytes.per_second(now) : null;
  state.bytes_rate_since = connection?.bytes.since ?? null;
  state.bytes_received = connection?.bytes.total ?? 0;
  state.asked_rate = connection?.asked_rate ?? null;
  state.hud_at = now;
  hud.update(state);
  const mode = colour_mode.value;
  hud.set_legend(mode, mode === 'charge' ? charge_scale : speed_scale.max);
}

window.kugel = {
  state,
  /** The newest snapshot as plain arrays, or null. */
  latest() {
    const s = buffer.newest;
    if (!s) return null;
    return { tick: s.tick, time: s.time, id: Array.from(s.id), position: Array.from(s.position), velocity: Array.from(s.velocity) };
  },
  /** One body in the newest snapshot: {position, velocity, radius}, or null. */
  body(id) {
    const s = buffer.newest;
    const i = s ? index_of(s, id) : -1;
    if (i < 0) return null;
    return {
      position: Array.from(s.position.subarray(3 * i, 3 * i + 3)),
      velocity: Array.from(s.velocity.subarray(3 * i, 3 * i + 3)),
      radius: s.radius[i],
    };
  },
  /**
   * The game mode's state, or null without `?game`: this player, its ball, every score this
   * tab counted, the scoreboard as shown, and the last goals.
   */
  game() {
    if (!game) return null;
    return {
      me: game.me,
      name: game.name,
      ready: game.ready,
      ball: game.ball,
      failed: game.failed,
      scores: Object.fromEntries(game.scores),
      scoreboard: game.scoreboard(state.players),
      goals: game.goals.slice(),
    };
  },
  /** How many spheres the last frame drew. */
  drawn: () => view.spheres?.count ?? 0,
  /** The spheres the last frame drew, as drawn: {id, position, radius}. */
  shown: () => view.shown(),
  /** Where a world point appears on the page, in CSS pixels. */
  screen_of: (x, y, z) => view.screen_of(x, y, z),
  /** The id of the sphere drawn under a point of the page (CSS pixels), or null. */
  body_at(x, y) {
    const i = view.body_at(x, y);
    return i < 0 ? null : view.frame.id[i];
  },
};

async function start() {
  state.rooms = await list_rooms();
  const requested = new URLSearchParams(window.location.search).get('room');
  const chosen = choose_room(state.rooms, requested);
  if (requested && chosen !== requested) {
    // ?room= named a room the server does not have: say so, and which rooms it has (the
    // picker lists them too), instead of opening another one without a word.
    hud.show_notice(`There is no room "${requested}" here; the rooms are ${state.rooms.join(', ')}. Showing "${chosen}".`);
  }
  connect(chosen);
  setInterval(update_hud, 250);
  requestAnimationFrame(animate);
}

start();
