/**
 * The anchor-scene chunks that are not residual streams (spec/FORMAT.md §17.3, §17.6, §17.7,
 * §17.12): the header ANCH, the offset masks AMSK, the Scaffold-GS MLP weights AMLP and the
 * optional view origins vorg. Every failure is a FormatError naming the chunk and the byte
 * offset, where and in the order the reference decoder reports it.
 */

import { ByteReader } from './bytes.mjs';
import { FormatError } from './errors.mjs';
import { readFloatStream } from './float_stream.mjs';
import { RangeDecodeError, RangeDecoder, prepareTable } from './range_decoder.mjs';
import { halfToFloat } from './semantic_layer.mjs';

const MAX_ANCHORS = 2 ** 26;
const MAX_VALUES = 2 ** 31;
const MAX_FEATURES = 4096;
const MAX_MLP_WIDTH = 4096;
const MAX_APPEARANCE_CAMERAS = 2 ** 20;
const FLAG_MLPS = 0x01;
/** Output width per offset of each Scaffold-GS head, in payload order. */
export const HEADS = [['opacity', 1], ['cov', 7], ['color', 3]];

function bounded(r, field, low, high) {
  const start = r.offset;
  const value = r.u8(field);
  if (value < low || value > high) throw r.error(`field '${field}' = ${value} outside [${low}, ${high}]`, start);
  return value;
}

/**
 * The ANCH payload (§17.3).
 * @returns {{count: number, featDim: number, nOffsets: number, gridBits: number,
 *   voxelSize: number, origin: number[], carmGroups: number, quality: number,
 *   hasMlps: boolean}} M, F, K, the voxel grid (world units), G, the quality and has_mlps
 */
export function readAnchorHeader(data, baseOffset) {
  const r = new ByteReader(data, baseOffset, 'ANCH');
  bounded(r, 'version', 1, 1);
  const count = r.varint('anchor_count', MAX_ANCHORS);
  let at = r.offset;
  const featDim = r.varint('feat_dim', MAX_FEATURES);
  if (featDim === 0) throw r.error('feat_dim is 0', at);
  const nOffsets = bounded(r, 'n_offsets', 1, 64);
  const gridBits = bounded(r, 'grid_bits', 0, 21);
  at = r.offset;
  const voxelSize = r.f64('voxel_size');
  const origin = [r.f64('origin'), r.f64('origin'), r.f64('origin')];
  if (!(Number.isFinite(voxelSize) && voxelSize > 0 && origin.every(Number.isFinite))) {
    throw r.error('voxel_size must be finite and > 0, origin finite', at);
  }
  bounded(r, 'frac_bits', 12, 12);
  bounded(r, 'mean_bits', 6, 6);
  const carmGroups = bounded(r, 'carm_groups', 1, Math.min(featDim, 64));
  const quality = bounded(r, 'quality', 1, 9);
  const flags = bounded(r, 'flags', 0, FLAG_MLPS);
  r.expectEnd('the anchor header');
  const perAnchor = featDim + 3 * nOffsets + 6;
  if (count * perAnchor > MAX_VALUES) throw r.error(`${count} anchors x ${perAnchor} values exceed the limit ${MAX_VALUES}`, baseOffset);
  return { count, featDim, nOffsets, gridBits, voxelSize, origin, carmGroups, quality, hasMlps: (flags & FLAG_MLPS) !== 0 };
}

/** Prepared binary tables [65536 - f, f] / 2^16, one per frequency f of kept. */
const binaryTables = new Map();
function binaryTable(f) {
  if (!binaryTables.has(f)) binaryTables.set(f, prepareTable([65536 - f, f], 4));
  return binaryTables.get(f);
}

/**
 * The AMSK payload (§17.6): the M x K offset-mask bits, 1 = kept.
 * @returns {Uint8Array} M x K, row-major
 */
