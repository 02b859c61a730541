/**
 * The viewer page: starts the decode worker first, loads the renderer meanwhile, draws the
 * splats as soon as their base color is decoded and again with the SH bands, reads the
 * semantic layer after it, and selects the object under a click.
 *
 * URL parameters: ``size=WxH`` a fixed drawing-buffer size (tests and screenshots; otherwise
 * the canvas fills the window), ``scene=URL`` and ``layers=color|color,semantic`` override
 * the server's /config.json; ``hashes=1`` has the worker hash every decoded array
 * (``state.hashes``, compared with the Python decoder's by the tests); ``lanes=N`` decodes on
 * N Web Workers (0: on the decode worker's own thread; default one per core but one, at
 * most 4). A file with levels of detail is streamed (level_open.mjs, level_view.mjs):
 * ``budget=N`` caps the Gaussians drawn (default 3,000,000), ``lodpx=X`` is the projected
 * Gaussian size in pixels above which a tile is refined (default 1.5).
 *
 * ``window.csgsViewer`` is the page's state for scripts (the browser tests read it):
 * ``state`` (phase, timings, counts, error, selection), ``setCamera(camera)``,
 * ``camera()``, ``frameDrawn()`` (a promise of the next frame with the splats sorted),
 * ``capture()`` (PNG data URL of the canvas) and ``selectAt(column, row)``.
 * Timings are ``performance.now()`` values (ms from navigation): ``firstFrameMs`` the first
 * frame drawn with every splat (base color), ``colorFrameMs`` the first with the whole color
 * layer (the same frame for a scene without SH bands); ``timeline`` has the steps before
 * them (workerStarted, tocRead, colorBytesRead, decodeStarted, colorDecoded from the worker;
 * rendererReady, 0 when it was ready before the file was opened). A streamed file fills
 * ``state.lod``: levels, tiles, decoded, drawn (tile numbers), drawnLevels, bytesRead,
 * firstFrameBytes (scene bytes read when the first frame was drawn), complete (every tile the
 * view wants is drawn), completeMs, and joined (the drawn tiles are one splat set, drawn as
 * the whole-file page draws the same tiles, once the view stayed complete a moment).
 */

import { CameraRig } from './camera_rig.mjs';
import { DEFAULT_BUDGET, DEFAULT_PIXELS, LevelStreamer } from './level_view.mjs';
import { DEFAULT_THRESHOLD, elementInstances, selectAtPixel, selectInstanceAtPixel } from './pick.mjs';

const $ = (id) => document.getElementById(id);
const params = new URLSearchParams(location.search);
const sizeMatch = /^(\d{1,5})x(\d{1,5})$/.exec(params.get('size') || '');
const fixedSize = sizeMatch ? { width: Number(sizeMatch[1]), height: Number(sizeMatch[2]) } : null;
if (fixedSize) document.body.classList.add('fixed-size');
const wantHashes = params.get('hashes') === '1';
const lanesParam = /^\d$/.test(params.get('lanes') || '') ? Number(params.get('lanes')) : null;
const budgetParam = /^\d{1,9}$/.test(params.get('budget') || '') ? Number(params.get('budget')) : DEFAULT_BUDGET;
const pixelsParam = Number(params.get('lodpx')) > 0 ? Number(params.get('lodpx')) : DEFAULT_PIXELS;

const state = {
  phase: 'starting', name: null, layers: ['color', 'semantic'], count: 0, fileEnd: null,
  colorEnd: null, hasSemantic: null, colorShown: false, semanticReady: false, firstFrameMs: null,
  colorFrameMs: null, colorMs: null, semanticMs: null, colorDecodeMs: null, shDecodeMs: null,
  semanticDecodeMs: null, colorBytesRead: null, semanticBytesRead: null, error: null,
  selection: null, hashes: null, timeline: {}, lod: null,
};
// The decoder starts before the renderer loads: the two overlap.
const worker = new Worker(new URL(`./decode_worker.mjs${lanesParam === null ? '' : `?lanes=${lanesParam}`}`, import.meta.url), { type: 'module' });
const rig = new CameraRig();
rig.attach($('canvas'));
let view = null;
const viewReady = import('./splat_view.mjs').then(({ SplatView }) => {
  view = new SplatView($('canvas'), fixedSize);
  state.timeline.rendererReady ??= performance.now();
  startDrawing();
  return view;
});
let requestId = 0;
let scene = null;
/** The open file's LevelStreamer when it has levels of detail, else null. */
let streamer = null;
let semantic = null;
let framesSinceChange = 0;
let settledFrames = 0; // consecutive frames that ended with no sort in flight
const frameWaiters = [];

