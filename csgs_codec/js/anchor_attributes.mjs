/**
 * Anchor attributes on the value grid (spec/FORMAT.md §17.2, §17.8-§17.11): the entropy
 * parameters the hyperprior (and, for the features, the CARM networks) give each value, and
 * the residual streams of AFEA, AOFF, ASCL and ASEM decoded to float32 values.
 *
 * Grid values are exact integers: a Float64Array holds each one (exactly up to 2^53 in
 * magnitude) and a Map holds the exact BigInt of any beyond, which the CARM networks read.
 */

import { ByteReader } from './bytes.mjs';
import { denseInputs, forwardDenseNet } from './dense_net.mjs';
import { FormatError } from './errors.mjs';
import { stepSize } from './float_stream.mjs';
import { decodeSymbols } from './residual.mjs';

const FRAC_BITS = 12;
const MEAN_SCALE = 2 ** 6; // mean indices are in units of 2^-6 values: grid = index << 6
const SCALE_MAX = 63;
const STEP_COUNT = 176;
const TWO52 = 2 ** 52;
const TWO53 = 2 ** 53;
const VALUE_RANGE = 2n ** 62n;
const MAX_STREAMS = 64;
/** q of every step index (§16.3.1). */
const STEPS = Float64Array.from({ length: STEP_COUNT }, (_, j) => stepSize(j));

/**
 * Split hyperprior outputs into the parameters of each attribute type (§17.2 layout).
 * @param {Float64Array} out M x O network outputs, row-major
 * @param {number[]} channels C of each attribute type, in layout order
 * @returns {{m: number, c: number, mean: Float64Array, scale: Float64Array,
 *   step: Float64Array}[]} per type: M x C mean indices and scale indices, M step indices
 */
export function splitOutputs(out, m, channels) {
  const width = channels.reduce((sum, c) => sum + 2 * c + 1, 0);
  let col = 0;
  return channels.map((c) => {
    const p = { m, c, mean: new Float64Array(m * c), scale: new Float64Array(m * c), step: new Float64Array(m) };
    for (let i = 0; i < m; i++) {
      const row = i * width + col;
      for (let ch = 0; ch < c; ch++) {
        p.mean[i * c + ch] = out[row + ch];
        p.scale[i * c + ch] = out[row + c + ch];
      }
      p.step[i] = out[row + 2 * c];
    }
    col += 2 * c + 1;
    return p;
  });
}

/**
 * Decode one residual stream of n values with per-value parameters (§16.3): the value is
 * mu + q r with mu = mean index << 6 and q = step_size(step index).
 * @param {{meanIndex: Float64Array, scale: ArrayLike<number>, step: ArrayLike<number>}} p
 * @returns {{values: Float64Array, big: Map<number, bigint>|null}} grid values
 */
export function decodeValues(stream, p, family, chunk, baseOffset) {
  const n = p.meanIndex.length;
  const mean = new Float64Array(n);
  for (let i = 0; i < n; i++) {
    mean[i] = p.meanIndex[i] * MEAN_SCALE;
    if (Math.abs(mean[i]) > TWO53) throw new FormatError('mean exceeds 2^53', { chunk });
  }
  for (let i = 0; i < n; i++) {
    if (!(p.step[i] >= 0 && p.step[i] < STEP_COUNT)) throw new FormatError(`step index ${p.step[i]} is outside [0, ${STEP_COUNT})`);
  }
  const { values: r, big: bigR } = decodeSymbols(stream, p.scale, n, family, chunk, baseOffset);
  const values = new Float64Array(n);
  let big = null;
  for (let i = 0; i < n; i++) {
    const q = STEPS[p.step[i]];
    const mu = mean[i];
    const exactR = bigR && bigR.has(i) ? bigR.get(i) : null;
    const product = q * r[i];
    const value = mu + product;
    if (exactR === null && Math.abs(product) < TWO52 && Math.abs(value) < TWO53) {
      values[i] = value; // both sums of exact integers below 2^53: exact
      continue;
    }
    const rr = exactR ?? BigInt(r[i]);
    const abs = (v) => (v < 0n ? -v : v);
    if (abs(rr) * BigInt(q) + abs(BigInt(mu)) > VALUE_RANGE) throw new FormatError('decoded value leaves the 2^62 grid range', { chunk });
    const exact = BigInt(mu) + BigInt(q) * rr;
    values[i] = Number(exact);
    if (abs(exact) > BigInt(TWO53)) (big = big || new Map()).set(i, exact);
  }
  return { values, big };
}

/** Grid values -> the float32 values a decoder outputs, float32(v 2^-12) (§17.2). Every
 * value is within 2^62 grid units, so the result is finite. */
export function gridFloats(values) {
  const out = new Float32Array(values.length);
  const unit = 2 ** -FRAC_BITS;
  for (let i = 0; i < values.length; i++) out[i] = values[i] * unit;
  return out;
}

/**
 * The count length-prefixed byte strings of an ACRM or AFEA payload (§17.5, §17.8), each
 * with the absolute offset of its first byte.
 * @returns {[Uint8Array, number][]}
 */
