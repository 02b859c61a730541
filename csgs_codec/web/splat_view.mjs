/**
 * Rendering through the vendored PlayCanvas engine (vendor/playcanvas): decoded arrays become
 * a GSplatData with the standard 3DGS PLY property names, drawn by the engine's splat
 * renderer (sorted in its own worker). Colors are written linear, without tone mapping or
 * gamma, as the project rasterizer outputs them; the background is black.
 */

import * as pc from './vendor/playcanvas/playcanvas.min.mjs';

const SH_C0 = 0.28209479177387814;
/** Highlight: Gaussians outside the selection keep this share of their opacity and color. */
const DIM_OPACITY = 0.12;
const DIM_COLOR = 0.35;

function floatProperty(name, storage) {
  return { type: 'float', name, storage, byteSize: 4 };
}

/** The f_rest columns of PLY order from sh_rest (N x R x 3): f_rest_{c * R + k} is
 * coefficient k of color channel c. */
function restColumns(shRest, n, rest) {
  const columns = [];
  for (let c = 0; c < 3; c++) {
    for (let k = 0; k < rest; k++) {
      const out = new Float32Array(n);
      for (let i = 0; i < n; i++) out[i] = shRest[i * 3 * rest + 3 * k + c];
      columns.push(out);
    }
  }
  return columns;
}

/** GSplatData of a decoded scene (positions, sh_dc, sh_rest N x R x 3, opacity, scales,
 * rotations w x y z); a scene whose SH bands are still decoding (sh_rest empty,
 * shCoefficients R > 0) gets R zero coefficients, filled in later by updateSH. */
function splatData(scene) {
  const n = scene.count;
  const column = (source, stride, k) => {
    const out = new Float32Array(n);
    for (let i = 0; i < n; i++) out[i] = source[i * stride + k];
    return out;
  };
  const properties = [];
  ['x', 'y', 'z'].forEach((name, k) => properties.push(floatProperty(name, column(scene.positions, 3, k))));
  [0, 1, 2].forEach((k) => properties.push(floatProperty(`f_dc_${k}`, column(scene.sh_dc, 3, k))));
  const rest = scene.sh_rest.length ? scene.sh_rest.length / (3 * n) : (scene.shCoefficients || 0);
  const columns = scene.sh_rest.length ? restColumns(scene.sh_rest, n, rest)
    : Array.from({ length: 3 * rest }, () => new Float32Array(n));
  columns.forEach((values, j) => properties.push(floatProperty(`f_rest_${j}`, values)));
  properties.push(floatProperty('opacity', Float32Array.from(scene.opacity)));
  [0, 1, 2].forEach((k) => properties.push(floatProperty(`scale_${k}`, column(scene.scales, 3, k))));
  [0, 1, 2, 3].forEach((k) => properties.push(floatProperty(`rot_${k}`, column(scene.rotations, 4, k))));
  return new pc.GSplatData([{ name: 'vertex', count: n, properties }]);
}

/** The base colors and opacities of ``data`` (restored when a selection is cleared). */
function originalColors(data) {
  return {
    dc: [0, 1, 2].map((k) => Float32Array.from(data.getProp(`f_dc_${k}`))),
    opacity: Float32Array.from(data.getProp('opacity')),
  };
}

/** Dim the splats of ``data`` outside ``mask`` (null: restore ``original``'s colors). */
function dimData(data, original, mask) {
  const dc = [0, 1, 2].map((k) => data.getProp(`f_dc_${k}`));
  const op = data.getProp('opacity');
  const { dc: dc0, opacity: op0 } = original;
  for (let i = 0; i < op.length; i++) {
    if (!mask || mask[i]) {
      for (let k = 0; k < 3; k++) dc[k][i] = dc0[k][i];
      op[i] = op0[i];
    } else {
      for (let k = 0; k < 3; k++) dc[k][i] = (DIM_COLOR * (0.5 + SH_C0 * dc0[k][i]) - 0.5) / SH_C0;
      const alpha = DIM_OPACITY / (1 + Math.exp(-op0[i]));
      op[i] = Math.log(alpha / (1 - alpha));
    }
  }
}

/** dimData on a tile entity's splats, uploaded. */
function dim(entity, mask) {
  const { data, original } = entity.csgsSplats;
  dimData(data, original, mask);
  entity.gsplat.resource.updateColorData(data);
  entity.gsplat.workBufferUpdate = pc.WORKBUFFER_UPDATE_ONCE;
}

