// Colours of the spheres: by speed (a sequential scale from 0 to a round maximum) or by
// charge (a diverging scale, blue negative, grey neutral, red positive). The legend is drawn
// from the same stops, so it always matches.

export const speed_stops = ['#3b6fd8', '#3fc1c9', '#9be15d', '#f7d038', '#f05a28'];
export const charge_stops = ['#3b6fd8', '#8fb0e8', '#d0d4da', '#eb9a8c', '#e0442e'];

const lut_size = 256;

function srgb_to_linear(c) {
  return c <= 0.04045 ? c / 12.92 : ((c + 0.055) / 1.055) ** 2.4;
}

function parse_hex(hex) {
  const v = parseInt(hex.slice(1), 16);
  return [(v >> 16) & 255, (v >> 8) & 255, v & 255].map((c) => c / 255);
}

/** 256 colours along the stops, in linear RGB (what WebGL blends in), 3 floats each. */
export function lookup_table(stops) {
  const rgb = stops.map(parse_hex);
  const lut = new Float32Array(3 * lut_size);
  for (let i = 0; i < lut_size; i++) {
    const x = (i / (lut_size - 1)) * (rgb.length - 1);
    const k = Math.min(rgb.length - 2, Math.floor(x));
    const s = x - k;
    for (let c = 0; c < 3; c++) lut[3 * i + c] = srgb_to_linear(rgb[k][c] + s * (rgb[k + 1][c] - rgb[k][c]));
  }
  return lut;
}

/** The smallest of 1, 2, 5 times a power of ten that is >= x (and >= `floor`). */
export function round_up(x, floor = 1e-12) {
  const v = Math.max(x, floor);
  const power = 10 ** Math.floor(Math.log10(v));
  for (const m of [1, 2, 5, 10]) if (m * power >= v * (1 - 1e-12)) return m * power;
  return 10 * power;
}

/**
 * Writes a colour per body into `out` (3 floats each): by speed, from the frame's velocities,
 * with 0 at the first stop and `max` at the last; by charge, -max to +max.
 */
export function colour_bodies(frame, mode, max, out) {
  const lut = mode === 'charge' ? charge_lut : speed_lut;
  const last = lut_size - 1;
  for (let i = 0; i < frame.count; i++) {
    let x;
    if (mode === 'charge') {
      const q = frame.charge ? frame.charge[i] : 0;
      x = 0.5 + (0.5 * q) / max;
    } else {
      const v = frame.velocity;
      x = Math.sqrt(v[3 * i] * v[3 * i] + v[3 * i + 1] * v[3 * i + 1] + v[3 * i + 2] * v[3 * i + 2]) / max;
    }
    const entry = 3 * Math.round(last * Math.min(1, Math.max(0, x)));
    out[3 * i] = lut[entry];
    out[3 * i + 1] = lut[entry + 1];
    out[3 * i + 2] = lut[entry + 2];
  }
}

/**
 * The speed (m/s) that a share q (such as 0.98) of a snapshot's bodies do not exceed,
 * estimated from at most 2048 of them, evenly spread: enough for a legend's scale.
 */
export function speed_quantile(snapshot, q) {
  if (snapshot.count === 0) return 0;
  const stride = Math.ceil(snapshot.count / 2048);
  const v = snapshot.velocity;
  const speeds2 = new Float64Array(Math.ceil(snapshot.count / stride));
  for (let i = 0, k = 0; i < snapshot.count; i += stride, k++) {
    speeds2[k] = v[3 * i] * v[3 * i] + v[3 * i + 1] * v[3 * i + 1] + v[3 * i + 2] * v[3 * i + 2];
  }
  speeds2.sort();
  return Math.sqrt(speeds2[Math.min(speeds2.length - 1, Math.floor(q * speeds2.length))]);
}

/** The largest |charge| in a snapshot, C; 0 when it sends no charges. */
export function max_charge(snapshot) {
  let max = 0;
  if (snapshot.charge) for (const q of snapshot.charge) max = Math.max(max, Math.abs(q));
  return max;
}

const speed_lut = lookup_table(speed_stops);
const charge_lut = lookup_table(charge_stops);
