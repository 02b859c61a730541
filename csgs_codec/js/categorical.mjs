/** Categorical streams (spec/FORMAT.md §12.18): N symbols of a small alphabet coded with one
 * frequency table carried in the stream. */

import { ByteReader } from './bytes.mjs';
import { FormatError } from './errors.mjs';
import { RangeDecodeError, RangeDecoder, prepareTable } from './range_decoder.mjs';

/**
 * @returns {Uint8Array} the ``count`` symbols
 */
export function decodeCategorical(bytes, count, chunk, baseOffset, expectedAlphabet = null) {
  const r = new ByteReader(bytes, baseOffset, chunk);
  const n = r.varint('count', 4294967295);
  if (n !== count) throw r.error(`categorical stream holds ${n} symbols, expected ${count}`);
  const alphabet = r.u8('alphabet');
  if (alphabet < 2) throw r.error(`alphabet ${alphabet} is below 2`);
  if (expectedAlphabet !== null && alphabet !== expectedAlphabet) throw r.error(`alphabet ${alphabet} is not the expected ${expectedAlphabet}`);
  const raw = r.raw(2 * alphabet, 'frequencies');
  const freqs = new Uint16Array(alphabet);
  let sum = 0;
  let ok = true;
  for (let i = 0; i < alphabet; i++) {
    freqs[i] = raw[2 * i] | (raw[2 * i + 1] << 8);
    sum += freqs[i];
    if (freqs[i] < 1) ok = false;
  }
  if (!ok || sum !== 65536) throw r.error('frequencies must be >= 1 and sum to 65536');
  const words = r.varint('word_count', Math.floor(r.remaining / 4));
  const data = r.raw(4 * words, 'range_data');
  r.expectEnd('the categorical stream');
  const out = new Uint8Array(n);
  if (n === 0) return out;
  const table = prepareTable(freqs);
  const decoder = new RangeDecoder(data, words);
  try {
    const symbols = new Int32Array(n);
    decoder.decodeMany(table, symbols, n);
    out.set(symbols);
  } catch (err) {
    if (err instanceof RangeDecodeError) throw new FormatError(`range decoder failed (${err.message})`, { chunk, offset: baseOffset });
    throw err;
  }
  return out;
}
