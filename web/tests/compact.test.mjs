// Unit tests of the page's compact-snapshot decoder (src/compact.js, through parse_frame as
// the worker runs it): PROTOCOL.md's worked examples, a long chain against the full form it
// was made from, and messages a hostile or broken server could send.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { apply_compact, CompactStream, max_quantized, prediction_factor, quantize } from '../src/compact.js';
import { parse_frame } from '../src/parse_frame.js';
import { delta, gap_coded, keyframe, quantize_state } from './compact_encoder.mjs';

// ------------------------------------------------------------------ PROTOCOL.md's examples

// The keyframe and the delta of "Compact snapshots", as the document prints them.
const example_keyframe = `{"type": "snapshot", "tick": 1204, "form": "key", "time": 20.066666666666666, "q": [0.001, 0.01],
 "bodies": {"id": [4, 13], "p": [0, 0, 100, 500, -250, 1750], "v": [0, 0, 0, 150, 0, -320],
            "radius": [0.1, 0.1], "mass": [32.67, 32.67], "owner": [0, 3]}}`;
const example_delta = `{"type": "snapshot", "tick": 1206, "form": "delta", "base": 1204, "time": 20.1,
 "moved": {"runs": [1, 1], "p": [0, -1, 1], "v": [0, 0, -33]},
 "appeared": {"id": [20], "p": [1, 2, 3], "v": [0, 0, 0], "radius": [0.2], "mass": [4.0], "owner": [7]},
 "vanished": [4]}`;

test('the keyframe of PROTOCOL.md decodes to bodies 4 and 17, where the full-form example has them', () => {
  const stream = new CompactStream();
  const { snapshot, refused } = parse_frame(example_keyframe, 1, stream);
  assert.equal(refused, null);
  assert.equal(snapshot.form, 'key');
  assert.equal(snapshot.tick, 1204);
  assert.deepEqual(Array.from(snapshot.id), [4, 17], 'ids are gap-coded: 4, then 4 + 13');
  // The document's full-form snapshot of the same two bodies.
  assert.deepEqual(Array.from(snapshot.position), [0.0, 0.0, 0.1, 0.5, -0.25, 1.75]);
  assert.deepEqual(Array.from(snapshot.velocity), [0.0, 0.0, 0.0, 1.5, 0.0, -3.2]);
  assert.deepEqual(Array.from(snapshot.radius), [0.1, 0.1]);
  assert.deepEqual(Array.from(snapshot.mass), [32.67, 32.67]);
  assert.deepEqual(Array.from(snapshot.owner), [0, 3]);
  assert.equal(snapshot.charge, null);
});

test('the delta of PROTOCOL.md: body 17 moved, body 20 appeared, body 4 vanished', () => {
  const stream = new CompactStream();
  parse_frame(example_keyframe, 1, stream);
  const { snapshot, refused } = parse_frame(example_delta, 2, stream);
  assert.equal(refused, null);
  assert.equal(snapshot.form, 'delta');
  assert.deepEqual(Array.from(snapshot.id), [17, 20]);
  // Body 17: v = [150, 0, −320] + [0, 0, −33]. k = (20.1 − 20.066666666666666) · 0.01 / 0.001 / 2
  // = 0.1666..., so the prediction moves x by floor(300 k + 0.5) = 50, y by 0, z by
  // floor(−673 k + 0.5) = −112; then p adds [0, −1, 1]: [550, −251, 1639] quanta.
  assert.deepEqual(Array.from(stream.held.v.subarray(0, 3)), [150, 0, -353]);
  assert.deepEqual(Array.from(stream.held.p.subarray(0, 3)), [550, -251, 1639]);
  assert.deepEqual(Array.from(snapshot.position.subarray(0, 3)), [550 * 0.001, -251 * 0.001, 1639 * 0.001]);
  assert.deepEqual(Array.from(snapshot.velocity.subarray(0, 3)), [150 * 0.01, 0, -353 * 0.01]);
  // Its constants stay from the keyframe; body 20 brings its own.
  assert.deepEqual(Array.from(snapshot.radius), [0.1, 0.2]);
  assert.deepEqual(Array.from(snapshot.mass), [32.67, 4]);
  assert.deepEqual(Array.from(snapshot.owner), [3, 7]);
  assert.deepEqual(Array.from(snapshot.position.subarray(3, 6)), [0.001, 0.002, 0.003]);
  assert.equal(snapshot.time, 20.1);
});