export class SplatView {
  /**
   * @param {HTMLCanvasElement} canvas
   * @param {{width: number, height: number}|null} fixedSize a fixed drawing-buffer size in
   *   pixels (tests), or null to fill the window
   */
  constructor(canvas, fixedSize = null) {
    this.canvas = canvas;
    this.app = new pc.Application(canvas, {
      graphicsDeviceOptions: { antialias: false, alpha: false, preserveDrawingBuffer: true, deviceTypes: ['webgl2'] },
    });
    this.app.graphicsDevice.maxPixelRatio = fixedSize ? 1 : Math.min(window.devicePixelRatio || 1, 2);
    if (fixedSize) {
      this.app.setCanvasFillMode(pc.FILLMODE_NONE, fixedSize.width, fixedSize.height);
      this.app.setCanvasResolution(pc.RESOLUTION_FIXED, fixedSize.width, fixedSize.height);
    } else {
      this.app.setCanvasFillMode(pc.FILLMODE_FILL_WINDOW);
      this.app.setCanvasResolution(pc.RESOLUTION_AUTO);
      window.addEventListener('resize', () => this.app.resizeCanvas());
    }
    this.app.scene.gsplat.dataFormat = pc.GSPLATDATA_LARGE;
    this.cameraEntity = new pc.Entity('camera');
    this.cameraEntity.addComponent('camera', {
      clearColor: new pc.Color(0, 0, 0, 1), fov: 40, nearClip: 0.01, farClip: 1000,
      gammaCorrection: pc.GAMMA_SRGB, toneMapping: pc.TONEMAP_NONE,
    });
    this.app.root.addChild(this.cameraEntity);
    this.splat = null;
    this.data = null;
    this.tiles = new Map(); // tile number -> entity, a file with levels of detail
    this.frames = 0;
    this.sorts = 0; // sort results received since the scene was shown
    this.app.scene.on('gsplat:sorted', () => { this.sorts++; });
    this.app.on('frameend', () => { this.frames++; });
    this.app.start();
  }

  /**
   * True when no splat sort is running or waiting to be applied and the splat data is wholly
   * in the engine's work buffer, so the next frame shows the current view completely. The
   * engine's own 'frame:ready' flag does not wait for a sort started by a camera move, so this
   * reads the sorter's state (internal fields of the pinned engine version; tests/web catch a
   * change).
   */
  get settled() {
    const director = this.app.renderer.gsplatDirector;
    if (!director) return true;
    for (const cameraData of director.camerasMap.values()) {
      for (const layerData of cameraData.layersMap.values()) {
        const sorter = layerData.gsplatManager && layerData.gsplatManager.cpuSorter;
        if (sorter && (sorter.jobsInFlight > 0 || sorter.pendingSorted)) return false;
      }
    }
    const copied = this.app.renderer._gsplatBufferCopy;
    return !(copied > 0 && copied < 100);
  }

  /** Drawing-buffer size in pixels. */
  get size() { return { width: this.app.graphicsDevice.width, height: this.app.graphicsDevice.height }; }

  /**
   * Draw exactly the tiles ``numbers`` of a file with levels of detail, ``scenes`` holding
   * every tile's decoded arrays: a tile drawn before keeps its entity (shown or hidden, all
   * sorted together by the engine); a new one gets its own.
   */
  showTiles(numbers, scenes) {
    if (this.splat) { this.splat.destroy(); this.splat = null; this.data = null; }
    if (this.joined) { this.joined.destroy(); this.joined = null; }
    for (const number of numbers) {
      if (this.tiles.has(number)) continue;
      const scene = scenes.get(number);
      if (!scene.count) continue;
      const entity = new pc.Entity(`tile ${number}`);
      const data = splatData(scene);
      entity.addComponent('gsplat', { resource: new pc.GSplatResource(this.app.graphicsDevice, data) });
      entity.csgsSplats = { data, original: originalColors(data) };
      this.app.root.addChild(entity);
      this.tiles.set(number, entity);
    }
    for (const [number, entity] of this.tiles) entity.enabled = numbers.has(number);
    this.sorts = 0;
  }

  /**
   * Draw the tiles ``numbers`` as one splat set, their Gaussians in tile order, as a page
   * decoding the whole file draws the same tiles (the engine's order among splats it sorts
   * alike follows their place in its buffers, so one set in file order draws the whole-file
   * page's frame exactly); the tile entities are hidden until showTiles draws them again.
   */
  joinTiles(numbers, scenes) {
    if (this.joined) this.joined.destroy();
    const parts = [...numbers].sort((a, b) => a - b).map((n) => scenes.get(n)).filter((s) => s.count);
    const field = (name) => {
      const out = new Float32Array(parts.reduce((n, s) => n + s[name].length, 0));
      let at = 0;
      for (const s of parts) { out.set(s[name], at); at += s[name].length; }
      return out;
    };
    const joined = {
      count: parts.reduce((n, s) => n + s.count, 0), positions: field('positions'), sh_dc: field('sh_dc'),
      sh_rest: field('sh_rest'), opacity: field('opacity'), scales: field('scales'), rotations: field('rotations'),
    };
    this.joined = new pc.Entity('joined tiles');
    const data = splatData(joined);
    this.joined.addComponent('gsplat', { resource: new pc.GSplatResource(this.app.graphicsDevice, data) });
    this.joined.csgsSplats = { data, original: originalColors(data), tiles: [...numbers].filter((n) => this.tiles.has(n)).sort((a, b) => a - b) };
    this.app.root.addChild(this.joined);
    for (const entity of this.tiles.values()) entity.enabled = false;
    this.sorts = 0;
  }

