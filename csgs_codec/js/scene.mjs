/**
 * Decoding a standard (Gaussian) scene: the color codec's chunks of spec/FORMAT.md §12.4 -
 * §12.19 on top of the container; a tiled file (§12.22) decodes tile by tile. Anchor scenes (§17)
 * decode with anchor_scene.mjs (decodeAnchorScene): given a file with an ANCH chunk,
 * decodeScene raises UnsupportedError saying so.
 */

import { readHeader } from './base_layer.mjs';
import { single } from './chunks.mjs';
import { BAND_CODES, readShTransforms } from './color_layer.mjs';
import { modelledStreams, parseColorPrior } from './color_prior.mjs';
import { readLayers, readPayloads, readToc } from './container.mjs';
import { planDecode, sceneOf } from './decode_plan.mjs';
import { LocalLane, runPlan } from './decode_runner.mjs';
import { FormatError, UnsupportedError } from './errors.mjs';
import { checkSameKind, checkTile, isTiled, joinTiles, levelCount, levelTiles, readTileIndex, tileContainer } from './tile_index.mjs';

const MAX_GAUSSIANS = 2 ** 24;
const MAX_GAUSSIANS_PER_BYTE = 64;

/**
 * The checks and parameters every decode starts with: container, header, color hyperprior.
 * @returns {object} the prepared decode (container, header, codes, prior, modelled, ...)
 */
export function prepareScene(data, options) {
  const layers = new Set(['color', ...(options.layers || [])]);
  const container = readLayers(data, layers);
  if (container.toc.entries.some((e) => e.type === 'ANCH')) {
    throw new UnsupportedError('anchor scenes (spec/FORMAT.md §17) are not implemented in decodeScene; decodeAnchorScene (anchor_scene.mjs) decodes them');
  }
  return prepareContainer(container, data.length, layers, options);
}

/** prepareScene's checks on one scene's (or one tile's) container of a ``size``-byte file. */
export function prepareContainer(container, size, layers, options) {
  const { family, sine } = options.tables;
  const header = readHeader(container);
  const limit = Math.min(options.maxGaussians ?? MAX_GAUSSIANS, (options.maxGaussiansPerByte ?? MAX_GAUSSIANS_PER_BYTE) * size);
  if (header.count > limit) throw new FormatError(`declares ${header.count} Gaussians, above this decoder's limit of ${limit}`, { chunk: 'SCNE' });
  const codes = ['SHDC', ...BAND_CODES.slice(0, header.coded), 'OPAC', 'SCAL', 'ROTN'];
  let prior = null;
  if (container.toc.entries.some((e) => e.type === 'CHYP')) {
    const [bytes, offset] = single(container, 'CHYP');
    const posBits = Math.max(header.bits, 1);
    if (posBits > 32) throw new FormatError('the color hyperprior needs a grid of at most 32 bits', { chunk: 'CHYP', offset });
    prior = parseColorPrior(bytes, offset, codes, posBits, family);
  }
  const present = new Set(container.toc.entries.map((e) => e.type));
  // SHXF comes before the band chunks in a file (and in the Python decoder's checks): its
  // faults are reported before a band chunk the header does not expect.
  const shTransforms = present.has('SHXF') ? readShTransforms(container, header.coded) : null;
  const extra = [...BAND_CODES, 'SHDC', 'OPAC', 'SCAL', 'ROTN'].filter((c) => present.has(c) && !codes.includes(c)).sort();
  if (extra.length) throw new FormatError(`unexpected color chunk(s) ${extra} for SH degree ${header.coded}`, { chunk: extra[0] });
  const modelled = prior ? modelledStreams(prior, codes) : new Set();
  return { layers, family, sine, container, header, codes, prior, modelled, shTransforms };
}

/**
 * Decode a standard scene: the one orchestration of the receiver (the Node command line, its
 * worker threads and the browser viewer's worker all call it). The plan (decode_plan.mjs)
 * says what each task needs and in what order errors count; the runner (decode_runner.mjs)
 * spreads the tasks over ``options.lanes`` (this thread when none is given). A tiled file
 * (§12.22) decodes tile by tile.
 * @param {Uint8Array} data the .csgs bytes (or a prefix holding the requested layers)
 * @param {{layers?: string[], tables: {family: object, sine: Int32Array},
 *   maxGaussians?: number, maxGaussiansPerByte?: number, lanes?: object[],
 *   onStage?: (stage: string, scene: object) => void,
 *   onProgress?: (fraction: number) => void}} options lanes: LocalLane / RemoteLane
 *   instances to decode on; onStage (an untiled file only) gets the scene a stage of
 *   decode_plan.mjs STAGES can show, as soon as it is decoded ('first': no SH bands yet)
 * @returns {Promise<object>} count, positions (N x 3), sh_dc (N x 3), sh_rest (N x R x 3),
 *   opacity, scales (N x 3), rotations (N x 4, w x y z), semantic (N x S) and
 *   semanticNames, labels, metadata {views, skipped}: the informative vdis record (§12.21;
 *   view_record.mjs)
 */
export async function decodeScene(data, options) {
  const lanes = options.lanes && options.lanes.length ? options.lanes : [new LocalLane()];
  const tiled = tiledScene(data, options);
  if (!tiled) {
    const prep = prepareScene(data, options);
    return decodePrepared(data, prep, lanes, options.onStage, options.onProgress);
  }
  const numbers = chosenTiles(tiled.tiles, options.lod);
  tiled.read(numbers);
  const scenes = [];
  for (const [k, i] of numbers.entries()) {
    const progress = options.onProgress && ((f) => options.onProgress((k + f) / numbers.length));
    scenes.push(checkedTile(tiled, i, await decodePrepared(data, tiled.prepare(i), lanes, null, progress)));
  }
  return joinTiledScenes(tiled, scenes, numbers);
}

