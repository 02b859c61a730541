/**
 * The frozen tables of spec/FORMAT.md §16.2: the Gaussian family v1 (gaussian_v1.bin) and
 * the sine table v1 (sine_v1.bin), parsed from their bytes. The caller supplies the bytes
 * (the files ship in csgs_codec/entropy/data/) and checks their SHA-256 against
 * GAUSSIAN_V1_SHA256 and SINE_V1_SHA256; see tables_node.mjs for Node.
 */

import { prepareTable } from './range_decoder.mjs';

export const GAUSSIAN_V1_SHA256 = 'be7447d49ca61827969ac45ce3fe504e5014afe6197cef91ff2c27303434d3ff';
export const SINE_V1_SHA256 = 'a776046b72ec50a186312712e4065b05eaba980074502b920f3cee8a071f311a';

/**
 * Parse gaussian_v1.bin: u16 count, then per table u16 K and 2K + 2 u16 frequencies.
 * @param {Uint8Array} bytes
 * @returns {{halfWidths: number[], freqs: Uint16Array[], prepared: object[]}}
 */
export function parseGaussianFamily(bytes) {
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const count = view.getUint16(0, true);
  let pos = 2;
  const halfWidths = [];
  const freqs = [];
  for (let t = 0; t < count; t++) {
    const half = view.getUint16(pos, true);
    const n = 2 * half + 2;
    const table = new Uint16Array(n);
    let sum = 0;
    for (let i = 0; i < n; i++) {
      table[i] = view.getUint16(pos + 2 + 2 * i, true);
      sum += table[i];
      if (table[i] < 1) throw new Error('frozen Gaussian table family is malformed');
    }
    if (sum !== 65536) throw new Error('frozen Gaussian table family is malformed');
    halfWidths.push(half);
    freqs.push(table);
    pos += 2 + 2 * n;
  }
  if (pos !== bytes.length) throw new Error('frozen Gaussian table family has trailing data');
  return { halfWidths, freqs, prepared: freqs.map((table) => prepareTable(table)) };
}

/**
 * Parse sine_v1.bin: 1024 i16 entries.
 * @returns {Int32Array}
 */
export function parseSineTable(bytes) {
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  if (bytes.length !== 2048) throw new Error('sine table must be 2048 bytes');
  const out = new Int32Array(1024);
  for (let i = 0; i < 1024; i++) out[i] = view.getInt16(2 * i, true);
  return out;
}
