// The compact snapshot form (protocol/PROTOCOL.md, "Compact snapshots"): keyframes and
// deltas of positions and velocities as whole numbers of announced quanta. This is the
// page's decoder, bit for bit the same as kugel_protocol's apply_compact (protocol/compact.cpp):
// the prediction is computed in the same double operations, so the page holds exactly the
// integers the server quantized and nothing drifts along a chain of deltas.
//
// Everything a message says is checked before it is used: a message that is malformed, or a
// delta that contradicts the state held (another base, runs past its bodies, a vanished id
// it does not hold, an appeared id it holds, a coordinate beyond 2^53), is refused with the
// reason, and the state held is left as it was.

const max_safe = Number.MAX_SAFE_INTEGER; // 2^53 − 1
/** Quantized coordinates stay within ±2^50 (protocol/compact.hpp, max_quantized). */
export const max_quantized = 2 ** 50;

/** x / quantum rounded to the nearest integer (halves up), clamped to ±2^50; NaN gives 0. */
export function quantize(x, quantum) {
  const steps = Math.floor(x / quantum + 0.5);
  if (!(steps > -max_quantized)) return steps < 0 ? -max_quantized : 0;
  if (!(steps < max_quantized)) return max_quantized;
  return steps;
}

/** (time − base_time) · velocity quantum / position quantum / 2, left to right as in C++. */
export function prediction_factor(base_time, time, q) {
  return ((time - base_time) * q[1]) / q[0] / 2;
}

/**
 * The prediction of a coordinate from its base position and velocity and its new velocity
 * (all whole quanta): base + floor((V + v) · k + 0.5) when that is below 2^50, else base.
 * V + v is a sum of two doubles holding whole numbers, rounded once to a double exactly as
 * C++ converts the exact int64 sum.
 */
export function predicted_offset(base_velocity, velocity, half_steps) {
  const moved = (base_velocity + velocity) * half_steps;
  if (!(Math.abs(moved) < max_quantized)) return 0;
  return Math.floor(moved + 0.5);
}

/** a + b + c of whole numbers, exactly: null when the exact sum is beyond ±(2^53 − 1). */
function exact_sum(a, b, c) {
  if (Math.abs(a) + Math.abs(b) + Math.abs(c) <= max_safe) return a + b + c;
  const sum = BigInt(a) + BigInt(b) + BigInt(c);
  return sum >= -BigInt(max_safe) && sum <= BigInt(max_safe) ? Number(sum) : null;
}

// ------------------------------------------------------------------ reading a message

class Refused extends Error {}

function refuse(why) {
  throw new Refused(why);
}

const is_whole = (x) => Number.isSafeInteger(x) && x >= 0;
const is_integer = (x) => Number.isSafeInteger(x); // −(2^53 − 1) ... 2^53 − 1

function array_of(value, where, count, check, what) {
  if (!Array.isArray(value)) refuse(`${where}: must be an array`);
  if (count !== null && value.length !== count) refuse(`${where}: must hold ${count} numbers, got ${value.length}`);
  for (let i = 0; i < value.length; i++) if (!check(value[i])) refuse(`${where}/${i}: must be ${what}, got ${JSON.stringify(value[i])}`);
  return value;
}

/** Gap-coded ids (the first, then each less the one before) as the ids: strictly increasing, below 2^53. */
function ungapped(value, where) {
  array_of(value, where, null, is_whole, 'a whole number');
  const ids = new Float64Array(value.length);
  let id = 0;
  for (let i = 0; i < value.length; i++) {
    if (i > 0 && value[i] === 0) refuse(`${where}/${i}: must be >= 1: ids are gap-coded and strictly increasing`);
    if (value[i] > max_safe - id) refuse(`${where}/${i}: the id it gives is beyond 2^53 - 1`);
    id += value[i];
    ids[i] = id;
  }
  return ids;
}

const finite_at_least_zero = (x) => typeof x === 'number' && Number.isFinite(x) && x >= 0;
const finite = (x) => typeof x === 'number' && Number.isFinite(x);

