/**
 * The range decoder of spec/FORMAT.md §16.2.4 and the coder view of a frequency table
 * (§16.2.3), in exact integer arithmetic on JavaScript numbers.
 *
 * The decoder keeps d = (point - lower) mod 2^64 and range, each as two 32-bit limbs
 * (hi * 2^32 + lo): the spec's updates never wrap d (d < range always, and both are below
 * 2^32 when renormalised), so lower itself is not needed. The quotient d / scale is taken in
 * float64 and checked: when it lies within 2^-26 of an integer the exact BigInt quotient is
 * used instead, so every symbol is the one the integer arithmetic gives.
 */

const TWO32 = 4294967296;
const TWO24 = 16777216;
const NEAR = 1 / 67108864; // 2^-26

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
 * A lookup index over a coder view: for each of 4096 buckets of the 24-bit quantile range,
 * the first symbol whose interval reaches into the bucket (speeds up step 4 of §16.2.4).
 */
export function viewIndex(view) {
  const index = new Int32Array(4097);
  let s = 0;
  const last = view.length - 2;
  for (let b = 0; b < 4096; b++) {
    const q = b * 4096;
    while (s < last && view[s + 1] <= q) s++;
    index[b] = s;
  }
  index[4096] = last;
  return index;
}

/** A prepared table: its coder view and lookup index. */
export function prepareTable(freqs) {
  const view = coderView(freqs);
  return { view, index: viewIndex(view) };
}

export class RangeDecoder {
  /**
   * @param {Uint8Array} bytes range_data: W little-endian u32 words
   * @param {number} wordCount W
   */
  constructor(bytes, wordCount) {
    this.words = new DataView(bytes.buffer, bytes.byteOffset, wordCount * 4);
    this.count = wordCount;
    this.pos = 0;
    this.rangeHi = TWO32 - 1;
    this.rangeLo = TWO32 - 1;
    this.dHi = this.readWord();
    this.dLo = this.readWord();
  }

  /** The next word, or 0 past the end of range_data. */
  readWord() {
    const p = this.pos++;
    return p < this.count ? this.words.getUint32(4 * p, true) : 0;
  }

  /**
   * Decode one symbol against a prepared table (§16.2.4 steps 1-6).
   * @param {{view: Float64Array, index: Int32Array}} table
   * @returns {number} the symbol
   */
  decode(table) {
    const view = table.view;
    const scale = this.rangeHi * 256 + (this.rangeLo >>> 24); // floor(range / 2^24) < 2^40
    const t = (this.dHi * TWO32 + this.dLo) / scale;
    let quantile = Math.floor(t);
    const frac = t - quantile;
    if (frac < NEAR || frac > 1 - NEAR) quantile = this.exactQuantile(scale);
    if (quantile >= TWO24) throw new RangeDecodeError(`quantile ${quantile} >= 2^24`);
    let s = table.index[quantile >>> 12];
    while (view[s + 1] <= quantile) s++;
    // d -= scale * L[s]; range = scale * (L[s+1] - L[s]); both products exact in two limbs.
    const low = view[s];
    const sHi = Math.floor(scale / 65536);
    const sLo = scale - sHi * 65536;
    let a = sHi * low;
    let aHi = Math.floor(a / 65536);
    let lo = (a - aHi * 65536) * 65536 + sLo * low;
    let carry = Math.floor(lo / TWO32);
    let pLo = lo - carry * TWO32;
    let pHi = aHi + carry;
    let dLo = this.dLo - pLo;
    let dHi = this.dHi - pHi;
    if (dLo < 0) { dLo += TWO32; dHi -= 1; }
    const width = view[s + 1] - low;
    a = sHi * width;
    aHi = Math.floor(a / 65536);
    lo = (a - aHi * 65536) * 65536 + sLo * width;
    carry = Math.floor(lo / TWO32);
    let rLo = lo - carry * TWO32;
    let rHi = aHi + carry;
    if (rHi === 0) { // range < 2^32: renormalise (d < range < 2^32, so dHi is 0)
      rHi = rLo; rLo = 0;
      dHi = dLo; dLo = this.readWord();
    }
    this.rangeHi = rHi; this.rangeLo = rLo;
    this.dHi = dHi; this.dLo = dLo;
    return s;
  }

  /** floor(d / scale) with BigInt, for quotients too close to an integer for float64. */
  exactQuantile(scale) {
    const d = (BigInt(this.dHi) << 32n) | BigInt(this.dLo);
    const q = d / BigInt(scale);
    return q >= BigInt(TWO24) ? TWO24 : Number(q);
  }

  /** Decode ``count`` symbols with one table into ``out`` at the given positions. */
  decodeInto(table, out, positions, count) {
    for (let i = 0; i < count; i++) out[positions ? positions[i] : i] = this.decode(table);
  }
}
