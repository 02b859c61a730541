/**
 * Decoding a standard (Gaussian) scene: the colour codec's chunks of spec/FORMAT.md §12.4 -
 * §12.19 on top of the container. Anchor scenes (§17) are not implemented here: a file with
 * an ANCH chunk raises UnsupportedError.
 */

import { ByteReader } from './bytes.mjs';
import { decodeCategorical } from './categorical.mjs';
import { channelPriors, modelledStreams, parseColourPrior, STREAM_CHANNELS } from './colour_prior.mjs';
import { readLayers } from './container.mjs';
import { FormatError, UnsupportedError } from './errors.mjs';
import { readFloatStream } from './float_stream.mjs';
import { decodeGeometry } from './geometry.mjs';
import { decodeSymbols } from './residual.mjs';

const MAX_GAUSSIANS = 2 ** 24;
const MAX_GAUSSIANS_PER_BYTE = 64;
const BAND_CODES = ['SHBA', 'SHBB', 'SHBC'];
const SH_REST = [0, 3, 8, 15];
const SQRT2 = Math.fround(Math.SQRT2);

/** The one payload of type ``code`` and its absolute offset; FormatError if missing or twice. */
function single(container, code) {
  const entries = container.toc.entries.filter((e) => e.type === code);
  if (!entries.length) throw new FormatError(`required chunk ${code} is missing`, { chunk: code });
  if (entries.length > 1) throw new FormatError(`chunk ${code} appears ${entries.length} times`, { chunk: code, offset: entries[1].offset });
  const entry = entries[0];
  if (!container.payloads.has(entry.index)) throw new FormatError(`chunk ${code} is cut off`, { chunk: code, offset: entry.offset });
  return [container.payloads.get(entry.index), entry.offset + 8];
}

/** The SCNE payload (§12.5). */
function readHeader(container) {
  const [data, offset] = single(container, 'SCNE');
  const r = new ByteReader(data, offset, 'SCNE');
  const count = r.varint('gaussian_count', 2 ** 28);
  const stored = r.u8('sh_degree_stored');
  const coded = r.u8('sh_degree_coded');
  const quality = r.u8('quality');
  const origin = [r.f64('grid_origin_x'), r.f64('grid_origin_y'), r.f64('grid_origin_z')];
  const cell = r.f64('grid_cell');
  const bits = r.u8('grid_bits');
  const far = r.varint('far_count', count);
  r.expectEnd('the scene header');
  if (stored > 3 || coded > stored) throw r.error(`SH degrees stored ${stored} / coded ${coded} are invalid`);
  if (!origin.every(Number.isFinite) || !(Number.isFinite(cell) && cell > 0)) throw r.error('grid origin and cell must be finite, cell > 0');
  if (bits > 21) throw r.error(`grid_bits ${bits} exceeds 21`);
  return { count, stored, coded, quality, origin, cell, bits, far };
}

function checkFinite(values, chunk) {
  for (let i = 0; i < values.length; i++) {
    if (!Number.isFinite(values[i])) throw new FormatError('decoded values overflow float32', { chunk });
  }
}

/** FormatError when a stream's channels in ``target`` hold a non-finite value. */
function checkTarget(target, channels, n, chunk) {
  const { array, stride, offset } = target;
  for (let i = 0; i < n; i++) {
    const row = i * stride + offset;
    for (let c = 0; c < channels; c++) {
      if (!Number.isFinite(array[row + c])) throw new FormatError('decoded values overflow float32', { chunk });
    }
  }
}

/** Base layer: float32 positions written into ``positions`` (§12.4 "Positions", §12.6,
 * §12.7); returns the grid cells. */
function decodePositions(container, header, positions) {
  const gridCount = header.count - header.far;
  const [data, offset] = single(container, 'GEOM');
  let cells;
  try {
    cells = decodeGeometry(data, gridCount);
  } catch (err) {
    if (err instanceof FormatError) throw new FormatError(err.detail, { chunk: 'GEOM', offset: offset + (err.offset ?? 0) });
    throw err;
  }
  if (cells.count !== gridCount) throw new FormatError(`geometry holds ${cells.count} points, the header says ${gridCount}`, { chunk: 'GEOM', offset });
  const limit = 2 ** Math.max(header.bits, 1);
  if (header.bits < 21) {
    for (const axis of [cells.x, cells.y, cells.z]) {
      for (let i = 0; i < axis.length; i++) if (axis[i] >= limit) throw new FormatError('a point lies outside the header\'s grid', { chunk: 'GEOM', offset });
    }
  }
  const [ox, oy, oz] = header.origin;
  const cell = header.cell;
  for (let i = 0; i < gridCount; i++) {
    positions[3 * i] = ox + cells.x[i] * cell;
    positions[3 * i + 1] = oy + cells.y[i] * cell;
    positions[3 * i + 2] = oz + cells.z[i] * cell;
  }
  if (header.far) {
    const [outl, at] = single(container, 'OUTL');
    const r = new ByteReader(outl, at, 'OUTL');
    const n = r.varint('far_count', header.far);
    if (n !== header.far) throw r.error(`${n} outliers, the header says ${header.far}`);
    const far = new Float32Array(3 * n);
    if (3 * n > Math.floor(r.remaining / 4)) {
      throw r.error(`truncated: field 'positions' needs ${3 * n} x 4 bytes`, r.baseOffset + r.bytes.length);
    }
    for (let i = 0; i < 3 * n; i++) far[i] = r.f32('positions');
    r.expectEnd('the outlier list');
    checkFinite(far, 'OUTL');
    positions.set(far, 3 * gridCount);
  }
  checkFinite(positions, 'GEOM');
  return cells;
}

