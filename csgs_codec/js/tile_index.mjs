/**
 * Tiled scenes (spec/FORMAT.md §6.3, §12.22): the TIDX tile index (version 2: levels of
 * detail, each tile with a level and a parent one level up), each tile's own container view,
 * the checks of a decoded tile against its entry, and joining tiles into one scene.
 */

import { ByteReader } from './bytes.mjs';
import { readFrame } from './container.mjs';
import { FormatError } from './errors.mjs';

const MAX_TILES = 65535;
const MAX_TILE_GAUSSIANS = 2 ** 24;
const MIN_ENTRY_BYTES = 25;
const MIN_LEVEL_ENTRY_BYTES = 27;
const MAX_LEVELS = 16;

/** True when ``toc`` (readToc's) lists a TIDX chunk (a tiled scene). */
export function isTiled(toc) {
  return toc.entries.some((e) => e.type === 'TIDX');
}

/**
 * The tile index of a tiled file, after the checks of §12.22: one TIDX, TOC entry 0 in tile
 * 0, every other chunk in a listed tile, the counts within ``maxPerByte`` x the file. Reads
 * the TIDX frame of ``data`` and no other (a decoder chooses the other frames from it), so
 * its faults are found before any other frame's, as in the Python decoder.
 * @param {Uint8Array} data the file (or the prefix at hand)
 * @param {object} toc readToc's result for ``data``
 * @param {number} size bytes of the whole file (default: ``data``'s), for the count limit
 * @returns {{count: number, lower: number[], upper: number[], level: number,
 *   parent: number|null}[]} one entry per tile (level 0 and no parent in version 1)
 */
export function readTileIndex(data, toc, maxPerByte, size = data.length) {
  const found = toc.entries.filter((e) => e.type === 'TIDX');
  if (found.length > 1) throw new FormatError(`chunk TIDX appears ${found.length} times`, { chunk: 'TIDX', offset: found[1].tocOffset });
  const entry = found[0];
  if (entry.index !== 0 || entry.tile !== 0) throw new FormatError('the tile index must be the first chunk, in tile 0', { chunk: 'TIDX', offset: entry.tocOffset });
  const r = new ByteReader(readFrame(data, entry), entry.offset + 8, 'TIDX');
  const version = r.u8('version');
  if (version !== 1 && version !== 2) throw r.error(`unknown tile index version ${version}`, r.offset - 1);
  const leveled = version === 2;
  let at = r.offset;
  const count = r.varint('tile_count', MAX_TILES);
  const entryBytes = leveled ? MIN_LEVEL_ENTRY_BYTES : MIN_ENTRY_BYTES;
  if (count < 1 || count > Math.floor(r.remaining / entryBytes)) throw r.error(`tile_count ${count} is 0 or more than the bytes after it hold`, at);
  const tiles = [];
  const links = [];
  let total = 0;
  for (let i = 0; i < count; i++) {
    at = r.offset;
    const n = r.varint('gaussian_count', MAX_TILE_GAUSSIANS);
    if (n < 1) throw r.error(`tile ${i} holds no Gaussian`, at);
    const boxAt = r.offset;
    const box = [0, 1, 2, 3, 4, 5].map(() => r.f32('bounds'));
    if (!box.every(Number.isFinite) || [0, 1, 2].some((a) => box[a] > box[a + 3])) throw r.error(`tile ${i}: bounds are not finite or lower > upper`, boxAt);
    let level = 0;
    let parent = null;
    if (leveled) {
      const levelAt = r.offset;
      level = r.u8('level');
      if (level >= MAX_LEVELS) throw r.error(`tile ${i}: level ${level} is above ${MAX_LEVELS - 1}`, levelAt);
      const linkAt = r.offset;
      const link = r.varint('parent', MAX_TILES);
      parent = link === 0 ? null : link - 1;
      links.push([levelAt, linkAt]);
    }
    tiles.push({ count: n, lower: box.slice(0, 3), upper: box.slice(3), level, parent });
    total += n;
  }
  r.expectEnd('the tile index');
  if (leveled) checkTree(r, tiles, links);
  for (const e of toc.entries.slice(1)) {
    if (e.tile >= count) throw new FormatError(`tile ${e.tile} is not in the tile index (${count} tiles)`, { chunk: e.type, offset: e.tocOffset });
  }
  const limit = maxPerByte * size;
  if (total > limit) throw new FormatError(`the tile index declares ${total} Gaussians, above this decoder's limit of ${limit}`, { chunk: 'TIDX', offset: entry.offset + 8 });
  return tiles;
}

/** FormatError unless version 2's tiles form a tree of levels (§12.22), as the Python
 * decoder checks it (same order, messages and offsets). */
