/**
 * Test helper: what a browser page does with an anchor file, in Node: decodeAnchorScene
 * (both layers), then bakeAnchorScene on its result as it is, and the baked scene's arrays
 * as a bundle (tests/js/array_bundle.py) on stdout.
 * Usage: node anchor_decode_bake.mjs FILE OPTIONS_JSON > baked.bundle
 */

import { readFileSync, writeSync } from 'node:fs';

import { bakeAnchorScene } from '../../csgs_codec/js/anchor_bake.mjs';
import { decodeAnchorScene } from '../../csgs_codec/js/anchor_scene.mjs';
import { loadTables } from '../../csgs_codec/js/tables_node.mjs';
import { pack } from './array_bundle.mjs';

const [file, options] = process.argv.slice(2);
const anchors = await decodeAnchorScene(new Uint8Array(readFileSync(file)), { layers: ['semantic'], tables: loadTables() });
const baked = bakeAnchorScene(anchors, JSON.parse(options));
const n = baked.count;
const out = {
  positions: [baked.positions, [n, 3]], sh_dc: [baked.sh_dc, [n, 3]],
  sh_rest: [baked.sh_rest, [n, baked.shCoefficients, 3]], opacity: [baked.opacity, [n]],
  scales: [baked.scales, [n, 3]], rotations: [baked.rotations, [n, 4]],
};
if (baked.semantic) out.semantic = [baked.semantic, [n, baked.semanticNames.length]];
if (baked.labels) out.labels = [baked.labels, [n]];
const bytes = pack(out);
let at = 0;
while (at < bytes.length) at += writeSync(1, bytes, at, bytes.length - at);
