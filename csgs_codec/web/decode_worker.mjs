/**
 * The viewer's Web Worker: reads a .csgs layer by layer and decodes it with the JavaScript
 * receiver's one orchestration (../js/scene.mjs decodeScene) on decode lanes, Web Workers of
 * their own (lane_worker.mjs; this thread when a browser cannot start them).
 *
 * Order: header and TOC, then the bytes up to the end of the color layer (one HTTP Range
 * request, or a slice of a picked file), decoded; the splats with their base color are
 * posted as soon as they are decoded (stage 'first'), the SH bands after; then, when asked,
 * the semantic layer's bytes, decoded and posted. An anchor scene (TOC lists ANCH) is
 * decoded and baked into splats (anchor_open.mjs): a quick preview bake first, then the
 * reference decoder's bake. A file with levels of detail (TIDX version 2) is streamed
 * (level_open.mjs): the tile index, the coarsest level, then the tiles the page asks for.
 *
 * Its URL may say ``?lanes=N`` (see decodeLanes).
 * Messages in: {kind: 'open', url | file, layers: ['color'] | ['color', 'semantic'],
 *   hashes: bool}; {kind: 'tiles', id, numbers} (a file with levels: read and decode these
 *   tiles, after those asked for before).
 * Messages out (each with the open request's id):
 *   {kind: 'progress', stage, fraction, text}
 *   {kind: 'toc', fileEnd, colorEnd, hasSemantic, chunks}
 *   {kind: 'color', scene, complete, bytesRead, decodeMs}   the splats; ``complete`` false
 *     while the SH bands are still decoding (scene.sh_rest then has no coefficients)
 *   {kind: 'sh', sh_rest, decodeMs}   the SH bands of an incomplete 'color' scene
 *   {kind: 'semantic', semantic, channels, names, labels, bytesRead, decodeMs}
 *   {kind: 'hashes', arrays}   when asked: {name: {shape, sha256}} of every decoded array,
 *     as decode_cli.mjs prints them (tests compare them with the Python decoder's)
 *   {kind: 'error', stage, message, chunk, offset, kind}   the receiver's errors name both;
 *     ``errorKind``: 'format', 'unsupported' or 'internal'
 *   {kind: 'mark', name, at}   when a step happened (epoch milliseconds)
 *   {kind: 'levels', ...} and {kind: 'tile', ...}   a file with levels (level_open.mjs)
 *   {kind: 'done'}
 */

import './receiver_modules.mjs';
import { RemoteLane } from '../js/lane_client.mjs';
import { readToc } from '../js/container.mjs';
import { LocalLane } from '../js/decode_runner.mjs';
import { FormatError, UnsupportedError } from '../js/errors.mjs';
import { decodeScene, decodeSemanticLayer, sceneArrays } from '../js/scene.mjs';
import { openAnchors } from './anchor_open.mjs';
import { hasLevels, openLevels } from './level_open.mjs';
import { loadTables, sha256Hex } from './tables_fetch.mjs';

const HEADER_SIZE = 16;
/** Decode lanes: one Web Worker per core but one (the page's own thread draws meanwhile; on
 * two cores one lane got the first frame 10% sooner than two, benchmarks/web_viewer.py), at
 * most this many. */
const MAX_LANES = 4;
let lanes = null;
/** The open file's tile reader when it has levels of detail (level_open.mjs), else null. */
let levelStream = null;

/** The decode lanes, started when this worker starts, for every file it opens: ``asked``
 * Web Workers (null: one per core but one, at least one, at most MAX_LANES; 0: decode on
 * this thread). */
function decodeLanes(asked) {
  if (lanes) return lanes;
  const cores = self.navigator?.hardwareConcurrency || 2;
  const count = asked ?? Math.max(1, Math.min(cores - 1, MAX_LANES));
  if (count === 0) {
    lanes = [new LocalLane()];
    return lanes;
  }
  try {
    lanes = Array.from({ length: count }, () => {
      const worker = new Worker(new URL('./lane_worker.mjs', import.meta.url), { type: 'module' });
      return new RemoteLane({
        post: (message, transfer = []) => worker.postMessage(message, transfer),
        listen: (handler) => { worker.onmessage = (event) => handler(event.data); },
        close: () => worker.terminate(),
      });
    });
  } catch { // no nested workers here: decode on this thread
    lanes = [new LocalLane()];
  }
  return lanes;
}

/** Bytes [start, end) of a scene at a URL, by HTTP Range requests. */
class UrlSource {
  constructor(url) { this.url = url; this.size = null; }

