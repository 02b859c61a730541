/**
 * Integer networks (spec/FORMAT.md §16.4): the payload (versions 1 and 2), its checks
 * including the exactness bound, and inference on the positional embedding. Every sum is
 * an integer of magnitude at most 2^53 (the bound guarantees it), so float64 is exact.
 */

import { ByteReader } from './bytes.mjs';
import { FormatError } from './errors.mjs';
import { decodeSymbols } from './residual.mjs';
import { denseInstance, forwardDense } from './wasm_intnet.mjs';

const MAX_WIDTH = 4096;
const BIAS_LIMIT = 2n ** 52n;
const OUTPUT_LIMIT = 2n ** 53n;
const EXACT_LIMIT = 2n ** 53n;
const EMBED_LIMIT = 16384n;

function bounded(r, field, low, high) {
  const start = r.offset;
  const value = r.u8(field);
  if (value < low || value > high) throw r.error(`field '${field}' = ${value} outside [${low}, ${high}]`, start);
  return value;
}

/** Most coded values a payload may declare per byte left (§16.4.3 version 2). */
function codedValueLimit(remaining) { return 4 * remaining + 65536; }

/**
 * Layer ``i``'s ``count`` weights of ``bits`` signed bits (§16.4.3): version 1 fixed-width
 * (range checked by the caller), version 2 a table index and a residual stream (checked
 * here). Also the weights of the dense networks of §17.5.
 * @returns {Float64Array}
 */
export function readWeights(r, version, i, count, bits, family) {
  if (version === 1) {
    const size = bits <= 8 ? 1 : bits <= 16 ? 2 : 4;
    if (count > Math.floor(r.remaining / size)) {
      throw r.error(`truncated: field 'layer ${i} weights' needs ${count} x ${size} bytes`, r.baseOffset + r.bytes.length);
    }
    const at = r.take(count * size, `layer ${i} weights`);
    const out = new Float64Array(count);
    for (let j = 0; j < count; j++) {
      out[j] = size === 1 ? r.view.getInt8(at + j) : size === 2 ? r.view.getInt16(at + 2 * j, true) : r.view.getInt32(at + 4 * j, true);
    }
    return out;
  }
  const start = r.offset;
  if (count > codedValueLimit(r.remaining)) throw r.error(`layer ${i}: ${count} weights exceed the allowed count`, start);
  const table = bounded(r, `layer ${i} table`, 0, family.halfWidths.length - 1);
  const stream = r.byteString(`layer ${i} weight stream`);
  const { values } = decodeSymbols(stream, table, count, family, r.chunk, r.offset - stream.length);
  const limit = 2 ** (bits - 1);
  for (let j = 0; j < count; j++) {
    if (values[j] < -limit || values[j] >= limit) throw r.error(`layer ${i}: a weight is outside ${bits} signed bits`, start);
  }
  return values;
}

function readBiases(r, version, i, count) {
  const out = new Float64Array(count);
  if (version === 1) {
    if (count > Math.floor(r.remaining / 8)) {
      throw r.error(`truncated: field 'layer ${i} biases' needs ${count} x 8 bytes`, r.baseOffset + r.bytes.length);
    }
    const big = [];
    for (let j = 0; j < count; j++) big.push(r.i64(`layer ${i} biases`));
    for (let j = 0; j < count; j++) {
      const b = big[j];
      if (b <= -BIAS_LIMIT || b >= BIAS_LIMIT) return { invalid: true };
      out[j] = Number(b);
    }
    return out;
  }
  if (count > r.remaining) throw r.error(`truncated: layer ${i} biases`);
  for (let j = 0; j < count; j++) {
    const start = r.offset;
    const b = r.svarintBig(`layer ${i} bias`);
    if (b <= -BIAS_LIMIT || b >= BIAS_LIMIT) throw r.error(`layer ${i}: bias is not below 2^52 in magnitude`, start);
    out[j] = Number(b);
  }
  return out;
}

/**
 * Parse a network payload (§16.4.3).
 * @returns {{posBits, numFreqs, actBits, layers: {w: Float64Array, b: Float64Array, out, in, shift}[],
 *   lo: Float64Array, hi: Float64Array}}
 */
