// Snapshot interpolation. The page draws the world a little in the past (about two snapshot
// intervals behind the newest), between two snapshots it already holds, so motion is smooth
// between snapshots and a lost snapshot only widens the interval being interpolated.
//
// Between two snapshots a body's position is the cubic Hermite curve through both positions
// with both sent velocities as its slopes. That reproduces any motion of constant
// acceleration exactly (a parabola is a cubic with a zero cubic term), so free fall and
// straight flight are drawn where the server has them. A bounce between the two snapshots is
// not such a motion: there the curve would dip through the wall, so those bodies are drawn on
// the straight line instead (see `moved_smoothly`).

/** A snapshot message as columns of typed arrays, stamped with its local arrival time. */
export function snapshot_from_message(message, received_at) {
  const bodies = message.bodies;
  const snapshot = {
    tick: message.tick,
    time: message.time,
    paused: message.paused === true, // the world stands still: time does not move on
    received_at, // local seconds
    count: bodies.id.length,
    id: Float64Array.from(bodies.id),
    position: Float64Array.from(bodies.position),
    velocity: Float64Array.from(bodies.velocity),
    radius: Float64Array.from(bodies.radius),
    mass: bodies.mass ? Float64Array.from(bodies.mass) : null,
    charge: bodies.charge ? Float64Array.from(bodies.charge) : null,
    index_by_id: null,
  };
  return snapshot;
}

/** The index of body `id` in a snapshot, or -1. Builds the snapshot's id index once. */
export function index_of(snapshot, id) {
  if (!snapshot.index_by_id) {
    snapshot.index_by_id = new Map();
    for (let i = 0; i < snapshot.count; i++) snapshot.index_by_id.set(snapshot.id[i], i);
  }
  const index = snapshot.index_by_id.get(id);
  return index === undefined ? -1 : index;
}

/**
 * Cubic Hermite interpolation of one coordinate: position p0 with velocity v0 at s = 0,
 * p1 with v1 at s = 1, over an interval of h seconds; s in [0, 1].
 */
export function hermite(p0, v0, p1, v1, h, s) {
  const s2 = s * s;
  const s3 = s2 * s;
  const h00 = 2 * s3 - 3 * s2 + 1;
  const h10 = s3 - 2 * s2 + s;
  const h01 = -2 * s3 + 3 * s2;
  const h11 = s3 - s2;
  return h00 * p0 + h10 * h * v0 + h01 * p1 + h11 * h * v1;
}

/**
 * The last few snapshots, oldest first, and the world drawn from them at any time.
 * Bounded: holds at most `capacity` snapshots.
 */
export class SnapshotBuffer {
  constructor({ capacity = 16, max_extrapolation = 0.1 } = {}) {
    this.capacity = capacity;
    this.max_extrapolation = max_extrapolation; // s of simulated time past the newest snapshot
    this.snapshots = [];
    this.frame = {
      count: 0,
      id: new Float64Array(0),
      position: new Float64Array(0),
      velocity: new Float64Array(0),
      radius: new Float64Array(0),
      mass: null, // the later snapshot's columns, when it sends them
      charge: null,
      time: 0,
      tick: 0,
    };
  }

  get length() {
    return this.snapshots.length;
  }

  get newest() {
    return this.snapshots.length ? this.snapshots[this.snapshots.length - 1] : null;
  }

  get oldest() {
    return this.snapshots.length ? this.snapshots[0] : null;
  }

  clear() {
    this.snapshots.length = 0;
  }

  /**
   * Adds a snapshot; one not newer than the newest held is ignored, except that a later tick
   * at the same time (a paused room, where commands still change the world) replaces the
   * newest. Returns whether kept.
   */
  push(snapshot) {
    const newest = this.newest;
    if (newest && snapshot.time === newest.time && snapshot.tick > newest.tick) {
      this.snapshots[this.snapshots.length - 1] = snapshot;
      return true;
    }
    if (newest && snapshot.time <= newest.time) return false;
    this.snapshots.push(snapshot);
    while (this.snapshots.length > this.capacity) this.snapshots.shift();
    return true;
  }

  /**
   * The world at simulated time t: every body of the later snapshot of the pair around t,
   * with interpolated positions and velocities. Before the oldest snapshot it shows the
   * oldest; past the newest it extrapolates along the velocities for at most
   * `max_extrapolation` seconds, then holds still. The returned frame is reused by the next
   * call.
   */
  sample(t) {
    const frame = this.frame;
    const n = this.snapshots.length;
    if (n === 0) {
      frame.count = 0;
      return frame;
    }
    let later = n - 1;
    while (later > 0 && this.snapshots[later - 1].time >= t) later--;
    const b = this.snapshots[later];
    const a = later > 0 && t < b.time ? this.snapshots[later - 1] : null;
    this.reserve(b.count);
    frame.count = b.count;
    frame.time = t;
    frame.tick = b.tick;
    frame.id.set(b.id);
    frame.radius.set(b.radius);
    frame.mass = b.mass;
    frame.charge = b.charge;
    if (a) this.interpolate(a, b, t);
    else this.extrapolate(b, b.paused ? 0 : Math.min(t - b.time, this.max_extrapolation));
    return frame;
  }

