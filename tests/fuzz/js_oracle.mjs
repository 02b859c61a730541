#!/usr/bin/env node
/**
 * The fuzz oracle's JavaScript side: decode each FILE with the receiver (csgs_codec/js/),
 * both layers, on this thread (an anchor scene, whose TOC lists ANCH, with
 * decodeAnchorScene; any other with decodeScene), and print one JSON line per file,
 * whatever happens:
 *
 *   {"ok": true, "kind", "count", "arrays": {name: {"shape", "sha256"}}, "semantic_names", "ms"}
 *   {"ok": false, "error": "FormatError" | "UnsupportedError", "chunk", "offset", "message", "ms"}
 *   {"ok": false, "error": "crash", "type", "message", "stack", "ms"}   (any other exception)
 *
 * A file with levels of detail (§12.22) is decoded at every level, level 0 first (the first
 * error ends it); the arrays of level k > 0 are named "lod<k>/<name>". Unlike decode_cli.mjs, an unexpected exception does not end the run: it is what a fuzz
 * campaign hunts for, and the other files of the batch are still decoded. The last line is
 * {"max_rss_bytes": ...}, the process's peak resident memory.
 *
 *   node tests/fuzz/js_oracle.mjs FILE...
 */

import { readFileSync } from 'node:fs';
import { performance } from 'node:perf_hooks';

import { decodeAnchorScene, isAnchorFile } from '../../csgs_codec/js/anchor_scene.mjs';
import { arrayDigests } from '../../csgs_codec/js/digests_node.mjs';
import { FormatError, UnsupportedError } from '../../csgs_codec/js/errors.mjs';
import { decodeScene, tiledScene } from '../../csgs_codec/js/scene.mjs';
import { levelCount } from '../../csgs_codec/js/tile_index.mjs';
import { loadTables } from '../../csgs_codec/js/tables_node.mjs';

/** Whether the TOC of `data` lists ANCH (false when the TOC is unreadable: either decoder
 * then refuses it the same way). */
function listsAnchors(data) {
  try {
    return isAnchorFile(data);
  } catch (err) {
    if (err instanceof FormatError) return false;
    throw err;
  }
}

/** The outcome of decoding `data` (see the header), without its time. */
async function outcome(data, tables) {
  try {
    const options = { layers: ['color', 'semantic'], tables };
    if (listsAnchors(data)) {
      const scene = await decodeAnchorScene(data, options);
      return { ok: true, kind: scene.kind ?? 'gaussians', count: scene.count, arrays: arrayDigests(scene), semantic_names: scene.semanticNames };
    }
    const scene = await decodeScene(data, options);
    const arrays = arrayDigests(scene);
    const tiled = tiledScene(data, options);
    for (let lod = 1; tiled && lod < levelCount(tiled.tiles); lod += 1) {
      const coarse = await decodeScene(data, { ...options, lod });
      for (const [name, digest] of Object.entries(arrayDigests(coarse))) arrays[`lod${lod}/${name}`] = digest;
    }
    return { ok: true, kind: scene.kind ?? 'gaussians', count: scene.count, arrays, semantic_names: scene.semanticNames };
  } catch (err) {
    if (err instanceof FormatError) return { ok: false, error: 'FormatError', chunk: err.chunk, offset: err.offset, message: err.message };
    if (err instanceof UnsupportedError) return { ok: false, error: 'UnsupportedError', chunk: null, offset: null, message: err.message };
    return {
      ok: false, error: 'crash', type: err?.constructor?.name ?? typeof err, message: String(err?.message ?? err), stack: String(err?.stack ?? '').slice(0, 2000),
    };
  }
}

const tables = loadTables();
for (const file of process.argv.slice(2)) {
  const data = new Uint8Array(readFileSync(file));
  const start = performance.now();
  const result = await outcome(data, tables);
  process.stdout.write(`${JSON.stringify({ file, ...result, ms: performance.now() - start })}\n`);
}
process.stdout.write(`${JSON.stringify({ max_rss_bytes: process.resourceUsage().maxRSS * 1024 })}\n`);
