// The heads-up display: connection state, room (and a picker when the server hosts several),
// tick, bodies, snapshots per second, bytes received per second and the snapshot form,
// round trip, server tick time, frame rate, the room's players; the colour
// legend; the game mode's scoreboard; and the server's errors as readable messages.
import { charge_stops, speed_stops } from './colour_scale.js';

const message_seconds = 8; // how long an error stays on screen
const max_messages = 4;

/** What an error code means for the person who clicked, in words. */
const plain_words = {
  outside_world: 'that point is outside the world',
  overlaps_wall: 'the sphere would cross a wall or an obstacle',
  overlaps_body: 'the sphere would sit inside another sphere',
  singular_force: 'its forces would be too strong for the world to step',
  room_full: 'the room is full',
  too_many_bodies: 'you have as many spheres as one visitor may have; remove one first',
  forbidden: 'only an admin may do that',
  rate_limited: 'too many commands at once, try again in a moment',
  unknown_body: 'that sphere is no longer in the world',
  bad_value: 'a value is out of range',
  missing_field: 'a value is missing',
  bad_resume: 'this page could not come back as the player it was (the server no longer keeps it), and plays on as a new one',
};

/** A readable line for an `error` message; `command` is the refused command's type, if known. */
export function describe_error(error, command) {
  if (error.code === 'not_connected') {
    return { headline: `${capitalised(command ?? 'command')} not sent: the page is not connected to the server`, code: error.code, detail: error.message };
  }
  const what = command ? `${capitalised(command)} refused` : 'The server refused a message';
  const why = plain_words[error.code] ?? error.message;
  return { headline: `${what}: ${why}`, code: error.code, detail: error.message };
}

export class Hud {
  constructor(document) {
    const $ = (id) => document.getElementById(id);
    this.document = document;
    this.connection = $('hud-connection');
    this.room = $('hud-room');
    this.picker = $('room-picker');
    this.scene = $('hud-scene');
    this.tick = $('hud-tick');
    this.bodies = $('hud-bodies');
    this.snapshot_rate = $('hud-snapshot-rate');
    this.bytes_rate = $('hud-bytes-rate');
    this.form = $('hud-form');
    this.rtt = $('hud-rtt');
    this.tick_time = $('hud-tick-time');
    this.fps = $('hud-fps');
    this.players = $('hud-players');
    this.scoreboard = $('scoreboard');
    this.messages = $('messages');
    this.legend_title = $('legend-title');
    this.legend_bar = $('legend-bar');
    this.legend_min = $('legend-min');
    this.legend_mid = $('legend-mid');
    this.legend_max = $('legend-max');
  }

  set_connection(state, detail) {
    this.connection.dataset.state = state;
    this.connection.textContent = state === 'reconnecting' && detail !== undefined ? `reconnecting in ${detail.toFixed(1)} s` : state;
  }

  /** The room shown; with more than one room, a picker that calls on_pick(name). */
  set_rooms(current, rooms, on_pick) {
    this.room.textContent = current;
    const several = rooms.length > 1;
    this.room.hidden = several;
    this.picker.hidden = !several;
    if (!several) return;
    this.picker.replaceChildren(
      ...rooms.map((name) => {
        const option = this.document.createElement('option');
        option.value = name;
        option.textContent = name;
        option.selected = name === current;
        return option;
      }),
    );
    this.picker.onchange = () => on_pick(this.picker.value);
  }

  set_scene(name) {
    this.scene.textContent = name;
  }

  /** The room's players: how many, and each by name ("player 7" until named), this page as "you". */
  set_players(players, me) {
    const names = players.map((p) => (p.id === me ? 'you' : (p.name ?? `player ${p.id}`)));
    this.players.textContent = players.length === 0 ? '–' : `${players.length}: ${names.join(', ')}`;
    this.players.title = this.players.textContent;
  }

  /**
   * The game's scoreboard (game.js, Game.scoreboard): a row per player with its colour, its
   * name ("(you)" after this tab's) and its goals; "(away)" for a player whose connection
   * dropped and may come back.
   */
  set_scoreboard(rows) {
    this.scoreboard.replaceChildren(
      ...rows.map((row) => {
        const item = this.document.createElement('li');
        item.dataset.player = String(row.id);
        if (row.you) item.dataset.you = '';
        if (row.away) item.dataset.away = '';
        const swatch = this.document.createElement('span');
        swatch.className = 'swatch';
        swatch.style.background = row.colour;
        const name = this.document.createElement('span');
        name.className = 'name';
        name.textContent = row.name + (row.you ? ' (you)' : '') + (row.away ? ' (away)' : '');
        name.title = name.textContent;
        const score = this.document.createElement('span');
        score.className = 'score';
        score.textContent = String(row.score);
        item.append(swatch, name, score);
        return item;
      }),
    );
  }

