// The three.js side: the spheres as one InstancedMesh, the walls, box and obstacles from
// `welcome`, lights, and an orbit camera framed on the scene's bounds. The server's z axis
// is up, and so is the camera's.
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { floor_index, grid_lines, unit_wall, wall_polygon } from './wall_geometry.js';

export const background_colour = 0x12161c;
const floor_colour = 0x262c35;
const grid_colour = 0x39424e;
const wall_colour = 0x8fa3b8;
const edge_colour = 0x5b6b7c;
const obstacle_colour = 0xa88a5c;

/**
 * Width and height segments of the spheres' shared geometry for a number of spheres: round
 * enough to look round when there are few, few enough triangles when there are many
 * (352, 140 and 80 triangles per sphere).
 */
function sphere_detail(count) {
  if (count <= 2048) return [16, 12];
  if (count <= 16384) return [10, 8];
  return [8, 6];
}

export class SceneView {
  constructor(canvas) {
    this.canvas = canvas;
    this.renderer = new THREE.WebGLRenderer({ canvas, antialias: true });
    this.renderer.setPixelRatio(Math.min(window.devicePixelRatio, 2));
    this.renderer.setClearColor(background_colour);

    this.scene = new THREE.Scene();
    this.camera = new THREE.PerspectiveCamera(45, 1, 0.01, 1000);
    this.camera.up.set(0, 0, 1);
    this.controls = new OrbitControls(this.camera, canvas);
    this.controls.enableDamping = true;

    const sky = new THREE.HemisphereLight(0xdfe8f5, 0x30281f, 1.6);
    sky.position.set(0, 0, 1); // the hemisphere's "up" is +z
    const sun = new THREE.DirectionalLight(0xffffff, 1.8);
    sun.position.set(-3, -5, 10);
    this.scene.add(sky, sun);

    this.static_group = new THREE.Group(); // walls and obstacles of the current scene
    this.scene.add(this.static_group);
    this.surfaces = []; // meshes a click may spawn on
    this.centre = new THREE.Vector3(); // of the scene's bounds

    this.sphere_geometry = null;
    this.sphere_material = new THREE.MeshStandardMaterial({ roughness: 0.45, metalness: 0.05 });
    this.spheres = null;
    this.capacity = 0;
    this.point_radius = 0.01; // m: how big a point mass (radius 0) is drawn; set from the bounds
    this.drawn_radius = new Float64Array(0);

    this.resize();
    new ResizeObserver(() => this.resize()).observe(canvas);
  }

  resize() {
    const width = this.canvas.clientWidth;
    const height = this.canvas.clientHeight;
    if (width === 0 || height === 0) return;
    this.renderer.setSize(width, height, false);
    this.camera.aspect = width / height;
    this.camera.updateProjectionMatrix();
  }

  /**
   * Draws a scene's static geometry (welcome.scene) and frames the camera on its bounds,
   * from `view` {azimuth, elevation} (degrees) when given.
   */
  set_scene(scene, { frame_camera = true, view = undefined } = {}) {
    for (const child of [...this.static_group.children]) {
      this.static_group.remove(child);
      child.geometry?.dispose();
      child.material?.dispose();
    }
    this.surfaces = [];
    const centre = scene.bounds.centre;
    this.centre.set(...centre);
    const radius = scene.bounds.radius > 0 ? scene.bounds.radius : 1;
    this.point_radius = radius * 0.004;
    const floor = floor_index(scene.walls);
    scene.walls.forEach((wall, i) => this.add_wall(scene.walls, i, i === floor, centre, radius));
    for (const obstacle of scene.obstacles) this.add_obstacle(obstacle);
    if (frame_camera) this.frame_camera(centre, radius, view);
  }

  add_wall(walls, index, is_floor, centre, radius) {
    const polygon = wall_polygon(walls, index, centre, 1.5 * radius);
    if (!polygon.length) return;
    const normal = unit_wall(walls[index]).normal;
    // A fan of triangles, counter-clockwise seen from the side bodies are on: seen from
    // behind (from outside a box) a wall is not drawn and a click passes through it.
    const positions = [];
    for (let i = 1; i + 1 < polygon.length; i++) positions.push(...polygon[0], ...polygon[i], ...polygon[i + 1]);
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute('position', new THREE.Float32BufferAttribute(positions, 3));
    geometry.computeVertexNormals();
    const material = is_floor
      ? new THREE.MeshStandardMaterial({ color: floor_colour, roughness: 0.9, side: THREE.FrontSide })
      : new THREE.MeshStandardMaterial({
          color: wall_colour,
          roughness: 0.9,
          transparent: true,
          opacity: 0.1,
          depthWrite: false,
          side: THREE.FrontSide,
        });
    const mesh = new THREE.Mesh(geometry, material);
    mesh.userData.normal = new THREE.Vector3(...normal);
    mesh.renderOrder = is_floor ? 0 : 2; // translucent walls after the spheres
    this.static_group.add(mesh);
    this.surfaces.push(mesh);

    const outline = new THREE.BufferGeometry().setFromPoints(polygon.map((p) => new THREE.Vector3(...p)));
    this.static_group.add(new THREE.LineLoop(outline, new THREE.LineBasicMaterial({ color: edge_colour })));
    if (is_floor) {
      const spacing = nice_spacing(radius / 5);
      const segments = grid_lines(polygon, normal, spacing).flat();
      // Lifted a hair above the floor so the lines win the depth test.
      const lifted = segments.map((p) => new THREE.Vector3(...p).addScaledVector(mesh.userData.normal, radius * 1e-4));
      const grid = new THREE.BufferGeometry().setFromPoints(lifted);
      this.static_group.add(new THREE.LineSegments(grid, new THREE.LineBasicMaterial({ color: grid_colour })));
    }
  }

