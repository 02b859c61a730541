/** SHA-256 digests of decoded arrays in Node, the form the Python side compares against. */

import { createHash } from 'node:crypto';

import { sceneArrays } from './scene.mjs';

/** Hex SHA-256 of a typed array's bytes (its view only, not the whole buffer). */
export function sha256(typed) {
  const bytes = new Uint8Array(typed.buffer, typed.byteOffset, typed.byteLength);
  return createHash('sha256').update(bytes).digest('hex');
}

/** {name: {shape, sha256}} of every array of a decoded scene (see sceneArrays). */
export function arrayDigests(scene) {
  const out = {};
  for (const [name, [values, shape]] of Object.entries(sceneArrays(scene))) out[name] = { shape, sha256: sha256(values) };
  return out;
}
