/**
 * The range decoder of spec/FORMAT.md §16.2.4 and the coder view of a frequency table
 * (§16.2.3), in exact integer arithmetic on JavaScript numbers.
 *
 * The decoder keeps d = (point - lower) mod 2^64 and range, each as hi * 2^24 + lo with
 * lo < 2^24 (so hi of range is the spec's scale): the spec's updates never wrap d (d < range
 * always, and both are below 2^32 when renormalised), so lower itself is not needed. The quotient d / scale is taken in
 * float64 and checked: when it lies within 2^-26 of an integer the exact BigInt quotient is
 * used instead, so every symbol is the one the integer arithmetic gives.
 */

const TWO32 = 4294967296;
const TWO24 = 16777216;
const NEAR = 1 / 67108864; // 2^-26
const INV24 = 1 / TWO24;
const MASK24 = 0xffffff;

import { wasmInstance } from './wasm_range.mjs';

/** Thrown when the spec's decoder fails (quantile >= 2^24): the stream is invalid. */
export class RangeDecodeError extends Error {}

/**
 * The coder view L[0..A] of integer frequencies summing to 2^16 (§16.2.3).
 * @param {ArrayLike<number>} freqs A >= 2 frequencies, each >= 1
 * @returns {Float64Array} L, with L[A] = 2^24
 */
export function coderView(freqs) {
  const a = freqs.length;
  const view = new Float64Array(a + 1);
  const free = TWO24 - a;
  let cumulative = 0;
  for (let s = 0; s < a; s++) {
    view[s] = Math.floor((cumulative * free) / 65536) + s; // F * free < 2^40: exact
    cumulative += freqs[s];
  }
  view[a] = TWO24;
  return view;
}

/**
 * A lookup index over a coder view: for each of 2^bits buckets of the 24-bit quantile range,
 * the first symbol whose interval reaches into the bucket (speeds up step 4 of §16.2.4).
 */
export function viewIndex(view, bits = 12) {
  const buckets = 1 << bits;
  const width = TWO24 / buckets;
  const index = new Int32Array(buckets + 1);
  let s = 0;
  const last = view.length - 2;
  for (let b = 0; b < buckets; b++) {
    const q = b * width;
    while (s < last && view[s + 1] <= q) s++;
    index[b] = s;
  }
  index[buckets] = last;
  return index;
}

/**
 * A prepared table: its coder view and a lookup index of 2^indexBits buckets (fewer suit
 * tables used for a handful of symbols, such as the geometry's adaptive ones).
 */
export function prepareTable(freqs, indexBits = 12) {
  const view = coderView(freqs);
  return { view, index: viewIndex(view, indexBits), shift: 24 - indexBits };
}

export class JsRangeDecoder {
  /**
   * @param {Uint8Array} bytes range_data: W little-endian u32 words
   * @param {number} wordCount W
   */
  constructor(bytes, wordCount) {
    const view = new DataView(bytes.buffer, bytes.byteOffset, wordCount * 4);
    this.words = new Uint32Array(wordCount);
    for (let i = 0; i < wordCount; i++) this.words[i] = view.getUint32(4 * i, true);
    // Start: range = 2^64 - 1 = (2^40 - 1) 2^24 + (2^24 - 1); point = (w0 << 32) | w1.
    this.rangeHi = 1099511627775;
    this.rangeLo = MASK24;
    const w0 = wordCount > 0 ? this.words[0] : 0;
    const w1 = wordCount > 1 ? this.words[1] : 0;
    this.dHi = w0 * 256 + (w1 >>> 24);
    this.dLo = w1 & MASK24;
    this.pos = 2;
  }

  /**
   * Decode one symbol against a prepared table (§16.2.4 steps 1-6).
   * @param {{view: Float64Array, index: Int32Array}} table
   * @returns {number} the symbol
   */
  decode(table) {
    this.decodeMany(table, ONE, 1);
    return ONE[0];
  }

  /**
   * Decode ``count`` symbols against one table into ``out[0..count)``.
   *
   * A product scale * x (scale < 2^40, x <= 2^24, so below 2^64) is split exactly into
   * hi * 2^24 + lo: lo is the low 24 bits of Math.imul(scale mod 2^24, x), and hi the
   * float64 product minus lo, times 2^-24, rounded (the float64 error, below 2^12, is far
   * from 2^23).
   * @param {{view: Float64Array, index: Int32Array}} table
   * @param {Int32Array} out
   * @param {number} count
   */
  decodeMany(table, out, count) {
    const view = table.view;
    const index = table.index;
    const shift = table.shift;
    const words = this.words;
    const nWords = words.length;
    let pos = this.pos;
    let rHi = this.rangeHi;
    let rLo = this.rangeLo;
    let dHi = this.dHi;
    let dLo = this.dLo;
    for (let i = 0; i < count; i++) {
      const scale = rHi; // floor(range / 2^24), in [2^8, 2^40)
      const t = (dHi * TWO24 + dLo) / scale;
      let quantile = Math.floor(t);
      const frac = t - quantile;
      if (frac < NEAR || frac > 1 - NEAR) quantile = exactQuantile(dHi, dLo, scale);
      if (quantile >= TWO24) {
        this.pos = pos; this.rangeHi = rHi; this.rangeLo = rLo; this.dHi = dHi; this.dLo = dLo;
        throw new RangeDecodeError(`quantile ${quantile} >= 2^24`);
      }
      let s = index[quantile >>> shift];
      while (view[s + 1] <= quantile) s++;
      out[i] = s;
      const low = view[s];
      const width = view[s + 1] - low;
      const sLo = scale - Math.floor(scale * INV24) * TWO24; // scale mod 2^24
      // d -= scale * low
      const pLo = Math.imul(sLo, low) & MASK24;
      dHi -= Math.floor((scale * low - pLo) * INV24 + 0.5);
      dLo -= pLo;
      if (dLo < 0) { dLo += TWO24; dHi -= 1; }
      // range = scale * width
      rLo = Math.imul(sLo, width) & MASK24;
      rHi = Math.floor((scale * width - rLo) * INV24 + 0.5);
      if (rHi < 256) { // range < 2^32: renormalise (d < range < 2^32 too)
        rHi = rHi * TWO32 + rLo * 256;
        rLo = 0;
        const w = pos < nWords ? words[pos] : 0;
        pos++;
        dHi = dHi * TWO32 + dLo * 256 + (w >>> 24);
        dLo = w & MASK24;
      }
    }
    this.pos = pos; this.rangeHi = rHi; this.rangeLo = rLo; this.dHi = dHi; this.dLo = dLo;
  }
}

