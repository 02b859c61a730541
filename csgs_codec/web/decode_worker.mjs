/**
 * The viewer's Web Worker: reads a .csgs layer by layer and decodes it with the JavaScript
 * receiver (../js/), reporting progress.
 *
 * Order: header and TOC, then the bytes up to the end of the color layer (one HTTP Range
 * request, or a slice of a picked file), decoded and posted at once so the page can draw;
 * then, when asked, the semantic layer's bytes, decoded and posted after.
 *
 * Messages in: {kind: 'open', url | file, layers: ['color'] | ['color', 'semantic']}.
 * Messages out (each with the open request's id):
 *   {kind: 'progress', stage, fraction, text}
 *   {kind: 'toc', fileEnd, colorEnd, hasSemantic}
 *   {kind: 'color', scene, bytesRead, decodeMs}   arrays transferred
 *   {kind: 'semantic', semantic, channels, names, labels, bytesRead, decodeMs}
 *   {kind: 'error', stage, message, chunk, offset}   the receiver's errors name both
 *   {kind: 'done'}
 */

import { channelPriors } from '../js/color_prior.mjs';
import { readToc } from '../js/container.mjs';
import { FormatError } from '../js/errors.mjs';
import { decodeTask, finishScene, makeTargets, prepareScene } from '../js/scene.mjs';
import { decodeSemantic } from '../js/semantic_layer.mjs';
import { GAUSSIAN_V1_SHA256, SINE_V1_SHA256, parseGaussianFamily, parseSineTable } from '../js/tables.mjs';

const HEADER_SIZE = 16;
const TABLES_URL = new URL('../entropy/data/', import.meta.url);
let tablesPromise = null;

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

async function sha256Hex(bytes) {
  const digest = new Uint8Array(await crypto.subtle.digest('SHA-256', bytes));
  return Array.from(digest, (b) => b.toString(16).padStart(2, '0')).join('');
}

/** The frozen tables (§16.2.1, §16.2.2), fetched once and checked against their SHA-256. */
function loadTables() {
  tablesPromise ??= (async () => {
    const get = async (name, expected) => {
      const response = await fetch(new URL(name, TABLES_URL));
      if (!response.ok) throw new Error(`cannot fetch the frozen table ${name}: HTTP ${response.status}`);
      const bytes = new Uint8Array(await response.arrayBuffer());
      if (await sha256Hex(bytes) !== expected) throw new Error(`the frozen table ${name} has the wrong SHA-256`);
      return bytes;
    };
    const [family, sine] = await Promise.all([get('gaussian_v1.bin', GAUSSIAN_V1_SHA256), get('sine_v1.bin', SINE_V1_SHA256)]);
    return { family: parseGaussianFamily(family), sine: parseSineTable(sine) };
  })();
  return tablesPromise;
}

/** Payload bytes of the chunks a decode task reads, as its share of the decode's work. */
function taskWeight(entries, code) {
  const types = code === 'GEOM' ? ['GEOM', 'OUTL', 'OUTQ'] : [code];
  return 1 + entries.filter((e) => types.includes(e.type)).reduce((s, e) => s + e.length, 0);
}

/**
 * Decode the base and color layers of ``bytes`` (a prefix of the file is enough), calling
 * ``report(fraction)`` after each stream. The task order and the hyperprior's cell check are
 * those of scene.mjs's decodePrepared, which has no progress hook.
 */
function decodeColor(bytes, tables, report) {
  const prep = prepareScene(bytes, { layers: [], tables });
  const out = makeTargets(prep.header);
  const modelled = prep.modelled.size > 0;
  const tasks = modelled ? ['GEOM', ...prep.codes] : [...prep.codes, 'GEOM'];
  const weights = tasks.map((code) => taskWeight(prep.container.toc.entries, code));
  const total = weights.reduce((a, b) => a + b, 0);
  let done = 0;
  let priors = new Map();
  let axis = null;
  tasks.forEach((code, k) => {
    if (code === 'GEOM') {
      const cells = decodeTask(prep, out, 'GEOM');
      if (modelled) {
        const cellLimit = 2 ** prep.prior.net.posBits;
        for (const values of [cells.x, cells.y, cells.z]) {
          for (let i = 0; i < values.length; i++) {
            if (values[i] >= cellLimit) throw new FormatError('the color hyperprior needs smaller cells', { chunk: 'CHYP' });
          }
        }
        priors = channelPriors(prep.prior, cells, prep.header.count, prep.codes, prep.sine);
      }
    } else {
      const result = decodeTask(prep, out, code, priors.get(code) || null);
      if (code === 'ROTN') axis = result;
    }
    done += weights[k];
    report(done / total);
  });
  return finishScene(prep, out, axis);
}

function errorMessage(error, stage) {
  return {
    kind: 'error', stage, message: String(error && (error.detail || error.message) || error),
    chunk: error && error.chunk !== undefined ? error.chunk : null,
    offset: error && error.offset !== undefined ? error.offset : null,
  };
}

async function open(request, post) {
  const source = request.file ? new FileSource(request.file) : new UrlSource(request.url);
  const wanted = new Set(request.layers || ['color', 'semantic']);
  const progress = (stage, fraction, text) => post({ kind: 'progress', stage, fraction, text });
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
    if (source.size !== null && source.size > fileEnd) {
      throw new FormatError(`${source.size - fileEnd} bytes follow the last chunk`, { offset: fileEnd });
    }
    const need = colorEnd - prefix.length;
    const body = await source.read(prefix.length, colorEnd,
      (n) => progress('color', 0.5 * n / Math.max(need, 1), `downloading the color layer: ${n.toLocaleString()} of ${need.toLocaleString()} bytes`));
    const colorBytes = concat([prefix, body]);
    const tables = await tablesReady;
    progress('color', 0.5, 'decoding the color layer');
    const t0 = performance.now();
    const scene = decodeColor(colorBytes, tables, (f) => progress('color', 0.5 + 0.5 * f, 'decoding the color layer'));
    const decodeMs = performance.now() - t0;
    const arrays = [scene.positions, scene.sh_dc, scene.sh_rest, scene.opacity, scene.scales, scene.rotations];
    post({ kind: 'color', scene: { ...scene, fileEnd, colorEnd }, bytesRead: colorBytes.length, decodeMs },
      arrays.map((a) => a.buffer));
    if (!wanted.has('semantic') || !hasSemantic) {
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
    const prep = prepareScene(whole, { layers: ['semantic'], tables });
    const layer = { semantic: null, semanticNames: [], labels: null };
    decodeSemantic(prep.container, prep.header, layer, tables.family);
    const channels = layer.semantic ? layer.semanticNames.length : 0;
    post({ kind: 'semantic', semantic: layer.semantic, channels, names: layer.semanticNames,
      labels: layer.labels, bytesRead: whole.length, decodeMs: performance.now() - t1 },
    [layer.semantic, layer.labels].filter(Boolean).map((a) => a.buffer));
    post({ kind: 'done' });
  } catch (error) {
    post(errorMessage(error, stage));
  }
}

self.onmessage = (event) => {
  const request = event.data;
  if (request.kind !== 'open') return;
  const post = (message, transfer = []) => self.postMessage({ ...message, id: request.id }, transfer);
  open(request, post);
};
