/**
 * The integer network's layers (spec/FORMAT.md §16.4.2) as a WebAssembly SIMD function, for
 * speed: two float64 lanes per instruction, four positions per pass over a weight row. The
 * arithmetic is the scalar loop's (intnet.mjs forwardIntNet): every product and partial sum
 * is an integer below 2^53, so float64 is exact and the lanes give the same bits; WebAssembly
 * never fuses a multiply and an add.
 *
 * ``dense(in, out, blocks, inWidth, outWidth, weights, biases, lo, hi, scale)`` computes for
 * each block of four positions and each output o
 *   out[block][o][lane] = min(max(floor((b'[o] + sum_j W[o][j] in[block][j][lane]) * scale),
 *                                 lo[o]), hi[o])
 * with b' = bias + rounding offset, the sum in order of j. Activations are float64, laid out
 * [block][channel][4 lanes]; W is row-major [out][in]. Addresses are byte offsets in the
 * exported memory.
 */

import { F64, I32, V128, moduleBytes, op } from './wasm_assembler.mjs';

// Parameters and locals of dense.
const IN = 0; const OUT = 1; const BLOCKS = 2; const IN_W = 3; const OUT_W = 4;
const W = 5; const B = 6; const LO = 7; const HI = 8; const SCALE = 9;
const BLK = 10; const O = 11; const J = 12; const IP = 13; const WP = 14; const IN_BASE = 15;
const OUT_AT = 16;
const ACC0 = 17; const ACC1 = 18; const WV = 19; const S = 20; const L = 21; const H = 22;

/** ``address + index * 8``. */
const at8 = (address, index) => [op.get(address), op.get(index), op.i32Const(3), op.i32Shl, op.i32Add];

function denseBody() {
  const clamp = (acc) => [op.get(acc), op.get(S), op.f64x2Mul, op.f64x2Floor, op.get(L), op.f64x2Max, op.get(H), op.f64x2Min];
  return [
    op.get(SCALE), op.f64x2Splat, op.set(S),
    op.i32Const(0), op.set(BLK),
    op.block, op.loop,
    op.get(BLK), op.get(BLOCKS), op.i32GeU, op.brIf(1),
    // The block's inputs: in + blk * inW * 32; its outputs: out + blk * outW * 32.
    op.get(IN), op.get(BLK), op.get(IN_W), op.i32Mul, op.i32Const(5), op.i32Shl, op.i32Add, op.set(IN_BASE),
    op.get(OUT), op.get(BLK), op.get(OUT_W), op.i32Mul, op.i32Const(5), op.i32Shl, op.i32Add, op.set(OUT_AT),
    op.i32Const(0), op.set(O),
    op.block, op.loop,
    op.get(O), op.get(OUT_W), op.i32GeU, op.brIf(1),
    ...at8(B, O), op.f64Load(0), op.f64x2Splat, op.tee(ACC0), op.set(ACC1),
    op.get(IN_BASE), op.set(IP),
    // Row o of W: W + o * inW * 8.
    op.get(W), op.get(O), op.get(IN_W), op.i32Mul, op.i32Const(3), op.i32Shl, op.i32Add, op.set(WP),
    op.i32Const(0), op.set(J),
    op.block, op.loop,
    op.get(J), op.get(IN_W), op.i32GeU, op.brIf(1),
    op.get(WP), op.f64Load(0), op.f64x2Splat, op.set(WV),
    op.get(ACC0), op.get(WV), op.get(IP), op.v128Load(0), op.f64x2Mul, op.f64x2Add, op.set(ACC0),
    op.get(ACC1), op.get(WV), op.get(IP), op.v128Load(16), op.f64x2Mul, op.f64x2Add, op.set(ACC1),
    op.get(IP), op.i32Const(32), op.i32Add, op.set(IP),
    op.get(WP), op.i32Const(8), op.i32Add, op.set(WP),
    op.get(J), op.i32Const(1), op.i32Add, op.set(J),
    op.br(0),
    op.end, op.end,
    ...at8(LO, O), op.f64Load(0), op.f64x2Splat, op.set(L),
    ...at8(HI, O), op.f64Load(0), op.f64x2Splat, op.set(H),
    op.get(OUT_AT), ...clamp(ACC0), op.v128Store(0),
    op.get(OUT_AT), ...clamp(ACC1), op.v128Store(16),
    op.get(OUT_AT), op.i32Const(32), op.i32Add, op.set(OUT_AT),
    op.get(O), op.i32Const(1), op.i32Add, op.set(O),
    op.br(0),
    op.end, op.end,
    op.get(BLK), op.i32Const(1), op.i32Add, op.set(BLK),
    op.br(0),
    op.end, op.end,
  ];
}

