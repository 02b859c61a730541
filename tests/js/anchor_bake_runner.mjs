/**
 * Test helper: bakes the anchor scene of a bundle (tests/js/array_bundle.py) read from stdin
 * with csgs_codec/js/anchor_bake.mjs and writes the baked scene's arrays as a bundle to
 * stdout. The input's meta holds F, K, the options and the semantic names.
 * Usage: node anchor_bake_runner.mjs < anchors.bundle > baked.bundle
 */

import { readFileSync, writeSync } from 'node:fs';

import { bakeAnchorScene } from '../../csgs_codec/js/anchor_bake.mjs';
import { pack, unpack } from './array_bundle.mjs';

const { arrays: a, shapes, meta } = unpack(new Uint8Array(readFileSync(0)));
const head = (name) => ({ w1: a[`${name}.w1`], b1: a[`${name}.b1`], w2: a[`${name}.w2`], b2: a[`${name}.b2`] });
const anchors = {
  count: shapes.positions[0], featDim: meta.feat_dim, nOffsets: meta.n_offsets,
  positions: a.positions, features: a.features, offsets: a.offsets, scaling: a.scaling,
  offsetMask: a.offset_mask,
  mlps: { opacity: head('opacity'), cov: head('cov'), color: head('color'),
    appearance: a.appearance || null, appearanceCount: a.appearance ? shapes.appearance[0] : 0 },
  viewOrigins: a.view_origins || null,
  semantic: a.semantic || null, semanticNames: meta.semantic_names || [], labels: a.labels || null,
};
const started = performance.now();
const baked = bakeAnchorScene(anchors, { ...meta.options, ...(a.origins ? { origins: a.origins } : {}) });
const ms = performance.now() - started;
const n = baked.count;
const out = {
  positions: [baked.positions, [n, 3]], sh_dc: [baked.sh_dc, [n, 3]],
  sh_rest: [baked.sh_rest, [n, baked.shCoefficients, 3]], opacity: [baked.opacity, [n]],
  scales: [baked.scales, [n, 3]], rotations: [baked.rotations, [n, 4]],
  anchor_index: [baked.anchorIndex, [n]],
};
if (baked.semantic) out.semantic = [baked.semantic, [n, baked.semanticNames.length]];
if (baked.labels) out.labels = [baked.labels, [n]];
const bytes = pack(out, { ms });
let at = 0;
while (at < bytes.length) at += writeSync(1, bytes, at, bytes.length - at);
