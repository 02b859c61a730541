#!/usr/bin/env node
/**
 * Command line of the JavaScript receiver.
 *
 *   node decode_cli.mjs FILE... [--layers color|color,semantic] [--container] [--repeat N]
 *                                [--threads N] [--range-coder wasm|js]
 *
 * Prints one JSON object per file, one per line, with the file's name under "file". Scene mode (default): {"ok": true, "count": N, "arrays": {name:
 * {"shape": [...], "sha256": hex}}, "semantic_names": [...], "decode_s": seconds} where each
 * hash is the SHA-256 of the array's little-endian bytes in row-major order (positions,
 * sh_dc, sh_rest (N x R x 3), opacity, scales, rotations (w x y z) as float32; semantic as
 * float32; labels as int32) and "views", the vdis record (§12.21: source, count, left_out,
 * description) or null. Container mode (--container): the header, every TOC entry and the
 * size and SHA-256 of each payload read. On a rejection: {"ok": false, "error":
 * "FormatError" | "UnsupportedError", "chunk": ..., "offset": ..., "message": ...}, exit
 * status 2 (FormatError) or 3 (unsupported). --repeat N decodes N times and reports the
 * fastest decode_s (wall) and decode_cpu_s (CPU time of the process), and first_decode_s,
 * the first decode (before the JIT has warmed up); tables are loaded once, outside the
 * timing. --threads N (default 2, as the Python decoder's) decodes on N worker threads
 * (parallel_node.mjs); 1 on this thread only. --range-coder picks the WebAssembly loops (the
 * range decoder's and the integer network's; default) or plain JavaScript; same output.
 */

import { createHash } from 'node:crypto';
import { readFileSync } from 'node:fs';
import { performance } from 'node:perf_hooks';

import { LAYERS, readLayers } from './container.mjs';
import { FormatError, UnsupportedError } from './errors.mjs';
import { setIntNetKernel } from './intnet.mjs';
import { workerLanes } from './parallel_node.mjs';
import { setRangeCoder } from './range_decoder.mjs';
import { decodeScene, sceneArrays } from './scene.mjs';
import { loadTables } from './tables_node.mjs';

function sha256(typed) {
  const bytes = new Uint8Array(typed.buffer, typed.byteOffset, typed.byteLength);
  return createHash('sha256').update(bytes).digest('hex');
}

function sceneSummary(scene) {
  const out = {};
  for (const [name, [values, shape]] of Object.entries(sceneArrays(scene))) out[name] = { shape, sha256: sha256(values) };
  const v = scene.metadata.views;
  const views = v && { source: v.source, count: v.count, left_out: v.leftOut, description: v.description };
  return { count: scene.count, arrays: out, semantic_names: scene.semanticNames, views };
}

function containerSummary(data, layers) {
  const { toc, payloads } = readLayers(data, layers);
  const last = toc.entries.length ? toc.entries[toc.entries.length - 1].end : toc.tocEnd;
  return {
    major_version: toc.major,
    minor_version: toc.minor,
    flags: toc.flags,
    complete: data.length >= last,
    toc: toc.entries.map((e) => ({ type: e.type, layer: LAYERS[e.layer], tile: e.tile, offset: e.offset, length: e.length, critical: e.critical })),
    payloads: [...payloads.entries()].map(([index, p]) => ({ index, bytes: p.length, sha256: sha256(p) })),
  };
}

async function decodeFile(file, wanted, container, repeat, tables, lanes) {
  const data = new Uint8Array(readFileSync(file));
  try {
    if (container) return [0, { ok: true, ...containerSummary(data, wanted) }];
    let best = Infinity;
    let bestCpu = Infinity;
    let first = null;
    let scene = null;
    const loaded = tables();
    for (let i = 0; i < repeat; i++) {
      const cpu = process.cpuUsage();
      const start = performance.now();
      scene = await decodeScene(data, { layers: [...wanted], tables: loaded, lanes });
      const wall = (performance.now() - start) / 1000;
      const used = process.cpuUsage(cpu);
      first = first ?? wall;
      best = Math.min(best, wall);
      bestCpu = Math.min(bestCpu, (used.user + used.system) / 1e6);
    }
    return [0, { ok: true, ...sceneSummary(scene), decode_s: best, decode_cpu_s: bestCpu, first_decode_s: first }];
  } catch (err) {
    if (err instanceof FormatError || err instanceof UnsupportedError) {
      const format = err instanceof FormatError;
      return [format ? 2 : 3, {
        ok: false, error: err.name, chunk: format ? err.chunk : null, offset: format ? err.offset : null, message: err.message,
      }];
    }
    throw err;
  }
}

async function main(argv) {
  const args = argv.slice(2);
  const files = [];
  let layers = ['color'];
  let container = false;
  let repeat = 1;
  let threads = 2;
  let rangeCoder = 'wasm';
  for (let i = 0; i < args.length; i++) {
    if (args[i] === '--layers') layers = args[++i].split(',').map((s) => s.trim()).filter(Boolean);
    else if (args[i] === '--container') container = true;
    else if (args[i] === '--repeat') repeat = Math.max(1, parseInt(args[++i], 10));
    else if (args[i] === '--threads') threads = Math.max(1, parseInt(args[++i], 10));
    else if (args[i] === '--range-coder') rangeCoder = args[++i];
    else files.push(args[i]);
  }
  if (!files.length) {
    process.stderr.write('usage: node decode_cli.mjs FILE... [--layers color,semantic] [--container] [--repeat N] [--threads N] [--range-coder wasm|js]\n');
    return 64;
  }
  setRangeCoder(rangeCoder);
  setIntNetKernel(rangeCoder);
  const wanted = new Set(layers);
  let loaded = null;
  const tables = () => { loaded = loaded || loadTables(); return loaded; };
  const lanes = threads > 1 && !container ? workerLanes(threads, rangeCoder) : [];
  let status = 0;
  try {
    for (const file of files) {
      const [code, result] = await decodeFile(file, wanted, container, repeat, tables, lanes);
      status = Math.max(status, code);
      process.stdout.write(`${JSON.stringify({ file, ...result })}\n`);
    }
  } finally {
    await Promise.all(lanes.map((lane) => lane.close()));
  }
  return status;
}

process.exitCode = await main(process.argv);