export function parseIntNet(bytes, family, chunk, baseOffset) {
  const r = new ByteReader(bytes, baseOffset, chunk);
  const start = r.offset;
  const version = r.u8('version');
  if (version !== 1 && version !== 2) throw r.error(`network payload version ${version} is not 1 or 2`, start);
  const posBits = bounded(r, 'pos_bits', 1, 32);
  const numFreqs = bounded(r, 'num_freqs', 1, 16);
  const actBits = bounded(r, 'act_bits', 1, 30);
  const count = bounded(r, 'layer_count', 1, 16);
  let width = 6 * numFreqs;
  const layers = [];
  let invalid = null;
  for (let i = 0; i < count; i++) {
    const at = r.offset;
    const out = r.varint(`layer ${i} out_width`, MAX_WIDTH);
    if (out === 0) throw r.error(`layer ${i} out_width is 0`, at);
    const bits = bounded(r, `layer ${i} weight_bits`, 2, 24);
    const shift = bounded(r, `layer ${i} shift`, 0, 62);
    const w = readWeights(r, version, i, out * width, bits, family);
    const b = readBiases(r, version, i, out);
    if (b.invalid) { invalid = invalid || `layer ${i} biases reach 2^52`; }
    if (version === 1 && !invalid) {
      const limit = 2 ** (bits - 1);
      for (let j = 0; j < w.length; j++) if (w[j] < -limit || w[j] >= limit) { invalid = `layer ${i} weights exceed ${bits} signed bits`; break; }
    }
    layers.push({ w, b: b.invalid ? new Float64Array(out) : b, out, in: width, shift });
    width = out;
  }
  const ranges = [];
  for (let o = 0; o < width; o++) ranges.push([r.svarintBig('output lo'), r.svarintBig('output hi')]);
  const end = r.offset;
  r.expectEnd('the network payload');
  const int64 = (v) => v >= -(2n ** 63n) && v < 2n ** 63n;
  if (!ranges.every(([lo, hi]) => int64(lo) && int64(hi))) {
    throw new FormatError('network output range exceeds 64 bits', { chunk, offset: end });
  }
  const fail = (message) => new FormatError(`invalid network: ${message}`, { chunk, offset: baseOffset });
  if (invalid) throw fail(invalid);
  if (ranges.some(([lo, hi]) => lo < -OUTPUT_LIMIT || hi > OUTPUT_LIMIT || lo > hi)) {
    throw fail('output ranges must satisfy -2^53 <= lo <= hi <= 2^53');
  }
  const hidden = (1n << BigInt(actBits)) - 1n;
  layers.forEach((layer, i) => {
    const bound = i === 0 ? EMBED_LIMIT : hidden;
    const half = layer.shift ? 1n << BigInt(layer.shift - 1) : 0n;
    for (let o = 0; o < layer.out; o++) {
      let rowAbs = 0;
      for (let j = 0; j < layer.in; j++) rowAbs += Math.abs(layer.w[o * layer.in + j]); // < 2^35: exact
      const total = BigInt(rowAbs) * bound + BigInt(Math.abs(layer.b[o])) + half;
      if (total > EXACT_LIMIT) throw fail(`layer ${i} worst-case accumulator exceeds 2^53`);
    }
  });
  return {
    posBits, numFreqs, actBits, layers,
    lo: Float64Array.from(ranges, ([lo]) => Number(lo)),
    hi: Float64Array.from(ranges, ([, hi]) => Number(hi)),
  };
}

/**
 * The positional embedding (§16.4.1) of positions [start, start + count): element j of
 * position start + i goes to h[at(i) + j * stride], where at(i) = i * width (stride 1) or,
 * with ``stride`` 4, ((i >> 2) * width) * 4 + (i & 3) (blocks of four positions,
 * wasm_intnet.mjs's layout).
 */
function embed(net, coords, sine, h, start, count, stride) {
  const width = 6 * net.numFreqs;
  for (let i = 0; i < count; i++) {
    const p = start + i;
    const at = stride === 1 ? i * width : (((i >> 2) * width) << 2) + (i & 3);
    for (let l = 0; l < net.numFreqs; l++) {
      const down = net.posBits - l - 10; // in [-25, 22]: posBits <= 32, l <= 15
      for (let d = 0; d < 3; d++) {
        const x = coords[d][p];
        // ((x << (l + 10)) >> B) mod 1024 on the integer x < 2^32: the low ten bits of a
        // shift, exact in 32-bit integer arithmetic.
        const k = down >= 0 ? (x >>> down) & 1023 : (x << -down) & 1023;
        const j = at + (6 * l + 2 * d) * stride;
        h[j] = sine[k];
        h[j + stride] = sine[(k + 256) & 1023];
      }
    }
  }
}

let useWasm = true;

/** Choose the loop forwardIntNet runs: 'wasm' (WebAssembly SIMD, where the engine has it)
 * or 'js'. Both give the same outputs; tests run both. */
export function setIntNetKernel(kind) {
  if (kind !== 'wasm' && kind !== 'js') throw new Error(`unknown integer-network kernel ${kind}`);
  useWasm = kind === 'wasm';
}

/** The loop integer networks run now: 'wasm' or 'js' (see setIntNetKernel). */
export function intNetKernel() { return useWasm ? 'wasm' : 'js'; }

/**
 * Evaluate the network on integer positions (§16.4.1, §16.4.2).
 * @param {object} net from parseIntNet
 * @param {ArrayLike<number>} xs, ys, zs coordinates, each in [0, 2^posBits)
 * @param {Int32Array} sine the frozen sine table
 * @returns {Float64Array} N x O outputs, row-major
 */
export function forwardIntNet(net, xs, ys, zs, n, sine) {
  const coords = [xs, ys, zs];
  if (useWasm && n >= 16 && denseInstance()) {
    return forwardDense(net, n, (h, start, count) => embed(net, coords, sine, h, start, count, 4));
  }
  const outWidth = net.layers[net.layers.length - 1].out;
  const result = new Float64Array(n * outWidth);
  const width0 = 6 * net.numFreqs;
  let maxWidth = width0;
  for (const layer of net.layers) maxWidth = Math.max(maxWidth, layer.out);
  let h = new Float64Array(maxWidth);
  let y = new Float64Array(maxWidth);
  const top = 2 ** net.actBits - 1;
  const scales = net.layers.map((layer) => 2 ** -layer.shift);
  const offsets = net.layers.map((layer) => (layer.shift ? 2 ** (layer.shift - 1) : 0));
  for (let p = 0; p < n; p++) {
    embed(net, coords, sine, h, p, 1, 1);
    for (let k = 0; k < net.layers.length; k++) {
      const layer = net.layers[k];
      const w = layer.w;
      const last = k === net.layers.length - 1;
      for (let o = 0; o < layer.out; o++) {
        let acc = layer.b[o] + offsets[k];
        const row = o * layer.in;
        for (let j = 0; j < layer.in; j++) acc += w[row + j] * h[j];
        let v = Math.floor(acc * scales[k]);
        if (last) {
          v = Math.min(Math.max(v, net.lo[o]), net.hi[o]);
          result[p * outWidth + o] = v;
        } else {
          y[o] = Math.min(Math.max(v, 0), top);
        }
      }
      if (!last) { const t = h; h = y; y = t; }
    }
  }
  return result;
}