/** floor(d / scale) with BigInt, for quotients too close to an integer for float64. */
function exactQuantile(dHi, dLo, scale) {
  const q = (BigInt(dHi) * 16777216n + BigInt(dLo)) / BigInt(scale);
  return q >= 16777216n ? TWO24 : Number(q);
}

const ONE = new Int32Array(1);

/** Bump allocator over a WebAssembly instance's memory, reset for each new decoder. */
const arena = { generation: 0, top: 64 };

function alloc(memory, bytes) {
  const at = arena.top;
  arena.top = at + Math.ceil(bytes / 8) * 8;
  const missing = arena.top - memory.buffer.byteLength;
  if (missing > 0) memory.grow(Math.ceil(missing / 65536));
  return at;
}

/** The range decoder of §16.2.4 running its loop in WebAssembly (wasm_range.mjs). */
export class WasmRangeDecoder {
  /**
   * @param {Uint8Array} bytes range_data: W little-endian u32 words
   * @param {number} wordCount W
   */
  constructor(bytes, wordCount) {
    this.exports = wasmInstance().exports;
    this.bytes = bytes.subarray(0, 4 * wordCount);
    this.wordCount = wordCount;
    const view = new DataView(bytes.buffer, bytes.byteOffset, 4 * wordCount);
    const w0 = wordCount > 0 ? view.getUint32(0, true) : 0;
    const w1 = wordCount > 1 ? view.getUint32(4, true) : 0;
    this.d = (BigInt(w0) << 32n) | BigInt(w1);
    this.range = (1n << 64n) - 1n;
    this.pos = 2;
    this.generation = -1;
  }

  /** Put this decoder's words in the arena (again, if another decoder reset it). */
  place() {
    if (this.generation === arena.generation) return;
    arena.generation += 1;
    arena.top = 64;
    const memory = this.exports.memory;
    this.wordsAt = alloc(memory, this.bytes.length);
    new Uint8Array(memory.buffer, this.wordsAt, this.bytes.length).set(this.bytes);
    this.generation = arena.generation;
  }

  /** The arena addresses of a prepared table's coder view and lookup index. */
  tableAt(table) {
    if (table.wasmGeneration === arena.generation) return table.wasmAt;
    const memory = this.exports.memory;
    const viewAt = alloc(memory, 4 * table.view.length);
    const indexAt = alloc(memory, 4 * table.index.length);
    new Int32Array(memory.buffer, viewAt, table.view.length).set(table.view);
    new Int32Array(memory.buffer, indexAt, table.index.length).set(table.index);
    table.wasmGeneration = arena.generation;
    table.wasmAt = [viewAt, indexAt];
    return table.wasmAt;
  }

  /** Decode one symbol against a prepared table. */
  decode(table) {
    this.decodeMany(table, ONE_SYMBOL, 1);
    return ONE_SYMBOL[0];
  }

  /** Decode ``count`` symbols against one prepared table into ``out[0..count)``. */
  decodeMany(table, out, count) {
    this.place();
    const [viewAt, indexAt] = this.tableAt(table);
    const memory = this.exports.memory;
    const outAt = alloc(memory, 4 * count);
    const state = new DataView(memory.buffer, 0, 32);
    state.setBigUint64(0, this.d, true);
    state.setBigUint64(8, this.range, true);
    state.setUint32(16, this.pos, true);
    state.setUint32(20, this.wordCount, true);
    state.setUint32(24, this.wordsAt, true);
    const done = this.exports.decode(viewAt, indexAt, outAt, count, table.shift);
    const after = new DataView(memory.buffer, 0, 32);
    this.d = after.getBigUint64(0, true);
    this.range = after.getBigUint64(8, true);
    this.pos = after.getUint32(16, true);
    out.set(new Int32Array(memory.buffer, outAt, done));
    arena.top = outAt; // the output is scratch: free it
    if (done < count) throw new RangeDecodeError('quantile >= 2^24');
  }
}

const ONE_SYMBOL = new Int32Array(1);

let useWasm = wasmInstance() !== null;

/**
 * Choose the implementation new RangeDecoders use: 'wasm' (default where WebAssembly exists)
 * or 'js'. Both give the same symbols; tests run both.
 */
export function setRangeCoder(kind) {
  if (kind !== 'wasm' && kind !== 'js') throw new Error(`unknown range coder ${kind}`);
  useWasm = kind === 'wasm' && wasmInstance() !== null;
}

/** A range decoder over ``wordCount`` words of ``bytes`` (§16.2.4). */
export class RangeDecoder {
  constructor(bytes, wordCount) {
    return useWasm ? new WasmRangeDecoder(bytes, wordCount) : new JsRangeDecoder(bytes, wordCount);
  }
}
