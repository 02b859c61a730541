/**
 * Decoding an anchor scene (spec/FORMAT.md §17): the anchors, their attributes and the
 * Scaffold-GS MLPs, in the reference decoder's order of reads and checks, so that a damaged
 * file is refused at the same chunk and byte offset. Plain ES module without Node imports:
 * the browser imports it as it is.
 *
 *   const scene = await decodeAnchorScene(bytes, {layers: ['semantic'], tables});
 */

import {
  decodeAnchorMajor, decodeFeatures, decodeOffsets, groupBounds, readStreamList, splitOutputs,
} from './anchor_attributes.mjs';
import { HEADS, readAnchorHeader, readMlps, readOffsetMasks, readViewOrigins } from './anchor_payloads.mjs';
import { ByteReader } from './bytes.mjs';
import { single } from './chunks.mjs';
import { readLayers, readToc } from './container.mjs';
import { parseDenseNet } from './dense_net.mjs';
import { FormatError } from './errors.mjs';
import { decodeGeometry } from './geometry.mjs';
import { forwardIntNet, parseIntNet } from './intnet.mjs';
import { readAnyLabels, readNames } from './semantic_layer.mjs';

const MAX_SEMANTIC_CHANNELS = 4096;
/** Most anchor values (M x (F + 3K + 6)) a file may declare per byte present (§10.1), as
 * the reference decoder's limit. */
const MAX_ANCHOR_VALUES_PER_BYTE = 256;

/** Whether the file's TOC lists an ANCH chunk (reads the header and TOC only; a FormatError
 * when they are invalid). */
export function isAnchorFile(data) {
  return readToc(data).entries.some((e) => e.type === 'ANCH');
}

/** The network of an AHYP or SHYP payload, which must take cells of ``posBits`` bits:
 * {net, offset (of the payload)}. */
function positionNetwork(container, code, posBits, family) {
  const [data, offset] = single(container, code);
  const net = parseIntNet(data, family, code, offset);
  if (net.posBits !== posBits) throw new FormatError(`network pos_bits ${net.posBits} differs from the grid's ${posBits}`, { chunk: code, offset });
  return { net, offset };
}

/** FormatError naming ``code`` at ``offset`` unless ``net`` has ``width`` outputs. */
function checkOutputs(net, width, code, offset) {
  const out = net.layers[net.layers.length - 1].out;
  if (out !== width) throw new FormatError(`hyperprior has ${out} outputs, the layout needs ${width}`, { chunk: code, offset });
}

/** Output width of a hyperprior for attribute types of ``channels`` channels (§17.2). */
function hyperWidth(channels) { return channels.reduce((sum, c) => sum + 2 * c + 1, 0); }

/** The M anchor cells of GEOM (§17.1), checked against the header. */
function anchorCells(container, header) {
  const [data, offset] = single(container, 'GEOM');
  let cells;
  try {
    cells = decodeGeometry(data, header.count);
  } catch (err) {
    if (err instanceof FormatError) throw new FormatError(err.detail, { chunk: 'GEOM', offset: offset + (err.offset ?? 0) });
    throw err;
  }
  if (cells.count !== header.count) throw new FormatError(`geometry holds ${cells.count} anchors, the header ${header.count}`, { chunk: 'GEOM', offset });
  const limit = 2 ** Math.max(header.gridBits, 1);
  for (const axis of [cells.x, cells.y, cells.z]) {
    for (let i = 0; i < axis.length; i++) if (axis[i] >= limit) throw new FormatError('an anchor cell lies outside the header\'s grid', { chunk: 'GEOM', offset });
  }
  return cells;
}

/** float32(origin + cell voxel_size) of every anchor, in float64 first (§17.1). */
function anchorPositions(cells, header) {
  const positions = new Float32Array(3 * cells.count);
  const axes = [cells.x, cells.y, cells.z];
  for (let i = 0; i < cells.count; i++) {
    for (let d = 0; d < 3; d++) positions[3 * i + d] = header.origin[d] + axes[d][i] * header.voxelSize;
  }
  if (!positions.every(Number.isFinite)) throw new FormatError('anchor positions overflow float32', { chunk: 'ANCH' });
  return positions;
}

/** The G - 1 CARM networks of ACRM (§17.5), each checked against its group. */
function carmNetworks(container, header, family) {
  const [data, offset] = single(container, 'ACRM');
  const bounds = groupBounds(header.featDim, header.carmGroups);
  return readStreamList(data, offset, 'ACRM', header.carmGroups - 1).map(([payload, at], i) => {
    const net = parseDenseNet(payload, family, 'ACRM', at);
    const [lo, hi] = bounds[i + 1];
    if (net.inWidth !== lo || net.outWidth !== 2 * (hi - lo)) {
      throw new FormatError(`CARM network ${i} (${net.inWidth} -> ${net.outWidth}) does not fit ${lo} decoded channels and a group of ${hi - lo}`, { chunk: 'ACRM', offset: at });
    }
    return net;
  });
}

/** SHYP and ASEM (§17.11): {names, values (M x S float32)}, or null when neither is there. */
function anchorSemantic(container, cells, posBits, family, sine) {
  const present = new Set(container.toc.entries.map((e) => e.type));
  if (present.has('ASEM') !== present.has('SHYP')) {
    throw new FormatError('ASEM and SHYP must both be present or both absent', { chunk: present.has('ASEM') ? 'SHYP' : 'ASEM' });
  }
  if (!present.has('ASEM')) return null;
  const { net, offset: netOffset } = positionNetwork(container, 'SHYP', posBits, family);
  const [data, offset] = single(container, 'ASEM');
  const r = new ByteReader(data, offset, 'ASEM');
  const names = readNames(r, MAX_SEMANTIC_CHANNELS);
  const stream = r.byteString('stream');
  r.expectEnd('the semantic payload');
  checkOutputs(net, hyperWidth([names.length]), 'SHYP', netOffset);
  const [params] = splitOutputs(forwardIntNet(net, cells.x, cells.y, cells.z, cells.count, sine), cells.count, [names.length]);
  return { names, values: decodeAnchorMajor(stream, r.offset - stream.length, params, family, 'ASEM') };
}