test('the prediction is the formula of PROTOCOL.md, in its order of double operations', () => {
  const q = [0.001, 0.01];
  const k = prediction_factor(20.066666666666666, 20.1, q);
  assert.equal(k, (((20.1 - 20.066666666666666) * 0.01) / 0.001) / 2);
  assert.equal(quantize(0.0005, 0.001), 1, 'halves round up');
  assert.equal(quantize(-0.0005, 0.001), 0, 'halves round up, also below zero');
  assert.equal(quantize(1e300, 0.001), max_quantized, 'clamped to 2^50');
  assert.equal(quantize(-1e300, 0.001), -max_quantized);
});

// ------------------------------------------------------------------ a long chain

/** A small deterministic generator (mulberry32), so the chain is the same on every run. */
function random_from(seed) {
  let a = seed >>> 0;
  return () => {
    a = (a + 0x6d2b79f5) >>> 0;
    let t = a;
    t = Math.imul(t ^ (t >>> 15), t | 1);
    t ^= t + Math.imul(t ^ (t >>> 7), t | 61);
    return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
  };
}

/**
 * A world of bodies stepped at 60 Hz: some at rest, some in free flight, some falling under
 * gravity and bouncing off a floor, one far beyond 2^50 quanta; bodies spawned (with their
 * owner) and removed as it runs, a pause, and at tick `reset_at` every body replaced by new
 * ones, as a reset does. Returns the full-form state of every tick.
 */
function simulate({ ticks, bodies: count, charges, reset_at, seed }) {
  const random = random_from(seed);
  const dt = 1 / 60;
  let next_id = 1;
  let world = [];
  const spawn = (owner) => {
    const kind = random();
    const body = {
      id: next_id++,
      position: [random() * 8 - 4, random() * 8 - 4, random() * 4],
      velocity: kind < 0.2 ? [0, 0, 0] : [random() * 6 - 3, random() * 6 - 3, random() * 6 - 3],
      falls: kind > 0.5,
      radius: random() < 0.1 ? 0 : 0.05 + random() * 0.2,
      mass: 0.1 + random() * 10,
      charge: charges ? random() * 2e-6 - 1e-6 : undefined,
      owner,
    };
    world.push(body);
  };
  for (let i = 0; i < count; i++) spawn(0);
  world.push({ id: next_id++, position: [1e15, -2e14, 3], velocity: [5, 0, 0], falls: false, radius: 0.1, mass: 1, charge: charges ? 0 : undefined, owner: 0 });
  let time = 0;
  let paused = false;
  const states = [];
  for (let tick = 1; tick <= ticks; tick++) {
    if (tick === reset_at) {
      world = [];
      for (let i = 0; i < count; i++) spawn(0);
    }
    if (tick % 7 === 0) spawn(1 + Math.floor(random() * 5));
    if (tick % 11 === 0 && world.length > 10) world.splice(Math.floor(random() * world.length), 1);
    if (tick === 40) paused = true;
    if (tick === 55) paused = false;
    if (!paused) {
      time += dt;
      for (const b of world) {
        if (b.falls) {
          b.position[2] += dt * b.velocity[2] - 0.5 * 9.81 * dt * dt;
          b.velocity[2] -= 9.81 * dt;
          if (b.position[2] < 0) {
            b.position[2] = -b.position[2];
            b.velocity[2] = -0.9 * b.velocity[2];
          }
          b.position[0] += dt * b.velocity[0];
          b.position[1] += dt * b.velocity[1];
        } else {
          for (let d = 0; d < 3; d++) b.position[d] += dt * b.velocity[d];
        }
        if (random() < 0.02) b.velocity = b.velocity.map((v) => v + random() * 2 - 1); // a collision
      }
    }
    // The engine's slots are not in id order after removals: shuffle the columns a little.
    const order = world.map((_, i) => i);
    if (tick % 5 === 0) order.reverse();
    states.push({
      tick,
      time,
      paused,
      id: order.map((i) => world[i].id),
      position: order.flatMap((i) => world[i].position),
      velocity: order.flatMap((i) => world[i].velocity),
      radius: order.map((i) => world[i].radius),
      mass: order.map((i) => world[i].mass),
      charge: charges ? order.map((i) => world[i].charge) : undefined,
      owner: order.map((i) => world[i].owner),
    });
  }
  return states;
}

/**
 * What kugel-server sends one client for these states, as text frames: a keyframe first,
 * then a delta against the last snapshot sent, or a keyframe when the client cannot hold the
 * base (a snapshot skipped for a slow reader), when `keyframe_every` snapshots passed, or when
 * a delta would not be smaller (a reset).
 */
