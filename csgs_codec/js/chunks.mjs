/**
 * Shared helpers of the scene decoders: the one payload of a chunk type, and the check that
 * decoded values are finite (§12.8: a decoded float32 value that is not finite is invalid).
 */

import { FormatError } from './errors.mjs';

/** The one payload of type ``code`` and its absolute offset; FormatError if missing or twice. */
export function single(container, code) {
  const entries = container.toc.entries.filter((e) => e.type === code);
  if (!entries.length) throw new FormatError(`required chunk ${code} is missing`, { chunk: code });
  if (entries.length > 1) throw new FormatError(`chunk ${code} appears ${entries.length} times`, { chunk: code, offset: entries[1].offset });
  const entry = entries[0];
  if (!container.payloads.has(entry.index)) throw new FormatError(`chunk ${code} is cut off`, { chunk: code, offset: entry.offset });
  return [container.payloads.get(entry.index), entry.offset + 8];
}

/** FormatError when ``values`` hold a non-finite value. */
export function checkFinite(values, chunk) {
  for (let i = 0; i < values.length; i++) {
    if (!Number.isFinite(values[i])) throw new FormatError('decoded values overflow float32', { chunk });
  }
}

