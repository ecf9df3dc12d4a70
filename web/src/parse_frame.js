// Reads one frame from the server: JSON, and for a snapshot its columns as typed arrays.
// Runs in parse_worker.js, off the page's main thread, or on it when no worker can start.
import { snapshot_from_message } from './interpolation.js';

/**
 * {message, snapshot}: the parsed message, and for a snapshot its columns
 * (snapshot_from_message) with the message's own arrays dropped; null for a frame that is
 * not JSON.
 */
export function parse_frame(data, received_at) {
  let message;
  try {
    message = JSON.parse(data);
  } catch {
    return null;
  }
  if (message?.type !== 'snapshot' || !message.bodies) return { message, snapshot: null };
  const snapshot = snapshot_from_message(message, received_at);
  delete message.bodies;
  return { message, snapshot };
}

/** The buffers of a parsed snapshot, to transfer rather than copy between threads. */
export function transferables(parsed) {
  const s = parsed?.snapshot;
  if (!s) return [];
  return [s.id, s.position, s.velocity, s.radius, s.mass, s.charge].filter(Boolean).map((a) => a.buffer);
}
