// Unit tests for the snapshot buffer, Hermite interpolation and the playback clock.
// Run with: node --test tests/interpolation.test.mjs (from web/)
import { test } from 'node:test';
import assert from 'node:assert/strict';
import {
  hermite,
  moved_smoothly,
  PlaybackClock,
  snapshot_from_message,
  SnapshotBuffer,
} from '../src/interpolation.js';

const interval = 1 / 30; // s between snapshots

/** A snapshot message of bodies given as {id, p: [x, y, z], v: [x, y, z], r}. */
function message(tick, time, bodies) {
  return {
    type: 'snapshot',
    tick,
    time,
    bodies: {
      id: bodies.map((b) => b.id),
      position: bodies.flatMap((b) => b.p),
      velocity: bodies.flatMap((b) => b.v),
      radius: bodies.map((b) => b.r ?? 0.1),
    },
  };
}

/** A projectile: x(t) = x0 + v0 t + g t^2 / 2. */
const projectile = {
  x0: [1, -2, 3],
  v0: [2, 0.5, 8],
  g: [0, 0, -9.81],
  at(t) {
    const p = [0, 1, 2].map((k) => this.x0[k] + this.v0[k] * t + 0.5 * this.g[k] * t * t);
    const v = [0, 1, 2].map((k) => this.v0[k] + this.g[k] * t);
    return { id: 7, p, v };
  },
};

function buffer_of(times, motion, options) {
  const buffer = new SnapshotBuffer(options);
  times.forEach((t, i) => buffer.push(snapshot_from_message(message(i + 1, t, [motion.at(t)]), t)));
  return buffer;
}

function position_at(buffer, t) {
  const frame = buffer.sample(t);
  return Array.from(frame.position.subarray(0, 3));
}

function assert_close(actual, expected, tolerance, what) {
  for (let k = 0; k < expected.length; k++) {
    const error = Math.abs(actual[k] - expected[k]);
    assert.ok(error <= tolerance, `${what}: component ${k} is ${actual[k]}, expected ${expected[k]} (error ${error} > ${tolerance})`);
  }
}

test('hermite gives the end points and reproduces a cubic exactly', () => {
  const f = (t) => 0.5 * t * t * t - 2 * t * t + 3 * t - 1;
  const df = (t) => 1.5 * t * t - 4 * t + 3;
  const t0 = 0.3;
  const h = 0.7;
  for (let s = 0; s <= 1; s += 0.125) {
    const got = hermite(f(t0), df(t0), f(t0 + h), df(t0 + h), h, s);
    assert.ok(Math.abs(got - f(t0 + s * h)) < 1e-14, `s = ${s}: ${got} vs ${f(t0 + s * h)}`);
  }
});

test('a projectile is drawn on its parabola at and between snapshots (error < 1e-12 m)', () => {
  const times = Array.from({ length: 10 }, (_, i) => i * interval);
  const buffer = buffer_of(times, projectile);
  for (let t = 0; t <= times.at(-1); t += interval / 7) {
    assert_close(position_at(buffer, t), projectile.at(t).p, 1e-12, `t = ${t}`);
  }
  for (const t of times) assert_close(position_at(buffer, t), projectile.at(t).p, 1e-12, `at snapshot t = ${t}`);
});

test('straight motion is drawn exactly between snapshots', () => {
  const line = { at: (t) => ({ id: 1, p: [1 + 3 * t, 2 - t, 0.5], v: [3, -1, 0] }) };
  const buffer = buffer_of([0, interval, 2 * interval], line);
  for (let t = 0; t <= 2 * interval; t += interval / 5) assert_close(position_at(buffer, t), line.at(t).p, 1e-12, `t = ${t}`);
});