/**
 * Decode an anchor scene.
 * @param {Uint8Array} data the .csgs bytes (or a prefix holding the requested layers)
 * @param {{layers?: string[], tables: {family: object, sine: Int32Array}}} options layers:
 *   [] or ['color'] (never reads a semantic byte), or ['semantic'] / ['color', 'semantic']
 * @returns {Promise<object>} {kind: 'anchors', count M, featDim F, nOffsets K, header (ANCH),
 *   positions (M x 3), features (M x F), offsets (M x K x 3, masked ones 0), scaling (M x 6),
 *   offsetMask (M x K, Uint8Array 0/1), mlps (null or {opacity, cov, color, appearance,
 *   appearanceCount, appearanceWidth}, see anchor_payloads.mjs readMlps: what
 *   anchor_bake.mjs bakeAnchorScene takes), viewOrigins (V x 3 or null), semantic (M x S or null),
 *   semanticNames, labels (Int32Array M or null)}; float32 arrays, row-major
 */
export async function decodeAnchorScene(data, options) {
  const { family, sine } = options.tables;
  const layers = new Set(['color', ...(options.layers || [])]);
  const container = readLayers(data, layers);
  const [anch, anchOffset] = single(container, 'ANCH');
  const header = readAnchorHeader(anch, anchOffset);
  const m = header.count;
  const k = header.nOffsets;
  const values = m * (header.featDim + 3 * k + 6);
  const limit = (options.maxValuesPerByte ?? MAX_ANCHOR_VALUES_PER_BYTE) * data.length;
  if (values > limit) {
    throw new FormatError(`declares ${m} anchors (${values} values) in a ${data.length}-byte file, above this decoder's limit of ${limit} values`, { chunk: 'ANCH', offset: anchOffset });
  }
  const cells = anchorCells(container, header);
  const positions = anchorPositions(cells, header);
  const posBits = Math.max(header.gridBits, 1);
  const channels = [header.featDim, 3 * k, 6];
  const { net: hyper, offset: hyperOffset } = positionNetwork(container, 'AHYP', posBits, family);
  checkOutputs(hyper, hyperWidth(channels), 'AHYP', hyperOffset);
  const carm = carmNetworks(container, header, family);
  const offsetMask = readOffsetMasks(...single(container, 'AMSK'), m, k);
  const mlps = header.hasMlps ? readMlps(...single(container, 'AMLP'), header.featDim, k, family) : null;
  const [pf, po, ps] = splitOutputs(forwardIntNet(hyper, cells.x, cells.y, cells.z, m, sine), m, channels);
  const [afea, afeaOffset] = single(container, 'AFEA');
  const features = decodeFeatures(readStreamList(afea, afeaOffset, 'AFEA', header.carmGroups), pf, carm, family);
  const offsets = decodeOffsets(...single(container, 'AOFF'), po, offsetMask, family);
  const scaling = decodeAnchorMajor(...single(container, 'ASCL'), ps, family, 'ASCL');
  const scene = {
    kind: 'anchors', count: m, featDim: header.featDim, nOffsets: k, header, positions, features,
    offsets, scaling, offsetMask, mlps, viewOrigins: readViewOrigins(container),
    semantic: null, semanticNames: [], labels: null,
  };
  if (layers.has('semantic')) {
    const semantic = anchorSemantic(container, cells, posBits, family, sine);
    if (semantic) [scene.semanticNames, scene.semantic] = [semantic.names, semantic.values];
    scene.labels = readAnyLabels(container, m, family);
  }
  return scene;
}

/** The decoded arrays of an anchor scene for hashing: {name: [typed array, shape]} in the
 * layout of the reference decoder's AnchorScene (float32; offset_mask one byte 0/1 per
 * slot; labels int32), the MLP arrays as ``mlp.<head>.<w1|b1|w2|b2>`` and
 * ``mlp.appearance``; view_origins, semantic and labels when present. */
export function anchorArrays(scene) {
  const { count: m, featDim: f, nOffsets: k } = scene;
  const arrays = {
    positions: [scene.positions, [m, 3]],
    features: [scene.features, [m, f]],
    offsets: [scene.offsets, [m, k, 3]],
    scaling: [scene.scaling, [m, 6]],
    offset_mask: [scene.offsetMask, [m, k]],
  };
  if (scene.mlps) {
    for (const [name] of HEADS) {
      const { hidden, inputs, outputs, w1, b1, w2, b2 } = scene.mlps[name];
      Object.assign(arrays, {
        [`mlp.${name}.w1`]: [w1, [hidden, inputs]], [`mlp.${name}.b1`]: [b1, [hidden]],
        [`mlp.${name}.w2`]: [w2, [outputs, hidden]], [`mlp.${name}.b2`]: [b2, [outputs]],
      });
    }
    const { appearance, appearanceCount, appearanceWidth } = scene.mlps;
    if (appearance) arrays['mlp.appearance'] = [appearance, [appearanceCount, appearanceWidth]];
  }
  if (scene.viewOrigins) arrays.view_origins = [scene.viewOrigins, [scene.viewOrigins.length / 3, 3]];
  if (scene.semantic) arrays.semantic = [scene.semantic, [m, scene.semanticNames.length]];
  if (scene.labels) arrays.labels = [scene.labels, [m]];
  return arrays;
}
