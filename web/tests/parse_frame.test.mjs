// Unit tests for reading a frame: JSON, and a snapshot's columns ready to transfer.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { parse_frame, transferables } from '../src/parse_frame.js';

test('a snapshot becomes typed columns, stamped with its arrival, without the JSON arrays', () => {
  const text = JSON.stringify({
    type: 'snapshot', tick: 12, time: 0.2,
    bodies: { id: [4, 17], position: [0, 0, 0.1, 0.5, -0.25, 1.75], velocity: [0, 0, 0, 1.5, 0, -3.2], radius: [0.1, 0.1] },
  });
  const { message, snapshot } = parse_frame(text, 3.5);
  assert.equal(message.type, 'snapshot');
  assert.equal(message.bodies, undefined);
  assert.equal(snapshot.tick, 12);
  assert.equal(snapshot.received_at, 3.5);
  assert.equal(snapshot.count, 2);
  assert.ok(snapshot.position instanceof Float64Array);
  assert.deepEqual(Array.from(snapshot.velocity), [0, 0, 0, 1.5, 0, -3.2]);
  assert.equal(snapshot.mass, null);
  assert.equal(transferables({ message, snapshot }).length, 4);
});

test('other messages pass through; a frame that is not JSON gives null', () => {
  assert.deepEqual(parse_frame('{"type":"pong","ref":5,"tick":7}', 0), { message: { type: 'pong', ref: 5, tick: 7 }, snapshot: null });
  assert.equal(parse_frame('{"type": "p', 0), null);
  assert.deepEqual(transferables(null), []);
});
