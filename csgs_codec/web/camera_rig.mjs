/**
 * The viewer's camera, kept in the project's convention (csgs_codec/scene/camera.py: OpenCV
 * pinhole, x right, y down, z forward, world_to_camera 4x4, pixel centres at integer + 0.5),
 * so a click is resolved with the same camera the Python rasterizer would use.
 *
 * Framing and up axis follow csgs_codec/scene/orbit.py: the default view is that module's
 * orbit view 0 (elevation 20 degrees, vertical field of view 40 degrees, robust extent filling
 * 0.7 of the smaller side). Orbit: drag to turn around the target, wheel to zoom, right-drag
 * or shift-drag to pan; fly: W/S forward and back, A/D sideways, Q/E down and up.
 */

const MIN_OPACITY_FOR_BOUNDS = 0.1;
const PERCENTILE = 2;
const DEFAULT_NEAR_PLANE = 0.01;

/** numpy's default (linear) percentile of sorted values. */
function percentileSorted(sorted, q) {
  const position = (q / 100) * (sorted.length - 1);
  const low = Math.floor(position);
  const high = Math.min(low + 1, sorted.length - 1);
  return sorted[low] + (sorted[high] - sorted[low]) * (position - low);
}

/**
 * Robust box of the visible Gaussians, as orbit.py's robust_bounds.
 * @param {Float32Array} positions N x 3
 * @param {Float32Array} opacity N logits
 * @returns {{low: number[], high: number[]}}
 */
export function robustBounds(positions, opacity) {
  const n = opacity.length;
  let keep = [];
  for (let i = 0; i < n; i++) if (1 / (1 + Math.exp(-opacity[i])) > MIN_OPACITY_FOR_BOUNDS) keep.push(i);
  if (keep.length < 16) keep = Array.from({ length: n }, (_, i) => i);
  const low = [];
  const high = [];
  for (let axis = 0; axis < 3; axis++) {
    const values = new Float64Array(keep.length);
    keep.forEach((i, k) => { values[k] = positions[3 * i + axis]; });
    values.sort();
    low.push(percentileSorted(values, PERCENTILE));
    high.push(percentileSorted(values, 100 - PERCENTILE));
  }
  return { low, high };
}

/** Up vector by orbit.py's conventions: a flat scene's thin axis (-y for y, +z otherwise), else -y. */
export function guessUp({ low, high }) {
  const sides = [0, 1, 2].map((a) => high[a] - low[a]);
  const order = [0, 1, 2].sort((a, b) => sides[a] - sides[b]);
  if (sides[order[1]] > 0 && sides[order[0]] < 0.5 * sides[order[1]]) return order[0] === 1 ? [0, -1, 0] : [0, 0, 1];
  return [0, -1, 0];
}

const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
const scale = (a, s) => [a[0] * s, a[1] * s, a[2] * s];
const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
const unit = (a) => scale(a, 1 / Math.hypot(...a));

/** Two unit vectors spanning the plane normal to ``up`` (orbit.py's _horizontal_basis). */
function horizontalBasis(up) {
  const seed = [0, 0, 0];
  const abs = up.map(Math.abs);
  seed[abs.indexOf(Math.min(...abs))] = 1;
  const first = unit(sub(seed, scale(up, dot(seed, up))));
  return [first, cross(up, first)];
}

/** Row-major 4 x 4 world-to-camera matrix of a camera at ``position`` facing ``target`` (orbit.py's look_at). */
export function lookAt(position, target, up) {
  const forward = unit(sub(target, position));
  let right = cross(forward, up);
  if (Math.hypot(...right) < 1e-9) right = cross(forward, horizontalBasis(up)[0]);
  right = unit(right);
  const down = cross(forward, right);
  const rows = [right, down, forward];
  const m = new Float64Array(16);
  rows.forEach((r, i) => {
    m[4 * i] = r[0]; m[4 * i + 1] = r[1]; m[4 * i + 2] = r[2];
    m[4 * i + 3] = -dot(r, position);
  });
  m[15] = 1;
  return m;
}

/** Camera centre of a row-major world-to-camera matrix. */
export function cameraPosition(w2c) {
  const t = [w2c[3], w2c[7], w2c[11]];
  return [0, 1, 2].map((j) => -(w2c[j] * t[0] + w2c[4 + j] * t[1] + w2c[8 + j] * t[2]));
}

/** Orbit-and-fly camera rig producing project-convention cameras for a canvas. */
export class CameraRig {
  constructor() {
    this.explicit = null; // a camera set with setCamera(), until the user moves
    this.fovY = 40;
    this.up = [0, -1, 0];
    this.target = [0, 0, 0];
    this.distance = 1;
    this.azimuth = 0;
    this.elevation = 20 * Math.PI / 180;
    this.near = DEFAULT_NEAR_PLANE;
    this.width = 1;
    this.height = 1;
    this.listeners = [];
  }