function stream_of(states, q, { skip = () => false, keyframe_every = 90 }) {
  const frames = [];
  let base = null;
  let since_keyframe = 0;
  let skipped = false;
  for (const full of states) {
    if (skip(full.tick)) {
      skipped = true; // replaced before it was written: the next one cannot be a delta
      continue;
    }
    const now = quantize_state(full, q);
    let message = null;
    if (base && !skipped && since_keyframe < keyframe_every) message = delta(base, now);
    if (message) since_keyframe++;
    else {
      message = keyframe(now);
      since_keyframe = 0;
    }
    frames.push({ full, text: JSON.stringify(message), form: message.form });
    base = now;
    skipped = false;
  }
  return frames;
}

function check_chain({ charges }) {
  const q = [0.001, 0.01];
  const states = simulate({ ticks: 240, bodies: 300, charges, reset_at: 150, seed: charges ? 11 : 7 });
  const frames = stream_of(states, q, { skip: (tick) => tick % 37 === 0 || tick === 100 || tick === 101 });
  const stream = new CompactStream();
  const seen = { key: 0, delta: 0, appeared: 0, vanished: 0, moved: 0 };
  for (const { full, text, form } of frames) {
    const { snapshot, refused } = parse_frame(text, full.time, stream);
    assert.equal(refused, null, `tick ${full.tick}`);
    seen[form]++;
    const message = JSON.parse(text);
    if (message.appeared) seen.appeared++;
    if (message.vanished) seen.vanished++;
    if (message.moved) seen.moved++;
    // Exactly the integers the server quantized, and the constants it sent once.
    const expected = quantize_state(full, q);
    assert.deepEqual(Array.from(stream.held.id), expected.id, `ids at tick ${full.tick}`);
    assert.deepEqual(Array.from(stream.held.p), expected.p, `position quanta at tick ${full.tick}`);
    assert.deepEqual(Array.from(stream.held.v), expected.v, `velocity quanta at tick ${full.tick}`);
    assert.deepEqual(Array.from(snapshot.radius), expected.radius);
    assert.deepEqual(Array.from(snapshot.mass), expected.mass);
    assert.deepEqual(Array.from(snapshot.owner), expected.owner);
    assert.deepEqual(snapshot.charge && Array.from(snapshot.charge), expected.charge);
    assert.equal(snapshot.paused, full.paused);
    // And so the full form to the quantum: within half a step of every coordinate (the body
    // beyond 2^50 quanta excepted: it is shown at that distance).
    for (let j = 0; j < full.id.length; j++) {
      const k = expected.id.indexOf(full.id[j]);
      for (let d = 0; d < 3; d++) {
        const x = full.position[3 * j + d];
        if (Math.abs(x / q[0]) < max_quantized) {
          const off = Math.abs(snapshot.position[3 * k + d] - x);
          assert.ok(off <= 0.5 * q[0] * (1 + 1e-9), `body ${full.id[j]} at tick ${full.tick}: ${off} m off`);
        } else {
          assert.equal(snapshot.position[3 * k + d], Math.sign(x) * max_quantized * q[0]);
        }
        const off = Math.abs(snapshot.velocity[3 * k + d] - full.velocity[3 * j + d]);
        assert.ok(off <= 0.5 * q[1] * (1 + 1e-9), `velocity of body ${full.id[j]} at tick ${full.tick}: ${off} m/s off`);
      }
    }
  }
  // The chain went through every case it was built for.
  assert.ok(seen.delta > 150, `${seen.delta} deltas`);
  assert.ok(seen.key >= 8, `${seen.key} keyframes: the first, after each skip, after the reset, every 90`);
  assert.ok(seen.appeared >= 20 && seen.vanished >= 15 && seen.moved >= 150, JSON.stringify(seen));
}

test('a long chain with spawns, removals, a pause, skipped snapshots and a reset decodes to the full form to the quantum', () => {
  check_chain({ charges: false });
});

test('the same with charges: a body\'s charge comes once and stays with it', () => {
  check_chain({ charges: true });
});

test('the reset is a keyframe, and a skipped snapshot is followed by one', () => {
  const q = [0.001, 0.01];
  const states = simulate({ ticks: 160, bodies: 50, charges: false, reset_at: 150, seed: 3 });
  const frames = stream_of(states, q, { skip: (tick) => tick === 120, keyframe_every: 1000 });
  const form_at = (tick) => frames.find((f) => f.full.tick === tick).form;
  assert.equal(form_at(119), 'delta');
  assert.equal(form_at(121), 'key');
  assert.equal(form_at(122), 'delta');
  assert.equal(form_at(150), 'key', 'every body replaced: a keyframe is smaller');
});