  add_obstacle(obstacle) {
    const [hx, hy, hz] = obstacle.half_extents;
    const geometry = new THREE.BoxGeometry(2 * hx, 2 * hy, 2 * hz);
    const mesh = new THREE.Mesh(
      geometry,
      new THREE.MeshStandardMaterial({ color: obstacle_colour, roughness: 0.6, metalness: 0.1 }),
    );
    const [a0, a1, a2] = obstacle.axes.map((a) => new THREE.Vector3(...a));
    const rotation = new THREE.Matrix4().makeBasis(a0, a1, a2);
    mesh.quaternion.setFromRotationMatrix(rotation);
    mesh.position.set(...obstacle.centre);
    mesh.updateMatrixWorld();
    this.static_group.add(mesh);
    this.surfaces.push(mesh);
    const edges = new THREE.LineSegments(new THREE.EdgesGeometry(geometry), new THREE.LineBasicMaterial({ color: 0x5e4a2e }));
    edges.quaternion.copy(mesh.quaternion);
    edges.position.copy(mesh.position);
    this.static_group.add(edges);
  }

  /**
   * Puts the camera where the whole bounding sphere fits in view: by default a little from
   * above, looking along +y and a little +x.
   */
  frame_camera(centre, radius, { azimuth = -62, elevation = 30 } = {}) {
    const fov = THREE.MathUtils.degToRad(this.camera.fov);
    const fit = Math.min(fov, 2 * Math.atan(Math.tan(fov / 2) * this.camera.aspect)); // the narrower angle
    const distance = (1.05 * radius) / Math.sin(fit / 2);
    const a = THREE.MathUtils.degToRad(azimuth);
    const e = THREE.MathUtils.degToRad(elevation);
    const direction = new THREE.Vector3(Math.cos(e) * Math.cos(a), Math.cos(e) * Math.sin(a), Math.sin(e));
    this.controls.target.set(...centre);
    this.camera.position.copy(this.controls.target).addScaledVector(direction, distance);
    this.camera.near = distance / 200;
    this.camera.far = distance * 20;
    this.camera.updateProjectionMatrix();
    this.controls.maxDistance = distance * 8;
    this.controls.update();
  }

  /** Draws the bodies of a frame (interpolation.js) with a colour each (3 linear floats). */
  set_bodies(frame, colours) {
    this.reserve(frame.count);
    const matrices = this.spheres.instanceMatrix.array;
    const drawn = this.drawn_radius;
    for (let i = 0; i < frame.count; i++) {
      const r = frame.radius[i] > 0 ? frame.radius[i] : this.point_radius;
      drawn[i] = r;
      const m = 16 * i;
      matrices[m] = r;
      matrices[m + 5] = r;
      matrices[m + 10] = r;
      matrices[m + 12] = frame.position[3 * i];
      matrices[m + 13] = frame.position[3 * i + 1];
      matrices[m + 14] = frame.position[3 * i + 2];
    }
    this.spheres.instanceColor.array.set(colours.subarray(0, 3 * frame.count));
    this.spheres.count = frame.count;
    this.spheres.instanceMatrix.needsUpdate = true;
    this.spheres.instanceColor.needsUpdate = true;
    this.frame = frame;
  }

  /**
   * The spheres the last set_bodies drew, read back from the instance matrices the GPU draws
   * from: {id, position (x, y, z each), radius}.
   */
  shown() {
    const count = this.spheres?.count ?? 0;
    const matrices = this.spheres?.instanceMatrix.array;
    const shown = { id: [], position: [], radius: [] };
    for (let i = 0; i < count; i++) {
      const m = 16 * i;
      shown.id.push(this.frame.id[i]);
      shown.position.push(matrices[m + 12], matrices[m + 13], matrices[m + 14]);
      shown.radius.push(matrices[m]);
    }
    return shown;
  }