  /** Frame the scene as orbit.py's view 0 for an image of width x height. */
  frame(positions, opacity, width, height) {
    if (!opacity.length) return; // an empty scene: keep the current view
    const bounds = robustBounds(positions, opacity);
    this.up = guessUp(bounds);
    this.target = [0, 1, 2].map((a) => (bounds.low[a] + bounds.high[a]) / 2);
    let extent = Math.max(...[0, 1, 2].map((a) => bounds.high[a] - bounds.low[a]));
    if (!(extent > 0)) extent = 1;
    this.extent = extent;
    const fy = 0.5 * height / Math.tan((this.fovY * Math.PI / 180) / 2);
    const halfSmall = Math.atan(0.5 * Math.min(width, height) / fy);
    this.distance = 0.5 * extent / 0.7 / Math.tan(halfSmall) + 0.5 * extent;
    this.near = Math.min(DEFAULT_NEAR_PLANE, DEFAULT_NEAR_PLANE * this.distance);
    this.azimuth = 0;
    this.elevation = 20 * Math.PI / 180;
    this.explicit = null;
    this.changed();
  }

  /** Show exactly this project-convention camera (fields of camera.py's Camera; matrix row-major). */
  setCamera(camera) {
    this.explicit = {
      width: camera.width, height: camera.height, fx: camera.fx, fy: camera.fy, cx: camera.cx, cy: camera.cy,
      world_to_camera: Float64Array.from(camera.world_to_camera.flat ? camera.world_to_camera.flat() : camera.world_to_camera),
      near_plane: camera.near_plane ?? DEFAULT_NEAR_PLANE,
    };
    this.changed();
  }

  /** The current camera for an image of width x height, project convention. */
  camera(width, height) {
    if (this.explicit) return { ...this.explicit, width, height };
    const [first, second] = horizontalBasis(this.up);
    const horizontal = add(scale(first, Math.cos(this.azimuth)), scale(second, Math.sin(this.azimuth)));
    const direction = add(scale(horizontal, Math.cos(this.elevation)), scale(this.up, Math.sin(this.elevation)));
    const position = add(this.target, scale(direction, this.distance));
    const fy = 0.5 * height / Math.tan((this.fovY * Math.PI / 180) / 2);
    return { width, height, fx: fy, fy, cx: width / 2, cy: height / 2, world_to_camera: lookAt(position, this.target, this.up), near_plane: this.near };
  }

  /** Leave an explicit camera for the orbit: keep its position, aim at the same distance. */
  toOrbit() {
    if (!this.explicit) return;
    const m = this.explicit.world_to_camera;
    const position = cameraPosition(m);
    const forward = [m[8], m[9], m[10]];
    this.target = add(position, scale(forward, this.distance));
    const back = scale(forward, -1);
    const [first, second] = horizontalBasis(this.up);
    this.elevation = Math.asin(Math.max(-1, Math.min(1, dot(back, this.up))));
    this.azimuth = Math.atan2(dot(back, second), dot(back, first));
    this.explicit = null;
  }

  orbit(dx, dy) {
    this.toOrbit();
    this.azimuth -= dx * 0.006;
    this.elevation = Math.max(-1.55, Math.min(1.55, this.elevation + dy * 0.006));
    this.changed();
  }

  zoom(steps) {
    this.toOrbit();
    this.distance *= Math.pow(1.1, steps);
    this.changed();
  }

  /** Move the target (and the camera with it) along the camera's right, down and forward axes. */
  move(right, down, forward) {
    this.toOrbit();
    const m = this.camera(this.width, this.height).world_to_camera;
    const axes = [[m[0], m[1], m[2]], [m[4], m[5], m[6]], [m[8], m[9], m[10]]];
    const step = [right, down, forward];
    for (let k = 0; k < 3; k++) this.target = add(this.target, scale(axes[k], step[k]));
    this.changed();
  }

  /** Pointer, wheel and key handlers on ``element``; keys on the window. */
  attach(element) {
    let last = null;
    let panning = false;
    let moved = 0;
    element.addEventListener('contextmenu', (e) => e.preventDefault());
    element.addEventListener('pointerdown', (e) => {
      last = [e.clientX, e.clientY];
      panning = e.button === 2 || e.shiftKey;
      moved = 0;
      element.setPointerCapture(e.pointerId);
    });
    element.addEventListener('pointermove', (e) => {
      if (!last) return;
      const dx = e.clientX - last[0];
      const dy = e.clientY - last[1];
      last = [e.clientX, e.clientY];
      moved += Math.abs(dx) + Math.abs(dy);
      if (panning) {
        const perPixel = this.distance * 2 * Math.tan((this.fovY * Math.PI / 180) / 2) / Math.max(element.clientHeight, 1);
        this.move(-dx * perPixel, -dy * perPixel, 0);
      } else {
        this.orbit(dx, dy);
      }
    });
    element.addEventListener('pointerup', () => { this.lastDragPixels = moved; last = null; });
    element.addEventListener('wheel', (e) => { e.preventDefault(); this.zoom(Math.sign(e.deltaY)); }, { passive: false });
    window.addEventListener('keydown', (e) => {
      if (e.target && (e.target.tagName === 'INPUT')) return;
      const step = 0.05 * this.distance;
      const moves = { w: [0, 0, step], s: [0, 0, -step], a: [-step, 0, 0], d: [step, 0, 0], q: [0, step, 0], e: [0, -step, 0] };
      const m = moves[e.key.toLowerCase()];
      if (m) this.move(...m);
    });
  }

  onChange(listener) { this.listeners.push(listener); }

  changed() { for (const listener of this.listeners) listener(); }
}