test('a lost snapshot is bridged: the parabola stays exact and a circle stays within 1e-5 m', () => {
  const times = [0, 1, 3, 4].map((i) => i * interval); // snapshot 2 lost
  const buffer = buffer_of(times, projectile);
  for (let t = interval; t <= 3 * interval; t += interval / 8) {
    assert_close(position_at(buffer, t), projectile.at(t).p, 1e-12, `in the gap, t = ${t}`);
  }
  const w = 2; // rad/s on a circle of radius 1 m: the Hermite error over h = 2/30 s is h^4 w^4 / 384
  const circle = { at: (t) => ({ id: 3, p: [Math.cos(w * t), Math.sin(w * t), 0], v: [-w * Math.sin(w * t), w * Math.cos(w * t), 0] }) };
  const circling = buffer_of(times, circle);
  for (let t = interval; t <= 3 * interval; t += interval / 8) assert_close(position_at(circling, t), circle.at(t).p, 1e-5, `circle, t = ${t}`);
});

test('a bounce between snapshots is drawn on the chord, never through the floor', () => {
  // Falling at 5 m/s onto z = 0, it hits the floor a tenth into the interval and leaves at
  // 2 m/s (a damped bounce). The Hermite curve through these samples dips below the floor.
  const h = interval;
  const a = { id: 1, p: [0, 0, 0.1 * h * 5], v: [0, 0, -5] };
  const b = { id: 1, p: [0, 0, 0.9 * h * 2], v: [0, 0, 2] };
  assert.ok(hermite(a.p[2], a.v[2], b.p[2], b.v[2], h, 0.2) < 0, 'this bounce would dip under Hermite');
  const buffer = new SnapshotBuffer();
  buffer.push(snapshot_from_message(message(1, 0, [a]), 0));
  buffer.push(snapshot_from_message(message(2, h, [b]), h));
  assert.equal(moved_smoothly(buffer.oldest, 0, buffer.newest, 0, h), false);
  for (let t = 0; t <= h; t += h / 16) assert.ok(position_at(buffer, t)[2] >= 0, `below the floor at t = ${t}`);
});

test('bodies are followed by id: reordered, spawned and removed bodies', () => {
  const buffer = new SnapshotBuffer();
  buffer.push(snapshot_from_message(message(1, 0, [
    { id: 1, p: [0, 0, 0], v: [1, 0, 0] },
    { id: 2, p: [5, 0, 0], v: [0, 0, 0] },
  ]), 0));
  buffer.push(snapshot_from_message(message(2, 1, [
    { id: 3, p: [9, 9, 9], v: [0, 0, 0] }, // spawned
    { id: 1, p: [1, 0, 0], v: [1, 0, 0] }, // body 2 removed, body 1 moved to another index
  ]), 1));
  const frame = buffer.sample(0.5);
  assert.equal(frame.count, 2);
  assert.deepEqual(Array.from(frame.id.subarray(0, 2)), [3, 1]);
  assert_close(Array.from(frame.position.subarray(0, 3)), [9, 9, 9], 0, 'a spawned body appears where it was spawned');
  assert_close(Array.from(frame.position.subarray(3, 6)), [0.5, 0, 0], 1e-15, 'body 1 half way');
});

test('the buffer holds at most its capacity and ignores snapshots older than its newest', () => {
  const buffer = new SnapshotBuffer({ capacity: 8 });
  for (let i = 0; i < 1000; i++) buffer.push(snapshot_from_message(message(i, i * interval, [projectile.at(0)]), i * interval));
  assert.equal(buffer.length, 8);
  assert.equal(buffer.newest.tick, 999);
  assert.equal(buffer.oldest.tick, 992);
  assert.equal(buffer.push(snapshot_from_message(message(5, 5 * interval, [projectile.at(0)]), 0)), false);
  assert.equal(buffer.newest.tick, 999);
});

test('a paused room: a later tick at the same time replaces the newest, and is drawn still', () => {
  const buffer = buffer_of([0, interval], projectile);
  const paused = (tick, body) => ({ ...message(tick, interval, [body]), paused: true });
  const still = { ...projectile.at(interval), id: 7 };
  assert.equal(buffer.push(snapshot_from_message(paused(3, still), 1)), true);
  const pushed = { ...still, v: [0, 0, 1] }; // an impulse while paused
  assert.equal(buffer.push(snapshot_from_message(paused(4, pushed), 2)), true);
  assert.equal(buffer.length, 2);
  assert.equal(buffer.newest.tick, 4);
  assert.equal(buffer.push(snapshot_from_message(paused(4, pushed), 3)), false, 'the same tick again');
  // Long after the pause began the body is drawn where it stands, not carried along.
  assert_close(position_at(buffer, interval + 5), still.p, 0, 'paused body');
  assert.deepEqual(Array.from(buffer.sample(interval + 5).velocity.subarray(0, 3)), [0, 0, 1]);
});

