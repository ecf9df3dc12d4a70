// The page's game mode (`?game`, see README.md): every tab is a player with a colour of its
// own, spawns one ball tagged "ball", pushes it (only its own: the game scene's push rule is
// "owner") and scores when it goes into the scene's sensor "goal".
//
// Everything here is the same in every tab, from what the server tells every client:
//   - a player's colour comes from its id (welcome.client), nothing else;
//   - who scored: each tab hears the sensor's `entered` events (hello.events) and gives the
//     goal to the owner of the body that entered, as the compact snapshots' owner column
//     says (the page holds each body's owner by id from the newest snapshot);
//   - who plays: the `players` list and `player` notices.
// So two tabs that saw the same goals show the same scores. A tab counts the goals it heard:
// one that joins late (or reloads) starts from 0 for everybody, since events are not replayed.
//
// After a goal of its own ball a tab puts the ball back on its start spot with `set`. A tab
// whose connection drops comes back as the same player with the resume token of its last
// welcome (kept per tab in sessionStorage), and so keeps its ball; when that fails it is a
// new player and spawns a new ball.

export const goal_sensor = 'goal';
export const ball_tag = 'ball';
export const ball = { radius: 0.4, mass: 1 }; // m, kg
export const max_speed = 12; // m/s: a push never takes the ball faster than this
export const key_push = 1.5; // m/s of Δv per key press

/**
 * Where the camera looks from (degrees): behind the start spots, above the -x end, so that
 * the goal is at the top of the screen and "up" pushes towards it.
 */
export const game_camera = { azimuth: 180, elevation: 55 };

/** Start spots on the pitch (x, y; z = 0), two columns of five on the side away from the goal. */
export const start_spots = [-6, -4.5].flatMap((x) => [0, -1.5, 1.5, -3, 3].map((y) => [x, y, 0]));

const names = ['otter', 'heron', 'lynx', 'badger', 'finch', 'marten', 'ibis', 'gecko', 'puffin', 'bison', 'tapir', 'wren'];

/** A name for a player that gave none: an animal and two digits. */
export function random_name(random = Math.random) {
  return `${names[Math.floor(random() * names.length)]} ${String(Math.floor(random() * 100)).padStart(2, '0')}`;
}

/**
 * A player's colour, from its id alone, so every tab shows it alike: hues a golden angle
 * apart (neighbouring ids far apart on the wheel). Id 0, the scene's bodies, is grey.
 * {css: '#rrggbb', rgb: [r, g, b] linear, for WebGL}.
 */
export function player_colour(id) {
  const srgb = id === 0 ? [0.55, 0.58, 0.62] : hsl_to_rgb((id * 0.6180339887498949) % 1, 0.7, 0.58);
  const css = `#${srgb.map((c) => Math.round(c * 255).toString(16).padStart(2, '0')).join('')}`;
  return { css, rgb: srgb.map(srgb_to_linear) };
}

function hsl_to_rgb(h, s, l) {
  const a = s * Math.min(l, 1 - l);
  const f = (n) => {
    const k = (n + h * 12) % 12;
    return l - a * Math.max(-1, Math.min(k - 3, 9 - k, 1));
  };
  return [f(0), f(8), f(4)];
}

function srgb_to_linear(c) {
  return c <= 0.04045 ? c / 12.92 : ((c + 0.055) / 1.055) ** 2.4;
}

/**
 * The change of velocity to send for a push of `delta_v` on a ball moving at `velocity`,
 * both in the pitch's plane (z dropped): as asked, unless that would leave the ball faster
 * than `max`; then shortened along its direction to reach exactly `max` (or nothing, when
 * the ball is that fast already and the push would not slow it).
 */
export function capped_push(velocity, delta_v, max = max_speed) {
  const dv = [delta_v[0], delta_v[1], 0];
  const v = [velocity[0], velocity[1], 0];
  const speed_after = (s) => Math.hypot(v[0] + s * dv[0], v[1] + s * dv[1]);
  if (speed_after(1) <= max) return dv;
  if (Math.hypot(...dv) === 0) return dv;
  // The largest s in [0, 1] with |v + s·dv| <= max: the root of a quadratic in s.
  const a = dv[0] ** 2 + dv[1] ** 2;
  const b = 2 * (v[0] * dv[0] + v[1] * dv[1]);
  const c = v[0] ** 2 + v[1] ** 2 - max * max;
  const root = (-b + Math.sqrt(Math.max(0, b * b - 4 * a * c))) / (2 * a);
  const s = Math.min(1, Math.max(0, root));
  return [s * dv[0], s * dv[1], 0];
}

