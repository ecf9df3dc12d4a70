// Unit tests for the reconnect backoff, failed attempts, the room URL, the room choice and
// the HUD's words.
import { mock, test } from 'node:test';
import assert from 'node:assert/strict';
import { backoff_delay, ByteRate, Connection, room_url } from '../src/connection.js';
import { choose_room } from '../src/rooms.js';
import { describe_error, format_bytes_rate, Hud } from '../src/hud.js';

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

/** A socket that is open at once and keeps what the page sends. */
class OpenSocket extends FakeSocket {
  constructor(url) {
    super(url);
    this.readyState = 1;
    this.sent = [];
    this.closed_with = null;
  }
  send(text) {
    this.sent.push(JSON.parse(text));
  }
  close(code) {
    this.closed_with = code;
  }
}

function open_connection(options = {}) {
  globalThis.WebSocket = OpenSocket;
  globalThis.performance ??= { now: () => Date.now() };
  mock.timers.enable({ apis: ['setTimeout', 'setInterval'] });
  const refused = [];
  const connection = new Connection({
    url: 'ws://127.0.0.1:8080/ws/arena',
    on_message: () => {},
    on_state: () => {},
    on_refused: (why) => refused.push(why),
    backoff: { initial: 100, max: 100, random: () => 0.5 },
    ...options,
  });
  connection.open();
  return { connection, refused, socket: () => FakeSocket.made.at(-1) };
}

function close_connection(connection) {
  connection.close();
  mock.timers.reset();
  delete globalThis.WebSocket;
}

const welcome = { type: 'welcome', snapshot_rate: 30 };

test('after the first welcome the page asks for compact snapshots at the room\'s rate, once', () => {
  const { connection, socket } = open_connection();
  try {
    connection.receive({ message: welcome });
    const hellos = () => socket().sent.filter((m) => m.type === 'hello');
    assert.deepEqual(hellos(), [{ type: 'hello', protocol: 1, name: 'kugel page', snapshots: { form: 'compact', rate: 30 } }]);
    // The answer: a second welcome saying what comes. No second hello.
    connection.receive({ message: { ...welcome, snapshots: { form: 'compact', rate: 30, position_quantum: 0.001, velocity_quantum: 0.01, keyframe_interval: 5 } } });
    assert.equal(hellos().length, 1);
    assert.equal(connection.granted.form, 'compact');
    assert.equal(connection.socket_welcomes, 2);
  } finally {
    close_connection(connection);
  }
});

test('a server that grants the full form, or ignores the hello, goes on being read in the full form', () => {
  const { connection, socket } = open_connection();
  try {
    connection.receive({ message: welcome });
    connection.receive({ message: { ...welcome, snapshots: { form: 'full', rate: 30 } } });
    const received = [];
    connection.on_message = (message, snapshot) => received.push(snapshot.form);
    connection.receive({ message: { type: 'snapshot', tick: 1 }, snapshot: { form: 'full', received_at: 0 }, bytes: 100, refused: null });
    assert.deepEqual(received, ['full']);
    assert.equal(socket().closed_with, null);
  } finally {
    close_connection(connection);
  }
});

test('a compact snapshot that cannot be applied replaces the socket; after 3 the page asks for the full form', () => {
  const { connection, refused, socket } = open_connection();
  try {
    for (let attempt = 1; attempt <= 3; attempt++) {
      connection.receive({ message: welcome });
      assert.equal(socket().sent.find((m) => m.type === 'hello').snapshots.form, attempt <= 3 ? 'compact' : 'full');
      const old = socket();
      const generation = connection.generation;
      connection.receive({ message: { type: 'snapshot', form: 'delta', tick: 9 }, snapshot: null, bytes: 50, refused: 'a delta against tick 8, and no keyframe came before it' });
      assert.equal(old.closed_with, 1000, `attempt ${attempt}: the socket is closed`);
      assert.ok(connection.generation > generation, 'frames of the old socket still in the worker are dropped');
      assert.equal(connection.state, 'reconnecting');
      mock.timers.tick(100);
      assert.notEqual(socket(), old, 'a new socket');
    }
    assert.equal(refused.length, 3);
    connection.receive({ message: welcome });
    assert.equal(socket().sent.find((m) => m.type === 'hello').snapshots.form, 'full');
  } finally {
    close_connection(connection);
  }
});

test('a refused full-form snapshot is dropped; the socket stays', () => {
  const { connection, refused, socket } = open_connection();
  try {
    connection.receive({ message: welcome });
    connection.receive({ message: { type: 'snapshot', tick: 4 }, snapshot: null, bytes: 50, refused: 'a snapshot without bodies.id' });
    assert.equal(refused.length, 1);
    assert.equal(socket().closed_with, null);
    assert.equal(connection.state, 'connected');
  } finally {
    close_connection(connection);
  }
});