/**
 * Draw on demand: after a change, keep drawing until two frames in a row end with the splats
 * sorted for the current view (and, for a new scene, its first sort received); a frame drawn
 * then is complete, and frameDrawn() waiters are answered.
 */
function startDrawing() {
  view.app.autoRender = false;
  view.app.on('frameend', () => {
    framesSinceChange++;
    settledFrames = view.settled && (!view.splat || view.sorts > 0) ? settledFrames + 1 : 0;
    const settled = settledFrames >= 2 && framesSinceChange >= 2;
    if (settled) {
      while (frameWaiters.length) frameWaiters.shift()();
    } else {
      view.app.renderNextFrame = true;
    }
  });
  rig.onChange(redraw);
  view.app.graphicsDevice.on('resizecanvas', redraw);
}

/** Draw again until settled (after any change to the view or the splats). */
function drawAgain() {
  if (!view) return;
  framesSinceChange = 0;
  settledFrames = 0;
  view.app.renderNextFrame = true;
}

function redraw() {
  if (!view) return;
  const { width, height } = view.size;
  view.setCamera(rig.camera(width, height));
  if (streamer && streamer.scenes.size) {
    streamer.update(rig.camera(width, height));
    noteComplete();
  }
  drawAgain();
}
/** A promise of the next frame drawn after the splats were sorted for the current view. */
async function frameDrawn() {
  await viewReady;
  return new Promise((resolve) => { frameWaiters.push(resolve); view.app.renderNextFrame = true; });
}

function setProgress(fraction, text) {
  $('progress').value = Math.max(0, Math.min(1, fraction));
  $('progress-text').textContent = text;
}

function setMessage(text, kind = 'info') {
  const box = $('message');
  box.textContent = text;
  box.className = kind;
}

/** The status line for the state reached (events can arrive while a frame is awaited). */
function showStatus() {
  if (state.error) {
    const { text, place } = describeError(state.error);
    setMessage(state.error.stage === 'semantic' && state.colorShown
      ? `The color layer is shown, but the semantic layer could not be read: ${text}${place}. ${advice(state.error)}`
      : `Cannot show this file: ${text}${place}. ${advice(state.error)}`, 'error');
    return;
  }
  if (state.lod) {
    const { lod } = state;
    const levels = lod.drawnLevels.map((n, k) => (n ? `${n} of level ${k}` : '')).filter(Boolean).join(', ');
    setMessage(`${state.count.toLocaleString()} Gaussians drawn (tiles ${levels}); read `
      + `${lod.bytesRead.toLocaleString()} of ${state.fileEnd.toLocaleString()} bytes`
      + `${lod.complete ? '' : ', reading more detail'}`
      + (state.semanticReady ? '; click an object to select it' : ''));
    return;
  }
  if (!state.colorShown) {
    if (state.firstFrameMs !== null) setMessage(`${state.count.toLocaleString()} Gaussians (base color); decoding the SH bands`);
    return;
  }
  const count = `${state.count.toLocaleString()} Gaussians`;
  if (state.semanticReady) {
    setMessage(`${count}, ${semantic.channels} semantic channels: click an object to select it`);
  } else if (!state.layers.includes('semantic')) {
    setMessage(`${count} (color layer only, as asked: no selection)`);
  } else if (state.phase === 'done') {
    setMessage(`${count}; the file has no semantic features to select by`);
  } else {
    setMessage(`${count} (color layer); reading the semantic layer`);
  }
}

