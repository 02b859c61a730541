/**
 * Dense integer networks (spec/FORMAT.md §17.5): the payload of an ACRM network and its
 * evaluation on integer inputs. The layers are those of §16.4.2 (intnet.mjs) with the shifted
 * and clipped inputs x' = clip(x >> input_shift, -(2^input_bits - 1), 2^input_bits - 1) in
 * place of the positional embedding; every sum is an integer of magnitude at most 2^53 (the
 * exactness bound guarantees it), so float64 is exact.
 */

import { ByteReader } from './bytes.mjs';
import { FormatError } from './errors.mjs';
import { intNetKernel, readWeights } from './intnet.mjs';
import { denseInstance, forwardDense } from './wasm_intnet.mjs';

const MAX_WIDTH = 4096;
const BIAS_LIMIT = 2n ** 52n;
const OUTPUT_LIMIT = 2n ** 53n;
const EXACT_LIMIT = 2n ** 53n;

function bounded(r, field, low, high) {
  const start = r.offset;
  const value = r.u8(field);
  if (value < low || value > high) throw r.error(`field '${field}' = ${value} outside [${low}, ${high}]`, start);
  return value;
}

/** An svarint field within +-``limit`` (BigInt), else FormatError at the field. */
function signed(r, field, limit) {
  const start = r.offset;
  const value = r.svarintBig(field);
  if (value < -limit || value > limit) throw r.error(`field '${field}' = ${value} is outside +-${limit}`, start);
  return value;
}

/** Why the parsed layers break a rule of §16.4.2 / §17.5 (null when they keep them all). */
function invalidity(layers, ranges, inputBits, actBits) {
  for (const [i, layer] of layers.entries()) {
    const limit = 2 ** (layer.bits - 1);
    if (layer.w.some((w) => w < -limit || w >= limit)) return `layer ${i} weights exceed ${layer.bits} signed bits`;
    if (layer.big.some((b) => b <= -BIAS_LIMIT || b >= BIAS_LIMIT)) return `layer ${i} biases reach 2^52`;
  }
  if (ranges.some(([lo, hi]) => lo > hi)) return 'output ranges must satisfy lo <= hi';
  for (const [i, layer] of layers.entries()) {
    const bound = (1n << BigInt(i === 0 ? inputBits : actBits)) - 1n;
    const half = layer.shift ? 1n << BigInt(layer.shift - 1) : 0n;
    for (let o = 0; o < layer.out; o++) {
      let rowAbs = 0;
      for (let j = 0; j < layer.in; j++) rowAbs += Math.abs(layer.w[o * layer.in + j]); // < 2^35: exact
      const total = BigInt(rowAbs) * bound + (layer.big[o] < 0n ? -layer.big[o] : layer.big[o]) + half;
      if (total > EXACT_LIMIT) return `layer ${i} worst-case accumulator exceeds 2^53`;
    }
  }
  return null;
}

/**
 * Parse one dense network payload (the whole of ``bytes``), checked as §17.5 says.
 * @param {Uint8Array} bytes the payload
 * @param {object} family the Gaussian tables (version 2 weights)
 * @param {string} chunk named in errors
 * @param {number} baseOffset absolute offset of bytes[0]
 * @returns {{inWidth, inputShift, inputBits, actBits, layers: {w: Float64Array,
 *   b: Float64Array, out, in, shift}[], lo: Float64Array, hi: Float64Array, outWidth}}
 */