/**
 * A key's push direction on the pitch (a unit vector in x, y), as seen by the camera: up (or
 * W) away from the camera along the ground, down towards it, left and right across; null for
 * any other key. `forward` is the camera's viewing direction.
 */
export function key_direction(key, forward) {
  const length = Math.hypot(forward[0], forward[1]);
  // Looking straight down: "up" is the pitch's +y.
  const f = length > 1e-9 ? [forward[0] / length, forward[1] / length] : [0, 1];
  const right = [f[1], -f[0]];
  switch (key) {
    case 'ArrowUp': case 'w': case 'W': return f;
    case 'ArrowDown': case 's': case 'S': return [-f[0], -f[1]];
    case 'ArrowRight': case 'd': case 'D': return right;
    case 'ArrowLeft': case 'a': case 'A': return [-right[0], -right[1]];
    default: return null;
  }
}

export class Game {
  /**
   * send(command): sends a command and returns its ref (null when not connected).
   * storage: where a tab keeps its name and resume token (sessionStorage), or null.
   * name: the name asked for (the URL's), else the tab's kept one, else a random one.
   */
  constructor({ send, storage = null, name = null, random = Math.random }) {
    this.send = send;
    this.storage = storage;
    this.name = name || this.load('kugel.name') || random_name(random);
    this.store('kugel.name', this.name);
    this.room = null;
    this.me = null; // this tab's player id
    this.ready = false; // this socket's hello was answered: the player it is is settled
    this.owners = new Map(); // body id -> owner (player id), from the newest snapshot
    this.scores = new Map(); // player id -> goals this tab saw
    this.ball = null; // this player's ball's id
    this.ball_since = 0; // the tick its spawn was applied: older snapshots do not show it yet
    this.velocity = [0, 0, 0]; // of this player's ball in the newest snapshot
    this.spawning = null; // ref of the spawn of this player's ball, until answered
    this.resetting = null; // ref of the set that puts it back, until answered
    this.spot = 0; // added to the start spot this player's id gives, past spots that were taken
    this.failed = null; // why this tab gave up spawning a ball, or null
    this.goals = []; // the last few goals: {tick, player, body}
  }

  load(key) {
    try {
      return this.storage?.getItem(key) ?? null;
    } catch {
      return null;
    }
  }

  store(key, value) {
    try {
      if (value === null) this.storage?.removeItem(key);
      else this.storage?.setItem(key, value);
    } catch {
      // a tab without storage plays on; it just cannot resume
    }
  }

  /**
   * What this tab's hello says besides the snapshots it asks for: its name always; on a
   * socket's first hello also the goal events it wants and, when it was a player of the room
   * before, the resume token of that player.
   */
  hello_fields(first_on_socket, room) {
    const fields = { name: this.name };
    if (!first_on_socket) return fields;
    fields.events = { sensors: [goal_sensor], tags: [ball_tag], kinds: ['entered'] };
    const token = this.load(`kugel.resume.${room}`);
    if (token) fields.resume = token;
    return fields;
  }

  /** Renames this tab's player; returns the hello to send. */
  rename(name) {
    this.name = name;
    this.store('kugel.name', name);
    return { type: 'hello', name };
  }

  on_welcome(welcome) {
    if (welcome.room !== this.room) {
      this.room = welcome.room;
      this.scores.clear();
      this.goals = [];
    }
    if (welcome.client !== this.me) {
      // Another player than before (a new connection; a resume gives the old one back).
      this.me = welcome.client;
      this.ball = null;
      this.ball_since = 0;
      this.spawning = null;
      this.resetting = null;
      this.spot = 0;
      this.failed = null;
    }
    this.store(`kugel.resume.${welcome.room}`, welcome.resume_token ?? null);
    // A welcome that answers the hello (it states the snapshots granted) comes after a resume
    // the hello asked for was answered: only then is it known which player this tab is.
    this.ready = welcome.snapshots !== undefined;
  }

  /** A snapshot's columns (compact snapshots carry the owners; the full form does not). */
  on_snapshot(snapshot) {
    if (!snapshot.owner) return;
    const owners = new Map();
    let mine = null;
    for (let i = 0; i < snapshot.count; i++) {
      const id = snapshot.id[i];
      const owner = snapshot.owner[i];
      owners.set(id, owner);
      if (owner === this.me && this.me !== null && (mine === null || id === this.ball)) mine = i;
    }
    this.owners = owners;
    if (mine === null) {
      // The ball went (removed, or never spawned); unless its spawn is still on its way, or
      // this snapshot is older than the tick that spawned it (an ack comes before the
      // snapshot of its tick, not before those of earlier ticks).
      if (this.spawning === null && snapshot.tick >= this.ball_since) this.ball = null;
    } else {
      this.ball = snapshot.id[mine];
      this.velocity = Array.from(snapshot.velocity.subarray(3 * mine, 3 * mine + 3));
    }
    if (this.ready && this.ball === null && this.spawning === null && this.failed === null) this.spawn();
  }