test('past the newest snapshot it extrapolates for at most max_extrapolation, before the oldest it holds', () => {
  const buffer = buffer_of([0, interval], projectile, { max_extrapolation: 0.1 });
  const newest = projectile.at(interval);
  const ahead = (dt) => newest.p.map((x, k) => x + dt * newest.v[k]);
  assert_close(position_at(buffer, interval + 0.05), ahead(0.05), 1e-12, 'extrapolated');
  assert_close(position_at(buffer, interval + 5), ahead(0.1), 1e-12, 'extrapolation capped');
  assert_close(position_at(buffer, -1), projectile.at(0).p, 0, 'held at the oldest');
});

/** A deterministic jitter in [-1, 1]. */
function jitter(i) {
  const x = Math.sin(i * 12.9898) * 43758.5453;
  return 2 * (x - Math.floor(x)) - 1;
}

/**
 * Plays 30 snapshots a second that arrive with up to 8 ms of jitter (and optionally lose
 * some) against 60 frames a second, and reports how far behind the newest snapshot the
 * drawing stays, in snapshot intervals, after a two-second warm-up.
 */
function play({ lost = () => false, seconds = 10 }) {
  const delay = 2 * interval;
  const clock = new PlaybackClock({ delay, rate: 1 });
  const buffer = new SnapshotBuffer();
  const arrival = (i) => i * interval + 0.02 + 0.008 * jitter(i);
  let next_snapshot = 0;
  let previous = null;
  const lags = [];
  let ahead = -Infinity; // the most the drawing ran past the newest snapshot, in intervals
  for (let frame = 0; frame < seconds * 60; frame++) {
    const now = frame / 60;
    for (; arrival(next_snapshot) <= now; next_snapshot++) {
      if (lost(next_snapshot)) continue;
      const time = next_snapshot * interval;
      buffer.push(snapshot_from_message(message(next_snapshot, time, [projectile.at(0)]), arrival(next_snapshot)));
      clock.on_snapshot(time, arrival(next_snapshot));
    }
    const t = clock.time(now);
    if (t === null) continue;
    if (previous !== null) assert.ok(t >= previous, `the drawing went back in time at frame ${frame}`);
    previous = t;
    if (now < 2) continue;
    const server_now = now - 0.02; // the simulated time the server has reached
    lags.push((server_now - t) / interval);
    ahead = Math.max(ahead, (t - buffer.newest.time) / interval);
    assert.ok(t >= buffer.oldest.time, `frame ${frame} is older than the buffer`);
  }
  return { min: Math.min(...lags), max: Math.max(...lags), ahead };
}

test('the drawing lags about two snapshot intervals behind the server, between buffered snapshots', () => {
  const { min, max, ahead } = play({});
  assert.ok(min > 1.6 && max < 2.4, `lag between ${min} and ${max} intervals, expected 2 +- 0.4`);
  assert.ok(ahead <= 0, `the drawing ran ${ahead} intervals past the newest snapshot`);
});

test('a lost snapshot (every 7th) is bridged: the drawing keeps its lag and barely extrapolates', () => {
  const { min, max, ahead } = play({ lost: (i) => i % 7 === 3 });
  assert.ok(min > 1.6 && max < 2.4, `lag between ${min} and ${max} intervals`);
  assert.ok(ahead < 0.5, `the drawing ran ${ahead} intervals past the newest snapshot`);
});

test('the clock jumps instead of crawling when the gap is large (a reconnect)', () => {
  const clock = new PlaybackClock({ delay: 2 * interval, rate: 1 });
  clock.on_snapshot(1, 0);
  assert.ok(Math.abs(clock.time(0) - (1 - 2 * interval)) < 1e-12);
  clock.on_snapshot(100, 0.1);
  assert.ok(Math.abs(clock.time(0.1) - (100 - 2 * interval)) < 1e-12);
});