function describeError(error) {
  const place = error.chunk ? ` — chunk ${error.chunk}${error.offset !== null ? `, byte offset ${error.offset}` : ''}`
    : (error.offset !== null ? ` — byte offset ${error.offset}` : '');
  return { text: `${error.message}`, place };
}

/** What the user can do about an error (the worker says which kind it is). */
function advice(error) {
  if (error.errorKind === 'unsupported') {
    return 'The page cannot draw what this file holds: `csgs info FILE` says what it is, and '
      + '`csgs decode FILE -o scene.ply` writes a standard scene where one can be made.';
  }
  if (error.errorKind === 'format') {
    return 'The file is damaged or cut short. If `csgs info FILE` reads it without an error, '
      + 'the page is wrong: please report it as a bug, with the file.';
  }
  return 'This is a bug in the viewer: please report it, with the file and this message.';
}

function open(source, name, layers) {
  requestId += 1;
  Object.assign(state, {
    phase: 'loading', name, layers, count: 0, fileEnd: null, colorEnd: null, hasSemantic: null,
    colorShown: false, semanticReady: false, firstFrameMs: null, colorFrameMs: null,
    colorMs: null, semanticMs: null, colorDecodeMs: null, shDecodeMs: null, error: null,
    selection: null, hashes: null, timeline: view ? { rendererReady: 0 } : {}, lod: null,
  });
  scene = null;
  streamer = null;
  if (view) view.clearTiles();
  semantic = null;
  drawing = Promise.resolve();
  bands = null;
  $('selection').textContent = '';
  setMessage('');
  $('title').textContent = name || 'csgs viewer';
  setProgress(0, 'starting');
  worker.postMessage({ kind: 'open', id: requestId, layers, hashes: wantHashes, ...source });
}

/** The drawing of the scene so far: messages that change the splats wait for it in turn. */
let drawing = Promise.resolve();
/** SH bands (sh_rest) received and not drawn yet. */
let bands = null;

/** Draw ``next`` (the whole scene, or its splats with the base color) and note the time. */
async function showScene(next, complete, id) {
  await viewReady;
  if (id !== requestId) return;
  if (!complete && bands) { // the SH bands came while the renderer loaded: one drawing
    next = { ...next, sh_rest: bands };
    complete = true;
  }
  bands = null;
  const first = scene === null || state.firstFrameMs === null;
  scene = next;
  view.show(scene);
  if (first) {
    const { width, height } = view.size;
    rig.frame(scene.positions, scene.opacity, width, height);
  }
  await frameDrawn();
  if (id !== requestId) return;
  const now = performance.now();
  if (first) state.firstFrameMs = now;
  if (complete) {
    state.colorFrameMs = now;
    state.colorShown = true;
  }
  showStatus();
}

/** Draw the scene shown again with its SH bands (sh_rest N x R x 3), unless showScene
 * drew them already. */
async function showBands(shRest, id) {
  if (id !== requestId || !scene || state.colorShown) return;
  scene = { ...scene, sh_rest: shRest };
  view.updateSH(shRest);
  drawAgain();
  await frameDrawn();
  if (id !== requestId) return;
  state.colorFrameMs = performance.now();
  state.colorShown = true;
  showStatus();
}

/** Draw the tiles ``drawn`` of a streamed file (LevelStreamer's draw), then note the first
 * frame and whether the view has all the detail it wants. */
function drawTiles(drawn, scenes, id) {
  drawing = drawing.then(async () => {
    await viewReady;
    if (id !== requestId) return;
    if (state.selection) clearSelection(); // the selection was made on other tiles
    view.showTiles(drawn, scenes);
    state.lod.joined = false;
    state.count = streamer.count;
    Object.assign(state.lod, { drawn: [...drawn].sort((a, b) => a - b), drawnLevels: streamer.drawnLevels });
    drawAgain();
    await frameDrawn();
    if (id !== requestId) return;
    if (state.firstFrameMs === null) {
      state.firstFrameMs = performance.now();
      state.colorFrameMs = state.firstFrameMs;
      state.colorShown = true;
      state.lod.firstFrameBytes = state.lod.bytesRead;
    }
    noteComplete();
  });
}

