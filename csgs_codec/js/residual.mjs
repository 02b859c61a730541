/**
 * Residual streams (spec/FORMAT.md §16.3.2, §16.3.3): N residuals range coded with frozen
 * Gaussian tables, grouped by table (tables increasing, positions increasing), then the
 * escape varints.
 */

import { ByteReader } from './bytes.mjs';
import { FormatError } from './errors.mjs';
import { RangeDecodeError, RangeDecoder } from './range_decoder.mjs';
import { decodeVarints } from './varints.mjs';

const MAX_COUNT = 4294967295;
const RESIDUAL_LIMIT = 1n << 62n;
const SAFE = 2 ** 52; // beyond this a residual is also kept exactly (BigInt)

/**
 * Positions 0..n-1 grouped by table: [[table, Int32Array positions], ...], tables increasing.
 * @param {ArrayLike<number>|number} tables per-position table index, or one for all
 */
export function groupsByTable(tables, n) {
  if (typeof tables === 'number') return [[tables, null]];
  const counts = new Int32Array(64);
  for (let i = 0; i < n; i++) counts[tables[i]]++;
  const groups = [];
  const fill = new Int32Array(64);
  const lists = [];
  for (let t = 0; t < 64; t++) lists.push(counts[t] ? new Int32Array(counts[t]) : null);
  for (let i = 0; i < n; i++) { const t = tables[i]; lists[t][fill[t]++] = i; }
  for (let t = 0; t < 64; t++) if (counts[t]) groups.push([t, lists[t]]);
  return groups;
}

/**
 * Decode a residual stream of ``n`` residuals.
 * @param {Uint8Array} bytes the stream
 * @param {ArrayLike<number>|number} tables per-position table index (0..63), or one for all
 * @param {number} n residuals the caller expects
 * @param {object} family the Gaussian family (tables.mjs)
 * @param {string|null} chunk named in errors
 * @param {number} baseOffset absolute offset of bytes[0]
 * @returns {{values: Float64Array, big: Map<number, bigint>|null}} residuals; ``big`` holds
 *   the exact value of any residual beyond 2^53 in magnitude (values then holds an
 *   approximation)
 */
export function decodeSymbols(bytes, tables, n, family, chunk, baseOffset) {
  const r = new ByteReader(bytes, baseOffset, chunk);
  const count = r.varint('count', MAX_COUNT);
  if (count !== n) throw r.error(`stream holds ${count} residuals, the caller expects ${n}`);
  if (typeof tables !== 'number') {
    // Per-value tables computed from decoded data (an anchor hyperprior's outputs) may lie
    // outside the family: the reference decoder refuses them here, naming no place.
    for (let i = 0; i < n; i++) {
      if (!(tables[i] >= 0 && tables[i] < 64)) throw new FormatError(`scale index ${tables[i]} is outside [0, 64)`);
    }
  }
  const words = r.varint('word_count', Math.floor(r.remaining / 4));
  const data = r.raw(4 * words, 'range_data');
  const decoder = new RangeDecoder(data, words);
  const values = new Float64Array(n);
  const escaped = [];
  const symbols = new Int32Array(n);
  for (const [table, positions] of groupsByTable(tables, n)) {
    const half = family.halfWidths[table];
    const m = positions ? positions.length : n;
    const escape = 2 * half + 1;
    try {
      decoder.decodeMany(family.prepared[table], symbols, m);
    } catch (err) {
      if (err instanceof RangeDecodeError) throw r.error(`range decoder failed in table ${table} (${err.message})`);
      throw err;
    }
    if (positions) {
      for (let i = 0; i < m; i++) {
        const s = symbols[i];
        values[positions[i]] = s - half;
        if (s === escape) escaped.push(positions[i], half);
      }
    } else {
      for (let i = 0; i < m; i++) {
        const s = symbols[i];
        values[i] = s - half;
        if (s === escape) escaped.push(i, half);
      }
    }
  }
  let big = null;
  if (escaped.length) {
    const start = r.offset;
    // Escapes follow in coding order (table groups), which is the order pushed above.
    const codes = decodeVarints(r.raw(r.remaining, 'escapes'), escaped.length / 2, chunk, start);
    for (let k = 0; k < codes.length; k++) {
      const p = escaped[2 * k];
      const magnitude = (codes[k] >> 1n) + BigInt(escaped[2 * k + 1]) + 1n;
      if (magnitude > RESIDUAL_LIMIT) throw new FormatError('escaped residual exceeds 2^62', { chunk, offset: start });
      const value = codes[k] & 1n ? -magnitude : magnitude;
      values[p] = Number(value);
      if (magnitude > BigInt(SAFE)) { big = big || new Map(); big.set(p, value); }
    }
  }
  r.expectEnd('the residual stream');
  return { values, big };
}
