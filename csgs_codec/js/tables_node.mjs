/** Loads the frozen tables in Node from the package's data folder, SHA-256 checked. */

import { createHash } from 'node:crypto';
import { readFileSync } from 'node:fs';

import {
  GAUSSIAN_V1_SHA256, SINE_V1_SHA256, parseGaussianFamily, parseSineTable,
} from './tables.mjs';

const DATA = new URL('../entropy/data/', import.meta.url);

function verified(name, sha256) {
  const bytes = new Uint8Array(readFileSync(new URL(name, DATA)));
  const digest = createHash('sha256').update(bytes).digest('hex');
  if (digest !== sha256) throw new Error(`frozen table ${name} does not match its SHA-256`);
  return bytes;
}

/** The frozen tables {family, sine} for the decoders. */
export function loadTables() {
  return {
    family: parseGaussianFamily(verified('gaussian_v1.bin', GAUSSIAN_V1_SHA256)),
    sine: parseSineTable(verified('sine_v1.bin', SINE_V1_SHA256)),
  };
}