export function parseDenseNet(bytes, family, chunk, baseOffset) {
  const r = new ByteReader(bytes, baseOffset, chunk);
  const start = r.offset;
  const version = r.u8('version');
  if (version !== 1 && version !== 2) throw r.error(`dense network version ${version} is not 1 or 2`, start);
  const inWidth = r.varint('in_width', MAX_WIDTH);
  if (inWidth === 0) throw r.error('in_width is 0');
  const inputShift = bounded(r, 'input_shift', 0, 62);
  const inputBits = bounded(r, 'input_bits', 1, 30);
  const actBits = bounded(r, 'act_bits', 1, 30);
  const count = bounded(r, 'layer_count', 1, 16);
  let width = inWidth;
  const layers = [];
  for (let i = 0; i < count; i++) {
    const out = r.varint(`layer ${i} out_width`, MAX_WIDTH);
    if (out === 0) throw r.error(`layer ${i} out_width is 0`);
    const bits = bounded(r, `layer ${i} weight_bits`, 2, 24);
    const shift = bounded(r, `layer ${i} shift`, 0, 62);
    const w = readWeights(r, version, i, out * width, bits, family);
    if (out > r.remaining) throw r.error(`truncated: layer ${i} biases`);
    const big = [];
    for (let o = 0; o < out; o++) big.push(signed(r, `layer ${i} bias`, BIAS_LIMIT));
    layers.push({ w, big, b: Float64Array.from(big, Number), out, in: width, shift, bits });
    width = out;
  }
  if (2 * width > r.remaining) throw r.error('truncated: output ranges');
  const ranges = [];
  for (let o = 0; o < width; o++) ranges.push([signed(r, 'output lo', OUTPUT_LIMIT), signed(r, 'output hi', OUTPUT_LIMIT)]);
  r.expectEnd('the dense network payload');
  const why = invalidity(layers, ranges, inputBits, actBits);
  if (why) throw new FormatError(`invalid dense network: ${why}`, { chunk, offset: start });
  return {
    inWidth, inputShift, inputBits, actBits, outWidth: width,
    layers: layers.map(({ w, b, out, in: inW, shift }) => ({ w, b, out, in: inW, shift })),
    lo: Float64Array.from(ranges, ([lo]) => Number(lo)),
    hi: Float64Array.from(ranges, ([, hi]) => Number(hi)),
  };
}

/**
 * The network's first-layer inputs: x' of §17.5 for rows of ``n`` inputs.
 * @param {(row: number, j: number) => number|bigint} input exact integer input j of row
 *   ``row`` (a BigInt where it is beyond 2^53 in magnitude)
 * @returns {Float64Array} n x D shifted and clipped inputs, row-major
 */
export function denseInputs(net, n, input) {
  const d = net.inWidth;
  const top = 2 ** net.inputBits - 1;
  const scale = 2 ** -net.inputShift;
  const shift = BigInt(net.inputShift);
  const out = new Float64Array(n * d);
  for (let row = 0; row < n; row++) {
    for (let j = 0; j < d; j++) {
      const x = input(row, j);
      // x >> s is floor(x / 2^s): exact on a float64 integer, and on a BigInt.
      const v = typeof x === 'bigint' ? Number(x >> shift) : Math.floor(x * scale);
      out[row * d + j] = Math.min(Math.max(v, -top), top);
    }
  }
  return out;
}

/**
 * Evaluate the network (§16.4.2 layers) on prepared inputs.
 * @param {object} net from parseDenseNet
 * @param {Float64Array} inputs n x D from denseInputs
 * @param {number} n rows
 * @returns {Float64Array} n x O integer outputs, row-major
 */
export function forwardDenseNet(net, inputs, n) {
  const d = net.inWidth;
  if (intNetKernel() === 'wasm' && n >= 16 && denseInstance()) {
    return forwardDense(net, n, (h, start, count) => {
      for (let i = 0; i < count; i++) {
        const at = (((i >> 2) * d) << 2) + (i & 3);
        const row = (start + i) * d;
        for (let j = 0; j < d; j++) h[at + 4 * j] = inputs[row + j];
      }
    });
  }
  const outWidth = net.outWidth;
  const result = new Float64Array(n * outWidth);
  let maxWidth = d;
  for (const layer of net.layers) maxWidth = Math.max(maxWidth, layer.out);
  let h = new Float64Array(maxWidth);
  let y = new Float64Array(maxWidth);
  const top = 2 ** net.actBits - 1;
  const last = net.layers.length - 1;
  for (let p = 0; p < n; p++) {
    h.set(inputs.subarray(p * d, (p + 1) * d));
    net.layers.forEach((layer, k) => {
      const offset = layer.shift ? 2 ** (layer.shift - 1) : 0;
      const scale = 2 ** -layer.shift;
      for (let o = 0; o < layer.out; o++) {
        let acc = layer.b[o] + offset;
        const row = o * layer.in;
        for (let j = 0; j < layer.in; j++) acc += layer.w[row + j] * h[j];
        const v = Math.floor(acc * scale);
        if (k === last) result[p * outWidth + o] = Math.min(Math.max(v, net.lo[o]), net.hi[o]);
        else y[o] = Math.min(Math.max(v, 0), top);
      }
      if (k !== last) { const t = h; h = y; y = t; }
    });
  }
  return result;
}