  /**
   * Dim everything outside the selection in the tiles drawn: ``masks`` maps a tile number
   * to its Uint8Array (1 = selected); null restores every tile's colors.
   */
  highlightTiles(masks) {
    for (const [number, entity] of this.tiles) {
      dim(entity, masks ? masks.get(number) || new Uint8Array(entity.csgsSplats.data.numSplats) : null);
    }
    if (this.joined) {
      const { tiles } = this.joined.csgsSplats;
      if (!masks) {
        dim(this.joined, null);
      } else {
        const parts = tiles.map((n) => masks.get(n) || new Uint8Array(this.tiles.get(n).csgsSplats.data.numSplats));
        const joined = new Uint8Array(parts.reduce((n, p) => n + p.length, 0));
        let at = 0;
        for (const p of parts) { joined.set(p, at); at += p.length; }
        dim(this.joined, joined);
      }
    }
  }

  /** Remove every tile entity (another file is opened). */
  clearTiles() {
    for (const entity of this.tiles.values()) entity.destroy();
    this.tiles.clear();
    if (this.joined) { this.joined.destroy(); this.joined = null; }
  }

  /** Replace the drawn scene with ``scene`` (decoded arrays). */
  show(scene) {
    this.clearTiles();
    if (this.splat) this.splat.destroy();
    this.splat = null;
    this.data = null;
    if (!scene.count) return; // nothing to draw (an empty scene is valid)
    this.data = splatData(scene);
    this.original = originalColors(this.data);
    this.resource = new pc.GSplatResource(this.app.graphicsDevice, this.data);
    this.splat = new pc.Entity('scene');
    this.splat.addComponent('gsplat', { resource: this.resource });
    this.app.root.addChild(this.splat);
    this.sorts = 0;
  }

  /** Fill in the SH coefficients of the scene shown (sh_rest N x R x 3, as show's scene's
   * shCoefficients said). */
  updateSH(shRest) {
    if (!this.data || !shRest.length) return;
    const n = this.data.numSplats;
    restColumns(shRest, n, shRest.length / (3 * n)).forEach((values, j) => this.data.getProp(`f_rest_${j}`).set(values));
    this.resource.updateSHData(this.data);
    this.splat.gsplat.workBufferUpdate = pc.WORKBUFFER_UPDATE_ONCE;
  }

  /** Point the engine's camera as the project-convention ``camera`` (camera_rig.mjs). */
  setCamera(camera) {
    const m = camera.world_to_camera;
    // Camera centre and axes from the rigid world-to-camera matrix (rows: right, down, forward).
    const t = [m[3], m[7], m[11]];
    const position = [0, 1, 2].map((j) => -(m[j] * t[0] + m[4 + j] * t[1] + m[8 + j] * t[2]));
    const pose = new pc.Mat4();
    const d = pose.data; // column-major: columns are the entity's x (right), y (up), z (back)
    d[0] = m[0]; d[1] = m[1]; d[2] = m[2];
    d[4] = -m[4]; d[5] = -m[5]; d[6] = -m[6];
    d[8] = -m[8]; d[9] = -m[9]; d[10] = -m[10];
    d[12] = position[0]; d[13] = position[1]; d[14] = position[2];
    this.cameraEntity.setPosition(position[0], position[1], position[2]);
    this.cameraEntity.setRotation(new pc.Quat().setFromMat4(pose));
    const cam = this.cameraEntity.camera;
    cam.fov = 2 * Math.atan(camera.height / (2 * camera.fy)) * 180 / Math.PI;
    cam.nearClip = camera.near_plane;
    cam.farClip = Math.max(1000, 1e4 * camera.near_plane);
    const centred = Math.abs(camera.cx - camera.width / 2) < 1e-9 && Math.abs(camera.cy - camera.height / 2) < 1e-9
      && Math.abs(camera.fx - camera.fy) <= 1e-12 * camera.fy;
    // A pinhole with its own focal lengths and principal point needs its own projection
    // (pixel u = fx x / z + cx maps to NDC 2u / W - 1; image rows run down, NDC y up).
    cam.calculateProjection = centred ? null : (matrix) => {
      const { width: W, height: H, fx, fy, cx, cy } = camera;
      const n = cam.nearClip;
      const f = cam.farClip;
      matrix.data.fill(0);
      matrix.data[0] = 2 * fx / W;
      matrix.data[5] = 2 * fy / H;
      matrix.data[8] = 1 - 2 * cx / W;
      matrix.data[9] = 2 * cy / H - 1;
      matrix.data[10] = -(f + n) / (f - n);
      matrix.data[11] = -1;
      matrix.data[14] = -2 * f * n / (f - n);
    };
  }

  /** Dim everything outside ``mask`` (Uint8Array, 1 = selected); null restores the colors. */
  highlight(mask) {
    if (!this.data) return;
    dimData(this.data, this.original, mask);
    this.resource.updateColorData(this.data);
    this.splat.gsplat.workBufferUpdate = pc.WORKBUFFER_UPDATE_ONCE;
  }

  /** The canvas as a PNG data URL (the drawing buffer is preserved). */
  capture() { return this.canvas.toDataURL('image/png'); }
}