/** The `bodies` of a keyframe or the `appeared` of a delta, checked, as typed columns. */
function read_bodies(value, where) {
  if (typeof value !== 'object' || value === null || Array.isArray(value)) refuse(`${where}: must be an object`);
  const id = ungapped(value.id, `${where}/id`);
  const n = id.length;
  const charge = value.charge === undefined ? null : Float64Array.from(array_of(value.charge, `${where}/charge`, n, finite, 'a finite number'));
  return {
    count: n,
    id,
    p: Float64Array.from(array_of(value.p, `${where}/p`, 3 * n, is_integer, 'a whole number of quanta')),
    v: Float64Array.from(array_of(value.v, `${where}/v`, 3 * n, is_integer, 'a whole number of quanta')),
    radius: Float64Array.from(array_of(value.radius, `${where}/radius`, n, finite_at_least_zero, 'a number >= 0')),
    mass: Float64Array.from(array_of(value.mass, `${where}/mass`, n, finite_at_least_zero, 'a number >= 0')),
    charge,
    owner: Float64Array.from(array_of(value.owner, `${where}/owner`, n, is_whole, 'a whole number')),
  };
}

function read_moves(value) {
  if (typeof value !== 'object' || value === null || Array.isArray(value)) refuse('/moved: must be an object');
  const runs = array_of(value.runs, '/moved/runs', null, is_whole, 'a whole number');
  let moved = 0;
  for (let i = 1; i < runs.length; i += 2) {
    moved += runs[i];
    if (moved > max_safe / 3) refuse(`/moved/runs/${i}: more moved bodies than a message holds`);
  }
  return {
    runs,
    p: array_of(value.p, '/moved/p', 3 * moved, is_integer, 'a whole number of quanta'),
    v: array_of(value.v, '/moved/v', 3 * moved, is_integer, 'a whole number of quanta'),
  };
}

/** The head of a compact snapshot: tick, time, paused, faults, checked. */
function read_head(message) {
  if (!is_whole(message.tick)) refuse('/tick: must be a whole number');
  if (!finite(message.time)) refuse('/time: must be a finite number');
  if (message.paused !== undefined && typeof message.paused !== 'boolean') refuse('/paused: must be a boolean');
  if (message.faults !== undefined && !is_whole(message.faults)) refuse('/faults: must be a whole number');
  return { tick: message.tick, time: message.time, paused: message.paused === true, faults: message.faults ?? 0 };
}

// ------------------------------------------------------------------ applying it

function keyframe_state(message) {
  const head = read_head(message);
  if (message.base !== undefined || message.moved !== undefined || message.appeared !== undefined || message.vanished !== undefined) {
    refuse('a keyframe has no base, moved, appeared or vanished');
  }
  const q = message.q;
  if (!Array.isArray(q) || q.length !== 2 || !q.every((x) => typeof x === 'number' && x > 0 && Number.isFinite(x))) {
    refuse('/q: must be 2 numbers > 0');
  }
  if (message.bodies === undefined) refuse('/bodies: missing (required in a keyframe)');
  return { ...head, q: [q[0], q[1]], ...read_bodies(message.bodies, '/bodies') };
}

function delta_state(message, held) {
  const head = read_head(message);
  if (!is_whole(message.base)) refuse('/base: missing or not a whole number');
  if (!(message.base < message.tick)) refuse('/base: must be below the tick');
  if (message.bodies !== undefined || message.q !== undefined) refuse('a delta has no bodies or q (its base\'s hold)');
  if (!held) refuse(`a delta against tick ${message.base}, and no keyframe came before it`);
  if (held.tick !== message.base) refuse(`a delta against tick ${message.base}, but the state held is of tick ${held.tick}`);
  const moved = message.moved === undefined ? { runs: [], p: [], v: [] } : read_moves(message.moved);
  const vanished = message.vanished === undefined ? new Float64Array(0) : ungapped(message.vanished, '/vanished');
  const added = message.appeared === undefined ? null : read_bodies(message.appeared, '/appeared');
  const charges = held.charge !== null;
  if (added && (added.charge !== null) !== charges) refuse('appeared bodies have charges where the keyframe\'s have none, or none where it has them');

  const half_steps = prediction_factor(held.time, message.time, held.q);
  const n = held.count;
  // The base's bodies, less the vanished, the moved ones updated.
  const kept = columns(n, charges);
  let k = 0; // bodies kept
  let run = 0; // index into moved.runs
  let run_left = 0; // bodies left in the current run
  let next_move = 0;
  let next_vanished = 0;
  const advance_runs = () => {
    while (run_left === 0 && run < moved.runs.length) run_left = moved.runs[run++];
  };
  for (let i = 0; i < n; i++) {
    advance_runs();
    const is_moved = run_left > 0 && run % 2 === 0; // run was counted past a run of moved bodies
    if (run_left > 0) run_left--;
    if (next_vanished < vanished.length && vanished[next_vanished] === held.id[i]) {
      next_vanished++;
      if (is_moved) refuse(`body ${held.id[i]} both moved and vanished`);
      continue;
    }
    copy_body(kept, k, held, i);
    if (is_moved) {
      for (let d = 0; d < 3; d++) {
        const vb = held.v[3 * i + d];
        const v = vb + moved.v[3 * next_move + d];
        if (!(Math.abs(v) <= max_safe)) refuse(`body ${held.id[i]} moves beyond 2^53 quanta`);
        const p = exact_sum(held.p[3 * i + d], predicted_offset(vb, v, half_steps), moved.p[3 * next_move + d]);
        if (p === null) refuse(`body ${held.id[i]} moves beyond 2^53 quanta`);
        kept.v[3 * k + d] = v;
        kept.p[3 * k + d] = p;
      }
      next_move++;
    }
    k++;
  }
  advance_runs();
  if (run_left > 0 || run < moved.runs.length) refuse(`moved.runs reach past the base's ${n} bodies`);
  if (next_vanished < vanished.length) refuse(`vanished body ${vanished[next_vanished]} is not in the base (or not in id order)`);

  // The bodies kept and those that appeared, merged in id order.
  const a_count = added ? added.count : 0;
  const out = columns(k + a_count, charges);
  let a = 0;
  let b = 0;
  let o = 0;
  while (a < k || b < a_count) {
    if (b === a_count || (a < k && kept.id[a] < added.id[b])) copy_body(out, o++, kept, a++);
    else if (a === k || added.id[b] < kept.id[a]) copy_body(out, o++, added, b++);
    else refuse(`appeared body ${added.id[b]} is already held`);
  }
  return { ...head, q: held.q, ...out };
}

