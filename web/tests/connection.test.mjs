// Unit tests for the reconnect backoff, the room URL and the room choice.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { backoff_delay, room_url } from '../src/connection.js';
import { choose_room } from '../src/rooms.js';
import { describe_error } from '../src/hud.js';

test('the backoff doubles from 250 ms up to 5 s, within +-20 %', () => {
  const middle = { random: () => 0.5 };
  assert.deepEqual([0, 1, 2, 3, 4, 5, 10].map((a) => backoff_delay(a, middle)), [250, 500, 1000, 2000, 4000, 5000, 5000]);
  assert.equal(backoff_delay(0, { random: () => 0 }), 200);
  assert.ok(Math.abs(backoff_delay(0, { random: () => 1 }) - 300) < 1e-9);
});

test('the room URL is on the page\'s own host', () => {
  assert.equal(room_url('pile', { protocol: 'http:', host: '127.0.0.1:8080' }), 'ws://127.0.0.1:8080/ws/pile');
  assert.equal(room_url('a b', { protocol: 'https:', host: 'example.org' }), 'wss://example.org/ws/a%20b');
});

test('the room asked for, else default, else the first', () => {
  assert.equal(choose_room(['arena', 'resting'], 'resting'), 'resting');
  assert.equal(choose_room(['arena', 'default'], 'nowhere'), 'default');
  assert.equal(choose_room(['arena', 'resting'], null), 'arena');
  assert.equal(choose_room([], 'pile'), 'pile', '/healthz unreadable: trust the URL');
  assert.equal(choose_room([], null), 'default');
});

test('a refusal reads as a sentence that names the command', () => {
  const { headline, code } = describe_error({ code: 'overlaps_wall', message: '/body/position: ...' }, 'spawn');
  assert.equal(headline, 'Spawn refused: the sphere would cross a wall or an obstacle');
  assert.equal(code, 'overlaps_wall');
  assert.equal(describe_error({ code: 'bad_json', message: '/: not valid JSON' }, null).headline, 'The server refused a message: /: not valid JSON');
  assert.equal(describe_error({ code: 'not_connected', message: '' }, 'impulse').headline, 'Impulse not sent: the page is not connected to the server');
});
