/** Escape varint lists (spec/FORMAT.md §16.3.3, §16.5): exactly ``count`` shortest-form
 * LEB128 varints filling a byte range, decoded to BigInt. */

import { FormatError } from './errors.mjs';

/**
 * @param {Uint8Array} bytes the whole escape section
 * @param {number} count varints expected
 * @param {string|null} chunk
 * @param {number} baseOffset absolute offset of bytes[0]
 * @returns {bigint[]}
 */
export function decodeVarints(bytes, count, chunk, baseOffset) {
  let ends = 0;
  for (let i = 0; i < bytes.length; i++) if (bytes[i] < 0x80) ends++;
  if (ends !== count || (count && bytes[bytes.length - 1] >= 0x80) || (!count && bytes.length)) {
    throw new FormatError(`escape stream holds ${ends} complete varints in ${bytes.length} bytes, expected exactly ${count}`,
      { chunk, offset: baseOffset });
  }
  const out = new Array(count);
  let pos = 0;
  for (let k = 0; k < count; k++) {
    const start = pos;
    let value = 0n;
    let shift = 0n;
    while (true) {
      const byte = bytes[pos++];
      value |= BigInt(byte & 0x7f) << shift;
      shift += 7n;
      if (byte < 0x80) break;
    }
    const length = pos - start;
    if (length > 10) throw new FormatError('escape varint longer than 10 bytes', { chunk, offset: baseOffset + start });
    const last = bytes[pos - 1];
    if ((length > 1 && last === 0) || (length === 10 && last > 1)) {
      throw new FormatError('escape varint is not in shortest form or exceeds 2^64 - 1', { chunk, offset: baseOffset + start });
    }
    out[k] = value;
  }
  return out;
}
