/**
 * Which tiles of a file with levels of detail the page draws (spec/FORMAT.md §12.22): a cut
 * of the tile tree — for every level-0 tile exactly one of itself and its ancestors — chosen
 * for the current view under a splat budget, and the tiles to read next.
 *
 * A tile is refined (replaced by its children) while its Gaussians' typical size (the median
 * of their largest scale, world units) projects to more than ``pixels`` on screen at the
 * tile's nearest point, it is in view, and its children fit the budget; the tiles that matter
 * most (largest projected size) are refined first. Only a decoded tile can be refined, so the
 * cut deepens by at most a level beyond what is decoded; a refined tile stays drawn until all
 * its children are decoded. Tiles out of view keep the level they have in the cut from the
 * roots down, so detail out of view is dropped as the camera moves.
 */

/** Default splat budget: Gaussians drawn at most (page option ``?budget=N``). */
export const DEFAULT_BUDGET = 3_000_000;
/** Default projected size above which a tile is refined, pixels (``?lodpx=X``). */
export const DEFAULT_PIXELS = 1.5;
/** Tiles asked of the worker at once, most important first. */
const REQUEST_BATCH = 8;

/** The median of the largest of each Gaussian's three log scales, as a linear size (world
 * units): a tile's typical Gaussian size. */
export function typicalSize(scene) {
  const n = scene.count;
  if (!n) return 0;
  const largest = new Float32Array(n);
  for (let i = 0; i < n; i++) {
    largest[i] = Math.max(scene.scales[3 * i], scene.scales[3 * i + 1], scene.scales[3 * i + 2]);
  }
  largest.sort();
  return Math.exp(largest[n >> 1]);
}

/** ``p`` (world, 3) in the camera's frame (x right, y down, z forward). */
function toCamera(camera, p) {
  const m = camera.world_to_camera;
  return [0, 1, 2].map((r) => m[4 * r] * p[0] + m[4 * r + 1] * p[1] + m[4 * r + 2] * p[2] + m[4 * r + 3]);
}

/** The camera centre in world coordinates. */
export function cameraCentre(camera) {
  const m = camera.world_to_camera;
  const t = [m[3], m[7], m[11]];
  return [0, 1, 2].map((j) => -(m[j] * t[0] + m[4 + j] * t[1] + m[8 + j] * t[2]));
}

/** Whether a tile's box (``lower``, ``upper``) can show in the camera's picture: false when
 * all 8 corners are behind the near plane or beyond one side of the picture. */
export function boxInView(camera, lower, upper) {
  const corners = [];
  for (let k = 0; k < 8; k++) {
    corners.push(toCamera(camera, [k & 1 ? upper[0] : lower[0], k & 2 ? upper[1] : lower[1], k & 4 ? upper[2] : lower[2]]));
  }
  const { fx, fy, cx, cy, width, height } = camera;
  const near = camera.near_plane ?? 0.01;
  const outside = [
    (c) => c[2] < near,
    (c) => fx * c[0] + cx * c[2] < 0, // u < 0
    (c) => fx * c[0] + (cx - width) * c[2] > 0, // u > width
    (c) => fy * c[1] + cy * c[2] < 0,
    (c) => fy * c[1] + (cy - height) * c[2] > 0,
  ];
  return !outside.some((test) => corners.every(test));
}

/** Distance from ``point`` to the closed box (0 inside). */
function boxDistance(point, lower, upper) {
  let sum = 0;
  for (let a = 0; a < 3; a++) {
    const d = Math.max(lower[a] - point[a], 0, point[a] - upper[a]);
    sum += d * d;
  }
  return Math.sqrt(sum);
}

/** Pixels tile ``info``'s Gaussians of typical size ``size`` span seen from ``camera``. */
export function projectedSize(camera, info, size) {
  const distance = boxDistance(cameraCentre(camera), info.lower, info.upper);
  return size * camera.fx / Math.max(distance, camera.near_plane ?? 0.01);
}

/**
 * The cut to draw: a Set of tile numbers.
 * @param {object[]} tiles index entries {count, lower, upper, level, parent}
 * @param {number[][]} children tile numbers whose parent each tile is
 * @param {object} camera the project-convention camera (camera_rig.mjs)
 * @param {Map<number, number>} sizes typical Gaussian size of each decoded tile
 * @param {{budget: number, pixels: number}} limits
 */