/** Milliseconds a streamed view must stay complete and unchanged before its tiles are
 * joined into one splat set (joinTiles). */
const JOIN_AFTER_MS = 400;

/** Mark a streamed file complete when the view has every tile it wants drawn, and join its
 * tiles once it has stayed so a moment. */
function noteComplete() {
  const complete = Boolean(streamer && streamer.complete && streamer.asked.size === 0);
  if (complete && !state.lod.complete) {
    state.lod.completeMs = performance.now();
    state.phase = 'done';
    setProgress(1, 'done');
  }
  state.lod.complete = complete;
  if (complete && !state.lod.joined) {
    const id = requestId;
    const drawn = streamer.drawn;
    setTimeout(() => {
      if (id !== requestId || !streamer || streamer.drawn !== drawn || !state.lod.complete) return;
      drawing = drawing.then(async () => {
        if (id !== requestId || streamer.drawn !== drawn) return;
        view.joinTiles(drawn, streamer.scenes);
        drawAgain();
        await frameDrawn();
        if (id === requestId && streamer.drawn === drawn) state.lod.joined = true;
      });
    }, JOIN_AFTER_MS);
  }
  showStatus();
}

/** A tile of a streamed file arrived: hand it to the streamer (which may draw and ask for
 * more), framing the view on the coarsest level once it is all here. */
async function tileArrived(message, id) {
  await viewReady;
  if (id !== requestId || !streamer) return;
  state.lod.decoded += 1;
  state.lod.bytesRead = message.bytesRead;
  const { width, height } = view.size;
  const roots = streamer.tiles.map((t, i) => i).filter((i) => streamer.tiles[i].parent === null);
  streamer.scenes.set(message.number, message.scene);
  if (!streamer.camera && roots.every((r) => streamer.scenes.has(r))) {
    const parts = roots.map((r) => streamer.scenes.get(r));
    const join = (name) => Float32Array.from(parts.flatMap((p) => Array.from(p[name])));
    rig.frame(join('positions'), join('opacity'), width, height);
    view.setCamera(rig.camera(width, height));
    streamer.camera = rig.camera(width, height);
  }
  if (message.scene.semantic || message.scene.labels) state.semanticReady = true;
  streamer.arrived(message.number, message.scene);
  setProgress(Math.min(0.99, state.lod.bytesRead / state.fileEnd), `read ${state.lod.bytesRead.toLocaleString()} bytes, ${state.lod.decoded} tiles`);
  noteComplete();
}