export function readOffsetMasks(data, baseOffset, count, slots) {
  const r = new ByteReader(data, baseOffset, 'AMSK');
  const m = r.varintBig('anchor_count');
  const start = r.offset;
  const k = r.u8('slots');
  if (m !== BigInt(count) || k !== slots) throw r.error(`mask stream holds ${m} x ${k}, the header says ${count} x ${slots}`, start);
  const contexts = (k * (k + 1)) / 2;
  if (contexts > Math.floor(r.remaining / 2)) {
    throw r.error(`truncated: field 'frequencies' needs ${contexts} x 2 bytes, ${r.remaining} remain`, r.baseOffset + r.bytes.length);
  }
  const freqs = [];
  for (let c = 0; c < contexts; c++) freqs.push(r.u16('frequencies'));
  if (freqs.some((f) => f < 1)) throw r.error('a mask frequency is outside [1, 65535]');
  const words = r.varint('word_count', Math.floor(r.remaining / 4));
  const range = r.raw(4 * words, 'range_data');
  r.expectEnd('the mask stream');
  const decoder = new RangeDecoder(range, words);
  const mask = new Uint8Array(count * k);
  const before = new Int32Array(count); // kept slots of each anchor before the current one
  const rows = new Int32Array(count); // anchors grouped by context, increasing in each group
  const starts = new Int32Array(k + 2);
  const bits = new Int32Array(count);
  for (let slot = 0; slot < k; slot++) {
    const base = (slot * (slot + 1)) / 2;
    starts.fill(0);
    for (let i = 0; i < count; i++) starts[before[i] + 1]++;
    for (let j = 0; j <= slot; j++) starts[j + 1] += starts[j];
    const fill = starts.slice(0, slot + 1);
    for (let i = 0; i < count; i++) rows[fill[before[i]]++] = i;
    for (let j = 0; j <= slot; j++) {
      const n = starts[j + 1] - starts[j];
      if (!n) continue;
      try {
        decoder.decodeMany(binaryTable(freqs[base + j]), bits, n);
      } catch (err) {
        if (err instanceof RangeDecodeError) throw new FormatError(`range decoder failed in mask slot ${slot} (${err.message})`, { chunk: 'AMSK', offset: baseOffset });
        throw err;
      }
      for (let t = 0; t < n; t++) mask[rows[starts[j] + t] * k + slot] = bits[t];
    }
    for (let i = 0; i < count; i++) before[i] += mask[i * k + slot];
  }
  return mask;
}

/** Most values an array coded in the ``remaining`` payload bytes may hold (§17.7). */
function codedValueLimit(remaining) { return 4 * remaining + 65536; }

/** ``count`` weights of an AMLP array (version 1: float16; 2: a float stream), float32. */
function weights(r, version, count, name, family) {
  if (version === 1) {
    if (count > Math.floor(r.remaining / 2)) {
      throw r.error(`truncated: field '${name}' needs ${count} x 2 bytes, ${r.remaining} remain`, r.baseOffset + r.bytes.length);
    }
    const at = r.take(2 * count, name);
    const out = new Float32Array(count);
    for (let i = 0; i < count; i++) out[i] = halfToFloat(r.view.getUint16(at + 2 * i, true));
    return out;
  }
  if (count > codedValueLimit(r.remaining)) {
    throw r.error(`${name}: ${count} weights exceed the ${codedValueLimit(r.remaining)} allowed with ${r.remaining} payload bytes left`);
  }
  return readFloatStream(r, count, 1, null, family);
}

/** Why the heads do not fit F and K (§17.7 "Invalid if"), or null when they do. */
function misfit(mlps, featDim, nOffsets) {
  if (mlps.appearance && (mlps.appearanceCount === 0 || mlps.appearanceWidth === 0 || !mlps.appearance.every(Number.isFinite))) {
    return 'the appearance table is empty or not finite';
  }
  for (const [name, perOffset] of HEADS) {
    const head = mlps[name];
    if (!['w1', 'b1', 'w2', 'b2'].every((key) => head[key].every(Number.isFinite))) return `${name}: a weight is not finite`;
    if (!head.hidden || !head.inputs || !head.outputs) return `${name}: a width is 0`;
    if (head.outputs !== perOffset * nOffsets) return `${name}: ${head.outputs} outputs for ${nOffsets} offsets`;
    const extra = head.inputs - featDim - 3 - (name === 'color' && mlps.appearance ? mlps.appearanceWidth : 0);
    if (extra !== 0 && extra !== 1) return `${name}: ${head.inputs} inputs do not fit feature width ${featDim}`;
  }
  return null;
}

