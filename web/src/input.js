// What the pointer does. A click (press and release without moving) on the floor, a wall or
// an obstacle spawns a sphere resting on it, also when a sphere passes under the pointer at
// that moment; a click on open space (a scene without walls) spawns one under the pointer,
// as far from the camera as the scene's centre; a drag that starts on a sphere pushes that
// sphere, with an arrow showing the push while dragging; any other drag orbits the camera.
// The game mode (game.js) turns spawning off, lets only the player's own ball be pushed, and
// pushes along the ground: from the ball to the point of the floor's plane under the pointer.
import * as THREE from 'three';
import { dot, unit_wall } from './wall_geometry.js';

const click_slop = 5; // px: a press that moves less than this is a click
const arrow_colour = 0xffe066;

/**
 * Where to put a new sphere of radius r for a click on a surface: on the surface, and
 * moved off any wall it would cross, since the server refuses a sphere across a wall.
 */
export function spawn_position(point, normal, r, walls) {
  const gap = 0.02 * r; // m: starts just clear of the surface
  const p = [0, 1, 2].map((k) => point[k] + normal[k] * (r + gap));
  for (const wall of walls.map(unit_wall)) {
    const distance = dot(wall.normal, p) - wall.offset;
    if (distance < r + gap) for (let k = 0; k < 3; k++) p[k] += wall.normal[k] * (r + gap - distance);
  }
  return p;
}

export class PointerInput {
  /**
   * view: the SceneView. settings(): {radius, density, push} from the panel.
   * on_spawn(position, radius, density), on_impulse(id, impulse, delta_v).
   * on_nothing_spawned(why): a click that spawned nothing, and why, in words.
   * walls(): the current scene's walls. mass_of(frame, index): the body's mass in kg.
   * spawns: whether a click spawns. can_push(id): whether a drag from that body pushes it
   * (else it turns the camera). ground: push in the horizontal plane through the body's
   * centre, not the plane facing the camera. max_delta_v: m/s, the longest push.
   */
  constructor({ view, settings, walls, mass_of, on_spawn, on_impulse, on_nothing_spawned, label, spawns = true, can_push = () => true, ground = false, max_delta_v = Infinity }) {
    this.view = view;
    this.spawns = spawns;
    this.can_push = can_push;
    this.ground = ground;
    this.max_delta_v = max_delta_v;
    this.settings = settings;
    this.walls = walls;
    this.mass_of = mass_of;
    this.on_spawn = on_spawn;
    this.on_impulse = on_impulse;
    this.on_nothing_spawned = on_nothing_spawned;
    this.label = label; // an element that shows the push next to the pointer
    this.press = null; // {x, y, pointer} of a press that may become a click
    this.drag = null; // {id, pointer, x, y, from_x, from_y} while pushing a sphere
    this.arrow = new THREE.ArrowHelper(new THREE.Vector3(1, 0, 0), new THREE.Vector3(), 1, arrow_colour);
    for (const part of [this.arrow.line, this.arrow.cone]) {
      part.material.depthTest = false; // drawn over the spheres it starts in
      part.renderOrder = 10;
    }
    this.arrow.visible = false;
    view.scene.add(this.arrow);

    const canvas = view.canvas;
    // Capture phase: decide before the orbit controls see the press.
    canvas.addEventListener('pointerdown', (e) => this.on_down(e), { capture: true });
    canvas.addEventListener('pointermove', (e) => this.on_move(e));
    canvas.addEventListener('pointerup', (e) => this.on_up(e));
    canvas.addEventListener('pointercancel', () => this.cancel());
  }

  on_down(event) {
    if (event.button !== 0 || this.drag) return;
    const index = this.view.body_at(event.clientX, event.clientY);
    if (index < 0 || !this.can_push(this.view.frame.id[index])) {
      this.press = { x: event.clientX, y: event.clientY, pointer: event.pointerId };
      return;
    }
    this.view.controls.enabled = false;
    this.view.canvas.setPointerCapture(event.pointerId);
    this.drag = {
      id: this.view.frame.id[index], pointer: event.pointerId,
      x: event.clientX, y: event.clientY, from_x: event.clientX, from_y: event.clientY,
    };
    this.update_arrow();
  }

