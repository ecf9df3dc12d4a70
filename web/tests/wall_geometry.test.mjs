// Unit tests for the drawn walls: a box's walls become its six faces, a lone floor a square.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { clip_polygon, floor_index, grid_lines, wall_polygon } from '../src/wall_geometry.js';

/** The six walls of an axis-aligned box, normals pointing in, as welcome.scene.walls has them. */
function box_walls(min, max) {
  const walls = [];
  for (let k = 0; k < 3; k++) {
    const n = [0, 0, 0];
    n[k] = 1;
    walls.push({ normal: [...n], offset: min[k] });
    n[k] = -1;
    walls.push({ normal: [...n], offset: -max[k] });
  }
  return walls;
}

const sorted_corners = (polygon) => polygon.map((p) => p.map((x) => Math.round(x * 1e9) / 1e9)).sort((a, b) => a[0] - b[0] || a[1] - b[1] || a[2] - b[2]);

test("a box's floor is drawn as exactly its bottom face, counter-clockwise seen from inside", () => {
  const walls = box_walls([-4, -4, 0], [4, 4, 12]);
  const floor = wall_polygon(walls, 4, [0, 0, 6], 20);
  assert.deepEqual(sorted_corners(floor), [[-4, -4, 0], [-4, 4, 0], [4, -4, 0], [4, 4, 0]]);
  const [a, b, c] = floor;
  const turn = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
  assert.ok(turn > 0, 'counter-clockwise about +z, the side the bodies are on');
  assert.equal(floor_index(walls), 4);
});

test("a box's side wall is drawn as its face", () => {
  const walls = box_walls([-4, -4, 0], [4, 4, 12]);
  const side = wall_polygon(walls, 1, [0, 0, 6], 20); // normal -x, at x = 4
  assert.deepEqual(sorted_corners(side), [[4, -4, 0], [4, -4, 12], [4, 4, 0], [4, 4, 12]]);
});

test('a lone floor is a square of the given half size around the centre, projected', () => {
  const floor = wall_polygon([{ normal: [0, 0, 2], offset: 2 }], 0, [1, 1, 5], 3); // z = 1, normal not unit
  assert.deepEqual(sorted_corners(floor), [[-2, -2, 1], [-2, 4, 1], [4, -2, 1], [4, 4, 1]]);
});

test('a wall with nothing left after clipping draws nothing', () => {
  assert.deepEqual(clip_polygon([[0, 0, 0], [1, 0, 0], [0, 1, 0]], { normal: [1, 0, 0], offset: 5 }), []);
  assert.equal(floor_index([{ normal: [1, 0, 0], offset: 0 }]), -1, 'no wall faces up');
});

test('grid lines stay inside the floor', () => {
  const walls = box_walls([-4, -4, 0], [4, 4, 12]);
  const lines = grid_lines(wall_polygon(walls, 4, [0, 0, 6], 20), [0, 0, 1], 2);
  assert.equal(lines.length, 10); // x and y = -4, -2, 0, 2, 4
  for (const point of lines.flat()) for (const x of point.slice(0, 2)) assert.ok(Math.abs(x) <= 4 + 1e-9, `${point} is outside`);
});