/**
 * The AMLP payload (§17.7): the three heads, checked against F and K.
 * @returns {{opacity: object, cov: object, color: object, appearance: Float32Array|null,
 *   appearanceCount: number, appearanceWidth: number}} each head {hidden H, inputs D,
 *   outputs O, w1 (H x D), b1 (H), w2 (O x H), b2 (O)}, float32, row-major (out x in); the
 *   appearance table C x A (C = appearanceCount cameras, A = appearanceWidth; 0 without one),
 *   the layout anchor_bake.mjs takes
 */
export function readMlps(data, baseOffset, featDim, nOffsets, family) {
  const r = new ByteReader(data, baseOffset, 'AMLP');
  let at = r.offset;
  const version = r.u8('version');
  if (version !== 1 && version !== 2) throw r.error(`MLP payload version ${version} is not 1 or 2`, at);
  at = r.offset;
  const flags = r.u8('flags');
  if (flags > 1) throw r.error(`reserved flag bits set (${flags})`, at);
  const mlps = { appearance: null, appearanceCount: 0, appearanceWidth: 0 };
  for (const [name] of HEADS) {
    const hidden = r.varint(`${name} hidden`, MAX_MLP_WIDTH);
    const inputs = r.varint(`${name} inputs`, MAX_MLP_WIDTH);
    const outputs = r.varint(`${name} outputs`, MAX_MLP_WIDTH);
    const w1 = weights(r, version, hidden * inputs, `${name}.w1`, family);
    const b1 = weights(r, version, hidden, `${name}.b1`, family);
    const w2 = weights(r, version, outputs * hidden, `${name}.w2`, family);
    const b2 = weights(r, version, outputs, `${name}.b2`, family);
    mlps[name] = { hidden, inputs, outputs, w1, b1, w2, b2 };
  }
  if (flags) {
    const cameras = r.varint('appearance cameras', MAX_APPEARANCE_CAMERAS);
    const width = r.varint('appearance width', MAX_MLP_WIDTH);
    Object.assign(mlps, { appearance: weights(r, version, cameras * width, 'appearance', family), appearanceCount: cameras, appearanceWidth: width });
  }
  r.expectEnd('the MLP weights');
  const why = misfit(mlps, featDim, nOffsets);
  if (why) throw new FormatError(`MLP weights do not fit the anchors: ${why}`, { chunk: 'AMLP', offset: baseOffset });
  return mlps;
}

/**
 * The view origins of a vorg payload (§17.12).
 * @returns {Float32Array} V x 3 origins, world units
 * @throws {FormatError} when the payload is invalid (the caller then reports none)
 */
export function parseViewOrigins(data, baseOffset) {
  const r = new ByteReader(data, baseOffset, 'vorg');
  const version = r.u8('version');
  if (version !== 1) throw r.error(`unknown view-origins version ${version}`, r.offset - 1);
  const start = r.offset;
  const count = r.varint('origin_count', 32);
  if (count === 0) throw r.error('origin_count is 0', start);
  const origins = new Float32Array(3 * count);
  for (let i = 0; i < 3 * count; i++) origins[i] = r.f32('origins');
  if (!origins.every(Number.isFinite)) throw r.error('an origin is not finite', start);
  r.expectEnd('the view-origins record');
  return origins;
}

/** The container's view origins (V x 3 float32), or null when it has no vorg chunk, more
 * than one, or one whose payload is invalid: never a reason to reject the file (§17.12). */
export function readViewOrigins(container) {
  const entries = container.toc.entries.filter((e) => e.type === 'vorg');
  if (entries.length !== 1 || !container.payloads.has(entries[0].index)) return null;
  try {
    return parseViewOrigins(container.payloads.get(entries[0].index), entries[0].offset + 8);
  } catch (err) {
    if (err instanceof FormatError) return null;
    throw err;
  }
}