  on_move(event) {
    if (this.press && Math.hypot(event.clientX - this.press.x, event.clientY - this.press.y) > click_slop) this.press = null;
    if (!this.drag || event.pointerId !== this.drag.pointer) return;
    this.drag.x = event.clientX;
    this.drag.y = event.clientY;
    this.update_arrow();
  }

  on_up(event) {
    if (this.drag && event.pointerId === this.drag.pointer) {
      const moved = Math.hypot(event.clientX - this.drag.from_x, event.clientY - this.drag.from_y);
      const push = this.push();
      this.cancel();
      if (moved <= click_slop) {
        // Pressed and released in place: a click, meant for the surface (a sphere that
        // moved under the pointer must not be pushed by it).
        this.click(event);
      } else if (push && push.delta_v.length() > 1e-6) {
        this.on_impulse(push.id, push.delta_v.clone().multiplyScalar(push.mass).toArray(), push.delta_v.toArray());
      }
      return;
    }
    if (!this.press || event.pointerId !== this.press.pointer) return;
    this.press = null;
    this.click(event);
  }

  /**
   * A click: a sphere resting on the surface under the pointer; with no surface there (a
   * scene without walls, or past its walls), one under the pointer on the plane through the
   * scene's centre that faces the camera, where the scene is, rather than nothing at all.
   */
  click(event) {
    if (!this.spawns) return;
    const { radius, density } = this.settings();
    const hit = this.view.surface_at(event.clientX, event.clientY);
    if (hit) {
      this.on_spawn(spawn_position(hit.point.toArray(), hit.normal.toArray(), radius, this.walls()), radius, density);
      return;
    }
    const point = this.view.point_facing_camera(event.clientX, event.clientY, this.view.centre);
    if (!point) {
      this.on_nothing_spawned('the click is on no surface, and the scene\'s centre is behind the camera');
      return;
    }
    this.on_spawn(spawn_position(point.toArray(), [0, 0, 0], radius, this.walls()), radius, density);
  }

  cancel() {
    this.drag = null;
    this.press = null;
    this.arrow.visible = false;
    this.label.hidden = true;
    this.view.controls.enabled = true;
  }

  /** The push being dragged: the body, its mass and the change of velocity, or null. */
  push() {
    const frame = this.view.frame;
    const index = frame ? index_in(frame, this.drag.id) : -1;
    if (index < 0) return null;
    const centre = new THREE.Vector3().fromArray(frame.position, 3 * index);
    const pointer = this.ground
      ? this.view.point_on_level(this.drag.x, this.drag.y, centre.z)
      : this.view.point_facing_camera(this.drag.x, this.drag.y, centre);
    if (!pointer) return null;
    const delta_v = pointer.sub(centre).multiplyScalar(this.settings().push); // m/s per m dragged
    if (delta_v.length() > this.max_delta_v) delta_v.setLength(this.max_delta_v);
    return { id: this.drag.id, centre, delta_v, mass: this.mass_of(frame, index) };
  }

  /** Follows the dragged body each frame, so the arrow stays on it while it moves. */
  update_arrow() {
    if (!this.drag) return;
    const push = this.push();
    if (!push) {
      this.cancel(); // the body left the world
      return;
    }
    const length = push.delta_v.length() / this.settings().push;
    this.arrow.visible = length > 1e-6;
    this.arrow.position.copy(push.centre);
    if (length > 1e-6) {
      this.arrow.setDirection(push.delta_v.clone().normalize());
      this.arrow.setLength(length, Math.min(0.3 * length, 0.5), Math.min(0.15 * length, 0.25));
    }
    const speed = push.delta_v.length();
    this.label.hidden = false;
    this.label.style.left = `${this.drag.x + 14}px`;
    this.label.style.top = `${this.drag.y + 14}px`;
    const impulse = speed * push.mass;
    this.label.textContent = `Δv ${speed.toFixed(2)} m/s · J ${impulse.toFixed(impulse >= 100 ? 0 : 2)} N·s`;
  }
}

function index_in(frame, id) {
  for (let i = 0; i < frame.count; i++) if (frame.id[i] === id) return i;
  return -1;
}
