/**
 * Decodes a file with levels of detail as the viewer streams it: header and TOC, the TIDX
 * frame, then each level's tiles from the byte ranges tile_frames.mjs names (fetched as
 * slices of the file, every range logged), tile by tile with decodeTileContainer, joined per
 * level in tile order. Prints one JSON line: {index: [[start, end], ...] (header, TOC,
 * TIDX), levels: [{level, tiles, count, arrays, ranges}]} coarsest first (arrays as
 * arrayDigests gives them, ranges the byte ranges read for the level).
 *
 *   node level_stream_runner.mjs FILE [--layers color|color,semantic] [--threads N]
 */

import { readFileSync } from 'node:fs';

import { readFrame, readToc } from '../../csgs_codec/js/container.mjs';
import { arrayDigests } from '../../csgs_codec/js/digests_node.mjs';
import { workerLanes } from '../../csgs_codec/js/parallel_node.mjs';
import { decodeTileContainer } from '../../csgs_codec/js/scene.mjs';
import { loadTables } from '../../csgs_codec/js/tables_node.mjs';
import { joinTiles, levelCount, levelTiles, readTileIndex } from '../../csgs_codec/js/tile_index.mjs';
import { frameRanges, rangePayloads, tileContainerOf, tileEntries } from '../../csgs_codec/js/tile_frames.mjs';

const args = process.argv.slice(2);
const file = args[0];
const layers = args.includes('--layers') ? args[args.indexOf('--layers') + 1].split(',').filter((n) => n !== 'color') : [];
const threads = args.includes('--threads') ? Number(args[args.indexOf('--threads') + 1]) : 1;
const whole = new Uint8Array(readFileSync(file));
const ranges = [];
const read = (start, end) => { ranges.push([start, end]); return whole.slice(start, end); };

const head = read(0, 16);
const tocSize = new DataView(head.buffer).getUint32(12, true);
const prefix = new Uint8Array(16 + tocSize + 4);
prefix.set(head);
prefix.set(read(16, 16 + tocSize + 4), 16);
const toc = readToc(prefix);
const tidx = toc.entries[0];
const withIndex = new Uint8Array(tidx.end);
withIndex.set(prefix);
withIndex.set(read(tidx.offset, tidx.end), tidx.offset);
const size = toc.entries[toc.entries.length - 1].end;
const tiles = readTileIndex(withIndex, toc, 64, size);
const tables = loadTables();
const lanes = threads > 1 ? workerLanes(threads, 'wasm') : [];
const out = [];
try {
  for (let level = levelCount(tiles) - 1; level >= 0; level--) {
    const numbers = levelTiles(tiles, level);
    const entries = tileEntries(toc, numbers, ['color', ...layers]);
    const payloads = new Map();
    const before = ranges.length;
    for (const range of frameRanges(entries)) rangePayloads(range, read(range.start, range.end), payloads);
    const scenes = [];
    for (const number of numbers) {
      const container = tileContainerOf(toc, entries, number, payloads, size);
      scenes.push(await decodeTileContainer(container, number, tiles[number], { tables, layers, lanes }));
    }
    const scene = joinTiles(scenes);
    out.push({ level, tiles: numbers, count: scene.count, arrays: arrayDigests(scene), ranges: ranges.slice(before) });
  }
} finally {
  await Promise.all(lanes.map((lane) => lane.close()));
}
process.stdout.write(`${JSON.stringify({ index: ranges.slice(0, 3), levels: out })}\n`);
