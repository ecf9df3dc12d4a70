// Unit tests for the colour scales and the legend's round numbers.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { colour_bodies, lookup_table, round_up, speed_quantile, speed_stops } from '../src/colour_scale.js';

test('round_up picks 1, 2 or 5 times a power of ten', () => {
  assert.deepEqual([0.3, 1, 1.01, 2.5, 7, 10, 0].map((x) => round_up(x, 0.5)), [0.5, 1, 2, 5, 10, 10, 0.5]);
});

test('the scale runs from the first stop to the last, in linear RGB', () => {
  const lut = lookup_table(['#000000', '#ffffff']);
  assert.deepEqual(Array.from(lut.slice(0, 3)), [0, 0, 0]);
  assert.deepEqual(Array.from(lut.slice(-3)), [1, 1, 1]);
  const frame = { count: 2, velocity: new Float64Array([0, 0, 0, 30, 40, 0]), charge: null };
  const out = new Float32Array(6);
  colour_bodies(frame, 'speed', 10, out); // 0 m/s and 50 m/s, clamped to the top
  const speed_lut = lookup_table(speed_stops);
  assert.deepEqual(Array.from(out), [...speed_lut.slice(0, 3), ...speed_lut.slice(-3)]);
});

test('speed_quantile ignores the fastest few', () => {
  const velocity = new Float64Array(300);
  for (let i = 0; i < 100; i++) velocity[3 * i] = i < 99 ? 1 : 50;
  assert.equal(speed_quantile({ count: 100, velocity }, 0.98), 1);
});
