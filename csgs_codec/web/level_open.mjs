/**
 * The decode worker's path for a file with levels of detail (spec/FORMAT.md §12.22, tile
 * index version 2): nothing is read whole. After the header and TOC it reads the tile index
 * (one range: TIDX is the first frame), tells the page the tree ('levels'), then reads and
 * decodes the coarsest level's tiles (their frames lead every layer: one range per layer),
 * posting each tile as it is decoded ('tile'), so the first frame waits for a few percent of
 * the file. From then on the page asks for tiles ('tiles' requests: the children of the tiles
 * that matter most on screen, level_view.mjs decides), which are read by range (adjacent
 * frames joined) and decoded on the decode lanes in the order asked.
 *
 * Messages out (besides progress/mark/error): {kind: 'levels', tiles, levels, fileEnd,
 * indexBytes, layers} and {kind: 'tile', number, scene, bytesRead, decodeMs}, ``bytesRead``
 * the scene bytes read so far (header, TOC and index included). A tile's semantic frames are
 * read with its color frames when the page asks for the semantic layer and the file has one.
 */

import { FormatError } from '../js/errors.mjs';
import { decodeTileContainer } from '../js/scene.mjs';
import { levelCount, levelTiles, readTileIndex } from '../js/tile_index.mjs';
import { frameRanges, rangePayloads, tileContainerOf, tileEntries } from '../js/tile_frames.mjs';

const MAX_GAUSSIANS_PER_BYTE = 64;

/** True when the file's tile index has levels of detail (TIDX version 2), read from the
 * byte after its frame header: the page streams such a file. */
export function hasLevels(toc, indexFrame) {
  return toc.entries.length > 0 && toc.entries[0].type === 'TIDX' && indexFrame[8] === 2;
}

/**
 * Stream a file with levels. ``indexed``: the file's bytes from 0 to the end of the TIDX frame
 * (header, TOC, index); returns {fetch(numbers)}, the handler of the page's tile requests.
 */
export async function openLevels({ source, indexed, toc, fileEnd, wanted, tablesReady, lanes, post, progress, mark }) {
  const tiles = readTileIndex(indexed, toc, MAX_GAUSSIANS_PER_BYTE, fileEnd);
  const levels = levelCount(tiles);
  let bytesRead = indexed.length;
  const semantic = wanted.has('semantic') && toc.entries.some((e) => e.layer === 2);
  const layers = semantic ? ['color', 'semantic'] : ['color'];
  post({ kind: 'levels', tiles, levels, fileEnd, indexBytes: indexed.length, layers });
  mark(post, 'indexRead');
  const tables = await tablesReady;
  let first = null; // the first tile decoded: every other must be of its kind (§12.22)

  async function fetchTiles(numbers) {
    const entries = tileEntries(toc, numbers, layers);
    const payloads = new Map();
    for (const range of frameRanges(entries)) {
      const bytes = await source.read(range.start, range.end);
      if (bytes.length < range.end - range.start) {
        throw new FormatError(`truncated: the chunk needs bytes up to ${range.end}`, { chunk: range.entries[0].type, offset: range.start + bytes.length });
      }
      bytesRead += bytes.length;
      rangePayloads(range, bytes, payloads);
    }
    for (const number of numbers) {
      const t0 = performance.now();
      const container = tileContainerOf(toc, entries, number, payloads, fileEnd);
      const scene = await decodeTileContainer(container, number, tiles[number], { tables, lanes, layers: layers.slice(1) });
      first ??= { number, rest: scene.sh_rest.length / Math.max(scene.count, 1) };
      if (scene.sh_rest.length / Math.max(scene.count, 1) !== first.rest) {
        throw new FormatError(`tile ${number} differs from tile ${first.number} in SH degree`, { chunk: 'SCNE', offset: container.toc.entries.find((e) => e.type === 'SCNE')?.offset + 8 });
      }
      post({ kind: 'tile', number, scene: { ...scene, level: tiles[number].level }, bytesRead, decodeMs: performance.now() - t0 });
    }
  }

  const top = levelTiles(tiles, levels - 1);
  progress('color', 0.1, `reading level ${levels - 1} of ${levels} (${top.length} tile${top.length > 1 ? 's' : ''})`);
  await fetchTiles(top);
  mark(post, 'coarsestDecoded');
  let queue = Promise.resolve();
  return {
    /** Read and decode tiles ``numbers`` after those asked for before; errors are posted. */
    fetch(numbers, onError) {
      queue = queue.then(() => fetchTiles(numbers)).catch(onError);
      return queue;
    },
  };
}