function checkTree(r, tiles, links) {
  const top = Math.max(...tiles.map((t) => t.level));
  if (top === 0) throw r.error('a version-2 tile index whose tiles are all of level 0', links[0][0]);
  const hasChild = tiles.map(() => false);
  tiles.forEach((tile, i) => {
    const linkAt = links[i][1];
    if (tile.level === top) {
      if (tile.parent !== null) throw r.error(`tile ${i} is of the top level ${top} and has a parent`, linkAt);
      return;
    }
    if (tile.parent === null) throw r.error(`tile ${i} of level ${tile.level} has no parent (only the top level ${top} has none)`, linkAt);
    if (tile.parent >= tiles.length || tiles[tile.parent].level !== tile.level + 1) throw r.error(`tile ${i} of level ${tile.level}: parent ${tile.parent} is not a tile of level ${tile.level + 1}`, linkAt);
    hasChild[tile.parent] = true;
  });
  tiles.forEach((tile, i) => {
    if (tile.level > 0 && !hasChild[i]) throw r.error(`tile ${i} of level ${tile.level} is no tile's parent`, links[i][0]);
  });
}

/** Levels of detail of a tile index: 1 + the highest tile level. */
export function levelCount(tiles) {
  return 1 + Math.max(...tiles.map((t) => t.level));
}

/** The tile numbers of level ``level``, increasing (level 0: the scene). */
export function levelTiles(tiles, level) {
  const out = [];
  tiles.forEach((t, i) => { if (t.level === level) out.push(i); });
  return out;
}

/** The container of tile ``number`` alone: its TOC entries (TIDX left out), shared payloads. */
export function tileContainer(container, number) {
  const entries = container.toc.entries.filter((e) => e.tile === number && e.type !== 'TIDX');
  return { ...container, toc: { ...container.toc, entries } };
}

function payloadOffset(container, code) {
  const entry = container.toc.entries.find((e) => e.type === code);
  return entry ? entry.offset + 8 : null;
}

/** FormatError when a decoded tile disagrees with its index entry (count, box). */
export function checkTile(scene, number, info, container) {
  if (scene.count !== info.count) throw new FormatError(`tile ${number} holds ${scene.count} Gaussians, the tile index says ${info.count}`, { chunk: 'SCNE', offset: payloadOffset(container, 'SCNE') });
  const p = scene.positions;
  for (let i = 0; i < p.length; i++) {
    const a = i % 3;
    if (p[i] < info.lower[a] || p[i] > info.upper[a]) throw new FormatError(`tile ${number} has a Gaussian outside its box in the tile index`, { chunk: 'GEOM', offset: payloadOffset(container, 'GEOM') });
  }
}

/** FormatError when a tile differs from the first in SH degree or semantic layer. */
export function checkSameKind(scenes, containers) {
  const first = scenes[0];
  const rest = (s) => s.sh_rest.length / Math.max(s.count, 1);
  scenes.forEach((s, i) => {
    const same = rest(s) === rest(first) && (s.semantic === null) === (first.semantic === null)
      && (s.labels === null) === (first.labels === null)
      && s.semanticNames.join('\u0000') === first.semanticNames.join('\u0000')
      && s.semanticNames.length === first.semanticNames.length;
    if (!same) throw new FormatError(`tile ${i} differs from the first tile in SH degree or semantic layer`, { chunk: 'SCNE', offset: payloadOffset(containers[i], 'SCNE') });
  });
}

function join(arrays) {
  const out = new arrays[0].constructor(arrays.reduce((n, a) => n + a.length, 0));
  let at = 0;
  for (const a of arrays) { out.set(a, at); at += a.length; }
  return out;
}

/** One scene holding the tiles' Gaussians in tile order (metadata: the first tile's). */
export function joinTiles(scenes) {
  const first = scenes[0];
  const field = (name) => join(scenes.map((s) => s[name]));
  return {
    count: scenes.reduce((n, s) => n + s.count, 0),
    positions: field('positions'),
    sh_dc: field('sh_dc'),
    sh_rest: field('sh_rest'),
    opacity: field('opacity'),
    scales: field('scales'),
    rotations: field('rotations'),
    semantic: first.semantic === null ? null : field('semantic'),
    semanticNames: first.semanticNames,
    labels: first.labels === null ? null : field('labels'),
    instances: unionInstances(scenes.map((s) => s.instances)),
    metadata: first.metadata,
  };
}

/** The instance tables of tiles as one: each prototype once, the first tile's row first
 * (as the reference decoder joins them). */
function unionInstances(tables) {
  const present = tables.filter(Boolean);
  if (!present.length) return null;
  const width = present[0].width;
  const seen = new Set();
  const prototypes = [];
  const embeddings = [];
  for (const table of present) {
    const k = table.embeddings.length / width;
    const channels = table.prototypes.length / k;
    const bits = new Uint32Array(table.prototypes.buffer, table.prototypes.byteOffset, table.prototypes.length);
    for (let i = 0; i < k; i++) {
      const key = Array.from(bits.subarray(i * channels, (i + 1) * channels)).join(',');
      if (seen.has(key)) continue;
      seen.add(key);
      prototypes.push(...table.prototypes.subarray(i * channels, (i + 1) * channels));
      embeddings.push(...table.embeddings.subarray(i * width, (i + 1) * width));
    }
  }
  return { prototypes: Float32Array.from(prototypes), embeddings: Float32Array.from(embeddings), width };
}