test('a page whose frames wait to be parsed asks for half the rate, not again at once, and twice again after 10 s of keeping up', () => {
  const posted = [];
  globalThis.Worker = class {
    postMessage(data) {
      posted.push(data);
    }
    terminate() {}
  };
  let now = 100;
  const real_performance = globalThis.performance;
  globalThis.performance = { now: () => now * 1000 };
  const { connection, socket } = open_connection({ worker_url: 'parse_worker.js' });
  try {
    connection.receive({ message: welcome });
    connection.receive({ message: { ...welcome, snapshots: { form: 'compact', rate: 30 } } });
    const rates = () => socket().sent.filter((m) => m.type === 'hello').map((m) => m.snapshots.rate);
    // 16 frames arrive and none is back from the worker: over half a second of 30 Hz.
    for (let i = 0; i < 16; i++) socket().onmessage({ data: '{}' });
    assert.equal(connection.in_flight, 16);
    mock.timers.tick(1000);
    assert.deepEqual(rates(), [30], 'not yet a whole second behind');
    mock.timers.tick(1000);
    assert.deepEqual(rates(), [30, 15]);
    now += 1;
    mock.timers.tick(1000);
    assert.deepEqual(rates(), [30, 15], 'still behind, but it just asked');
    // Caught up: no more lowering.
    for (let i = 0; i < 16; i++) connection.worker.onmessage({ data: { generation: connection.generation, parsed: { message: { type: 'pong' }, bytes: 2 } } });
    assert.equal(connection.in_flight, 0);
    now += 5;
    mock.timers.tick(2000);
    assert.deepEqual(rates(), [30, 15]);
    // Kept up from the first check after the catch-up (at 106 s) for 10 s: twice the rate
    // again, up to the room's, and no higher.
    for (let s = 0; s < 9; s++) {
      now += 1;
      mock.timers.tick(1000);
    }
    assert.deepEqual(rates(), [30, 15], 'calm for 9 s');
    now += 1;
    mock.timers.tick(1000);
    assert.deepEqual(rates(), [30, 15, 30], 'calm for 10 s');
    for (let s = 0; s < 30; s++) {
      now += 1;
      mock.timers.tick(1000);
    }
    assert.deepEqual(rates(), [30, 15, 30], 'at the room\'s rate already');
  } finally {
    close_connection(connection);
    delete globalThis.Worker;
    globalThis.performance = real_performance;
  }
});

test('a page\'s own hello fields: all of them on a socket\'s first hello, only the lasting ones later', () => {
  const asked = [];
  const hello = (first_on_socket, welcome) => {
    asked.push([first_on_socket, welcome.client]);
    return first_on_socket ? { name: 'ann', events: true, resume: 'token' } : { name: 'ann' };
  };
  const posted = [];
  globalThis.Worker = class {
    postMessage(data) {
      posted.push(data);
    }
    terminate() {}
  };
  let now = 100;
  const real_performance = globalThis.performance;
  globalThis.performance = { now: () => now * 1000 };
  const { connection, socket } = open_connection({ worker_url: 'parse_worker.js', hello });
  try {
    connection.receive({ message: { ...welcome, client: 9 } });
    const hellos = () => socket().sent.filter((m) => m.type === 'hello');
    assert.deepEqual(hellos(), [{ type: 'hello', protocol: 1, name: 'ann', events: true, resume: 'token', snapshots: { form: 'compact', rate: 30 } }]);
    // The resume's answer (a welcome for the player resumed), then the snapshots' answer.
    connection.receive({ message: { ...welcome, client: 3 } });
    connection.receive({ message: { ...welcome, client: 3, snapshots: { form: 'compact', rate: 30 } } });
    assert.equal(hellos().length, 1);
    // Falling behind: the hello asking for less names the player again, and asks nothing once-only.
    for (let i = 0; i < 16; i++) socket().onmessage({ data: '{}' });
    mock.timers.tick(2000);
    assert.deepEqual(hellos()[1], { type: 'hello', protocol: 1, name: 'ann', snapshots: { form: 'compact', rate: 15 } });
    assert.deepEqual(asked, [[true, 9], [false, 3]]);
  } finally {
    close_connection(connection);
    delete globalThis.Worker;
    globalThis.performance = real_performance;
  }
});

test('bytes per second: what was read since the reading about a second ago', () => {
  const rate = new ByteRate();
  assert.equal(rate.per_second(10.0), null, 'no reading a second old yet');
  rate.add(1000);
  assert.equal(rate.per_second(10.5), null);
  rate.add(500);
  assert.equal(rate.per_second(11.0), 1500, 'since 10.0 s');
  assert.deepEqual(rate.since, [10.0, 0]);
  assert.equal(rate.per_second(11.5), 500, 'since 10.5 s');
  // A page that drew for 3 s and then read 3 s of frames at once: averaged over the 3 s.
  rate.add(3000);
  assert.equal(rate.per_second(14.5), 1000);
  assert.equal(rate.total, 4500);
});

test('the HUD shows bytes per second and the form with its rate', () => {
  const elements = new Map();
  const document = { getElementById: (id) => elements.get(id) ?? elements.set(id, { textContent: '', dataset: {}, style: {} }).get(id) };
  const hud = new Hud(document);
  hud.update({ bytes_per_second: 123456, form: 'compact', snapshots: { form: 'compact', rate: 30 } });
  assert.equal(elements.get('hud-bytes-rate').textContent, '123 kB/s');
  assert.equal(elements.get('hud-form').textContent, 'compact at 30 Hz');
  hud.update({ bytes_per_second: 2.5e6, form: 'full', snapshots: { form: 'compact', rate: 30 } });
  assert.equal(elements.get('hud-bytes-rate').textContent, '2.50 MB/s');
  assert.equal(elements.get('hud-form').textContent, 'full');
  hud.update({ bytes_per_second: null, form: null });
  assert.equal(elements.get('hud-bytes-rate').textContent, '–');
  assert.equal(format_bytes_rate(999), '999 B/s');
});
