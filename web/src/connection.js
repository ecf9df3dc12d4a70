// The WebSocket to one room: numbers commands with refs, pings once a second for the round
// trip time (and the server's tick time its pongs carry), and reconnects by itself with
// exponential backoff when the connection drops (a server restart), until close() is
// called. Frames are parsed by a worker (parse_worker.js) when one can start, otherwise here.
import { parse_frame } from './parse_frame.js';

/** Milliseconds to wait before reconnect attempt `attempt` (0, 1, 2, ...), with +-20 % jitter. */
export function backoff_delay(attempt, { initial = 250, max = 5000, random = Math.random } = {}) {
  const base = Math.min(max, initial * 2 ** attempt);
  return base * (0.8 + 0.4 * random());
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
   */
  constructor({ url, on_message, on_state, on_attempt_failed = () => {}, ping_interval = 1000, backoff = {}, worker_url = null }) {
    this.url = url;
    this.on_message = on_message;
    this.on_state = on_state;
    this.on_attempt_failed = on_attempt_failed;
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
      if (event.data.generation === this.generation && !this.stopped) this.receive(event.data.parsed);
    });
  }

  open() {
    this.stopped = false;
    this.set_state('connecting');
    this.welcomed = false;
    const socket = new WebSocket(this.url);
    const generation = ++this.generation;
    this.socket = socket;
    socket.onmessage = (event) => {
      if (socket !== this.socket) return; // a closed socket's last frames
      const received_at = performance.now() / 1000;
      if (this.worker) this.worker.postMessage({ generation, data: event.data, received_at });
      else this.receive(parse_frame(event.data, received_at));
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

  receive(parsed) {
    if (!parsed) {
      console.warn('kugel: the server sent a frame that is not JSON');
      return;
    }
    const { message, snapshot } = parsed;
    if (message.type === 'welcome') {
      this.attempt = 0;
      this.welcomed = true;
      this.set_state('connected');
      this.start_pings();
    } else if (message.type === 'pong' && this.pings.has(message.ref)) {
      this.rtt_ms = performance.now() - this.pings.get(message.ref);
      this.pings.delete(message.ref);
    }
    this.on_message(message, snapshot);
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
  }

  dropped() {
    clearInterval(this.ping_timer);
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
