// Unit tests for the reconnect backoff, failed attempts, the room URL, the room choice and
// the HUD's words.
import { mock, test } from 'node:test';
import assert from 'node:assert/strict';
import { backoff_delay, Connection, room_url } from '../src/connection.js';
import { choose_room } from '../src/rooms.js';
import { describe_error, Hud } from '../src/hud.js';

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

/** A stand-in for the browser's WebSocket that never opens: the test closes it by hand. */
class FakeSocket {
  static OPEN = 1;
  static made = [];
  constructor(url) {
    this.url = url;
    this.readyState = 0;
    FakeSocket.made.push(this);
  }
  send() {}
  close() {}
}

test('a socket that closes before its welcome is a failed attempt; one that drops after it is not', () => {
  globalThis.WebSocket = FakeSocket;
  mock.timers.enable({ apis: ['setTimeout', 'setInterval'] });
  let failed = 0;
  const connection = new Connection({
    url: 'ws://127.0.0.1:8080/ws/gone',
    on_message: () => {},
    on_state: () => {},
    on_attempt_failed: () => failed++,
    backoff: { initial: 1000, max: 1000, random: () => 0.5 },
  });
  try {
    connection.open();
    FakeSocket.made.at(-1).onclose(); // refused, as an upgrade to a room the server lacks is
    assert.equal(failed, 1);
    assert.equal(connection.state, 'reconnecting');
    mock.timers.tick(1000); // the retry
    assert.equal(FakeSocket.made.length, 2);
    connection.receive({ message: { type: 'welcome' } });
    FakeSocket.made.at(-1).onclose(); // the server went away after the welcome
    assert.equal(failed, 1, 'a drop after a welcome is not a failed attempt');
    assert.equal(connection.state, 'reconnecting');
  } finally {
    connection.close();
    mock.timers.reset();
    delete globalThis.WebSocket;
  }
});

test('the HUD shows the server\'s tick time in ms when a pong gave one, n/a otherwise', () => {
  const elements = new Map();
  const document = { getElementById: (id) => elements.get(id) ?? elements.set(id, { textContent: '', dataset: {}, style: {} }).get(id) };
  const hud = new Hud(document);
  const stats = { tick: 1, bodies: 2, snapshots_per_second: 30, rtt_ms: 1.5, frames_per_second: 60 };
  hud.update({ ...stats, tick_ms: 0.4237 });
  assert.equal(elements.get('hud-tick-time').textContent, '0.42 ms');
  hud.update({ ...stats, tick_ms: null });
  assert.equal(elements.get('hud-tick-time').textContent, 'n/a');
});
