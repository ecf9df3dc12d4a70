// The WebSocket to one room: numbers commands with refs, pings once a second for the round
// trip time (and the server's tick time its pongs carry), and reconnects by itself with
// exponential backoff when the connection drops (a server restart), until close() is
// called. Frames are parsed by a worker (parse_worker.js) when one can start, otherwise here.
//
// Snapshots: after each socket's first welcome it says `hello` asking for the compact form
// (PROTOCOL.md, "Compact snapshots") at the room's snapshot rate. When the page falls behind
// (more than half a second of the asked rate's frames, at least 4, waiting to be parsed for a
// whole second) it asks for half the rate, at most once every 3 s and not below 1 Hz; once it
// has kept up for 10 s (at most one frame waiting at every check) it asks for twice the rate
// again, up to the room's; a new socket asks for the room's rate again. A compact snapshot
// that cannot be applied (malformed, or a delta whose base the page does not hold) drops the
// socket and opens a new one, whose first snapshot is a keyframe, as PROTOCOL.md asks; after
// 3 such refusals the connection asks for the full form instead, which needs no state. A server that does not grant the compact form
// (it answers with `"form": "full"`, or not at all) goes on sending the full form, which the
// page reads as before.
import { CompactStream } from './compact.js';
import { parse_frame } from './parse_frame.js';

const backlog_check_interval = 1000; // ms
const rate_lowering_pause = 3; // s between two halvings of the asked rate
const rate_raising_calm = 10; // s of keeping up before the asked rate is doubled again
const max_resyncs = 3; // refused compact snapshots before the connection asks for the full form

/** Milliseconds to wait before reconnect attempt `attempt` (0, 1, 2, ...), with +-20 % jitter. */
export function backoff_delay(attempt, { initial = 250, max = 5000, random = Math.random } = {}) {
  const base = Math.min(max, initial * 2 ** attempt);
  return base * (0.8 + 0.4 * random());
}

/**
 * Bytes received per second, over about the last `window` seconds: add() each frame's
 * bytes as the page reads it, per_second(now) the bytes read since the newest reading at
 * least `window` old, divided by the time since. Measured between readings on the page's
 * own clock rather than by each frame's arrival, because a page busy drawing reads a whole
 * second of frames at once: by arrival they would all seem to have come in the last moment.
 */
export class ByteRate {
  constructor(window = 1) {
    this.window = window; // s
    this.total = 0; // every byte added
    this.readings = []; // [local s, total], oldest first
    this.since = null; // the reading the last rate was measured from: [local s, total]
  }

  add(bytes) {
    this.total += bytes;
  }

  /** Bytes per second since about `window` seconds ago; null until a reading that old. */
  per_second(now) {
    this.readings.push([now, this.total]);
    while (this.readings.length > 1 && now - this.readings[1][0] >= this.window) this.readings.shift();
    const [then, total] = this.readings[0];
    if (now - then < this.window) return null;
    this.since = this.readings[0];
    return (this.total - total) / (now - then);
  }
}

/** The WebSocket URL of a room on the server that served the page. */
export function room_url(room, location = window.location) {
  const scheme = location.protocol === 'https:' ? 'wss:' : 'ws:';
  return `${scheme}//${location.host}/ws/${encodeURIComponent(room)}`;
}