// ------------------------------------------------------------------ hostile messages

const keyframe_message = () => JSON.parse(example_keyframe);
const delta_message = () => JSON.parse(example_delta);

/** Applies the keyframe, then `message`; returns the failure (and checks nothing was applied). */
function refusal(message, base = keyframe_message()) {
  const stream = new CompactStream();
  if (base) assert.ok(stream.apply(base).state);
  const { snapshot, refused } = parse_frame(JSON.stringify(message), 0, stream);
  assert.equal(snapshot, null, 'a refused snapshot draws nothing');
  assert.equal(stream.held, null, 'and leaves nothing to apply a delta to');
  return refused;
}

test('a delta without a keyframe before it, or against another base, is refused', () => {
  assert.match(refusal(delta_message(), null), /no keyframe came before it/);
  assert.match(refusal({ ...delta_message(), base: 1203 }), /against tick 1203, but the state held is of tick 1204/);
});

test('after a refusal only a keyframe applies again', () => {
  const stream = new CompactStream();
  stream.apply(keyframe_message());
  assert.ok(stream.apply({ ...delta_message(), base: 1200 }).failure);
  assert.ok(stream.apply(delta_message()).failure, 'its base is gone with the refusal');
  assert.ok(stream.apply(keyframe_message()).state);
  assert.ok(stream.apply(delta_message()).state);
});