export function readStreamList(data, offset, chunk, count) {
  const r = new ByteReader(data, offset, chunk);
  const n = r.varint('stream_count', MAX_STREAMS);
  if (n !== count) throw r.error(`${n} streams, expected ${count}`);
  const out = [];
  for (let i = 0; i < n; i++) {
    const stream = r.byteString('stream');
    out.push([stream, r.offset - stream.length]);
  }
  r.expectEnd(`the ${chunk} payload`);
  return out;
}

/** Channel ranges of G groups of C channels: group g is [g C // G, (g + 1) C // G). */
export function groupBounds(channels, groups) {
  const bounds = [];
  for (let g = 0; g < groups; g++) bounds.push([Math.floor((g * channels) / groups), Math.floor(((g + 1) * channels) / groups)]);
  return bounds;
}

/**
 * The AFEA features (§17.8): one stream per CARM group, group g's parameters refined by CARM
 * network g - 1 over the decoded channels before it.
 * @param {[Uint8Array, number][]} streams from readStreamList
 * @param {object} params the hyperprior's feature parameters (splitOutputs)
 * @param {object[]} carm the G - 1 dense networks (dense_net.mjs)
 * @returns {Float32Array} M x F features
 */
export function decodeFeatures(streams, params, carm, family) {
  const { m, c: f } = params;
  const grid = new Float64Array(m * f);
  let big = null;
  const input = (row, j) => {
    const at = row * f + j;
    return big && big.has(at) ? big.get(at) : grid[at];
  };
  groupBounds(f, carm.length + 1).forEach(([lo, hi], g) => {
    const c = hi - lo;
    const meanIndex = new Float64Array(m * c);
    const scale = new Float64Array(m * c);
    const step = new Float64Array(m * c);
    const refine = g ? forwardDenseNet(carm[g - 1], denseInputs(carm[g - 1], m, input), m) : null;
    for (let i = 0; i < m; i++) {
      for (let ch = 0; ch < c; ch++) {
        const t = i * c + ch;
        meanIndex[t] = params.mean[i * f + lo + ch];
        scale[t] = params.scale[i * f + lo + ch];
        step[t] = params.step[i];
        if (refine) {
          meanIndex[t] += refine[i * 2 * c + ch];
          scale[t] = Math.min(Math.max(scale[t] + refine[i * 2 * c + c + ch], 0), SCALE_MAX);
        }
      }
    }
    const [stream, offset] = streams[g];
    const decoded = decodeValues(stream, { meanIndex, scale, step }, family, 'AFEA', offset);
    for (let i = 0; i < m; i++) {
      for (let ch = 0; ch < c; ch++) grid[i * f + lo + ch] = decoded.values[i * c + ch];
    }
    if (decoded.big) {
      big = big || new Map();
      for (const [t, v] of decoded.big) big.set(Math.floor(t / c) * f + lo + (t % c), v);
    }
  });
  return gridFloats(grid);
}

/**
 * The AOFF offsets (§17.9): the kept slots' 3 axes, anchor by anchor; masked ones are 0.
 * @param {Uint8Array} mask M x K offset-mask bits
 * @returns {Float32Array} M x K x 3 offsets
 */
export function decodeOffsets(data, offset, params, mask, family) {
  const { m } = params;
  const k = params.c / 3;
  let kept = 0;
  for (let i = 0; i < mask.length; i++) kept += mask[i];
  const meanIndex = new Float64Array(3 * kept);
  const scale = new Float64Array(3 * kept);
  const step = new Float64Array(3 * kept);
  let t = 0;
  for (let i = 0; i < m; i++) {
    for (let s = 0; s < k; s++) {
      if (!mask[i * k + s]) continue;
      for (let d = 0; d < 3; d++, t++) {
        meanIndex[t] = params.mean[i * 3 * k + 3 * s + d];
        scale[t] = params.scale[i * 3 * k + 3 * s + d];
        step[t] = params.step[i];
      }
    }
  }
  const values = gridFloats(decodeValues(data, { meanIndex, scale, step }, family, 'AOFF', offset).values);
  const offsets = new Float32Array(3 * mask.length);
  t = 0;
  for (let slot = 0; slot < mask.length; slot++) {
    if (!mask[slot]) continue;
    offsets.set(values.subarray(t, t + 3), 3 * slot);
    t += 3;
  }
  return offsets;
}

/**
 * A residual stream of M x C values, anchor-major, with one attribute type's parameters
 * (ASCL's scaling, §17.10; ASEM's semantic features, §17.11).
 * @returns {Float32Array} M x C values
 */
export function decodeAnchorMajor(data, offset, params, family, chunk) {
  const { m, c } = params;
  const step = new Float64Array(m * c);
  for (let i = 0; i < m; i++) step.fill(params.step[i], i * c, (i + 1) * c);
  return gridFloats(decodeValues(data, { meanIndex: params.mean, scale: params.scale, step }, family, chunk, offset).values);
}
