/**
 * Chosen tiles of a tiled file read frame by frame (spec/FORMAT.md §6.3, §12.22): a reader of
 * byte ranges (the viewer streaming levels of detail) reads the header, the TOC and TIDX, then
 * only the frames of the tiles it draws. This module says which frames a set of tiles needs,
 * coalesces them into byte ranges, and turns fetched frames into a tile's container.
 */

import { LAYERS, checkFrame } from './container.mjs';
import { FormatError } from './errors.mjs';

/**
 * The TOC entries of tiles ``numbers`` in the base layer and ``layers`` (names: 'color',
 * 'semantic'), in file order: those a decoder reads (§7.2), unknown optional chunks left
 * out; a FormatError for an unknown critical chunk, as readPayloads raises it.
 */
export function tileEntries(toc, numbers, layers) {
  const tiles = new Set(numbers);
  const wanted = new Set([0, ...[...layers].map((name) => LAYERS.indexOf(name))]);
  const out = [];
  for (const entry of toc.entries) {
    if (!tiles.has(entry.tile) || entry.type === 'TIDX' || !wanted.has(entry.layer)) continue;
    if (!entry.known) {
      if (entry.critical) throw new FormatError(`unknown critical chunk in the ${LAYERS[entry.layer]} layer`, { chunk: entry.type, offset: entry.tocOffset });
      continue;
    }
    out.push(entry);
  }
  return out;
}

/**
 * Byte ranges holding the frames of ``entries`` (file order): [{start, end, entries}],
 * frames that follow each other in the file joined into one range.
 */
export function frameRanges(entries) {
  const ranges = [];
  for (const entry of entries) {
    const last = ranges[ranges.length - 1];
    if (last && last.end === entry.offset) {
      last.end = entry.end;
      last.entries.push(entry);
    } else {
      ranges.push({ start: entry.offset, end: entry.end, entries: [entry] });
    }
  }
  return ranges;
}

/**
 * The frames of a fetched range (``bytes``: the file's bytes ``range.start`` ..
 * ``range.end``), checked (length, type, CRC): a Map of entry index to payload.
 */
export function rangePayloads(range, bytes, into = new Map()) {
  for (const entry of range.entries) {
    const at = entry.offset - range.start;
    into.set(entry.index, checkFrame(bytes.subarray(at, Math.min(at + entry.end - entry.offset, bytes.length)), entry));
  }
  return into;
}

/** Tile ``number``'s container from the payloads read so far (entries of ``entries`` whose
 * tile it is): what decodeTileContainer (scene.mjs) decodes. ``size``: the file's bytes. */
export function tileContainerOf(toc, entries, number, payloads, size) {
  const own = entries.filter((e) => e.tile === number);
  const mine = new Map(own.map((e) => [e.index, payloads.get(e.index)]));
  return { toc: { ...toc, entries: own }, payloads: mine, size };
}