  /**
   * stats: {tick, bodies, snapshots_per_second, bytes_per_second, form, snapshots, rtt_ms,
   * tick_ms, frames_per_second}; null shows a dash.
   */
  update(stats) {
    const show = (element, value, format) => {
      element.textContent = value === null || value === undefined ? '–' : format(value);
    };
    show(this.tick, stats.tick, String);
    show(this.bodies, stats.bodies, String);
    show(this.snapshot_rate, stats.snapshots_per_second, (v) => v.toFixed(1));
    if (this.bytes_rate) show(this.bytes_rate, stats.bytes_per_second, format_bytes_rate);
    if (this.form) show(this.form, stats.form, (form) => describe_form(form, stats.snapshots));
    show(this.rtt, stats.rtt_ms, (v) => `${v.toFixed(1)} ms`);
    this.tick_time.textContent = typeof stats.tick_ms === 'number' ? `${stats.tick_ms.toFixed(2)} ms` : 'n/a';
    show(this.fps, stats.frames_per_second, (v) => v.toFixed(0));
  }

  /** The legend of the colour scale: mode 'speed' (0 to max m/s) or 'charge' (-max to max C). */
  set_legend(mode, max) {
    const stops = mode === 'charge' ? charge_stops : speed_stops;
    this.legend_bar.style.background = `linear-gradient(to right, ${stops.join(', ')})`;
    if (mode === 'charge') {
      this.legend_title.textContent = max > 0 ? 'charge (C)' : 'charge: this scene has no charges';
      this.legend_min.textContent = max > 0 ? format_number(-max) : '';
      this.legend_mid.textContent = '0';
      this.legend_max.textContent = max > 0 ? format_number(max) : '';
    } else {
      this.legend_title.textContent = 'speed (m/s)';
      this.legend_min.textContent = '0';
      this.legend_mid.textContent = format_number(max / 2);
      this.legend_max.textContent = `≥ ${format_number(max)}`;
    }
  }

  /** Shows a line of text among the messages for a while (no error code); kind 'goal' shows it as good news. */
  show_notice(text, kind = null) {
    const element = this.document.createElement('div');
    element.className = kind ? `message ${kind}` : 'message';
    element.textContent = text;
    this.messages.append(element);
    while (this.messages.children.length > max_messages) this.messages.firstElementChild.remove();
    setTimeout(() => element.remove(), 2 * message_seconds * 1000);
  }

  /** Shows a readable error for a while. */
  show_error(error, command) {
    const { headline, code, detail } = describe_error(error, command);
    const element = this.document.createElement('div');
    element.className = 'message';
    const code_element = this.document.createElement('code');
    code_element.textContent = code;
    element.append(`${headline} `, code_element);
    element.title = detail;
    this.messages.append(element);
    while (this.messages.children.length > max_messages) this.messages.firstElementChild.remove();
    setTimeout(() => element.remove(), message_seconds * 1000);
  }
}

/** Bytes per second in B/s, kB/s or MB/s (powers of 1000), three significant digits. */
export function format_bytes_rate(bytes) {
  if (bytes < 1e3) return `${bytes.toFixed(0)} B/s`;
  if (bytes < 1e6) return `${(bytes / 1e3).toPrecision(3)} kB/s`;
  return `${(bytes / 1e6).toPrecision(3)} MB/s`;
}

/** The form in use, with the rate the server grants when it said one ('compact at 30 Hz'). */
export function describe_form(form, granted) {
  if (!granted || granted.form !== form) return form;
  return `${form} at ${Number(granted.rate.toPrecision(3))} Hz`;
}

function capitalised(word) {
  return word[0].toUpperCase() + word.slice(1);
}

function format_number(x) {
  const a = Math.abs(x);
  if (a !== 0 && (a < 0.01 || a >= 1e4)) return x.toExponential(0);
  return String(Number(x.toPrecision(3)));
}
