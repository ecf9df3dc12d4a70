// Reads one frame from the server: JSON, and for a snapshot its columns as typed arrays —
// a full-form snapshot copied, a compact one (keyframe or delta) applied to the stream's
// state (compact.js). Runs in parse_worker.js, off the page's main thread, or on it when no
// worker can start.
import { to_snapshot } from './compact.js';
import { snapshot_from_message } from './interpolation.js';

/** The bytes of a text frame's UTF-8 payload (what the socket received for it). */
export function utf8_length(text) {
  // Snapshots are ASCII: one byte a character. Otherwise count the characters beyond.
  if (!/[^\x00-\x7f]/.test(text)) return text.length;
  let bytes = 0;
  for (const character of text) {
    const c = character.codePointAt(0);
    bytes += c < 0x80 ? 1 : c < 0x800 ? 2 : c < 0x10000 ? 3 : 4;
  }
  return bytes;
}

/**
 * {message, snapshot, bytes, refused, received_at}: the parsed message (null for a frame that is not
 * JSON), for a snapshot its columns (snapshot_from_message, compact.js to_snapshot) with the
 * message's own arrays dropped, the frame's bytes, and for a snapshot that cannot be read
 * (malformed, or a compact one that does not apply to the state held) why not. `stream` is
 * the connection's CompactStream.
 */
export function parse_frame(data, received_at, stream) {
  const parsed = read_frame(data, received_at, stream);
  parsed.received_at = received_at;
  return parsed;
}

function read_frame(data, received_at, stream) {
  const bytes = typeof data === 'string' ? utf8_length(data) : data.byteLength ?? 0;
  let message;
  try {
    message = JSON.parse(data);
  } catch {
    return { message: null, snapshot: null, bytes, refused: null };
  }
  if (message?.type !== 'snapshot') return { message, snapshot: null, bytes, refused: null };
  if (message.form !== undefined) {
    const result = stream.apply(message);
    const head = { type: 'snapshot', form: message.form, tick: message.tick, time: message.time, base: message.base };
    if (result.failure) return { message: head, snapshot: null, bytes, refused: result.failure };
    const snapshot = to_snapshot(result.state, received_at);
    snapshot.form = message.form;
    return { message: head, snapshot, bytes, refused: null };
  }
  const refused = full_form_fault(message);
  if (refused) return { message: { type: 'snapshot', tick: message.tick }, snapshot: null, bytes, refused };
  const snapshot = snapshot_from_message(message, received_at);
  snapshot.form = 'full';
  delete message.bodies;
  return { message, snapshot, bytes, refused: null };
}

/** Why a full-form snapshot cannot be drawn (columns missing or of the wrong length), or null. */
export function full_form_fault(message) {
  const b = message.bodies;
  if (typeof message.tick !== 'number' || !Number.isFinite(message.time)) return 'a snapshot without a tick and a finite time';
  if (typeof b !== 'object' || b === null || !Array.isArray(b.id)) return 'a snapshot without bodies.id';
  const n = b.id.length;
  const sized = (column, per) => Array.isArray(column) && column.length === per * n && column.every(Number.isFinite);
  if (!sized(b.position, 3) || !sized(b.velocity, 3) || !sized(b.radius, 1)) return 'a snapshot whose position, velocity or radius does not match its ids';
  if ((b.mass !== undefined && !sized(b.mass, 1)) || (b.charge !== undefined && !sized(b.charge, 1))) return 'a snapshot whose mass or charge does not match its ids';
  return null;
}

/** The buffers of a parsed snapshot, to transfer rather than copy between threads. */
export function transferables(parsed) {
  const s = parsed?.snapshot;
  if (!s) return [];
  return [s.id, s.position, s.velocity, s.radius, s.mass, s.charge, s.owner].filter(Boolean).map((a) => a.buffer);
}