  /** Up to end - start bytes from start (fewer where the file is shorter; end may be
   * Infinity); ``onBytes(received)`` follows the download. */
  async read(start, end, onBytes = null) {
    if (end <= start) return new Uint8Array(0);
    const range = Number.isFinite(end) ? `bytes=${start}-${end - 1}` : `bytes=${start}-`;
    const response = await fetch(this.url, { headers: { Range: range }, cache: 'no-store' });
    if (response.status === 416) {
      this.noteSize(response.headers.get('Content-Range'));
      return new Uint8Array(0);
    }
    if (!response.ok) throw new Error(`cannot read ${this.url}: HTTP ${response.status}`);
    this.noteSize(response.headers.get('Content-Range'));
    const body = await readBody(response, onBytes);
    if (response.status === 200) { // a server without ranges sent the whole file
      this.size = body.length;
      return body.subarray(start, Math.min(end, body.length));
    }
    return body;
  }

  noteSize(contentRange) {
    const match = /\/(\d+)$/.exec(contentRange || '');
    if (match) this.size = Number(match[1]);
  }
}

/** Bytes [start, end) of a file the user picked. */
class FileSource {
  constructor(file) { this.file = file; this.size = file.size; }

  async read(start, end, onBytes = null) {
    const bytes = new Uint8Array(await this.file.slice(start, Math.min(end, this.size)).arrayBuffer());
    if (onBytes) onBytes(bytes.length);
    return bytes;
  }
}

async function readBody(response, onBytes) {
  if (!response.body || !onBytes) return new Uint8Array(await response.arrayBuffer());
  const parts = [];
  let received = 0;
  const reader = response.body.getReader();
  for (;;) {
    const { done, value } = await reader.read();
    if (done) break;
    parts.push(value);
    received += value.length;
    onBytes(received);
  }
  return concat(parts);
}

function concat(parts) {
  const total = parts.reduce((sum, p) => sum + p.length, 0);
  const out = new Uint8Array(total);
  let at = 0;
  for (const p of parts) { out.set(p, at); at += p.length; }
  return out;
}

/** {name: {shape, sha256}} of a decoded scene's arrays (decode_cli.mjs's layout; ``arrays``
 * gives them for an anchor scene). */
async function arrayHashes(scene, arrays = sceneArrays) {
  const out = {};
  for (const [name, [values, shape]] of Object.entries(arrays(scene))) {
    out[name] = { shape, sha256: await sha256Hex(new Uint8Array(values.buffer, values.byteOffset, values.byteLength)) };
  }
  return out;
}

/** Tell the page when a step of the load happened (its ``state.timeline``, in the page's
 * milliseconds since navigation). */
function mark(post, name) {
  post({ kind: 'mark', name, at: performance.timeOrigin + performance.now() });
}

function errorMessage(error, stage) {
  const errorKind = error instanceof FormatError ? 'format' : error instanceof UnsupportedError ? 'unsupported' : 'internal';
  return {
    kind: 'error', stage, errorKind, message: String(error && (error.detail || error.message) || error),
    chunk: error && error.chunk !== undefined ? error.chunk : null,
    offset: error && error.offset !== undefined ? error.offset : null,
  };
}