export class Connection {
  /**
   * on_message(message, snapshot): every message from the server, parsed; for a snapshot,
   * its columns (interpolation.js, snapshot_from_message) instead of message.bodies.
   * on_state(state, detail): 'connecting', 'connected', 'reconnecting' (detail: seconds until
   * the next attempt), 'closed'.
   * on_attempt_failed(): a socket closed before its welcome (the server is down, or up
   * without this room: the browser is not told which); called before the next attempt.
   * worker_url: the bundled parse_worker.js, or null to parse on the main thread.
   * on_refused(why, message): a snapshot that could not be read, and what of it could.
   * form: the snapshot form to ask for, 'compact' or 'full'.
   * hello(first_on_socket, welcome): what each hello says besides the protocol and the
   * snapshots it asks for (the player's name; on a socket's first hello, after its first
   * welcome, also what is asked once: events, a resume).
   */
  constructor({ url, on_message, on_state, on_attempt_failed = () => {}, on_refused = () => {}, ping_interval = 1000, backoff = {}, worker_url = null, form = 'compact', hello = () => ({ name: 'kugel page' }) }) {
    this.url = url;
    this.on_message = on_message;
    this.on_state = on_state;
    this.on_attempt_failed = on_attempt_failed;
    this.on_refused = on_refused;
    this.form = form; // what the next hello asks for
    this.hello = hello;
    this.welcome = null; // the newest welcome on this socket
    this.room_rate = null; // Hz: the room's snapshot rate, from the welcome
    this.asked_rate = null; // Hz: what the last hello asked for
    this.granted = null; // the welcome's `snapshots`: what the server sends this socket
    this.hello_sent = false; // on this socket
    this.socket_welcomes = 0; // welcomes on this socket: the first starts a new stream of snapshots
    this.lowered_at = -Infinity; // local s: when the asked rate was last halved
    this.calm_since = null; // local s: since when the page has kept up (null: it has not)
    this.in_flight = 0; // frames handed to the worker and not yet back
    this.min_in_flight = 0; // the fewest since the last check
    this.backlog_timer = null;
    this.resyncs = 0; // compact snapshots refused on this connection
    this.stream = new CompactStream(); // when parsing on the main thread
    this.bytes = new ByteRate();
    this.ping_interval = ping_interval; // ms
    this.backoff = backoff;
    this.socket = null;
    this.state = 'closed';
    this.attempt = 0; // failed attempts since the last welcome
    this.welcomed = false; // the current socket got its welcome
    this.next_ref = 1;
    this.pings = new Map(); // ref -> performance.now() when sent
    this.rtt_ms = null;
    this.ping_timer = null;
    this.retry_timer = null;
    this.stopped = false;
    this.generation = 0; // counts sockets, so frames of a closed one are recognised and dropped
    this.worker = start_worker(worker_url, (event) => {
      if (event.data.generation !== this.generation || this.stopped) return;
      this.min_in_flight = Math.min(this.min_in_flight, --this.in_flight);
      this.receive(event.data.parsed);
    });
  }

  open() {
    this.stopped = false;
    this.set_state('connecting');
    this.welcomed = false;
    this.hello_sent = false;
    this.socket_welcomes = 0;
    this.granted = null;
    this.welcome = null;
    this.in_flight = 0;
    this.min_in_flight = 0;
    this.stream = new CompactStream();
    const socket = new WebSocket(this.url);
    const generation = ++this.generation;
    this.socket = socket;
    socket.onmessage = (event) => {
      if (socket !== this.socket) return; // a closed socket's last frames
      const received_at = performance.now() / 1000;
      if (this.worker) {
        this.worker.postMessage({ generation, data: event.data, received_at });
        this.in_flight++;
      } else {
        this.receive(parse_frame(event.data, received_at, this.stream));
      }
    };
    socket.onclose = () => {
      if (socket === this.socket) this.dropped();
    };
    // An error is always followed by a close, which handles it.
    socket.onerror = () => {};
  }

  /** Closes for good: no reconnect. */
  close() {
    this.stopped = true;
    clearTimeout(this.retry_timer);
    clearInterval(this.ping_timer);
    clearInterval(this.backlog_timer);
    const socket = this.socket;
    this.socket = null;
    if (socket) socket.close(1000);
    this.worker?.terminate();
    this.worker = null;
    this.set_state('closed');
  }

  /** Sends a command with a fresh ref; returns the ref, or null when not connected. */
  send(command) {
    if (!this.socket || this.socket.readyState !== WebSocket.OPEN) return null;
    const ref = this.next_ref++;
    this.socket.send(JSON.stringify({ ...command, ref }));
    return ref;
  }

  /** Sends a message that takes no ref (hello); returns whether it was sent. */
  send_without_ref(message) {
    if (!this.socket || this.socket.readyState !== WebSocket.OPEN) return false;
    this.socket.send(JSON.stringify(message));
    return true;
  }

  /** Asks for the snapshots this connection wants: its form, at `rate` Hz. */
  ask_for_snapshots(rate, first_on_socket = false) {
    this.asked_rate = rate;
    const fields = this.hello(first_on_socket, this.welcome);
    return this.send_without_ref({ type: 'hello', protocol: 1, ...fields, snapshots: { form: this.form, rate } });
  }