  /** Makes room for `count` spheres: a new InstancedMesh of twice the size when full. */
  reserve(count) {
    if (count <= this.capacity) return;
    const capacity = Math.max(count, 2 * this.capacity, 1024);
    if (this.spheres) {
      this.scene.remove(this.spheres);
      this.spheres.dispose();
      this.sphere_geometry.dispose();
    }
    this.sphere_geometry = new THREE.SphereGeometry(1, ...sphere_detail(capacity));
    const spheres = new THREE.InstancedMesh(this.sphere_geometry, this.sphere_material, capacity);
    spheres.instanceMatrix.setUsage(THREE.DynamicDrawUsage);
    spheres.instanceColor = new THREE.InstancedBufferAttribute(new Float32Array(3 * capacity), 3);
    spheres.instanceColor.setUsage(THREE.DynamicDrawUsage);
    spheres.frustumCulled = false; // the instances move every frame: no single bound to cull by
    spheres.renderOrder = 1;
    const identity = new THREE.Matrix4();
    for (let i = 0; i < capacity; i++) spheres.setMatrixAt(i, identity);
    this.spheres = spheres;
    this.capacity = capacity;
    this.drawn_radius = new Float64Array(capacity);
    this.scene.add(spheres);
  }

  render() {
    this.controls.update();
    this.renderer.render(this.scene, this.camera);
  }

  /** A ray from the camera through a point given in CSS pixels of the canvas. */
  ray_at(client_x, client_y) {
    const rect = this.canvas.getBoundingClientRect();
    const ndc = new THREE.Vector2(((client_x - rect.left) / rect.width) * 2 - 1, -((client_y - rect.top) / rect.height) * 2 + 1);
    const raycaster = new THREE.Raycaster();
    raycaster.setFromCamera(ndc, this.camera);
    return raycaster;
  }

  /** The index in the drawn frame of the nearest sphere under a point, or -1. */
  body_at(client_x, client_y) {
    const frame = this.frame;
    if (!frame) return -1;
    const { origin, direction } = this.ray_at(client_x, client_y).ray;
    let best = -1;
    let best_t = Infinity;
    const p = frame.position;
    for (let i = 0; i < frame.count; i++) {
      // Ray–sphere: the nearest t >= 0 with |origin + t·direction - centre| = r.
      const ox = origin.x - p[3 * i];
      const oy = origin.y - p[3 * i + 1];
      const oz = origin.z - p[3 * i + 2];
      const b = ox * direction.x + oy * direction.y + oz * direction.z;
      const r = this.drawn_radius[i];
      const c = ox * ox + oy * oy + oz * oz - r * r;
      const discriminant = b * b - c;
      if (discriminant < 0) continue;
      const t = -b - Math.sqrt(discriminant);
      if (t >= 0 && t < best_t) {
        best_t = t;
        best = i;
      }
    }
    return best;
  }

  /**
   * The point on a wall or obstacle under a point on the screen and the surface's outward
   * normal there (towards where bodies may be), or null. Walls seen from behind are skipped.
   */
  surface_at(client_x, client_y) {
    const hits = this.ray_at(client_x, client_y).intersectObjects(this.surfaces, false);
    if (!hits.length) return null;
    const hit = hits[0];
    const normal = hit.object.userData.normal
      ? hit.object.userData.normal.clone()
      : hit.face.normal.clone().transformDirection(hit.object.matrixWorld);
    return { point: hit.point.clone(), normal };
  }

  /** The point where the ray through a screen point meets the plane through `through` facing the camera. */
  point_facing_camera(client_x, client_y, through) {
    const normal = this.camera.getWorldDirection(new THREE.Vector3());
    const plane = new THREE.Plane().setFromNormalAndCoplanarPoint(normal, through);
    return this.ray_at(client_x, client_y).ray.intersectPlane(plane, new THREE.Vector3());
  }

  /** The point where the ray through a screen point meets the horizontal plane at height z, or null. */
  point_on_level(client_x, client_y, z) {
    const plane = new THREE.Plane(new THREE.Vector3(0, 0, 1), -z);
    return this.ray_at(client_x, client_y).ray.intersectPlane(plane, new THREE.Vector3());
  }

  /** The camera's viewing direction, [x, y, z]. */
  forward() {
    return this.camera.getWorldDirection(new THREE.Vector3()).toArray();
  }

  /** Where a world point appears, in CSS pixels of the page. */
  screen_of(x, y, z) {
    const rect = this.canvas.getBoundingClientRect();
    this.camera.updateMatrixWorld(); // framed since the last frame drawn: project as it now is
    const v = new THREE.Vector3(x, y, z).project(this.camera);
    return { x: rect.left + ((v.x + 1) / 2) * rect.width, y: rect.top + ((1 - v.y) / 2) * rect.height };
  }
}

/** 1, 2 or 5 times a power of ten, near x: the floor grid's spacing. */
function nice_spacing(x) {
  const power = 10 ** Math.floor(Math.log10(x));
  const m = x / power;
  return (m < 1.5 ? 1 : m < 3.5 ? 2 : 5) * power;
}
