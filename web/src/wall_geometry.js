// The drawable part of the scene's walls. A wall is an infinite plane n·x = d whose normal
// points to where bodies may be; what is drawn of it is a square around the scene's bounds,
// cut by every other wall to the side where bodies may be. For a box that leaves exactly its
// six faces; for a lone floor, a square floor.

export const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
const scale = (a, s) => [a[0] * s, a[1] * s, a[2] * s];
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
const lerp = (a, b, s) => add(a, scale(add(b, scale(a, -1)), s));

/** A wall with a unit normal: {normal, offset} such that normal·x - offset is a distance. */
export function unit_wall(wall) {
  const length = Math.hypot(...wall.normal);
  return { ...wall, normal: scale(wall.normal, 1 / length), offset: wall.offset / length };
}

/** Two unit vectors u, w along the plane with u × w = n. */
export function plane_basis(n) {
  const reference = Math.abs(n[2]) < 0.9 ? [0, 0, 1] : [1, 0, 0]; // any axis not along n
  const u = cross(reference, n);
  const u_unit = scale(u, 1 / Math.hypot(...u));
  return [u_unit, cross(n, u_unit)];
}

/** Keeps the part of a convex polygon where normal·x >= offset (Sutherland–Hodgman). */
export function clip_polygon(points, wall) {
  const kept = [];
  for (let i = 0; i < points.length; i++) {
    const a = points[i];
    const b = points[(i + 1) % points.length];
    const da = dot(wall.normal, a) - wall.offset;
    const db = dot(wall.normal, b) - wall.offset;
    if (da >= 0) kept.push(a);
    if (da >= 0 !== db >= 0) kept.push(lerp(a, b, da / (da - db)));
  }
  return kept;
}

/**
 * The drawn polygon of walls[index]: counter-clockwise seen from where its normal points,
 * clipped by the other walls; empty when the other walls leave nothing of it.
 * `half_size` is half the side of the square it starts from, around `centre`.
 */
export function wall_polygon(walls, index, centre, half_size) {
  const wall = unit_wall(walls[index]);
  const n = wall.normal;
  const foot = add(centre, scale(n, wall.offset - dot(n, centre))); // centre projected onto the plane
  const [u, w] = plane_basis(n);
  let polygon = [
    [-1, -1],
    [1, -1],
    [1, 1],
    [-1, 1],
  ].map(([su, sw]) => add(foot, add(scale(u, su * half_size), scale(w, sw * half_size))));
  walls.forEach((other, k) => {
    if (k !== index && polygon.length) polygon = clip_polygon(polygon, unit_wall(other));
  });
  return polygon.length >= 3 ? polygon : [];
}

/**
 * Grid lines on a wall's polygon, `spacing` apart along the wall's own axes, as pairs of
 * end points. The polygon is convex, so each line is clipped by its edges.
 */
export function grid_lines(polygon, normal, spacing) {
  if (polygon.length < 3) return [];
  const [u, w] = plane_basis(normal);
  const lines = [];
  for (const [along, across] of [
    [u, w],
    [w, u],
  ]) {
    const values = polygon.map((p) => dot(p, across));
    const spans = polygon.map((p) => dot(p, along));
    const lo = Math.min(...spans) - 1;
    const hi = Math.max(...spans) + 1;
    const base = scale(normal, dot(normal, polygon[0]));
    for (let c = Math.ceil(Math.min(...values) / spacing) * spacing; c <= Math.max(...values); c += spacing) {
      const a = add(base, add(scale(across, c), scale(along, lo)));
      const b = add(base, add(scale(across, c), scale(along, hi)));
      const segment = clip_segment_to_polygon(a, b, polygon, normal);
      if (segment) lines.push(segment);
    }
  }
  return lines;
}

/** The part of segment a–b inside a convex polygon (counter-clockwise about `normal`), or null. */
function clip_segment_to_polygon(a, b, polygon, normal) {
  let t0 = 0;
  let t1 = 1;
  for (let i = 0; i < polygon.length; i++) {
    const p = polygon[i];
    const q = polygon[(i + 1) % polygon.length];
    const inward = cross(normal, add(q, scale(p, -1))); // points into the polygon
    const da = dot(inward, add(a, scale(p, -1)));
    const db = dot(inward, add(b, scale(p, -1)));
    if (da < 0 && db < 0) return null;
    if (da < 0) t0 = Math.max(t0, da / (da - db));
    else if (db < 0) t1 = Math.min(t1, da / (da - db));
  }
  return t0 < t1 ? [lerp(a, b, t0), lerp(a, b, t1)] : null;
}

/** The index of the wall most like a floor (normal closest to +z, at least 60° up), or -1. */
export function floor_index(walls) {
  let best = -1;
  let best_z = 0.5;
  walls.forEach((wall, i) => {
    const z = unit_wall(wall).normal[2];
    if (z > best_z) {
      best = i;
      best_z = z;
    }
  });
  return best;
}