  /** The start spot of this player: the one its id gives, or a later one when that was taken. */
  start_spot() {
    return start_spots[(this.me - 1 + this.spot + start_spots.length * 1000) % start_spots.length];
  }

  spawn() {
    this.spawning = this.send({
      type: 'spawn',
      body: { position: this.start_spot(), radius: ball.radius, mass: ball.mass, tag: ball_tag },
    });
  }

  /** Puts this player's ball back on its start spot, at rest. */
  reset() {
    if (this.ball === null) return;
    this.resetting = this.send({ type: 'set', id: this.ball, position: this.start_spot(), velocity: [0, 0, 0] });
  }

  /** An ack: the ball's id once its spawn is acked. */
  on_ack(ack) {
    if (ack.ref === this.spawning) {
      this.spawning = null;
      this.ball = ack.id;
      this.ball_since = ack.tick;
    } else if (ack.ref === this.resetting) {
      this.resetting = null;
    }
  }

  /**
   * An error: a start spot that was taken is passed over for the next one, and a spawn that
   * came too fast is tried again with the next snapshot.
   */
  on_error(error) {
    const taken = error.code === 'overlaps_body';
    if (error.ref === this.spawning && error.ref !== undefined) {
      this.spawning = null;
      if (error.code === 'rate_limited') return;
      // Tried every spot, or refused for another reason: say so rather than try for ever.
      if (taken && this.spot < start_spots.length - 1) this.spot++;
      else this.failed = error.message;
    } else if (error.ref === this.resetting && error.ref !== undefined) {
      this.resetting = null;
      if (taken && this.spot < start_spots.length - 1) {
        this.spot++;
        this.reset();
      }
    }
  }

  /**
   * A sensor event: a ball entering the goal scores for its owner. Returns the scorer's id,
   * or null for an event that scores nothing (another sensor, a body without an owner).
   */
  on_event(event) {
    if (event.kind !== 'entered' || event.sensor !== goal_sensor) return null;
    const owner = this.owners.get(event.body) ?? 0;
    if (owner === 0) return null;
    this.scores.set(owner, (this.scores.get(owner) ?? 0) + 1);
    this.goals.push({ tick: event.tick, player: owner, body: event.body });
    if (this.goals.length > 20) this.goals.shift();
    if (owner === this.me && event.body === this.ball) this.reset();
    return owner;
  }

  /** Pushes this player's ball by a change of velocity in the pitch's plane (capped); returns the ref or null. */
  push(delta_v) {
    if (this.ball === null) return null;
    const dv = capped_push(this.velocity, delta_v);
    if (Math.hypot(...dv) < 1e-6) return null;
    // Counted now, so that pushes sent before the next snapshot are capped together.
    for (let k = 0; k < 3; k++) this.velocity[k] += dv[k];
    return this.send({ type: 'impulse', id: this.ball, impulse: dv.map((x) => x * ball.mass) });
  }

  /** Stops this player's ball. */
  brake() {
    return this.push(this.velocity.map((x) => -x));
  }

  /**
   * The scoreboard: every player of the room (`players`: {id, name, away}) with its colour and
   * goals, most goals first, then by id.
   */
  scoreboard(players) {
    return players
      .map((p) => ({
        id: p.id,
        name: p.name ?? `player ${p.id}`,
        colour: player_colour(p.id).css,
        score: this.scores.get(p.id) ?? 0,
        you: p.id === this.me,
        away: p.away === true,
      }))
      .sort((a, b) => b.score - a.score || a.id - b.id);
  }
}

const owner_colours = new Map(); // player id -> linear [r, g, b]

/** Writes each body's colour into `out` (3 floats each): its owner's colour, grey for the scene's bodies. */
export function colour_by_owner(frame, owners, out) {
  for (let i = 0; i < frame.count; i++) {
    const owner = owners.get(frame.id[i]) ?? 0;
    let rgb = owner_colours.get(owner);
    if (!rgb) {
      rgb = player_colour(owner).rgb;
      owner_colours.set(owner, rgb);
    }
    out[3 * i] = rgb[0];
    out[3 * i + 1] = rgb[1];
    out[3 * i + 2] = rgb[2];
  }
}