/** One colour stream, its values written into ``target`` (and for ROTN the dropped-component
 * indices returned). */
function decodeStream(container, header, code, priors, family, target) {
  const [data, offset] = single(container, code);
  const r = new ByteReader(data, offset, code);
  let axis = null;
  if (code === 'ROTN') {
    const stream = r.byteString('axis_stream');
    axis = decodeCategorical(stream, header.count, code, r.offset - stream.length);
    for (let i = 0; i < axis.length; i++) if (axis[i] > 3) throw r.error('dropped-component index above 3');
  }
  readFloatStream(r, header.count, STREAM_CHANNELS[code], priors, family, target);
  r.expectEnd(`the ${code} stream`);
  checkTarget(target, STREAM_CHANNELS[code], header.count, code);
  return axis;
}

/** (w, x, y, z) float32 quaternions from the smallest three, N x 3 (§12.4 "rotation"). */
function rotations(axis, rest, n) {
  const out = new Float32Array(4 * n);
  const t = new Float32Array(3);
  for (let i = 0; i < n; i++) {
    const t0 = Math.fround(rest[3 * i] / SQRT2);
    const t1 = Math.fround(rest[3 * i + 1] / SQRT2);
    const t2 = Math.fround(rest[3 * i + 2] / SQRT2);
    const sum = Math.fround(Math.fround(Math.fround(t0 * t0) + Math.fround(t1 * t1)) + Math.fround(t2 * t2));
    const m = Math.fround(1 - sum);
    const big = Math.fround(Math.sqrt(Math.max(m, 0)));
    const d = axis[i];
    t[0] = t0; t[1] = t1; t[2] = t2;
    let j = 0;
    for (let a = 0; a < 4; a++) out[4 * i + a] = a === d ? big : t[j++];
  }
  return out;
}

/**
 * The checks and parameters every decode starts with: container, header, colour hyperprior.
 * @returns {object} the prepared decode (container, header, codes, prior, modelled, ...)
 */
export function prepareScene(data, options) {
  const layers = new Set(['color', ...(options.layers || [])]);
  const { family, sine } = options.tables;
  const container = readLayers(data, layers);
  if (container.toc.entries.some((e) => e.type === 'ANCH')) {
    throw new UnsupportedError('anchor scenes (spec/FORMAT.md §17) are not implemented in the JavaScript receiver');
  }
  const header = readHeader(container);
  const limit = Math.min(options.maxGaussians ?? MAX_GAUSSIANS, (options.maxGaussiansPerByte ?? MAX_GAUSSIANS_PER_BYTE) * data.length);
  if (header.count > limit) throw new FormatError(`declares ${header.count} Gaussians, above this decoder's limit of ${limit}`, { chunk: 'SCNE' });
  const codes = ['SHDC', ...BAND_CODES.slice(0, header.coded), 'OPAC', 'SCAL', 'ROTN'];
  let prior = null;
  if (container.toc.entries.some((e) => e.type === 'CHYP')) {
    const [bytes, offset] = single(container, 'CHYP');
    const posBits = Math.max(header.bits, 1);
    if (posBits > 32) throw new FormatError('the colour hyperprior needs a grid of at most 32 bits', { chunk: 'CHYP', offset });
    prior = parseColourPrior(bytes, offset, codes, posBits, family);
  }
  const present = new Set(container.toc.entries.map((e) => e.type));
  const extra = [...BAND_CODES, 'SHDC', 'OPAC', 'SCAL', 'ROTN'].filter((c) => present.has(c) && !codes.includes(c)).sort();
  if (extra.length) throw new FormatError(`unexpected colour chunk(s) ${extra} for SH degree ${header.coded}`, { chunk: extra[0] });
  const modelled = prior ? modelledStreams(prior, codes) : new Set();
  return { layers, family, sine, container, header, codes, prior, modelled };
}

/**
 * The output arrays of the colour streams, each stream's place in them ({array, stride,
 * offset}) and the positions array; ``Buffer`` makes their storage (ArrayBuffer or
 * SharedArrayBuffer).
 */
export function makeTargets(header, Buffer = ArrayBuffer) {
  const n = header.count;
  const f32 = (length) => new Float32Array(new Buffer(4 * length));
  const restCount = SH_REST[header.stored];
  const shRest = f32(n * restCount * 3);
  const targets = {
    SHDC: { array: f32(3 * n), stride: 3, offset: 0 },
    OPAC: { array: f32(n), stride: 1, offset: 0 },
    SCAL: { array: f32(3 * n), stride: 3, offset: 0 },
    ROTN: { array: f32(3 * n), stride: 3, offset: 0 },
  };
  BAND_CODES.forEach((code, b) => { targets[code] = { array: shRest, stride: restCount * 3, offset: SH_REST[b] * 3 }; });
  return { targets, shRest, positions: f32(3 * n) };
}