export function chooseCut(tiles, children, camera, sizes, limits) {
  const cut = new Set();
  let total = 0;
  const queue = [];
  const consider = (number) => {
    cut.add(number);
    total += tiles[number].count;
    const size = sizes.get(number);
    if (tiles[number].level === 0 || size === undefined) return;
    if (!boxInView(camera, tiles[number].lower, tiles[number].upper)) return;
    const pixels = projectedSize(camera, tiles[number], size);
    if (pixels > limits.pixels) queue.push({ number, pixels });
  };
  tiles.forEach((t, i) => { if (t.parent === null) consider(i); });
  while (queue.length) {
    let best = 0;
    for (let k = 1; k < queue.length; k++) if (queue[k].pixels > queue[best].pixels) best = k;
    const { number } = queue.splice(best, 1)[0];
    const kids = children[number];
    const added = kids.reduce((n, c) => n + tiles[c].count, 0) - tiles[number].count;
    if (total + added > limits.budget) continue;
    cut.delete(number);
    total -= tiles[number].count;
    kids.forEach(consider);
  }
  return cut;
}

/**
 * The tiles to draw now for the wanted ``cut``: each cut tile where it is decoded, else its
 * nearest decoded ancestor in its place (all its decoded siblings' subtrees then drawn as
 * that ancestor too); and the cut tiles still missing. Returns {drawn: Set, missing: []}.
 */
export function drawnTiles(tiles, children, cut, decoded) {
  const drawn = new Set();
  const missing = [];
  const walk = (number) => { // the tiles drawing ``number``'s part, or null when it cannot
    if (cut.has(number)) {
      if (decoded.has(number)) return [number];
      missing.push(number);
      return null;
    }
    const parts = children[number].map(walk);
    if (parts.every((p) => p !== null)) return parts.flat();
    return decoded.has(number) ? [number] : null;
  };
  tiles.forEach((t, i) => {
    if (t.parent !== null) return;
    for (const n of walk(i) || []) drawn.add(n);
  });
  return { drawn, missing };
}

/**
 * The page's streaming state for one file: tiles decoded (their scenes), the cut, what is
 * asked of the worker. ``request(numbers)`` asks the worker for tiles; ``draw(drawn,
 * scenes)`` makes the view show exactly the tiles in ``drawn``.
 */
export class LevelStreamer {
  constructor({ tiles, levels, budget = DEFAULT_BUDGET, pixels = DEFAULT_PIXELS, request, draw }) {
    this.tiles = tiles;
    this.levels = levels;
    this.limits = { budget, pixels };
    this.children = tiles.map(() => []);
    tiles.forEach((t, i) => { if (t.parent !== null) this.children[t.parent].push(i); });
    this.scenes = new Map();
    this.sizes = new Map();
    this.asked = new Set();
    this.request = request;
    this.draw = draw;
    this.drawn = new Set();
    this.cut = new Set();
    this.camera = null;
    // The worker reads the coarsest level unasked.
    tiles.forEach((t, i) => { if (t.parent === null) this.asked.add(i); });
  }

  /** Tile ``number`` was decoded. */
  arrived(number, scene) {
    this.scenes.set(number, scene);
    this.sizes.set(number, typicalSize(scene));
    this.asked.delete(number);
    if (this.camera) this.update(this.camera);
  }

  /** Choose the cut for ``camera``, draw what can be drawn, ask for what is missing. */
  update(camera) {
    this.camera = camera;
    this.cut = chooseCut(this.tiles, this.children, camera, this.sizes, this.limits);
    const { drawn, missing } = drawnTiles(this.tiles, this.children, this.cut, this.scenes);
    const changed = drawn.size !== this.drawn.size || [...drawn].some((n) => !this.drawn.has(n));
    if (changed) { // the same Set while nothing changes: the page's join waits on it
      this.drawn = drawn;
      this.draw(drawn, this.scenes);
    }
    const wanted = missing.filter((n) => !this.asked.has(n));
    if (wanted.length) {
      const scored = wanted.map((n) => ({ n, pixels: projectedSize(camera, this.tiles[n], this.sizes.get(this.tiles[n].parent) ?? 0) }));
      scored.sort((a, b) => b.pixels - a.pixels || a.n - b.n);
      const batch = scored.slice(0, REQUEST_BATCH).map((s) => s.n);
      batch.forEach((n) => this.asked.add(n));
      this.request(batch);
    }
  }

  /** True when every tile of the wanted cut is decoded and drawn. */
  get complete() {
    return this.cut.size > 0 && [...this.cut].every((n) => this.drawn.has(n));
  }

  /** Gaussians drawn. */
  get count() {
    let n = 0;
    for (const t of this.drawn) n += this.tiles[t].count;
    return n;
  }

  /** Level counts of the drawn tiles: [tiles of level 0, of level 1, ...]. */
  get drawnLevels() {
    const out = new Array(this.levels).fill(0);
    for (const t of this.drawn) out[this.tiles[t].level] += 1;
    return out;
  }
}
