/**
 * Far points with relative precision: the OUTQ payload (spec/FORMAT.md §12.20). Each point is
 * an offset from a centre as one shared binary exponent and one integer mantissa per axis;
 * it decodes to float32(centre_a + float64(m) * 2^(e - b)) with exact IEEE arithmetic.
 */

import { ByteReader } from './bytes.mjs';
import { FormatError } from './errors.mjs';

const EXPONENT_BIAS = 128;
const MAX_MANTISSA_BITS = 30;
/** Smallest and largest scale exponent e - b: e in [-128, 127], b in [1, 30]. */
const MIN_SCALE = -128 - MAX_MANTISSA_BITS;
const MAX_SCALE = 127 - 1;

/** 2^k for k in MIN_SCALE..MAX_SCALE, built by exact doubling and halving (every entry is a
 * normal float64), so no pow() implementation decides a decoded bit. */
const POWERS = (() => {
  const table = new Float64Array(MAX_SCALE - MIN_SCALE + 1);
  table[-MIN_SCALE] = 1;
  for (let k = 1; k <= MAX_SCALE; k++) table[k - MIN_SCALE] = table[k - 1 - MIN_SCALE] * 2;
  for (let k = -1; k >= MIN_SCALE; k--) table[k - MIN_SCALE] = table[k + 1 - MIN_SCALE] * 0.5;
  return table;
})();

/**
 * The K unsigned ``width``-bit fields of ``bytes``, least significant bit first (§12.20
 * "Mantissa fields"); null when a padding bit after the last field is set.
 * @returns {Float64Array|null} the field values (width <= 31, so each is exact)
 */
export function unpackFields(bytes, count, width) {
  const out = new Float64Array(count);
  let bit = 0;
  for (let k = 0; k < count; k++) {
    let value = 0;
    let got = 0;
    while (got < width) {
      const shift = bit & 7;
      const take = Math.min(8 - shift, width - got);
      value += ((bytes[bit >> 3] >> shift) & ((1 << take) - 1)) * 2 ** got;
      got += take;
      bit += take;
    }
    out[k] = value;
  }
  if (bit & 7 && bytes[bit >> 3] >> (bit & 7)) return null;
  return out;
}

/**
 * The decoded far positions of an OUTQ payload (§12.20).
 * @param {Uint8Array} data the payload
 * @param {number} offset absolute offset of the payload
 * @param {number} maxCount far_count of the scene header (Q may not exceed it)
 * @returns {Float32Array} Q x (x, y, z)
 */
export function readFarPoints(data, offset, maxCount) {
  const r = new ByteReader(data, offset, 'OUTQ');
  const start = r.offset;
  const count = r.varint('count', maxCount);
  if (count === 0) throw r.error('an OUTQ chunk must hold at least one point', start);
  const bitsAt = r.offset;
  const bits = r.u8('mantissa_bits');
  if (bits < 1 || bits > MAX_MANTISSA_BITS) throw r.error(`mantissa_bits ${bits} outside 1..${MAX_MANTISSA_BITS}`, bitsAt);
  const centreAt = r.offset;
  const centre = [r.f64('centre_x'), r.f64('centre_y'), r.f64('centre_z')];
  if (!centre.every(Number.isFinite)) throw r.error('the centre must be finite', centreAt);
  const exponents = r.raw(count, 'exponents');
  const width = bits + 1;
  const packedAt = r.offset;
  const packed = r.raw(Math.ceil((3 * count * width) / 8), 'mantissas');
  r.expectEnd('the OUTQ payload');
  const fields = unpackFields(packed, 3 * count, width);
  if (fields === null) throw r.error('padding bits after the last mantissa are not zero', packedAt + packed.length - 1);
  const half = 2 ** bits;
  const positions = new Float32Array(3 * count);
  for (let i = 0; i < count; i++) {
    const scale = POWERS[exponents[i] - EXPONENT_BIAS - bits - MIN_SCALE];
    for (let a = 0; a < 3; a++) {
      // The product is exact (|m| <= 2^30), the sum is one float64 operation, fround the
      // one rounding to float32; JavaScript never fuses the two.
      const value = Math.fround(centre[a] + (fields[3 * i + a] - half) * scale);
      if (!Number.isFinite(value)) throw new FormatError('a far point decodes beyond the float32 range', { chunk: 'OUTQ', offset: start });
      positions[3 * i + a] = value;
    }
  }
  return positions;
}
