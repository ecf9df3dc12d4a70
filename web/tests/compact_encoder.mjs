// The server's side of the compact form, written again in JavaScript for the decoder's tests:
// quantize, keyframe and delta as protocol/compact.cpp computes them (the same double
// operations, the same rounding), and the wire form as protocol/codec.cpp writes it (ids
// gap-coded, `paused` only when true, absent parts left out). A stream built here from a
// sequence of full-form states is what kugel-server would send for them.
import { predicted_offset, prediction_factor, quantize } from '../src/compact.js';

/** A full-form state (ids in any order) quantized: bodies sorted by id, integers of q. */
export function quantize_state(full, q) {
  const n = full.id.length;
  const order = [...Array(n).keys()].sort((l, r) => full.id[l] - full.id[r]);
  const s = { tick: full.tick, time: full.time, paused: full.paused ?? false, faults: full.faults ?? 0, q, id: [], p: [], v: [], radius: [], mass: [], charge: full.charge ? [] : null, owner: [] };
  for (const i of order) {
    s.id.push(full.id[i]);
    for (let d = 0; d < 3; d++) {
      s.p.push(quantize(full.position[3 * i + d], q[0]));
      s.v.push(quantize(full.velocity[3 * i + d], q[1]));
    }
    s.radius.push(full.radius[i]);
    s.mass.push(full.mass[i]);
    s.owner.push(full.owner?.[i] ?? 0);
    if (s.charge) s.charge.push(full.charge[i]);
  }
  return s;
}

/** Ids as the wire has them: the first, then each less the one before. */
export function gap_coded(ids) {
  return ids.map((id, i) => (i === 0 ? id : id - ids[i - 1]));
}

function head(state, form) {
  const m = { type: 'snapshot', tick: state.tick, form, time: state.time };
  if (state.paused) m.paused = true;
  if (state.faults) m.faults = state.faults;
  return m;
}

function wire_bodies(b, indices) {
  const pick = (column, per) => indices.flatMap((i) => column.slice(per * i, per * i + per));
  const out = { id: gap_coded(indices.map((i) => b.id[i])), p: pick(b.p, 3), v: pick(b.v, 3), radius: pick(b.radius, 1), mass: pick(b.mass, 1) };
  if (b.charge) out.charge = pick(b.charge, 1);
  out.owner = pick(b.owner, 1);
  return out;
}

/** The keyframe message of a quantized state. */
export function keyframe(state) {
  return { ...head(state, 'key'), q: state.q, bodies: wire_bodies(state, [...state.id.keys()]) };
}

/**
 * The delta message from `base` to `now` (compact.cpp, delta()), or null when a keyframe
 * serves better: other quanta, a tick not after the base's, or more bodies appeared and
 * vanished than half of those there are now (plus 8).
 */
export function delta(base, now) {
  if (base.q[0] !== now.q[0] || base.q[1] !== now.q[1] || !(base.tick < now.tick)) return null;
  const half_steps = prediction_factor(base.time, now.time, now.q);
  const moved = { runs: [], p: [], v: [] };
  const appeared = [];
  const vanished = [];
  let skip = 0;
  let take = 0;
  const still = () => {
    if (take > 0) {
      moved.runs.push(skip, take);
      skip = take = 0;
    }
    skip++;
  };
  let i = 0;
  let j = 0;
  while (i < base.id.length || j < now.id.length) {
    if (j === now.id.length || (i < base.id.length && base.id[i] < now.id[j])) {
      vanished.push(base.id[i++]);
      still();
    } else if (i === base.id.length || now.id[j] < base.id[i]) {
      appeared.push(j++);
    } else {
      let same = true;
      for (let d = 0; d < 3; d++) same &&= base.p[3 * i + d] === now.p[3 * j + d] && base.v[3 * i + d] === now.v[3 * j + d];
      if (same) {
        still();
      } else {
        take++;
        for (let d = 0; d < 3; d++) {
          const v = now.v[3 * j + d];
          const vb = base.v[3 * i + d];
          moved.p.push(now.p[3 * j + d] - (base.p[3 * i + d] + predicted_offset(vb, v, half_steps)));
        }
        for (let d = 0; d < 3; d++) moved.v.push(now.v[3 * j + d] - base.v[3 * i + d]);
      }
      i++;
      j++;
    }
  }
  if (take > 0) moved.runs.push(skip, take);
  if (appeared.length + vanished.length > Math.floor(now.id.length / 2) + 8) return null;
  const m = { ...head(now, 'delta'), base: base.tick };
  // The codec writes base after tick; key order does not matter to a reader.
  if (moved.runs.length) m.moved = moved;
  if (appeared.length) m.appeared = wire_bodies(now, appeared);
  if (vanished.length) m.vanished = gap_coded(vanished);
  return m;
}