  interpolate(a, b, t) {
    const { position, velocity } = this.frame;
    const h = b.time - a.time;
    const s = (t - a.time) / h;
    for (let j = 0; j < b.count; j++) {
      const j3 = 3 * j;
      // Bodies usually keep their order from one snapshot to the next: try the same index first.
      const i = j < a.count && a.id[j] === b.id[j] ? j : index_of(a, b.id[j]);
      if (i < 0) {
        // Spawned since a: drawn where it first appeared.
        for (let k = 0; k < 3; k++) {
          position[j3 + k] = b.position[j3 + k];
          velocity[j3 + k] = b.velocity[j3 + k];
        }
        continue;
      }
      const i3 = 3 * i;
      // Hermite when the body moved smoothly; the chord when it bounced.
      const smooth = moved_smoothly(a, i3, b, j3, h);
      for (let k = 0; k < 3; k++) {
        const p0 = a.position[i3 + k];
        const p1 = b.position[j3 + k];
        const v0 = a.velocity[i3 + k];
        const v1 = b.velocity[j3 + k];
        position[j3 + k] = smooth ? hermite(p0, v0, p1, v1, h, s) : p0 + s * (p1 - p0);
        velocity[j3 + k] = v0 + s * (v1 - v0);
      }
    }
  }

  extrapolate(b, dt) {
    const { position, velocity } = this.frame;
    const ahead = Math.max(0, dt);
    for (let j3 = 0; j3 < 3 * b.count; j3++) {
      position[j3] = b.position[j3] + ahead * b.velocity[j3];
      velocity[j3] = b.velocity[j3];
    }
  }

  reserve(count) {
    const frame = this.frame;
    if (frame.id.length >= count) return;
    const capacity = Math.max(count, 2 * frame.id.length);
    frame.id = new Float64Array(capacity);
    frame.radius = new Float64Array(capacity);
    frame.position = new Float64Array(3 * capacity);
    frame.velocity = new Float64Array(3 * capacity);
  }
}

/**
 * Whether a body (index i3 / 3 in snapshot a, j3 / 3 in b, h seconds apart) moved the way a
 * constant acceleration moves it. Under constant acceleration the displacement equals h
 * times the mean of the two velocities exactly (the trapezoid rule is exact for a
 * parabola); a bounce or a push in between breaks that by about a speed times h, far more
 * than a smooth force does in one snapshot interval.
 */
export function moved_smoothly(a, i3, b, j3, h) {
  let mismatch2 = 0;
  let chord2 = 0;
  for (let k = 0; k < 3; k++) {
    const chord = b.position[j3 + k] - a.position[i3 + k];
    const trapezoid = 0.5 * h * (a.velocity[i3 + k] + b.velocity[j3 + k]);
    mismatch2 += (chord - trapezoid) ** 2;
    chord2 += chord * chord;
  }
  const tolerance = 1e-4 + 0.1 * Math.sqrt(chord2); // m
  return mismatch2 <= tolerance * tolerance;
}

/**
 * The simulated time to draw. It runs at the server's pace (`rate` simulated seconds per
 * second) and stays `delay` behind the newest simulated time the server is estimated to
 * have reached: the newest snapshot's time plus the time since it arrived. Instead of
 * jumping with every snapshot's arrival jitter it speeds up or slows down by at most
 * `max_correction`, closing a gap within about `catch_up` seconds; a gap larger than
 * `snap_after` (a reconnect, a tab that slept) is closed at once.
 */
export class PlaybackClock {
  constructor({ delay, rate = 1, max_correction = 0.1, catch_up = 0.5, snap_after = 0.5 }) {
    this.delay = delay; // s of simulated time
    this.rate = rate; // simulated s per local s
    this.max_correction = max_correction;
    this.catch_up = catch_up; // local s
    this.snap_after = snap_after; // s of simulated time
    this.reset();
  }

  reset() {
    this.render_time = null; // simulated s
    this.last_now = null; // local s
    this.newest_time = null;
    this.newest_arrival = null;
  }

  /** Tells the clock a snapshot of simulated time `time` arrived at local time `now`. */
  on_snapshot(time, now) {
    if (this.newest_time !== null && time <= this.newest_time) return;
    this.newest_time = time;
    this.newest_arrival = now;
  }

  /** Where the drawing should be at local time `now`, or null before any snapshot. */
  target(now) {
    if (this.newest_time === null) return null;
    return this.newest_time + (now - this.newest_arrival) * this.rate - this.delay;
  }

  /** Advances to local time `now` (seconds) and returns the simulated time to draw. */
  time(now) {
    const target = this.target(now);
    if (target === null) return null;
    if (this.render_time === null || Math.abs(target - this.render_time) > this.snap_after) {
      this.render_time = target;
    } else {
      const step = Math.max(0, now - this.last_now) * this.rate;
      const gap = target - (this.render_time + step);
      const correction = clamp(gap / (this.catch_up * this.rate), -this.max_correction, this.max_correction);
      this.render_time += step * (1 + correction);
    }
    this.last_now = now;
    return this.render_time;
  }
}

function clamp(x, lo, hi) {
  return Math.min(hi, Math.max(lo, x));
}