worker.onmessage = (event) => {
  const message = event.data;
  const id = message.id;
  if (id !== requestId) return; // from a file opened before this one
  if (message.kind === 'progress') {
    const base = message.stage === 'semantic' ? 0.8 : 0;
    const span = message.stage === 'semantic' ? 0.2 : 0.8;
    setProgress(base + span * message.fraction, message.text);
  } else if (message.kind === 'toc') {
    Object.assign(state, { fileEnd: message.fileEnd, colorEnd: message.colorEnd, hasSemantic: message.hasSemantic });
  } else if (message.kind === 'color') {
    Object.assign(state, {
      phase: 'color', count: message.scene.count, colorMs: performance.now(),
      colorDecodeMs: message.decodeMs, colorBytesRead: message.bytesRead,
    });
    drawing = drawing.then(() => showScene(message.scene, message.complete, id));
  } else if (message.kind === 'sh') {
    state.shDecodeMs = message.decodeMs;
    bands = message.sh_rest;
    drawing = drawing.then(() => showBands(message.sh_rest, id));
  } else if (message.kind === 'semantic') {
    semantic = message.semantic || message.labels ? {
      features: message.semantic, channels: message.channels, names: message.names,
      instances: elementInstances(message.labels, message.semantic, message.channels),
    } : null;
    Object.assign(state, {
      semanticReady: Boolean(semantic), semanticMs: performance.now(),
      semanticDecodeMs: message.decodeMs, semanticBytesRead: message.bytesRead,
    });
    showStatus();
  } else if (message.kind === 'levels') {
    state.phase = 'streaming';
    state.fileEnd = message.fileEnd;
    state.layers = message.layers;
    state.hasSemantic = message.layers.includes('semantic');
    state.lod = {
      levels: message.levels, tiles: message.tiles.length, decoded: 0, drawn: [], drawnLevels: [],
      bytesRead: message.indexBytes, firstFrameBytes: null, complete: false, completeMs: null,
      joined: false,
      budget: budgetParam, pixels: pixelsParam,
    };
    streamer = new LevelStreamer({
      tiles: message.tiles, levels: message.levels, budget: budgetParam, pixels: pixelsParam,
      request: (numbers) => worker.postMessage({ kind: 'tiles', id, numbers }),
      draw: (drawn, scenes) => drawTiles(drawn, scenes, id),
    });
  } else if (message.kind === 'tile') {
    drawing = drawing.then(() => tileArrived(message, id));
  } else if (message.kind === 'mark') {
    state.timeline[message.name] = message.at - performance.timeOrigin;
  } else if (message.kind === 'hashes') {
    state.hashes = message.arrays;
  } else if (message.kind === 'done') {
    if (state.lod) return; // a streamed file is done when the view has its detail
    state.phase = 'done';
    setProgress(1, 'done');
    showStatus();
  } else if (message.kind === 'error') {
    state.phase = 'error';
    state.error = {
      stage: message.stage, errorKind: message.errorKind, message: message.message,
      chunk: message.chunk, offset: message.offset,
    };
    showStatus();
    setProgress($('progress').value, 'stopped');
  }
};

/** Select the object under drawing-buffer pixel (column, row): by instance when the scene
 * has instances, else by cosine; updates the page. */
/**
 * The drawn tiles of a streamed file as one scene (tile order) with its semantic arrays, and
 * each tile's share of it: {scene, semantic, parts: [[number, start, count], ...]}.
 */
function drawnScene() {
  const numbers = [...streamer.drawn].sort((a, b) => a - b);
  const parts = [];
  let at = 0;
  for (const n of numbers) { parts.push([n, at, streamer.scenes.get(n).count]); at += streamer.scenes.get(n).count; }
  const scenes = numbers.map((n) => streamer.scenes.get(n));
  const join = (name, Type = Float32Array) => {
    if (scenes.some((s) => !s[name])) return null;
    const out = new Type(scenes.reduce((n, s) => n + s[name].length, 0));
    let k = 0;
    for (const s of scenes) { out.set(s[name], k); k += s[name].length; }
    return out;
  };
  const joined = { count: at, positions: join('positions'), sh_dc: join('sh_dc'), sh_rest: join('sh_rest'),
    opacity: join('opacity'), scales: join('scales'), rotations: join('rotations') };
  const channels = scenes[0].semanticNames ? scenes[0].semanticNames.length : 0;
  const features = join('semantic');
  const labels = join('labels', Int32Array);
  const instances = elementInstances(labels, features, channels);
  return { scene: joined, semantic: (features || labels) ? { features, channels, instances } : null, parts };
}

/** The selection at drawing-buffer pixel (column, row) of ``splats`` (arrays) by ``meaning``
 * ({instances, features, channels}): by instance when there are instances, else by cosine
 * with the page's threshold. Returns {result, rule, threshold}. */
function pickAt(splats, meaning, column, row) {
  const { width, height } = view.size;
  const camera = rig.camera(width, height);
  if (meaning.instances) {
    return { result: selectInstanceAtPixel(splats, meaning.instances.ids, camera, column, row),
      rule: `instance from ${meaning.instances.source}`, threshold: null };
  }
  const threshold = Number($('threshold').value) || DEFAULT_THRESHOLD;
  return { result: selectAtPixel(splats, meaning.features, meaning.channels, camera, column, row, threshold),
    rule: `threshold ${threshold}`, threshold };
}

