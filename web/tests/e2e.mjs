// End-to-end test of the page, the way a person uses it: kugel-server serves the built page
// and two rooms (the last tests restart it with others), headless Chromium (WebGL through
// SwiftShader) opens it, and Playwright clicks and drags. Screenshots go to --screenshots
// for a person to look at.
//
//   node tests/e2e.mjs --server ../build/release/server/kugel-server \
//       [--web-root dist] [--chromium /usr/bin/chromium] [--screenshots DIR]
//
// Every wait is bounded and says what it was waiting for; no test asserts a wall-clock time.
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import { spawn } from 'node:child_process';
import { existsSync, mkdirSync } from 'node:fs';
import { dirname, join, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';
import { parseArgs } from 'node:util';
import { chromium } from 'playwright-core';

const web = resolve(dirname(fileURLToPath(import.meta.url)), '..');
const { values: options } = parseArgs({
  options: {
    server: { type: 'string', default: join(web, '..', 'build', 'release', 'server', 'kugel-server') },
    'web-root': { type: 'string', default: join(web, 'dist') },
    chromium: { type: 'string', default: '/usr/bin/chromium' },
    screenshots: { type: 'string', default: join(web, '..', 'build', 'release', 'web-screenshots') },
  },
});

const wait_seconds = 30; // the longest any one wait may take
const viewport = { width: 1280, height: 800 };
// Chromium as root in a container, without a GPU and without a network beyond this machine.
const chromium_args = [
  '--no-sandbox',
  '--use-angle=swiftshader', // WebGL in software
  '--enable-unsafe-swiftshader',
  '--disable-background-networking',
  '--disable-component-update',
  '--disable-sync',
  '--no-first-run',
  '--disable-quic',
];

let server = null; // {process, port, log}
let browser = null;
let page = null;
const page_problems = []; // uncaught exceptions and console errors on the page
// Every WebSocket frame the browser received, as Chromium reports it to Playwright (not as
// the page counts it): {at (s, this process's clock), bytes}.
const frames_received = [];

// ---------------------------------------------------------------- the server

const scene_files = {
  gas: join(web, '..', 'scenes', 'gas.json'), // 10,000 spheres, every one moving
  resting: join(web, 'tests', 'resting.json'),
  arena: join(web, '..', 'scenes', 'arena.json'),
  open: join(web, 'tests', 'open.json'), // no walls: nothing for a click to land on
  game: join(web, '..', 'scenes', 'game.json'), // the game mode's pitch
  pile: join(web, '..', 'scenes', 'pile.json'), // 500 spheres dropped into a box: a pile
  obstacles: join(web, '..', 'scenes', 'obstacles.json'), // 300 spheres onto ramps and a floor
};

/** Starts kugel-server with rooms (room name -> scene file); resolves once it logs its port. */
function start_server(port = 0, rooms = { resting: scene_files.resting, arena: scene_files.arena }) {
  const args = ['--port', String(port), '--web-root', options['web-root']];
  for (const [name, file] of Object.entries(rooms)) args.push('--room', `${name}=${file}`);
  const child = spawn(options.server, args, { stdio: ['ignore', 'ignore', 'pipe'] });
  const started = { process: child, port: null, log: '' };
  return new Promise((resolve_start, reject) => {
    const timer = setTimeout(() => reject(new Error(`kugel-server did not log "serving on" within ${wait_seconds} s; its log:\n${started.log}`)), wait_seconds * 1000);
    child.stderr.setEncoding('utf8');
    child.stderr.on('data', (text) => {
      started.log += text;
      const match = started.log.match(/serving on http:\/\/[^:]+:(\d+)\//);
      if (match && started.port === null) {
        started.port = Number(match[1]);
        clearTimeout(timer);
        resolve_start(started);
      }
    });
    child.on('error', (error) => reject(new Error(`cannot start ${options.server}: ${error.message}`)));
    child.on('exit', (code, signal) => {
      if (started.port === null) reject(new Error(`kugel-server exited (${code ?? signal}) before serving; its log:\n${started.log}`));
    });
  });
}

function stop_server(started) {
  if (!started || started.process.exitCode !== null) return Promise.resolve();
  return new Promise((done) => {
    started.process.once('exit', done);
    started.process.kill('SIGTERM');
  });
}

process.on('exit', () => server?.process.kill('SIGKILL'));

// ---------------------------------------------------------------- the page

/**
 * Polls `condition` in the page (a function of window.kugel and `arg`) until it returns a
 * truthy value, which it returns; after `seconds` fails naming what was missing and
 * showing the page's state.
 */
function wait_for(what, condition, arg, seconds = wait_seconds) {
  return wait_on(page, page_problems, what, condition, arg, seconds);
}

/** wait_for on another page than the test's main one; `problems` are that page's. */
async function wait_on(on, problems, what, condition, arg, seconds = wait_seconds) {
  const deadline = Date.now() + seconds * 1000;
  for (;;) {
    const value = await on.evaluate(({ source, arg }) => {
      const f = new Function('kugel', 'arg', `return (${source})(kugel, arg);`);
      return window.kugel ? f(window.kugel, arg) : null;
    }, { source: condition.toString(), arg });
    if (value) return value;
    if (Date.now() > deadline) {
      const state = await on.evaluate(() => (window.kugel ? { ...window.kugel.state, game: window.kugel.game() } : 'window.kugel is not defined'));
      throw new Error(`timed out after ${seconds} s waiting for ${what}\npage state: ${JSON.stringify(state)}\npage problems: ${JSON.stringify(problems)}`);
    }
    await new Promise((r) => setTimeout(r, 100));
  }
}

const state = () => page.evaluate(() => window.kugel.state);
const hud_number = async (id) => Number.parseInt(await page.locator(`#${id}`).textContent(), 10);

async function screenshot(name) {
  const path = join(options.screenshots, `${name}.png`);
  await page.screenshot({ path });
  return path;
}

/** Pixels of the WebGL canvas, read right after the page drew a frame: how many differ from the background, and how many colours. */
function canvas_coverage() {
  return page.evaluate(
    () =>
      new Promise((resolve_coverage) => {
        // Registered after the page's own frame callback, so this runs after it drew.
        requestAnimationFrame(() => {
          const canvas = document.getElementById('view');
          const copy = document.createElement('canvas');
          copy.width = canvas.width;
          copy.height = canvas.height;
          const context = copy.getContext('2d');
          context.drawImage(canvas, 0, 0);
          const pixels = context.getImageData(0, 0, copy.width, copy.height).data;
          const background = [0x12, 0x16, 0x1c];
          let drawn = 0;
          const colours = new Set();
          for (let i = 0; i < pixels.length; i += 4) {
            const d = Math.abs(pixels[i] - background[0]) + Math.abs(pixels[i + 1] - background[1]) + Math.abs(pixels[i + 2] - background[2]);
            if (d > 24) drawn++;
            colours.add((pixels[i] >> 3) * 1024 + (pixels[i + 1] >> 3) * 32 + (pixels[i + 2] >> 3));
          }
          resolve_coverage({ drawn: drawn / (copy.width * copy.height), colours: colours.size, width: copy.width, height: copy.height });
        });
      }),
  );
}

/** A body of the resting room that the page picks when pressed at its centre, and that point. */
async function pickable_body() {
  return wait_for('a sphere of the resting room that is not hidden behind another', (kugel) => {
    const latest = kugel.latest();
    if (!latest) return null;
    for (let i = 0; i < latest.id.length; i++) {
      const [x, y, z] = latest.position.slice(3 * i, 3 * i + 3);
      const point = kugel.screen_of(x, y, z);
      if (kugel.body_at(point.x, point.y) === latest.id[i]) return { id: latest.id[i], x: point.x, y: point.y };
    }
    return null;
  });
}

/**
 * Opens a WebSocket of the browser's own (not the page's) to a room, named `name`, and
 * resolves once the welcome arrived; its close event's code, reason and wasClean are kept for
 * socket_closed(). A client library other than ours: what it reports is what a browser saw.
 */
function open_socket(name, room) {
  return page.evaluate(({ name, url }) => new Promise((resolve_open, reject) => {
    const ws = new WebSocket(url);
    window.test_sockets ??= {};
    const entry = (window.test_sockets[name] = { ws, closed: null });
    ws.onmessage = () => resolve_open(true);
    ws.onclose = (event) => {
      entry.closed = { code: event.code, reason: event.reason, clean: event.wasClean };
      reject(new Error(`closed before the welcome: ${event.code}`));
    };
  }), { name, url: `ws://127.0.0.1:${server.port}/ws/${room}` });
}

/** What the browser reported when the socket `name` closed, once it did. */
function socket_closed(name) {
  return wait_for(`the browser's socket "${name}" to close`, (kugel, name) => window.test_sockets?.[name]?.closed, name);
}

async function open_room(room) {
  await page.goto(`http://127.0.0.1:${server.port}/?room=${room}`);
  // A frame drawn after the welcome: the camera and the floor are where the scene put them
  // (three.js updates their matrices as it draws), so a click lands where the test aims.
  // A slow machine draws a few frames a second: a click before then missed the floor.
  await wait_for(`the page to connect to room "${room}" and draw it`, (kugel, room) => kugel.state.connection === 'connected' && kugel.state.room === room && kugel.state.bodies > 0 && kugel.state.frames >= 2, room);
}

before(async () => {
  for (const [what, path] of [
    ['kugel-server', options.server],
    ['the built page (the normal build runs the bundler)', join(options['web-root'], 'index.html')],
    ['Chromium (script/bootstrap installs Debian\'s chromium)', options.chromium],
  ]) {
    if (!existsSync(path)) throw new Error(`missing ${what}: ${path}`);
  }
  mkdirSync(options.screenshots, { recursive: true });
  server = await start_server();
  // Playwright gives the browser a fresh, empty profile (--user-data-dir) of its own.
  browser = await chromium.launch({ executablePath: options.chromium, headless: true, args: chromium_args });
  page = await browser.newPage({ viewport });
  page.on('pageerror', (error) => page_problems.push(`uncaught: ${error.message}`));
  page.on('console', (message) => {
    if (message.type() === 'error') page_problems.push(`console: ${message.text()} (${message.location().url})`);
  });
  page.on('websocket', (socket) => {
    socket.on('framereceived', ({ payload }) => frames_received.push({ at: performance.now() / 1000, bytes: Buffer.byteLength(payload) }));
  });
});

after(async () => {
  await browser?.close();
  await stop_server(server);
});

// ---------------------------------------------------------------- the tests

test('the page loads, connects and shows the world in its HUD: bodies and an advancing tick', async () => {
  await page.goto(`http://127.0.0.1:${server.port}/`);
  // Two rooms and neither is "default": the page joins the first and offers the other.
  await wait_for('the HUD to show "connected"', () => document.getElementById('hud-connection').textContent === 'connected');
  await wait_for('bodies > 0 in the HUD', () => Number.parseInt(document.getElementById('hud-bodies').textContent, 10) > 0);
  const first_tick = await hud_number('hud-tick');
  await wait_for(`the HUD's tick to advance past ${first_tick}`, (kugel, first) => Number.parseInt(document.getElementById('hud-tick').textContent, 10) > first, first_tick);
  const s = await state();
  assert.equal(s.room, 'arena');
  assert.equal(s.bodies, 400);
  assert.deepEqual(s.rooms, ['arena', 'resting']);
  assert.equal(s.parser, 'worker', 'snapshots are parsed off the main thread');
  await wait_for('compact deltas after a keyframe', (kugel) => kugel.state.form === 'compact' && kugel.state.keyframes > 0 && kugel.state.deltas > 0);
  const granted = (await state()).snapshots;
  assert.equal(granted.form, 'compact');
  assert.equal(granted.rate, s.room_snapshot_rate, 'the page asks for the room\'s rate');
  assert.match(await page.locator('#hud-form').textContent(), /^compact at \d+ Hz$/);
  await wait_for('a round trip time in the HUD', () => /ms$/.test(document.getElementById('hud-rtt').textContent));
  assert.ok(await page.locator('#room-picker').isVisible(), 'a room picker when the server hosts several rooms');
});

test('the HUD lists the room\'s players: a second page joining shows on the first, and leaving goes', async () => {
  await wait_for('the HUD to list this page', (kugel) => kugel.state.me !== null && kugel.state.players.some((p) => p.id === kugel.state.me));
  const before = (await state()).players.length;
  const second = await browser.newPage({ viewport: { width: 320, height: 240 } });
  await second.goto(`http://127.0.0.1:${server.port}/`);
  await second.waitForFunction(() => window.kugel?.state.me !== null && window.kugel?.state.connection === 'connected');
  const second_id = await second.evaluate(() => window.kugel.state.me);
  await wait_for('the second page in the first page\'s players', (kugel, id) => kugel.state.players.some((p) => p.id === id && p.name === 'kugel page'), second_id);
  assert.equal((await state()).players.length, before + 1);
  assert.match(await page.locator('#hud-players').textContent(), new RegExp(`^${before + 1}: .*you.*kugel page`));
  await second.close();
  await wait_for('the second page gone from the first page\'s players', (kugel, id) => !kugel.state.players.some((p) => p.id === id), second_id);
});

test('the HUD shows the server\'s tick time, which its pongs carry', async () => {
  // What the server answers a ping, read on a socket of the test's own: if the HUD shows no
  // tick time, this says whether the server sent none or the page did not show it.
  await open_socket('pong', 'arena');
  const pong = await page.evaluate((seconds) => new Promise((resolve_pong) => {
    const { ws } = window.test_sockets.pong;
    setTimeout(() => resolve_pong(null), seconds * 1000);
    ws.onmessage = (event) => {
      const message = JSON.parse(event.data);
      if (message.type === 'pong') resolve_pong(message);
    };
    ws.send(JSON.stringify({ type: 'ping', ref: 7 }));
  }), wait_seconds);
  await page.evaluate(() => window.test_sockets.pong.ws.close(1000));
  assert.ok(pong, `no pong within ${wait_seconds} s`);
  assert.equal(typeof pong.tick_ms, 'number', `the server's pong carries no tick_ms: ${JSON.stringify(pong)}`);
  const shown = await wait_for('a number of milliseconds under "server tick" in the HUD', () => {
    const text = document.getElementById('hud-tick-time').textContent;
    return /^\d+(\.\d+)? ms$/.test(text) ? text : null;
  });
  assert.equal(typeof (await state()).tick_ms, 'number', `kugel.state.tick_ms while the HUD shows ${shown}`);
});

test('the compact form decodes to the full form\'s positions to the quantum, tick by tick', async () => {
  // A socket of the test's own asks for nothing: it gets the full form. For the ticks both
  // received, every body the page decoded is at the full form's position quantized, exactly.
  await open_socket('full', 'arena');
  await page.evaluate(() => {
    window.full_snapshots = new Map();
    window.test_sockets.full.ws.onmessage = (event) => {
      const message = JSON.parse(event.data);
      if (message.type !== 'snapshot') return;
      window.full_snapshots.set(message.tick, message.bodies);
      if (window.full_snapshots.size > 90) window.full_snapshots.delete(window.full_snapshots.keys().next().value);
    };
  });
  let compared = 0;
  const ticks = new Set();
  while (ticks.size < 5) {
    const result = await wait_for('a tick the page decoded and the full-form socket received', () => {
      const latest = kugel.latest();
      const full = latest && window.full_snapshots.get(latest.tick);
      if (!full) return null;
      const [qp, qv] = [kugel.state.snapshots.position_quantum, kugel.state.snapshots.velocity_quantum];
      const wrong = [];
      const index = new Map(full.id.map((id, i) => [id, i]));
      for (let k = 0; k < latest.id.length; k++) {
        const i = index.get(latest.id[k]);
        if (i === undefined) wrong.push(`body ${latest.id[k]} is not in the full form`);
        for (let d = 0; d < 3; d++) {
          const p = Math.floor(full.position[3 * i + d] / qp + 0.5) * qp;
          const v = Math.floor(full.velocity[3 * i + d] / qv + 0.5) * qv;
          if (latest.position[3 * k + d] !== p || latest.velocity[3 * k + d] !== v) wrong.push(`body ${latest.id[k]}: ${latest.position.slice(3 * k, 3 * k + 3)} for ${full.position.slice(3 * i, 3 * i + 3)}`);
        }
      }
      return { tick: latest.tick, bodies: latest.id.length, full_bodies: full.id.length, wrong: wrong.slice(0, 5) };
    });
    assert.deepEqual(result.wrong, [], `tick ${result.tick}`);
    assert.equal(result.bodies, result.full_bodies);
    ticks.add(result.tick);
    compared += result.bodies;
    await new Promise((r) => setTimeout(r, 200));
  }
  await page.evaluate(() => window.test_sockets.full.ws.close(1000));
  assert.ok(compared >= 5 * 400, `${compared} bodies compared`);
});

test('the canvas draws the scene: not blank, many colours', async () => {
  await wait_for('frames drawn with bodies', (kugel) => kugel.state.frames >= 3);
  const coverage = await canvas_coverage();
  await screenshot('arena');
  assert.ok(coverage.drawn > 0.05, `only ${(100 * coverage.drawn).toFixed(2)} % of the ${coverage.width}x${coverage.height} canvas differs from the background`);
  assert.ok(coverage.colours > 50, `only ${coverage.colours} distinct colours on the canvas`);
});

test('the room picker switches rooms', async () => {
  await page.locator('#room-picker').selectOption('resting');
  await wait_for('the page to join room "resting" with its 9 bodies', (kugel) => kugel.state.room === 'resting' && kugel.state.scene === 'resting' && kugel.state.bodies === 9);
  assert.match(page.url(), /\?room=resting$/);
});

test('a room that does not exist is named on the page, with the rooms there are', async () => {
  await page.goto(`http://127.0.0.1:${server.port}/?room=nosuch`);
  const message = page.locator('#messages .message', { hasText: 'nosuch' });
  await message.waitFor({ state: 'visible', timeout: wait_seconds * 1000 });
  assert.match(await message.textContent(), /There is no room "nosuch" here; the rooms are arena, resting\. Showing "arena"\./);
  await wait_for('the page to open room "arena" instead', (kugel) => kugel.state.room === 'arena' && kugel.state.connection === 'connected');
});

test('a click on the floor spawns a sphere there, and the server confirms it', async () => {
  await open_room('resting');
  const before_count = (await state()).bodies;
  const floor = await page.evaluate(() => window.kugel.screen_of(2, -2, 0));
  await page.mouse.click(floor.x, floor.y);
  const ack = await wait_for('an ack of the spawn with the new body\'s id', (kugel) => kugel.state.acks.find((a) => a.command === 'spawn' && a.id !== null));
  await wait_for(`the body count to rise from ${before_count}`, (kugel, n) => kugel.state.bodies === n + 1, before_count);
  const body = await wait_for(`body ${ack.id} in a snapshot`, (kugel, id) => kugel.body(id), ack.id);
  const radius = Number(await page.locator('#spawn-radius').inputValue());
  assert.ok(Math.abs(body.position[0] - 2) < 0.05 && Math.abs(body.position[1] + 2) < 0.05, `spawned at ${body.position}, clicked at (2, -2, 0)`);
  assert.ok(Math.abs(body.position[2] - radius) < 0.05 * radius + 1e-9, `resting on the floor: z = ${body.position[2]}, radius ${radius}`);
  await wait_for(`the HUD to show ${before_count + 1} bodies`, (kugel, n) => document.getElementById('hud-bodies').textContent === String(n), before_count + 1);
  await screenshot('spawned');
});

test('a drag from a sphere pushes it: its velocity changes in the next snapshots', async () => {
  const target = await pickable_body();
  const before_push = await page.evaluate((id) => window.kugel.body(id), target.id);
  assert.deepEqual(before_push.velocity, [0, 0, 0], 'the resting room\'s spheres are at rest');
  await page.mouse.move(target.x, target.y);
  await page.mouse.down();
  await page.mouse.move(target.x - 160, target.y - 40, { steps: 8 });
  await wait_for('the push label while dragging', () => !document.getElementById('push-label').hidden);
  await screenshot('dragging');
  await page.mouse.up();
  const ack = await wait_for('an ack of the impulse', (kugel) => kugel.state.acks.find((a) => a.command === 'impulse'));
  const moving = await wait_for(`body ${target.id} moving in a snapshot after tick ${ack.tick}`, (kugel, { id, tick }) => {
    const latest = kugel.latest();
    const body = kugel.body(id);
    if (!latest || latest.tick < tick || !body) return null;
    const speed = Math.hypot(...body.velocity);
    return speed > 0.5 ? { speed, velocity: body.velocity } : null;
  }, { id: target.id, tick: ack.tick });
  assert.ok(moving.speed > 0.5, `speed ${moving.speed} m/s after the push`);
  await screenshot('pushed');
});

test('a press and release on a sphere without moving is a click, not a push', async () => {
  const target = await pickable_body();
  const impulses_before = (await state()).acks.filter((a) => a.command === 'impulse').length;
  const spawn_answers = async () => {
    const s = await state();
    return s.acks.filter((a) => a.command === 'spawn').length + s.errors.filter((e) => e.command === 'spawn').length;
  };
  const spawns_before = await spawn_answers();
  await page.mouse.click(target.x, target.y);
  // The click is meant for the surface behind the sphere: a spawn is answered (an ack, or an
  // error if the sphere there is in the way), and no impulse is sent.
  await wait_for('an answer to the spawn the click made', (kugel, n) =>
    kugel.state.acks.filter((a) => a.command === 'spawn').length + kugel.state.errors.filter((e) => e.command === 'spawn').length > n,
  spawns_before);
  const impulses_after = (await state()).acks.filter((a) => a.command === 'impulse').length;
  assert.equal(impulses_after, impulses_before, 'a click in place sent an impulse');
});

test('a refused command shows a readable message on the page', async () => {
  // A sphere wider than the box cannot be put anywhere in it.
  await page.locator('#spawn-radius').fill('4');
  const floor = await page.evaluate(() => window.kugel.screen_of(-2, 2, 0));
  const earlier = (await state()).errors.length; // an earlier test's click may have been refused
  await page.mouse.click(floor.x, floor.y);
  const error = await wait_for('an error answering the spawn', (kugel, n) => kugel.state.errors.slice(n).find((e) => e.command === 'spawn'), earlier);
  assert.equal(error.code, 'overlaps_wall');
  const message = page.locator('#messages .message').last();
  await message.waitFor({ state: 'visible', timeout: wait_seconds * 1000 });
  assert.match(await message.textContent(), /Spawn refused: the sphere would cross a wall or an obstacle/);
  await screenshot('refused');
  await page.locator('#spawn-radius').fill('0.25');
});

test('a frame over the server\'s limit reaches the browser as close code 1009, not 1006', async () => {
  // 4 MiB against the default limit of 64 KiB: most of it is still arriving when the server
  // closes, and unless the server reads it away the connection is reset and the close lost.
  await open_socket('oversized', 'resting');
  await page.evaluate(() => window.test_sockets.oversized.ws.send('x'.repeat(4 << 20)));
  const closed = await socket_closed('oversized');
  assert.deepEqual(closed, { code: 1009, reason: 'message too big', clean: true });
});

test('the page reconnects by itself when the server restarts', async () => {
  const port = server.port;
  const welcomes = (await state()).welcomes;
  await open_socket('shutdown', 'arena');
  await stop_server(server);
  // A server that shuts down closes every connection with 1001 (going away), in a handshake.
  assert.deepEqual(await socket_closed('shutdown'), { code: 1001, reason: 'server shutting down', clean: true });
  await wait_for('the HUD to say it is reconnecting', () => document.getElementById('hud-connection').textContent.startsWith('reconnecting'));
  server = await start_server(port);
  await wait_for('a new welcome after the restart', (kugel, n) => kugel.state.welcomes > n && kugel.state.connection === 'connected', welcomes);
  await wait_for('the restarted room\'s 9 bodies', (kugel) => kugel.state.room === 'resting' && kugel.state.bodies === 9);
  assert.equal(await page.locator('#hud-connection').textContent(), 'connected');
});

test('a room the restarted server no longer hosts: the page says so and joins one it has', async () => {
  const port = server.port;
  assert.equal((await state()).room, 'resting');
  await stop_server(server);
  await wait_for('the HUD to say it is reconnecting', () => document.getElementById('hud-connection').textContent.startsWith('reconnecting'));
  // The server comes back without "resting": it answers /ws/resting with 404.
  server = await start_server(port, { arena: scene_files.arena, open: scene_files.open });
  const message = page.locator('#messages .message', { hasText: 'no longer' });
  await message.waitFor({ state: 'visible', timeout: wait_seconds * 1000 });
  assert.match(await message.textContent(), /Room "resting" is no longer on the server; the rooms are arena, open\. Showing "arena"\./);
  await wait_for('the page to join room "arena" instead', (kugel) => kugel.state.room === 'arena' && kugel.state.scene === 'arena' && kugel.state.connection === 'connected');
  assert.deepEqual((await state()).rooms, ['arena', 'open']);
  assert.equal(await page.locator('#room-picker').inputValue(), 'arena');
  assert.match(page.url(), /\?room=arena$/);
});

test('a click on open space in a scene without walls spawns a sphere as far away as the scene\'s centre', async () => {
  await open_room('open');
  const { bounds, bodies } = await state();
  // The ray through the centre's screen point meets the plane through the centre facing the
  // camera at the centre itself, and nowhere else: a sphere there was put at the centre's depth.
  const aim = await page.evaluate((c) => window.kugel.screen_of(...c), bounds.centre);
  assert.equal(await page.evaluate(({ x, y }) => window.kugel.body_at(x, y), aim), null, 'a sphere is drawn where the test clicks');
  await page.mouse.click(aim.x, aim.y);
  const ack = await wait_for('an ack of the spawn with the new body\'s id', (kugel) => kugel.state.acks.find((a) => a.command === 'spawn' && a.id !== null));
  const body = await wait_for(`body ${ack.id} in a snapshot`, (kugel, id) => kugel.body(id), ack.id);
  const off = Math.hypot(...body.position.map((x, k) => x - bounds.centre[k]));
  assert.ok(off < 0.01, `spawned at ${body.position}, ${off} m from the scene's centre ${bounds.centre}`);
  await wait_for(`the body count to rise from ${bodies}`, (kugel, n) => kugel.state.bodies === n + 1, bodies);
  await screenshot('open-space');
});

/** The scoreboard a page shows: each row's name, score and colour, top to bottom. */
function scoreboard_of(on) {
  return on.evaluate(() =>
    [...document.querySelectorAll('#scoreboard li')].map((li) => ({
      name: li.querySelector('.name').textContent,
      score: li.querySelector('.score').textContent,
      colour: li.querySelector('.swatch').style.backgroundColor,
    })),
  );
}

test('the game: two pages play at once, each pushes its own ball into the goal with the mouse, and each shows both scores', async () => {
  // A server of its own, with the game's room: the pages are its first two players. The
  // test's main page waits on a blank page meanwhile, so that three pages drawing in
  // software do not share two cores.
  await page.goto('about:blank');
  const game_server = await start_server(0, { game: scene_files.game });
  const players = [];
  try {
    for (const name of ['ann', 'bob']) {
      const player_page = await browser.newPage({ viewport: { width: 800, height: 600 } });
      const problems = [];
      player_page.on('pageerror', (error) => problems.push(`uncaught: ${error.message}`));
      player_page.on('console', (message) => {
        if (message.type() === 'error') problems.push(`console: ${message.text()}`);
      });
      players.push({ name, page: player_page, problems });
    }
    const [ann, bob] = players;
    await Promise.all(players.map((p) => p.page.goto(`http://127.0.0.1:${game_server.port}/?room=game&game&name=${p.name}`)));
    // Each page names itself, spawns its ball, and lists both players.
    for (const p of players) {
      p.me = (await wait_on(p.page, p.problems, `${p.name}'s ball in its page's snapshots and both players named`, (kugel) => {
        const game = kugel.game();
        const named = game.scoreboard.map((row) => row.name).sort().join();
        return game.ball !== null && kugel.body(game.ball) && named === 'ann,bob' && game;
      })).me;
    }
    assert.notEqual(ann.me, bob.me);
    for (const p of players) {
      // Nobody scored yet: both at 0, on both pages.
      const rows = await scoreboard_of(p.page);
      assert.deepEqual(rows.map((row) => [row.name, row.score]).sort(), [['ann', '0'], ['bob', '0']].map(([n, s]) => [n === p.name ? `${n} (you)` : n, s]).sort());
    }

    for (const p of players) {
      // The ball at rest on its start spot, drawn where the pointer can take it.
      const aim = await wait_on(p.page, p.problems, `${p.name}'s ball at rest on its spot, under the pointer`, (kugel) => {
        const { ball } = kugel.game();
        const body = ball === null ? null : kugel.body(ball);
        if (!body || body.velocity.some((v) => v !== 0) || body.position[0] > -4) return null;
        const point = kugel.screen_of(...body.position);
        const on_canvas = document.elementFromPoint(point.x, point.y)?.id === 'view'; // no panel over it
        return on_canvas && kugel.body_at(point.x, point.y) === ball ? { ball, x: point.x, y: point.y, at: body.position } : null;
      });
      const goal = await p.page.evaluate(() => window.kugel.screen_of(7.25, 0, 0));
      const impulses = (await p.page.evaluate(() => window.kugel.state.acks.filter((a) => a.command === 'impulse').length));
      // A drag from the ball to the middle of the goal: a push along the ground towards it.
      await p.page.mouse.move(aim.x, aim.y);
      await p.page.mouse.down();
      await p.page.mouse.move(goal.x, goal.y, { steps: 8 });
      await p.page.mouse.up();
      await wait_on(p.page, p.problems, `the ack of ${p.name}'s push`, (kugel, n) => kugel.state.acks.filter((a) => a.command === 'impulse').length > n, impulses);
      // Both pages see the goal, and give it to this page's player.
      for (const q of players) {
        await wait_on(q.page, q.problems, `${p.name}'s goal on ${q.name}'s page`, (kugel, id) => kugel.game().scores[id] === 1, p.me);
      }
      // Its page put the ball back on its spot: at rest, out of the other ball's way.
      await wait_on(p.page, p.problems, `${p.name}'s ball back on its spot after the goal`, (kugel, ball) => {
        const body = kugel.body(ball);
        return body && body.velocity.every((v) => v === 0) && body.position[0] < -4;
      }, aim.ball);
      await p.page.screenshot({ path: join(options.screenshots, `game-${p.name}-scored.png`) });
    }

    // Each page shows its own score and the other's, by name, in the same colours.
    const boards = await Promise.all(players.map((p) => scoreboard_of(p.page)));
    for (const [i, p] of players.entries()) {
      const rows = boards[i];
      const own = rows.find((row) => row.name === `${p.name} (you)`);
      const other = rows.find((row) => row.name === players[1 - i].name);
      assert.ok(own && other, `${p.name}'s page shows ${JSON.stringify(rows)}`);
      assert.equal(own.score, '1', `${p.name}'s own score on its page`);
      assert.equal(other.score, '1', `${players[1 - i].name}'s score on ${p.name}'s page`);
      assert.equal(rows.length, 2);
    }
    const colour = (rows, name) => rows.find((row) => row.name.startsWith(name)).colour;
    assert.equal(colour(boards[0], 'ann'), colour(boards[1], 'ann'), 'ann in one colour on both pages');
    assert.equal(colour(boards[0], 'bob'), colour(boards[1], 'bob'), 'bob in one colour on both pages');
    assert.notEqual(colour(boards[0], 'ann'), colour(boards[0], 'bob'));
    // The keys: up pushes the ball towards the goal (the camera looks from behind the start
    // spots), space stops it again.
    const { ball } = await ann.page.evaluate(() => window.kugel.game());
    await ann.page.keyboard.press('ArrowUp');
    const pushed = await wait_on(ann.page, ann.problems, 'ann\'s ball moving towards the goal after ArrowUp', (kugel, id) => {
      const body = kugel.body(id);
      return body && body.velocity[0] > 1 && body.velocity;
    }, ball);
    assert.ok(Math.abs(pushed[1]) < 1e-6 && pushed[2] === 0, `ArrowUp pushed along +x, the ball moves at ${pushed}`);
    await ann.page.keyboard.press(' ');
    await wait_on(ann.page, ann.problems, 'ann\'s ball at rest after space', (kugel, id) => {
      const body = kugel.body(id);
      return body && Math.hypot(...body.velocity) < 0.05;
    }, ball);
    for (const p of players) {
      const final = await p.page.evaluate(() => window.kugel.game());
      assert.deepEqual(final.scores, { [ann.me]: 1, [bob.me]: 1 }, `${p.name}'s page counted ${JSON.stringify(final.goals)}`);
      assert.deepEqual(p.problems, [], `${p.name}'s page`);
    }
  } finally {
    for (const p of players) await p.page.close();
    await stop_server(game_server);
  }
});

test('the scenes that pile up come to rest on the page: every sphere still, drawn where it lies, none sunk into another', async () => {
  // A server of its own with the two scenes that pile up in discrete mode (both asleep after
  // about 7 s of their time, run headless); the page watches each until the newest snapshot
  // shows every sphere still. In the compact form the page asks for: the full snapshots a
  // socket gets before its hello is answered hold the exact doubles, the compact ones the
  // same positions to the quantum, so the first compact one may differ from them.
  const pile_server = await start_server(0, { pile: scene_files.pile, obstacles: scene_files.obstacles });
  try {
    for (const [room, count] of [['pile', 500], ['obstacles', 300]]) {
      await page.goto(`http://127.0.0.1:${pile_server.port}/?room=${room}`);
      // A second after a snapshot with every sphere still, the world has ticked on and nothing
      // has moved: the same positions in the newest snapshot, and the last frame drew exactly
      // those (to the float32 of the instance matrices, 6e-8 of a coordinate: 1e-6 m is ample
      // in boxes a few metres wide). Still in a compact snapshot means slower than its velocity
      // quantum, which a pile whose spheres all crawl below it is before it sleeps, and it may
      // then move by a position quantum: until the deadline, such a second starts the wait again.
      const deadline = Date.now() + 4 * wait_seconds * 1000;
      let still, later, shown;
      for (;;) {
        still = await wait_for(`every sphere of room "${room}" still in the page's newest snapshot, and all ${count} drawn`, (kugel, { room, n }) => {
          const s = kugel.latest();
          return kugel.state.room === room && kugel.state.form === 'compact' && s && s.id.length === n && kugel.drawn() === n && s.velocity.every((v) => v === 0) && s;
        }, { room, n: count }, 4 * wait_seconds);
        await new Promise((r) => setTimeout(r, 1000));
        ({ later, shown } = await page.evaluate(() => ({ later: window.kugel.latest(), shown: window.kugel.shown() })));
        if (JSON.stringify(later.position) === JSON.stringify(still.position) || Date.now() > deadline) break;
      }
      const quantum = (await state()).snapshots.position_quantum ?? 0;
      assert.ok(later.tick > still.tick, `${room}: the tick moved on (${still.tick} -> ${later.tick})`);
      assert.deepEqual(later.id, still.id, room);
      assert.deepEqual(later.position, still.position, `${room}: a sphere moved while at rest`);
      assert.deepEqual(shown.id, later.id, room);
      const drawn_off = Math.max(...shown.position.map((x, k) => Math.abs(x - later.position[k])));
      assert.ok(drawn_off <= 1e-6, `${room}: a sphere drawn ${drawn_off} m from where the snapshot has it`);
      // No sphere sunk into another by more than the issue's bound, 0.05 of the smaller
      // radius, plus what the snapshot's quantum can add to a distance (half a quantum in
      // each of three coordinates of two centres: sqrt(3) quanta).
      const radius = shown.radius;
      let deepest = 0;
      for (let i = 0; i < count; i++) {
        for (let j = i + 1; j < count; j++) {
          const d = Math.hypot(...[0, 1, 2].map((a) => later.position[3 * i + a] - later.position[3 * j + a]));
          deepest = Math.max(deepest, (radius[i] + radius[j] - d) / Math.min(radius[i], radius[j]));
        }
      }
      const bound = 0.05 + Math.sqrt(3) * quantum / Math.min(...radius);
      assert.ok(deepest <= bound, `${room}: spheres overlap by ${deepest} of a radius (at most ${bound})`);
      await screenshot(room);
    }
  } finally {
    await page.goto('about:blank');
    await stop_server(pile_server);
  }
});

/**
 * The bytes/s the HUD shows, as a number (rate), when the HUD showed it (at, s on the page's
 * clock), the bytes the page had counted then (bytes), and the page's reading the rate was
 * measured from (since: [s, bytes]): all from one HUD update, the first after this asks.
 */
async function hud_bytes_reading() {
  const [text, at, bytes, since] = await page.evaluate(() => new Promise((resolve) => {
    const asked = performance.now() / 1000;
    const poll = () => {
      const s = window.kugel.state;
      if (s.hud_at > asked) resolve([document.getElementById('hud-bytes-rate').textContent, s.hud_at, s.bytes_received, s.bytes_rate_since]);
      else setTimeout(poll, 50);
    };
    poll();
  }));
  const match = text.match(/^([\d.]+) (B|kB|MB)\/s$/);
  if (!match) {
    const s = await state();
    assert.fail(`the HUD shows "${text}" as bytes received; connection ${s.connection}, welcomes ${s.welcomes}, refused ${JSON.stringify(s.refused)}`);
  }
  return { rate: Number(match[1]) * { B: 1, kB: 1e3, MB: 1e6 }[match[2]], at, bytes, since };
}

/** A room's counters from the server's /metrics: {name: value} for the lines labelled with the room. */
async function room_metrics(room) {
  const text = await (await fetch(`http://127.0.0.1:${server.port}/metrics`)).text();
  const values = {};
  for (const line of text.split('\n')) {
    const match = line.match(/^(\w+)\{([^}]*)\} (\S+)$/);
    if (!match || !match[2].includes(`room="${room}"`)) continue;
    const kind = match[2].match(/kind="(\w+)"/);
    values[kind ? `${match[1]}:${kind[1]}` : match[1]] = Number(match[3]);
  }
  return values;
}

test('a 10,000-body room at the room\'s snapshot rate in the compact form: every body drawn, every snapshot read, bytes/s as received', async () => {
  const port = server.port;
  await stop_server(server);
  server = await start_server(port, { gas: scene_files.gas, arena: scene_files.arena });
  // A smaller canvas: Chromium draws in software here, and ten thousand spheres on a large
  // one keep the page from reading for long enough that the server drops it as stalled.
  await page.setViewportSize({ width: 640, height: 400 });
  const frames_at_load = frames_received.length;
  await page.goto(`http://127.0.0.1:${server.port}/?room=gas`);
  await wait_for('the page to draw all 10,000 bodies of room "gas" from compact snapshots', (kugel) =>
    kugel.state.room === 'gas' && kugel.state.connection === 'connected' && kugel.state.bodies === 10000 && kugel.drawn() === 10000 && kugel.state.form === 'compact' && kugel.state.deltas > 0,
  null, 2 * wait_seconds);
  await wait_for('bytes per second in the HUD', () => /B\/s$/.test(document.getElementById('hud-bytes-rate').textContent));
  // A window of the run: what the page read and counted, and what its HUD showed.
  const window_snapshots = 60;
  const start_at = performance.now() / 1000;
  const start = await state();
  const hud_samples = [await hud_bytes_reading()];
  let end = start;
  while ((end.snapshots_read < start.snapshots_read + window_snapshots || performance.now() / 1000 - start_at < 6) && performance.now() / 1000 - start_at < 4 * wait_seconds) {
    await new Promise((r) => setTimeout(r, 200));
    hud_samples.push(await hud_bytes_reading());
    end = await state();
  }
  const seconds = performance.now() / 1000 - start_at;
  const read = end.snapshots_read - start.snapshots_read;
  // On the page's clock, between the HUD's first and last readings: the bytes it counted.
  const first = hud_samples[0];
  const last = hud_samples[hud_samples.length - 1];
  const page_rate = (last.bytes - first.bytes) / (last.at - first.at);
  // What the server handed to the page's socket since it started (the page is the room's only
  // client, and this page load its only connection): every snapshot of it read in the end.
  // The counter counts a snapshot when it is handed to the socket; one replaced unsent (the
  // dropped counter) was never handed, so it is not in it and not subtracted.
  const counters = await room_metrics('gas');
  const written = counters['kugel_messages_out_total:snapshot'];
  const caught_up = await wait_for(`the page to read the ${written} snapshots the server wrote to it`, (kugel, n) => kugel.state.snapshots_read >= n && kugel.state, written);
  const chromium = frames_received.slice(frames_at_load).reduce((sum, f) => sum + f.bytes, 0);
  const biggest = Math.max(...frames_received.slice(frames_at_load).map((f) => f.bytes));
  const report = `${read} snapshots read in ${seconds.toFixed(1)} s (${end.keyframes - start.keyframes} keyframes); since the start the server wrote ${written}, ` +
    `dropped ${counters.kugel_snapshots_dropped_total} for a slow reader, skipped ${counters.kugel_snapshots_skipped_total} while encoding, over ${caught_up.tick} ticks; ` +
    `bytes: server ${counters.kugel_bytes_out_total}, Chromium ${chromium}, page ${caught_up.bytes_read}; page ${page_rate.toPrecision(3)} B/s, HUD ${hud_samples.map((h) => `${h.rate.toPrecision(3)} at ${h.at.toFixed(1)} s`).join(', ')} B/s`;
  console.log(`# ${report}`);
  // Compact, at the room's rate: granted, and the page did not have to ask for less.
  assert.equal(end.snapshots.form, 'compact');
  assert.equal(end.snapshots.rate, start.room_snapshot_rate, report);
  assert.equal(end.asked_rate, start.room_snapshot_rate, report);
  assert.ok(read >= window_snapshots, report);
  assert.ok(written >= read, report); // the page read no snapshot the server did not hand it
  // (Snapshots the server dropped while the page was busy starting, or skipped while it
  // encoded on a machine the browser keeps busy, are in the report, not asserted: neither
  // is the page's reading.)
  // Every body, in the newest snapshot and on the canvas.
  assert.deepEqual(await page.evaluate(() => [window.kugel.state.bodies, window.kugel.drawn(), window.kugel.latest().id.length]), [10000, 10000, 10000]);
  // The page counted the bytes the server sent and Chromium received (up to the frames on
  // their way), and its HUD shows about what it read per second. (The bytes as counted when
  // it read its latest snapshot: the HUD's own count waits for its timer, which a busy
  // Chromium may hold back for seconds while the snapshots are read.)
  assert.ok(Math.abs(caught_up.bytes_read - counters.kugel_bytes_out_total) <= 4 * biggest, report);
  assert.ok(Math.abs(caught_up.bytes_read - chromium) <= 4 * biggest, report);
  // Each reading shows what the page counted since an earlier reading of its own, at least a
  // second before, over the time between (to the three digits shown): the HUD says what the
  // page read per second. Not asked: that it read evenly. Chromium drawing in software here
  // sometimes stops reading for seconds, and then reads them at once.
  for (const h of hud_samples) {
    const [then, counted] = h.since;
    const read_rate = (h.bytes - counted) / (h.at - then);
    assert.ok(h.at - then >= 1, `a HUD rate over ${h.at - then} s; ${report}`);
    assert.ok(Math.abs(h.rate - read_rate) <= Math.max(0.01 * read_rate, 1), `HUD ${h.rate} B/s at ${h.at} s against ${read_rate} B/s read since ${then} s; ${report}`);
  }
  await screenshot('gas');
});

test('nothing went wrong on the page', () => {
  // Chromium logs each refused connection attempt while the server restarts, and each read
  // of the room list the page tries after one: expected.
  const unexpected = page_problems.filter((p) => !/WebSocket connection to .* failed/.test(p) && !/Failed to load resource: net::ERR_CONNECTION_REFUSED \(.*\/healthz\)$/.test(p));
  assert.deepEqual(unexpected, []);
});
