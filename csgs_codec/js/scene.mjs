/**
 * Decoding a standard (Gaussian) scene: the color codec's chunks of spec/FORMAT.md §12.4 -
 * §12.19 on top of the container; a tiled file (§12.22) decodes tile by tile. Anchor scenes (§17) are not implemented here: a file with
 * an ANCH chunk raises UnsupportedError.
 */

import { decodePositions, readHeader } from './base_layer.mjs';
import { single } from './chunks.mjs';
import { BAND_CODES, SH_REST, decodeStream, rotations } from './color_layer.mjs';
import { channelPriors, modelledStreams, parseColorPrior } from './color_prior.mjs';
import { readLayers } from './container.mjs';
import { FormatError, UnsupportedError } from './errors.mjs';
import { decodeSemantic } from './semantic_layer.mjs';
import { checkSameKind, checkTile, isTiled, joinTiles, readTileIndex, tileContainer } from './tile_index.mjs';
import { readViews } from './view_record.mjs';

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
    throw new UnsupportedError('anchor scenes (spec/FORMAT.md §17) are not implemented in the JavaScript receiver');
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
  const extra = [...BAND_CODES, 'SHDC', 'OPAC', 'SCAL', 'ROTN'].filter((c) => present.has(c) && !codes.includes(c)).sort();
  if (extra.length) throw new FormatError(`unexpected color chunk(s) ${extra} for SH degree ${header.coded}`, { chunk: extra[0] });
  const modelled = prior ? modelledStreams(prior, codes) : new Set();
  return { layers, family, sine, container, header, codes, prior, modelled };
}

/**
 * The output arrays of the color streams, each stream's place in them ({array, stride,
 * offset}) and the positions array; ``Buffer`` makes their storage (ArrayBuffer or
 * SharedArrayBuffer).
 */
export function makeTargets(header, Buffer = ArrayBuffer) {
  const n = header.count;
  const f32 = (length) => new Float32Array(new Buffer(4 * length));
  const restCount = SH_REST[header.stored];
  const shRest = f32(n * restCount * 3);
  const targets = {
    SHDC: { array: f32(3 * n), stride: 3, offset: 0 },
    OPAC: { array: f32(n), stride: 1, offset: 0 },
    SCAL: { array: f32(3 * n), stride: 3, offset: 0 },
    ROTN: { array: f32(3 * n), stride: 3, offset: 0 },
  };
  BAND_CODES.forEach((code, b) => { targets[code] = { array: shRest, stride: restCount * 3, offset: SH_REST[b] * 3 }; });
  return { targets, shRest, positions: f32(3 * n) };
}

/** Decode one task ('GEOM' or a color stream code) of a prepared scene into its targets;
 * returns the dropped-component indices for ROTN. ``earlierDone``: SCAL and OPAC are already
 * in their targets (a sequential decode); otherwise a ROTN channel in mode 6 or 7 decodes
 * them for itself (the parallel decode runs only without the hyperprior, so they need no
 * priors there). */
export function decodeTask(prep, out, code, priors = null, earlierDone = false) {
  if (code === 'GEOM') return decodePositions(prep.container, prep.header, out.positions);
  const own = (source, channels) => {
    let decoded = null; // decoded once, however many channels ask
    return () => {
      if (earlierDone) return out.targets[source].array;
      if (!decoded) {
        const target = { array: new Float32Array(channels * prep.header.count), stride: channels, offset: 0 };
        decodeStream(prep.container, prep.header, source, null, prep.family, target);
        decoded = target.array;
      }
      return decoded;
    };
  };
  const attributes = { logScales: own('SCAL', 3), opacity: own('OPAC', 1) };
  return decodeStream(prep.container, prep.header, code, priors, prep.family, out.targets[code], attributes);
}