function selectAt(column, row) {
  if (state.lod) return selectInStreamed(column, row);
  if (!scene) throw new Error('no scene is open');
  if (!semantic) throw new Error('the semantic layer is not loaded, so there is nothing to select by');
  const { result, rule, threshold } = pickAt(scene, semantic, column, row);
  state.selection = { count: result.count, column, row, alpha: result.alpha, threshold, rule, mask: result.mask };
  view.highlight(result.mask);
  drawAgain();
  $('selection').textContent = `selected ${result.count.toLocaleString()} of ${scene.count.toLocaleString()} Gaussians (pixel ${column},${row}, ${rule})`;
  return result;
}

/** selectAt on the tiles a streamed file draws: the same rules on their Gaussians joined. */
function selectInStreamed(column, row) {
  if (!streamer || !streamer.drawn.size) throw new Error('nothing is drawn yet');
  const { scene: drawn, semantic: meaning, parts } = drawnScene();
  if (!meaning) throw new Error('the semantic layer is not loaded, so there is nothing to select by');
  const { result, rule, threshold } = pickAt(drawn, meaning, column, row);
  const masks = new Map(parts.map(([n, start, count]) => [n, result.mask.subarray(start, start + count)]));
  state.selection = { count: result.count, column, row, alpha: result.alpha, threshold, rule, mask: result.mask, tiles: parts.map((p) => p[0]) };
  view.highlightTiles(masks);
  drawAgain();
  $('selection').textContent = `selected ${result.count.toLocaleString()} of ${drawn.count.toLocaleString()} Gaussians drawn (pixel ${column},${row}, ${rule})`;
  return result;
}

function clearSelection() {
  const streamed = Boolean(state.lod);
  state.selection = null;
  if (view && streamed) view.highlightTiles(null);
  else if (view) view.highlight(null);
  drawAgain();
  $('selection').textContent = '';
}

$('canvas').addEventListener('click', (e) => {
  if ((rig.lastDragPixels || 0) > 3 || (!scene && !state.lod)) return;
  const canvas = $('canvas');
  const column = Math.floor(e.offsetX * canvas.width / canvas.clientWidth);
  const row = Math.floor(e.offsetY * canvas.height / canvas.clientHeight);
  try {
    selectAt(column, row);
  } catch (error) {
    clearSelection();
    $('selection').textContent = error.message;
  }
});
window.addEventListener('keydown', (e) => { if (e.key === 'Escape') clearSelection(); });
$('file').addEventListener('change', () => {
  const file = $('file').files[0];
  if (file) open({ file }, file.name, ['color', 'semantic']);
});
window.addEventListener('dragover', (e) => e.preventDefault());
window.addEventListener('drop', (e) => { // a file dropped on the page opens like a picked one
  e.preventDefault();
  const file = e.dataTransfer && e.dataTransfer.files[0];
  if (file) open({ file }, file.name, ['color', 'semantic']);
});

window.csgsViewer = {
  state,
  setCamera(camera) { rig.setCamera(camera); },
  camera() { const { width, height } = view.size; return rig.camera(width, height); },
  frameDrawn,
  capture() { return view.capture(); },
  selectAt,
  selectionIndices() {
    const mask = state.selection && state.selection.mask;
    if (!mask) return [];
    const out = [];
    for (let i = 0; i < mask.length; i++) if (mask[i]) out.push(i);
    return out;
  },
};

async function start() {
  let config = { scene: null, name: null, layers: ['color', 'semantic'] };
  try {
    const response = await fetch('/config.json', { cache: 'no-store' });
    if (response.ok) config = { ...config, ...(await response.json()) };
  } catch { /* opened without the server's config: the file picker still works */ }
  const url = params.get('scene') || config.scene;
  const layers = (params.get('layers') || config.layers.join(',')).split(',');
  if (url) {
    open({ url: new URL(url, location.href).href }, config.name || url, layers);
  } else {
    state.phase = 'idle';
    setMessage('Choose a .csgs file to open.');
  }
}
start();