/** Decode one task ('GEOM' or a colour stream code) of a prepared scene into its targets;
 * returns the dropped-component indices for ROTN. */
export function decodeTask(prep, out, code, priors = null) {
  if (code === 'GEOM') return decodePositions(prep.container, prep.header, out.positions);
  return decodeStream(prep.container, prep.header, code, priors, prep.family, out.targets[code]);
}

/** The scene object of decoded targets, with the semantic layer when it was asked for. */
export function finishScene(prep, out, axis) {
  const n = prep.header.count;
  const scene = {
    count: n,
    positions: out.positions,
    sh_dc: out.targets.SHDC.array,
    sh_rest: out.shRest,
    opacity: out.targets.OPAC.array,
    scales: out.targets.SCAL.array,
    rotations: rotations(axis, out.targets.ROTN.array, n),
    semantic: null,
    semanticNames: [],
    labels: null,
  };
  if (prep.layers.has('semantic')) decodeSemantic(prep.container, prep.header, scene, prep.family);
  return scene;
}

/**
 * Decode a standard scene on this thread (parallel_node.mjs spreads it over two in Node).
 * @param {Uint8Array} data the .csgs bytes (or a prefix holding the requested layers)
 * @param {{layers?: string[], tables: {family: object, sine: Int32Array},
 *   maxGaussians?: number, maxGaussiansPerByte?: number}} options
 * @returns {object} count, positions (N x 3), sh_dc (N x 3), sh_rest (N x R x 3), opacity,
 *   scales (N x 3), rotations (N x 4, w x y z), semantic (N x S) and semanticNames, labels
 */
export function decodeScene(data, options) {
  return decodePrepared(prepareScene(data, options));
}

/** The rest of decodeScene after prepareScene, on this thread. Errors come in the order the
 * reference decoder reports them: hyperprior cells, colour streams in order, geometry. */
export function decodePrepared(prep) {
  const out = makeTargets(prep.header);
  let priors = new Map();
  let geometryDone = false;
  if (prep.modelled.size) {
    const cells = decodeTask(prep, out, 'GEOM');
    geometryDone = true;
    const cellLimit = 2 ** prep.prior.net.posBits;
    for (const axis of [cells.x, cells.y, cells.z]) {
      for (let i = 0; i < axis.length; i++) if (axis[i] >= cellLimit) throw new FormatError('the colour hyperprior needs smaller cells', { chunk: 'CHYP' });
    }
    priors = channelPriors(prep.prior, cells, prep.header.count, prep.codes, prep.sine);
  }
  let axis = null;
  for (const code of prep.codes) {
    const result = decodeTask(prep, out, code, priors.get(code) || null);
    if (code === 'ROTN') axis = result;
  }
  if (!geometryDone) decodeTask(prep, out, 'GEOM');
  return finishScene(prep, out, axis);
}

/** Semantic layer: SEMF features and SEML labels (§12.16, §12.17). */
function decodeSemantic(container, header, scene, family) {
  const present = new Set(container.toc.entries.map((e) => e.type));
  if (present.has('SEMF')) {
    const [data, offset] = single(container, 'SEMF');
    const r = new ByteReader(data, offset, 'SEMF');
    const count = r.varint('channel_count', 256);
    const names = [];
    const decoder = new TextDecoder('utf-8', { fatal: true });
    for (let i = 0; i < count; i++) {
      const raw = r.byteString('channel_name', 256);
      try { names.push(decoder.decode(raw)); } catch { throw r.error('channel name is not UTF-8'); }
    }
    const values = readFloatStream(r, header.count, names.length, null, family);
    r.expectEnd('the semantic feature stream');
    checkFinite(values, 'SEMF');
    scene.semantic = values;
    scene.semanticNames = names;
  }
  if (present.has('SEML')) {
    const [data, offset] = single(container, 'SEML');
    const r = new ByteReader(data, offset, 'SEML');
    const base = r.svarintBig('label_base');
    const table = r.u8('scale_index');
    const stream = r.byteString('label_stream');
    r.expectEnd('the label stream');
    if (table >= 64) throw r.error(`scale index ${table} out of range`);
    const { values, big } = decodeSymbols(stream, table, header.count, family, 'SEML', r.offset - stream.length);
    const labels = new Int32Array(header.count);
    const exact = base >= -(2n ** 52n) && base <= 2n ** 52n;
    const baseNum = Number(base);
    for (let i = 0; i < values.length; i++) {
      let v;
      if (exact && !(big && big.has(i))) v = values[i] + baseNum;
      else v = Number((big && big.has(i) ? big.get(i) : BigInt(values[i])) + base);
      if (v < -(2 ** 31) || v >= 2 ** 31) throw r.error('label outside the int32 range');
      labels[i] = v;
    }
    scene.labels = labels;
  }
}
