/** SHA-256 digests of decoded arrays in Node, the form the Python side compares against. */

import { createHash } from 'node:crypto';

import { anchorArrays } from './anchor_scene.mjs';
import { sceneArrays } from './scene.mjs';

/** Hex SHA-256 of a typed array's bytes (its view only, not the whole buffer). */
export function sha256(typed) {
  const bytes = new Uint8Array(typed.buffer, typed.byteOffset, typed.byteLength);
  return createHash('sha256').update(bytes).digest('hex');
}

/** {name: {shape, sha256}} of every array of a decoded scene (see sceneArrays, and
 * anchorArrays for an anchor scene). */
export function arrayDigests(scene) {
  const out = {};
  const arrays = scene.kind === 'anchors' ? anchorArrays(scene) : sceneArrays(scene);
  for (const [name, [values, shape]] of Object.entries(arrays)) out[name] = { shape, sha256: sha256(values) };
  return out;
}