function columns(n, charges) {
  return {
    count: n,
    id: new Float64Array(n),
    p: new Float64Array(3 * n),
    v: new Float64Array(3 * n),
    radius: new Float64Array(n),
    mass: new Float64Array(n),
    charge: charges ? new Float64Array(n) : null,
    owner: new Float64Array(n),
  };
}

function copy_body(to, j, from, i) {
  to.id[j] = from.id[i];
  for (let d = 0; d < 3; d++) {
    to.p[3 * j + d] = from.p[3 * i + d];
    to.v[3 * j + d] = from.v[3 * i + d];
  }
  to.radius[j] = from.radius[i];
  to.mass[j] = from.mass[i];
  to.owner[j] = from.owner[i];
  if (to.charge) to.charge[j] = from.charge[i];
}

/**
 * Applies a compact snapshot (a parsed `snapshot` message with `form` "key" or "delta") to
 * `held`, the state of its base (null when none is held). Returns {state} — the new state:
 * tick, time, paused, faults, q, count and the columns id, p and v (whole quanta), radius,
 * mass, charge (or null), owner — or {failure}, the reason it cannot apply. `held` is never
 * changed.
 */
export function apply_compact(message, held) {
  try {
    if (message.form === 'key') return { state: keyframe_state(message) };
    if (message.form === 'delta') return { state: delta_state(message, held) };
    refuse(`/form: must be "key" or "delta", got ${JSON.stringify(message.form)}`);
  } catch (error) {
    if (error instanceof Refused) return { failure: error.message };
    throw error;
  }
}

/**
 * The state as the columns the page draws from (interpolation.js, snapshot_from_message):
 * positions and velocities as quanta · integer, each in a new array (they are transferred
 * away from the worker; the state keeps its own).
 */
export function to_snapshot(state, received_at) {
  const [qp, qv] = state.q;
  const position = new Float64Array(3 * state.count);
  const velocity = new Float64Array(3 * state.count);
  for (let k = 0; k < 3 * state.count; k++) {
    position[k] = state.p[k] * qp;
    velocity[k] = state.v[k] * qv;
  }
  return {
    tick: state.tick,
    time: state.time,
    paused: state.paused,
    received_at,
    count: state.count,
    id: state.id.slice(),
    position,
    velocity,
    radius: state.radius.slice(),
    mass: state.mass.slice(),
    charge: state.charge ? state.charge.slice() : null,
    owner: state.owner.slice(),
    index_by_id: null,
  };
}

/**
 * One connection's compact stream: the state of the last compact snapshot applied. A refused
 * message drops it, so that nothing but a keyframe applies after it.
 */
export class CompactStream {
  constructor() {
    this.held = null;
  }

  /** {state} after applying `message`, or {failure}. */
  apply(message) {
    const result = apply_compact(message, this.held);
    this.held = result.state ?? null;
    return result;
  }
}