test('a delta that contradicts its base is refused', () => {
  const d = delta_message;
  assert.match(refusal({ ...d(), moved: { runs: [2, 1], p: [0, 0, 0], v: [0, 0, 0] } }), /runs reach past the base's 2 bodies/);
  assert.match(refusal({ ...d(), vanished: [5] }), /vanished body 5 is not in the base/);
  assert.match(refusal({ ...d(), vanished: [17, 0] }), /gap-coded and strictly increasing/);
  assert.match(refusal({ ...d(), moved: undefined, vanished: [17, 4] }), /vanished body 21 is not in the base/);
  assert.match(refusal({ ...d(), appeared: { ...d().appeared, id: [17] } }), /appeared body 17 is already held/);
  assert.match(refusal({ ...d(), vanished: [17] }), /body 17 both moved and vanished/);
  assert.match(refusal({ ...d(), appeared: { ...d().appeared, charge: [1e-6] } }), /charges where the keyframe's have none/);
});

test('a coordinate driven beyond 2^53 quanta is refused', () => {
  const key = keyframe_message();
  key.bodies.p[3] = Number.MAX_SAFE_INTEGER; // allowed: a whole number below 2^53
  key.bodies.v[3] = 0;
  const moved = { runs: [1, 1], p: [Number.MAX_SAFE_INTEGER, 0, 0], v: [0, 0, 0] };
  assert.match(refusal({ ...delta_message(), moved }, key), /body 17 moves beyond 2\^53 quanta/);
  const faster = { runs: [1, 1], p: [0, 0, 0], v: [Number.MAX_SAFE_INTEGER, 0, 0] };
  key.bodies.v[3] = 10;
  assert.match(refusal({ ...delta_message(), moved: faster }, key), /moves beyond 2\^53 quanta/);
  // Where the exact sum comes back below 2^53 it is taken, as the server's int64 arithmetic does.
  key.bodies.v[3] = 0;
  const back = { runs: [1, 1], p: [-10, 0, 0], v: [0, 0, 0] };
  const stream = new CompactStream();
  stream.apply(key);
  const result = stream.apply({ ...delta_message(), moved: back });
  assert.equal(result.state.p[0], Number.MAX_SAFE_INTEGER - 10);
});

test('malformed snapshots are refused with the field at fault, never thrown', () => {
  const k = keyframe_message;
  const cases = [
    [{ ...k(), form: 'diff' }, /form: must be "key" or "delta"/],
    [{ ...k(), q: [0, 0.01] }, /q: must be 2 numbers > 0/],
    [{ ...k(), q: undefined }, /q: must be 2 numbers > 0/],
    [{ ...k(), bodies: undefined }, /bodies: missing/],
    [{ ...k(), bodies: { ...k().bodies, p: [0, 0, 100] } }, /bodies\/p: must hold 6 numbers, got 3/],
    [{ ...k(), bodies: { ...k().bodies, p: [0, 0, 100.5, 500, -250, 1750] } }, /bodies\/p\/2: must be a whole number of quanta/],
    [{ ...k(), bodies: { ...k().bodies, v: [0, 0, 0, '150', 0, -320] } }, /bodies\/v\/3/],
    [{ ...k(), bodies: { ...k().bodies, p: [0, 0, 1e300, 500, -250, 1750] } }, /bodies\/p\/2/],
    [{ ...k(), bodies: { ...k().bodies, radius: [0.1, -1] } }, /bodies\/radius\/1: must be a number >= 0/],
    [{ ...k(), bodies: { ...k().bodies, owner: [0] } }, /bodies\/owner: must hold 2 numbers/],
    [{ ...k(), bodies: { ...k().bodies, mass: undefined } }, /bodies\/mass: must be an array/],
    [{ ...k(), bodies: { ...k().bodies, id: [4, 9007199254740990] } }, /beyond 2\^53 - 1/],
    [{ ...k(), bodies: { ...k().bodies, id: [4, -13] } }, /bodies\/id\/1: must be a whole number/],
    [{ ...k(), bodies: 'all of them' }, /bodies: must be an object/],
    [{ ...k(), tick: -1 }, /tick: must be a whole number/],
    [{ ...k(), time: 'now' }, /time: must be a finite number/],
    [{ ...k(), base: 1200 }, /a keyframe has no base/],
    [{ ...delta_message(), base: 1206 }, /base: must be below the tick/],
    [{ ...delta_message(), q: [1, 1] }, /a delta has no bodies or q/],
    [{ ...delta_message(), moved: { runs: [1, 1], p: [0, -1], v: [0, 0, -33] } }, /moved\/p: must hold 3 numbers/],
    [{ ...delta_message(), moved: { runs: [1, 4e15], p: [], v: [] } }, /more moved bodies than a message holds/],
    [{ ...delta_message(), moved: null }, /moved: must be an object/],
    [{ ...delta_message(), vanished: 4 }, /vanished: must be an array/],
  ];
  for (const [message, why] of cases) assert.match(refusal(message), why, JSON.stringify(message).slice(0, 120));
});

test('randomly broken messages are refused or applied consistently, never thrown', () => {
  const random = random_from(99);
  const q = [0.001, 0.01];
  const states = simulate({ ticks: 30, bodies: 20, charges: false, reset_at: 0, seed: 5 });
  const frames = stream_of(states, q, {}).map((f) => JSON.parse(f.text));
  const junk = [-1, 0.5, 1e300, 'x', null, [], {}, true, 2 ** 53, -(2 ** 53)];
  let refused = 0;
  for (let round = 0; round < 400; round++) {
    const stream = new CompactStream();
    const broken = Math.floor(random() * frames.length);
    for (let i = 0; i <= broken; i++) {
      const message = structuredClone(frames[i]);
      if (i === broken) break_somewhere(message, random, junk);
      const parsed = parse_frame(JSON.stringify(message), 0, stream);
      if (parsed.message?.type !== 'snapshot' || parsed.message.form === undefined) break; // no longer a compact snapshot
      if (parsed.refused) {
        refused++;
        assert.equal(stream.held, null);
        break;
      }
      const s = stream.held;
      for (let j = 1; j < s.count; j++) assert.ok(s.id[j] > s.id[j - 1], 'ids in increasing order');
      assert.equal(s.p.length, 3 * s.count);
      assert.ok(s.p.every(Number.isSafeInteger) && s.v.every(Number.isSafeInteger));
      assert.equal(parsed.snapshot.count, s.count);
    }
  }
  assert.ok(refused > 200, `only ${refused} of 400 broken messages refused`);
});

/** Replaces one value somewhere in a message (a field, or an entry of an array) by junk, or drops it. */
function break_somewhere(message, random, junk) {
  const paths = [];
  const walk = (value, path) => {
    if (value && typeof value === 'object') {
      for (const key of Object.keys(value)) {
        paths.push([...path, key]);
        walk(value[key], [...path, key]);
      }
    }
  };
  walk(message, []);
  const path = paths[Math.floor(random() * paths.length)];
  let parent = message;
  for (const key of path.slice(0, -1)) parent = parent[key];
  const last = path.at(-1);
  if (random() < 0.2 && !Array.isArray(parent)) delete parent[last];
  else parent[last] = junk[Math.floor(random() * junk.length)];
}

test('apply_compact is the same function the stream uses, and leaves the state it was given alone', () => {
  const key = apply_compact(keyframe_message(), null).state;
  const before = Array.from(key.p);
  const after = apply_compact(delta_message(), key).state;
  assert.deepEqual(Array.from(key.p), before);
  assert.deepEqual(Array.from(after.id), [17, 20]);
  assert.deepEqual(gap_coded([4, 17, 20]), [4, 13, 3]);
});