/** The module's bytes: one function ``dense`` and one exported memory. */
export function assembleDense() {
  return moduleBytes({
    exportName: 'dense', params: [I32, I32, I32, I32, I32, I32, I32, I32, I32, F64], results: [],
    locals: [[7, I32], [6, V128]], body: denseBody(),
  });
}

let instance;

/** This thread's instance, or null where WebAssembly SIMD is not available. */
export function denseInstance() {
  if (instance === undefined) {
    instance = null;
    try {
      const bytes = assembleDense();
      if (typeof WebAssembly === 'object' && WebAssembly.validate(bytes)) {
        instance = new WebAssembly.Instance(new WebAssembly.Module(bytes), {});
      }
    } catch { /* no SIMD here: the scalar loop runs */ }
  }
  return instance;
}

/** Positions per call of dense: blocks of four, as many as fit in about 4 MiB of
 * activations. */
function chunkBlocks(maxWidth) {
  return Math.max(1, Math.floor((4 << 20) / (32 * maxWidth)));
}

/**
 * The network on n positions with the SIMD function (see intnet.mjs forwardIntNet for the
 * arguments); the same outputs, bit for bit.
 * @param {(h: Float64Array, start: number, count: number) => void} embed writes the
 *   embedding of positions [start, start + count) into h in the layout above
 * @returns {Float64Array} N x O outputs, row-major
 */
export function forwardDense(net, n, embed) {
  const { exports } = denseInstance();
  const layers = net.layers;
  const width0 = layers[0].in;
  const outWidth = layers[layers.length - 1].out;
  const maxWidth = Math.max(width0, ...layers.map((l) => l.out));
  const blocks = chunkBlocks(maxWidth);
  const top = 2 ** net.actBits - 1;
  // Memory: per layer weights, biases + offsets, lo, hi; then two activation buffers.
  let size = 64;
  const placed = layers.map((layer, k) => {
    const last = k === layers.length - 1;
    const item = { layer, last, w: size };
    size += 8 * layer.w.length;
    item.b = size; size += 8 * layer.out;
    item.lo = size; size += 8 * layer.out;
    item.hi = size; size += 8 * layer.out;
    return item;
  });
  const bufferBytes = 32 * blocks * maxWidth;
  const bufA = size;
  const bufB = bufA + bufferBytes;
  size = bufB + bufferBytes;
  const memory = exports.memory;
  if (size > memory.buffer.byteLength) memory.grow(Math.ceil((size - memory.buffer.byteLength) / 65536));
  const f64 = (address, length) => new Float64Array(memory.buffer, address, length);
  for (const { layer, last, w, b, lo, hi } of placed) {
    f64(w, layer.w.length).set(layer.w);
    const offset = layer.shift ? 2 ** (layer.shift - 1) : 0;
    const biases = f64(b, layer.out);
    for (let o = 0; o < layer.out; o++) biases[o] = layer.b[o] + offset;
    f64(lo, layer.out).set(last ? net.lo : new Float64Array(layer.out));
    f64(hi, layer.out).set(last ? net.hi : new Float64Array(layer.out).fill(top));
  }
  const result = new Float64Array(n * outWidth);
  for (let start = 0; start < n; start += 4 * blocks) {
    const count = Math.min(4 * blocks, n - start);
    const used = Math.ceil(count / 4);
    const h = f64(bufA, used * 4 * width0);
    h.fill(0);
    embed(h, start, count);
    let from = bufA;
    let to = bufB;
    for (const { layer, w, b, lo, hi } of placed) {
      exports.dense(from, to, used, layer.in, layer.out, w, b, lo, hi, 2 ** -layer.shift);
      [from, to] = [to, from];
    }
    const out = f64(from, used * 4 * outWidth);
    for (let i = 0; i < count; i++) {
      const row = ((i >> 2) * outWidth) * 4 + (i & 3);
      for (let o = 0; o < outWidth; o++) result[(start + i) * outWidth + o] = out[row + 4 * o];
    }
  }
  return result;
}
