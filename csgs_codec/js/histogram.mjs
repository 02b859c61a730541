/** Histogram streams (spec/FORMAT.md §16.5): N values coded with a frequency table of their
 * own, values outside the table as escape varints. */

import { ByteReader } from './bytes.mjs';
import { FormatError } from './errors.mjs';
import { RangeDecodeError, RangeDecoder, prepareTable } from './range_decoder.mjs';
import { decodeVarints } from './varints.mjs';

const LIMIT = 1n << 62n;
const SAFE = 2n ** 52n; // beyond this a value is also kept exactly (BigInt)

/**
 * @returns {{values: Float64Array, big: Map<number, bigint>|null}} as residual.mjs
 */
export function decodeHistogram(bytes, count, chunk, baseOffset) {
  const r = new ByteReader(bytes, baseOffset, chunk);
  const n = r.varint('count', 4294967295);
  if (n !== count) throw r.error(`histogram stream holds ${n} values, expected ${count}`);
  if (n === 0) { r.expectEnd('the histogram stream'); return { values: new Float64Array(0), big: null }; }
  const lo = r.svarintBig('lowest_symbol');
  const k = r.varint('symbol_count', 4096);
  const abs = (v) => (v < 0n ? -v : v);
  if (k < 1 || abs(lo) > LIMIT || abs(lo + BigInt(k)) > LIMIT) throw r.error(`symbol range [${lo}, ${lo} + ${k}) is invalid`);
  const freqs = new Float64Array(k + 1);
  let sum = 0;
  let ok = true;
  for (let i = 0; i <= k; i++) {
    freqs[i] = r.varint('frequency', 65536);
    sum += freqs[i];
    if (freqs[i] < 1) ok = false;
  }
  if (!ok || sum !== 65536) throw r.error('frequencies must be >= 1 and sum to 65536');
  const words = r.varint('word_count', Math.floor(r.remaining / 4));
  const data = r.raw(4 * words, 'range_data');
  const table = prepareTable(freqs);
  const decoder = new RangeDecoder(data, words);
  const values = new Float64Array(n);
  const escaped = [];
  const loSafe = abs(lo) <= SAFE;
  const loNum = Number(lo);
  let big = loSafe ? null : new Map();
  const symbols = new Int32Array(n);
  try {
    decoder.decodeMany(table, symbols, n);
  } catch (err) {
    if (err instanceof RangeDecodeError) throw r.error(`range decoder failed (${err.message})`);
    throw err;
  }
  for (let i = 0; i < n; i++) {
    const s = symbols[i];
    if (s === k) escaped.push(i);
    else if (loSafe) values[i] = loNum + s;
    else { big.set(i, lo + BigInt(s)); values[i] = Number(lo + BigInt(s)); }
  }
  if (escaped.length) {
    const start = r.offset;
    const codes = decodeVarints(r.raw(r.remaining, 'escapes'), escaped.length, chunk, start);
    for (let j = 0; j < codes.length; j++) {
      const z = codes[j];
      const v = z & 1n ? -((z + 1n) >> 1n) : z >> 1n;
      if (abs(v) > LIMIT || (v >= lo && v < lo + BigInt(k))) {
        throw new FormatError('an escaped value exceeds 2^62 or lies inside the table\'s range', { chunk, offset: start });
      }
      values[escaped[j]] = Number(v);
      if (abs(v) > SAFE) { big = big || new Map(); big.set(escaped[j], v); }
    }
  }
  r.expectEnd('the histogram stream');
  return { values, big };
}