async function open(request, post) {
  const source = request.file ? new FileSource(request.file) : new UrlSource(request.url);
  const wanted = new Set(request.layers || ['color', 'semantic']);
  const progress = (stage, fraction, text) => post({ kind: 'progress', stage, fraction, text });
  const decoding = decodeLanes(null);
  let stage = 'color';
  try {
    progress('color', 0, 'reading the header');
    const tablesReady = loadTables();
    let prefix = await source.read(0, HEADER_SIZE);
    if (prefix.length >= HEADER_SIZE) {
      const tocSize = new DataView(prefix.buffer, prefix.byteOffset, HEADER_SIZE).getUint32(12, true);
      prefix = concat([prefix, await source.read(HEADER_SIZE, HEADER_SIZE + tocSize + 4)]);
    }
    const toc = readToc(prefix); // names what is wrong with a short or damaged header or TOC
    const entries = toc.entries;
    const colorEnd = entries.filter((e) => e.layer <= 1).reduce((m, e) => Math.max(m, e.end), toc.tocEnd);
    const fileEnd = entries.length ? entries[entries.length - 1].end : toc.tocEnd;
    const hasSemantic = entries.some((e) => e.layer === 2);
    post({ kind: 'toc', fileEnd, colorEnd, hasSemantic, chunks: entries.length });
    mark(post, 'tocRead');
    if (source.size !== null && source.size > fileEnd) {
      throw new FormatError(`${source.size - fileEnd} bytes follow the last chunk`, { offset: fileEnd });
    }
    if (entries.length && entries[0].type === 'TIDX') { // a tiled file: its index is next
      const index = await source.read(prefix.length, entries[0].end);
      const indexed = concat([prefix, index]);
      if (hasLevels(toc, index)) {
        levelStream = await openLevels({ source, indexed, toc, fileEnd, wanted, tablesReady,
          lanes: decoding, post, progress, mark });
        post({ kind: 'done' });
        return;
      }
      prefix = indexed;
    }
    if (entries.some((e) => e.type === 'ANCH')) {
      const stageOf = (name) => { stage = name; };
      await openAnchors({ source, prefix, colorEnd, fileEnd, hasSemantic, wanted, tablesReady,
        hashes: request.hashes, post, progress, mark, concat, arrayHashes, stageOf });
      return;
    }
    const need = colorEnd - prefix.length;
    const body = await source.read(prefix.length, colorEnd,
      (n) => progress('color', 0.3 * n / Math.max(need, 1), `downloading the color layer: ${n.toLocaleString()} of ${need.toLocaleString()} bytes`));
    const colorBytes = concat([prefix, body]);
    mark(post, 'colorBytesRead');
    const tables = await tablesReady;
    progress('color', 0.3, 'decoding the color layer');
    mark(post, 'decodeStarted');
    const t0 = performance.now();
    let shown = false;
    const onStage = (done, partial) => {
      if (done === 'first') {
        shown = partial;
        post({ kind: 'color', scene: { ...partial, fileEnd, colorEnd }, complete: partial.complete, bytesRead: colorBytes.length, decodeMs: performance.now() - t0 });
      }
    };
    const scene = await decodeScene(colorBytes, {
      layers: [], tables, lanes: decoding, onStage,
      onProgress: (f) => progress('color', 0.3 + 0.7 * f, 'decoding the color layer'),
    });
    const decodeMs = performance.now() - t0;
    mark(post, 'colorDecoded');
    if (!shown) { // a tiled file: the whole scene at once
      post({ kind: 'color', scene: { ...scene, fileEnd, colorEnd }, complete: true, bytesRead: colorBytes.length, decodeMs });
    } else if (!shown.complete) {
      post({ kind: 'sh', sh_rest: scene.sh_rest, decodeMs });
    }
    let hashes = request.hashes ? await arrayHashes(scene) : null;
    if (!wanted.has('semantic') || !hasSemantic) {
      if (hashes) post({ kind: 'hashes', arrays: hashes });
      post({ kind: 'done' });
      return;
    }
    stage = 'semantic';
    const more = fileEnd - colorEnd;
    const rest = await source.read(colorEnd, fileEnd,
      (n) => progress('semantic', 0.5 * n / Math.max(more, 1), `downloading the semantic layer: ${n.toLocaleString()} of ${more.toLocaleString()} bytes`));
    const whole = concat([colorBytes, rest]);
    progress('semantic', 0.5, 'decoding the semantic layer');
    const t1 = performance.now();
    const layer = await decodeSemanticLayer(whole, { tables });
    const channels = layer.semantic ? layer.semanticNames.length : 0;
    if (hashes) {
      hashes = await arrayHashes({ ...scene, semantic: layer.semantic, semanticNames: layer.semanticNames, labels: layer.labels });
    }
    post({ kind: 'semantic', semantic: layer.semantic, channels, names: layer.semanticNames,
      labels: layer.labels, bytesRead: whole.length, decodeMs: performance.now() - t1 });
    if (hashes) post({ kind: 'hashes', arrays: hashes });
    post({ kind: 'done' });
  } catch (error) {
    post(errorMessage(error, stage));
  }
}

const workerStarted = performance.timeOrigin + performance.now();
const lanesAsked = new URLSearchParams(self.location.search).get('lanes');
decodeLanes(/^\d$/.test(lanesAsked || '') ? Number(lanesAsked) : null); // start them now

self.onmessage = (event) => {
  const request = event.data;
  if (request.kind !== 'open' && request.kind !== 'tiles') return;
  const post = (message, transfer = []) => self.postMessage({ ...message, id: request.id }, transfer);
  if (request.kind === 'tiles') {
    if (levelStream) levelStream.fetch(request.numbers, (error) => post(errorMessage(error, 'color')));
    return;
  }
  levelStream = null;
  post({ kind: 'mark', name: 'workerStarted', at: workerStarted });
  open(request, post);
};