/**
 * One tile of a tiled file decoded from its frames alone (a reader of byte ranges, as the
 * viewer streaming levels of detail): ``container`` {toc (the tile's entries), payloads (a
 * Map of entry index to checked payload), size (bytes of the whole file)}; checked against
 * its index entry ``info`` (count, box) as tile ``number``.
 */
export async function decodeTileContainer(container, number, info, options) {
  const lanes = options.lanes && options.lanes.length ? options.lanes : [new LocalLane()];
  const layers = new Set(['color', ...(options.layers || [])]);
  const prep = prepareContainer(container, container.size, layers, options);
  const scene = await decodePrepared(null, prep, lanes, null, options.onProgress);
  checkTile(scene, number, info, container);
  return scene;
}

/** The tiles a decode of level ``lod`` (default 0, the scene) reads: that level's tiles,
 * increasing (every tile of a file without levels). A RangeError names a level the file
 * does not have. */
export function chosenTiles(tiles, lod = null) {
  const levels = levelCount(tiles);
  const level = lod ?? 0;
  if (!Number.isInteger(level) || level < 0 || level >= levels) {
    throw new RangeError(`level ${level} is not in the file (it has ${levels === 1 ? 'one level (0)' : `levels 0..${levels - 1}`})`);
  }
  return levelTiles(tiles, level);
}

/**
 * The semantic layer alone (a viewer that decoded the color layer from a prefix of the file
 * reads it on, say): {semantic (N x S), semanticNames, labels}, each null or empty when the
 * file has none. ``data`` holds the file up to the end of its semantic layer; an untiled
 * file only.
 */
export async function decodeSemanticLayer(data, options) {
  const prep = prepareScene(data, { ...options, layers: ['semantic'] });
  const plan = planDecode(prep, { stages: ['semantic'] });
  const results = await runPlan(plan, [new LocalLane()]);
  return results.get('SEMANTIC');
}

/** The decoded arrays of a scene in the receiver's canonical layout, for hashing: {name:
 * [typed array, shape]} (float32 arrays, int32 labels; semantic and labels when present). */
export function sceneArrays(scene) {
  const n = scene.count;
  const arrays = {
    positions: [scene.positions, [n, 3]],
    sh_dc: [scene.sh_dc, [n, 3]],
    sh_rest: [scene.sh_rest, [n, scene.sh_rest.length / Math.max(3 * n, 1), 3]],
    opacity: [scene.opacity, [n]],
    scales: [scene.scales, [n, 3]],
    rotations: [scene.rotations, [n, 4]],
  };
  if (scene.semantic) arrays.semantic = [scene.semantic, [n, scene.semanticNames.length]];
  if (scene.labels) arrays.labels = [scene.labels, [n]];
  if (scene.instances) {
    const k = scene.instances.embeddings.length / scene.instances.width;
    arrays.instance_prototypes = [scene.instances.prototypes, [k, scene.semanticNames.length]];
    arrays.instance_embeddings = [scene.instances.embeddings, [k, scene.instances.width]];
  }
  return arrays;
}

/** The scene (or tile) of one prepared container, decoded on ``lanes``; ``data`` the file's
 * bytes, or null when the container holds its payloads alone (sent to the lanes as they
 * are). */
async function decodePrepared(data, prep, lanes, onStage, onProgress) {
  const plan = planDecode(prep, { priorParts: lanes.length });
  plan.source = data ? { data, entries: prep.container.toc.entries, layers: prep.layers }
    : { payloads: prep.container.payloads, size: prep.container.size, entries: prep.container.toc.entries, layers: prep.layers };
  const results = await runPlan(plan, lanes, {
    onStage: onStage && ((stage, done) => { if (stage !== 'semantic') onStage(stage, sceneOf(plan, done, stage)); }),
    onTask: onProgress && ((task, done, total) => onProgress(done / total)),
  });
  return sceneOf(plan, results);
}

/**
 * A tiled file (§12.22) read and checked up to its tiles' decoding: {tiles (index entries),
 * read(numbers) (reads and checks the frames of those tiles, in file order, as the Python
 * decoder does before decoding any: a frame of another tile, another level's say, is never
 * read), containers (one per tile, after read), layers, prepare(i) (tile i's prepareScene)};
 * null for a file without a tile index. Tiles are prepared when decoded, so errors come in
 * tile order.
 */
export function tiledScene(data, options) {
  const layers = new Set(['color', ...(options.layers || [])]);
  const toc = readToc(data);
  if (!isTiled(toc)) return null;
  const tiles = readTileIndex(data, toc, options.maxGaussiansPerByte ?? MAX_GAUSSIANS_PER_BYTE);
  const tiled = { tiles, containers: [], layers };
  tiled.read = (numbers) => {
    const chosen = new Set(numbers);
    const container = readPayloads(data, { ...toc, entries: toc.entries.filter((e) => chosen.has(e.tile) && e.type !== 'TIDX') }, layers);
    tiled.containers = tiles.map((_, number) => tileContainer(container, number));
  };
  tiled.prepare = (i) => prepareContainer(tiled.containers[i], data.length, layers, options);
  return tiled;
}

/** Tile ``i``'s decoded scene after checking it against its index entry (count, box). */
export function checkedTile(tiled, i, scene) {
  checkTile(scene, i, tiled.tiles[i], tiled.containers[i]);
  return scene;
}

/** The scene of a tiled file from its tiles' checked scenes, in tile order (tiles
 * ``numbers``; default all). */
export function joinTiledScenes(tiled, scenes, numbers = null) {
  checkSameKind(scenes, (numbers ?? tiled.containers.map((_, i) => i)).map((i) => tiled.containers[i]));
  return joinTiles(scenes);
}