/** The scene object of decoded targets, with the semantic layer when it was asked for. */
export function finishScene(prep, out, axis) {
  const n = prep.header.count;
  const scene = {
    count: n,
    positions: out.positions,
    sh_dc: out.targets.SHDC.array,
    sh_rest: out.shRest,
    opacity: out.targets.OPAC.array,
    scales: out.targets.SCAL.array,
    rotations: rotations(axis, out.targets.ROTN.array, n),
    semantic: null,
    semanticNames: [],
    labels: null,
    metadata: readViews(prep.container),
  };
  if (prep.layers.has('semantic')) decodeSemantic(prep.container, prep.header, scene, prep.family);
  return scene;
}

/**
 * Decode a standard scene on this thread (parallel_node.mjs spreads it over two in Node).
 * @param {Uint8Array} data the .csgs bytes (or a prefix holding the requested layers)
 * @param {{layers?: string[], tables: {family: object, sine: Int32Array},
 *   maxGaussians?: number, maxGaussiansPerByte?: number}} options
 * @returns {object} count, positions (N x 3), sh_dc (N x 3), sh_rest (N x R x 3), opacity,
 *   scales (N x 3), rotations (N x 4, w x y z), semantic (N x S) and semanticNames, labels,
 *   metadata {views, skipped}: the informative vdis record (§12.21; view_record.mjs)
 */
export function decodeScene(data, options) {
  const tiled = tiledScene(data, options);
  if (!tiled) return decodePrepared(prepareScene(data, options));
  return joinTiledScenes(tiled, tiled.tiles.map((_, i) => checkedTile(tiled, i, decodePrepared(tiled.prepare(i)))));
}

/**
 * A tiled file (§12.22) read and checked up to its tiles' decoding: {tiles (index entries),
 * containers (one per tile), layers, prepare(i) (tile i's prepareScene)}; null for a file
 * without a tile index. Tiles are prepared when decoded, so errors come in tile order.
 */
export function tiledScene(data, options) {
  const layers = new Set(['color', ...(options.layers || [])]);
  const container = readLayers(data, layers);
  if (!isTiled(container)) return null;
  const tiles = readTileIndex(container, data.length, options.maxGaussiansPerByte ?? MAX_GAUSSIANS_PER_BYTE);
  const containers = tiles.map((_, number) => tileContainer(container, number));
  const prepare = (i) => prepareContainer(containers[i], data.length, layers, options);
  return { tiles, containers, layers, prepare };
}

/** Tile ``i``'s decoded scene after checking it against its index entry (count, box). */
export function checkedTile(tiled, i, scene) {
  checkTile(scene, i, tiled.tiles[i], tiled.containers[i]);
  return scene;
}

/** The scene of a tiled file from its tiles' checked scenes, in tile order. */
export function joinTiledScenes(tiled, scenes) {
  checkSameKind(scenes, tiled.containers);
  return joinTiles(scenes);
}

/** The rest of decodeScene after prepareScene, on this thread. Errors come in the order the
 * reference decoder reports them: hyperprior cells, color streams in order, geometry. */
export function decodePrepared(prep) {
  const out = makeTargets(prep.header);
  let priors = new Map();
  let geometryDone = false;
  if (prep.modelled.size) {
    const cells = decodeTask(prep, out, 'GEOM');
    geometryDone = true;
    const cellLimit = 2 ** prep.prior.net.posBits;
    for (const axis of [cells.x, cells.y, cells.z]) {
      for (let i = 0; i < axis.length; i++) if (axis[i] >= cellLimit) throw new FormatError('the color hyperprior needs smaller cells', { chunk: 'CHYP' });
    }
    priors = channelPriors(prep.prior, cells, prep.header.count, prep.codes, prep.sine);
  }
  let axis = null;
  for (const code of prep.codes) {
    const result = decodeTask(prep, out, code, priors.get(code) || null, true);
    if (code === 'ROTN') axis = result;
  }
  if (!geometryDone) decodeTask(prep, out, 'GEOM');
  return finishScene(prep, out, axis);
}
