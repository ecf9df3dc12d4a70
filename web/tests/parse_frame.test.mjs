// Unit tests for reading a frame: JSON, a snapshot's columns ready to transfer, the frame's
// bytes, and full-form snapshots that cannot be drawn.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { CompactStream } from '../src/compact.js';
import { parse_frame, transferables, utf8_length } from '../src/parse_frame.js';

test('a snapshot becomes typed columns, stamped with its arrival, without the JSON arrays', () => {
  const text = JSON.stringify({
    type: 'snapshot', tick: 12, time: 0.2,
    bodies: { id: [4, 17], position: [0, 0, 0.1, 0.5, -0.25, 1.75], velocity: [0, 0, 0, 1.5, 0, -3.2], radius: [0.1, 0.1] },
  });
  const { message, snapshot, bytes, refused } = parse_frame(text, 3.5, new CompactStream());
  assert.equal(refused, null);
  assert.equal(bytes, text.length);
  assert.equal(message.type, 'snapshot');
  assert.equal(message.bodies, undefined);
  assert.equal(snapshot.form, 'full');
  assert.equal(snapshot.tick, 12);
  assert.equal(snapshot.received_at, 3.5);
  assert.equal(snapshot.count, 2);
  assert.ok(snapshot.position instanceof Float64Array);
  assert.deepEqual(Array.from(snapshot.velocity), [0, 0, 0, 1.5, 0, -3.2]);
  assert.equal(snapshot.mass, null);
  assert.equal(transferables({ message, snapshot }).length, 4);
});

test('other messages pass through; a frame that is not JSON has no message, but its bytes count', () => {
  const pong = parse_frame('{"type":"pong","ref":5,"tick":7}', 0, new CompactStream());
  assert.deepEqual(pong.message, { type: 'pong', ref: 5, tick: 7 });
  assert.equal(pong.snapshot, null);
  assert.equal(pong.bytes, 32);
  const broken = parse_frame('{"type": "p', 0, new CompactStream());
  assert.equal(broken.message, null);
  assert.equal(broken.bytes, 11);
  assert.deepEqual(transferables(null), []);
});

test('bytes are the frame\'s UTF-8 bytes, not its characters', () => {
  assert.equal(utf8_length('abc'), 3);
  assert.equal(utf8_length('m³'), 3);
  assert.equal(utf8_length('–'), 3);
  assert.equal(utf8_length('😀'), 4);
  assert.equal(utf8_length(JSON.stringify({ type: 'error', message: 'naïve' })), Buffer.byteLength(JSON.stringify({ type: 'error', message: 'naïve' })));
});

test('a full-form snapshot whose columns do not match its ids is refused, not drawn', () => {
  const bodies = { id: [4, 17], position: [0, 0, 0.1, 0.5, -0.25, 1.75], velocity: [0, 0, 0, 1.5, 0, -3.2], radius: [0.1, 0.1] };
  const read = (message) => parse_frame(JSON.stringify({ type: 'snapshot', tick: 3, time: 0.1, ...message }), 0, new CompactStream());
  assert.match(read({ bodies: { ...bodies, position: [0, 0] } }).refused, /position, velocity or radius/);
  assert.match(read({ bodies: { ...bodies, mass: [1] } }).refused, /mass or charge/);
  assert.match(read({ bodies: { ...bodies, radius: [0.1, 'x'] } }).refused, /radius/);
  assert.match(read({ bodies: null }).refused, /without bodies/);
  assert.match(read({ bodies, time: null }).refused, /finite time/);
  assert.equal(read({ bodies }).snapshot.count, 2);
});