  receive(parsed) {
    const { message, snapshot, bytes, refused } = parsed;
    if (bytes !== undefined) this.bytes.add(bytes);
    if (!message) {
      console.warn('kugel: the server sent a frame that is not JSON');
      return;
    }
    if (refused) {
      this.refused(refused, message);
      return;
    }
    if (message.type === 'welcome') {
      this.attempt = 0;
      this.socket_welcomes++;
      if (!this.welcomed) {
        this.welcomed = true;
        this.set_state('connected');
        this.start_pings();
      }
      this.room_rate = message.snapshot_rate ?? null;
      this.welcome = message;
      if (message.snapshots) this.granted = message.snapshots;
      else if (!this.hello_sent && this.room_rate) this.hello_sent = this.ask_for_snapshots(this.room_rate, true);
    } else if (message.type === 'pong' && this.pings.has(message.ref)) {
      this.rtt_ms = performance.now() - this.pings.get(message.ref);
      this.pings.delete(message.ref);
    }
    this.on_message(message, snapshot);
  }

  /**
   * A snapshot that could not be read. A full-form one is dropped (the next stands on its
   * own); a compact one leaves the page without the base of the next delta, so the socket is
   * replaced by a new one, which starts with a keyframe.
   */
  refused(why, message) {
    this.on_refused(why, message);
    if (message.form === undefined || !this.socket) return;
    if (++this.resyncs >= max_resyncs) this.form = 'full';
    const socket = this.socket;
    this.generation++; // the old socket's frames still in the worker are dropped
    this.socket = null;
    socket.close(1000);
    this.dropped();
  }

  /**
   * Halves the asked rate when frames waited too long to be parsed, and doubles it again
   * after a calm while (see the top of the file).
   */
  check_backlog() {
    const now = performance.now() / 1000;
    const limit = Math.max(4, Math.ceil(this.asked_rate / 2));
    const waiting = this.min_in_flight; // never fewer waiting since the last check
    this.min_in_flight = this.in_flight;
    if (waiting > 1) this.calm_since = null;
    else this.calm_since ??= now;
    if (!this.granted) return;
    if (waiting > limit && this.asked_rate > 1 && now - this.lowered_at >= rate_lowering_pause) {
      this.lowered_at = now;
      this.ask_for_snapshots(Math.max(1, this.asked_rate / 2));
    } else if (this.calm_since !== null && now - this.calm_since >= rate_raising_calm && this.room_rate && this.asked_rate < this.room_rate) {
      this.calm_since = now; // another calm while before the next doubling
      this.ask_for_snapshots(Math.min(this.room_rate, this.asked_rate * 2));
    }
  }

  start_pings() {
    clearInterval(this.ping_timer);
    this.pings.clear();
    const ping = () => {
      const ref = this.send({ type: 'ping' });
      if (ref !== null) this.pings.set(ref, performance.now());
      // Forget pings that were never answered.
      if (this.pings.size > 10) this.pings.delete(this.pings.keys().next().value);
    };
    ping();
    this.ping_timer = setInterval(ping, this.ping_interval);
    clearInterval(this.backlog_timer);
    if (this.worker) this.backlog_timer = setInterval(() => this.check_backlog(), backlog_check_interval);
  }

  dropped() {
    clearInterval(this.ping_timer);
    clearInterval(this.backlog_timer);
    this.socket = null;
    if (this.stopped) return;
    const delay = backoff_delay(this.attempt++, this.backoff);
    this.set_state('reconnecting', delay / 1000);
    this.retry_timer = setTimeout(() => this.open(), delay);
    if (!this.welcomed) this.on_attempt_failed();
  }

  set_state(state, detail) {
    this.state = state;
    this.on_state(state, detail);
  }
}

/** A worker running parse_worker.js, or null where none can start (then frames are parsed on the main thread). */
function start_worker(url, on_parsed) {
  if (!url || typeof Worker === 'undefined') return null;
  try {
    const worker = new Worker(url);
    worker.onmessage = on_parsed;
    return worker;
  } catch {
    return null;
  }
}
