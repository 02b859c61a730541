#!/usr/bin/env node
/**
 * Command line of the JavaScript receiver.
 *
 *   node decode_cli.mjs FILE... [--layers color|color,semantic] [--container] [--repeat N]
 *                                [--threads N] [--range-coder wasm|js] [--lod K]
 *
 * Prints one JSON object per file, one per line, with the file's name under "file". Scene mode (default): {"ok": true, "count": N, "arrays": {name:
 * {"shape": [...], "sha256": hex}}, "semantic_names": [...], "decode_s": seconds} where each
 * hash is the SHA-256 of the array's little-endian bytes in row-major order (positions,
 * sh_dc, sh_rest (N x R x 3), opacity, scales, rotations (w x y z) as float32; semantic as
 * float32; labels as int32) and "views", the vdis record (§12.21: source, count, left_out,
 * description) or null, with "kind": "gaussians". An anchor scene (§17, anchor_scene.mjs)
 * gives "kind": "anchors", the anchor count and the arrays of anchorArrays (positions,
 * features, offsets (M x K x 3), scaling, offset_mask (one byte 0/1 per slot), the MLP
 * arrays mlp.<head>.<w1|b1|w2|b2> and mlp.appearance, view_origins, semantic as float32;
 * labels as int32), decoded on this thread whatever --threads says. Container mode (--container): the header, every TOC entry and the
 * size and SHA-256 of each payload read. On a rejection: {"ok": false, "error":
 * "FormatError" | "UnsupportedError", "chunk": ..., "offset": ..., "message": ...}, exit
 * status 2 (FormatError) or 3 (unsupported); a file that is missing, a folder or unreadable
 * gives {"ok": false, "error": "InputError", "chunk": null, "offset": null, "message": ...}
 * and exit status 2 (the other files are still decoded; the status is the highest). A bad
 * command line (no file, an unknown option, a layer other than color and semantic, a missing
 * or non-numeric value) prints one usage line on stderr and exits with 2. --repeat N decodes N times and reports the
 * fastest decode_s (wall) and decode_cpu_s (CPU time of the process), and first_decode_s,
 * the first decode (before the JIT has warmed up); tables are loaded once, outside the
 * timing. --threads N (1..256, default 2, as the Python decoder's) decodes on N worker threads
 * (parallel_node.mjs); 1 on this thread only. --range-coder picks the WebAssembly loops (the
 * range decoder's and the integer network's; default) or plain JavaScript; same output.
 */

import { readFileSync, statSync } from 'node:fs';
import { performance } from 'node:perf_hooks';

import { decodeAnchorScene, isAnchorFile } from './anchor_scene.mjs';
import { LAYERS, readLayers } from './container.mjs';
import { arrayDigests, sha256 } from './digests_node.mjs';
import { FormatError, UnsupportedError } from './errors.mjs';
import { setIntNetKernel } from './intnet.mjs';
import { workerLanes } from './parallel_node.mjs';
import { setRangeCoder } from './range_decoder.mjs';
import { decodeScene } from './scene.mjs';
import { loadTables } from './tables_node.mjs';

function sceneSummary(scene) {
  const out = arrayDigests(scene);
  if (scene.kind === 'anchors') return { kind: 'anchors', count: scene.count, arrays: out, semantic_names: scene.semanticNames };
  const v = scene.metadata.views;
  const views = v && { source: v.source, count: v.count, left_out: v.leftOut, description: v.description };
  return { kind: 'gaussians', count: scene.count, arrays: out, semantic_names: scene.semanticNames, views };
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

const USAGE = 'usage: node decode_cli.mjs FILE... [--layers color|color,semantic] [--container] [--repeat N] [--threads N] [--range-coder wasm|js] [--lod K]';
const LAYER_NAMES = ['color', 'semantic'];

/** A bad command line: main prints its message and the usage on one line, exit status 2. */
class UsageError extends Error {}

/** The bytes of `file`, or null and the InputError result when it cannot be read. */
function readInput(file) {
  let info;
  try {
    info = statSync(file);
  } catch (err) {
    return [null, inputError(err.code === 'ENOENT' ? 'file not found' : `cannot read: ${err.code || err.message}`)];
  }
  // A folder or a FIFO is refused before reading: readFileSync would fail or block on it.
  if (!info.isFile()) return [null, inputError(info.isDirectory() ? 'is a folder, not a file' : 'is not a regular file')];
  try {
    return [new Uint8Array(readFileSync(file)), null];
  } catch (err) {
    return [null, inputError(`cannot read: ${err.code || err.message}`)];
  }
}

function inputError(message) {
  return [2, { ok: false, error: 'InputError', chunk: null, offset: null, message }];
}

async function decodeFile(file, wanted, container, repeat, tables, lanes, lod = null) {
  const [data, failure] = readInput(file);
  if (failure) return failure;
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
      const options = { layers: [...wanted], tables: loaded, lanes, lod };
      // Anchor scenes decode on this thread (their lanes are not implemented).
      scene = isAnchorFile(data) ? await decodeAnchorScene(data, options) : await decodeScene(data, options);
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
    if (err instanceof RangeError) return inputError(err.message); // a level the file lacks
    throw err;
  }
}

/** The value after option `args[i]`, or a UsageError when there is none. */
function valueOf(args, i) {
  if (i + 1 >= args.length || args[i + 1].startsWith('--')) throw new UsageError(`${args[i]} needs a value`);
  return args[i + 1];
}

/** Most worker threads --threads may start (each holds its own decoder; 100000 reached 13 GB). */
const MAX_THREADS = 256;

/** A positive integer option value (at most `most`), or a UsageError. */
function countOf(name, text, most = Number.MAX_SAFE_INTEGER, least = 1) {
  if (!/^[0-9]+$/.test(text) || Number(text) < least || Number(text) > most) {
    const range = most < Number.MAX_SAFE_INTEGER ? `${least}..${most}` : `>= ${least}`;
    throw new UsageError(`${name} must be a whole number ${range}, got '${text}'`);
  }
  return Number(text);
}

/**
 * The layer names of a --layers value: color and/or semantic, comma-separated; an empty value
 * is the base layer alone (container mode reads no other; the container vectors record it).
 */
function layersOf(text) {
  const names = text.split(',').map((s) => s.trim()).filter(Boolean);
  const unknown = names.filter((name) => !LAYER_NAMES.includes(name));
  if (unknown.length) throw new UsageError(`--layers takes color or color,semantic, got '${text}'`);
  return names;
}

/** The options of the command line `args` (process.argv without node and the script). */
function parseArgs(args) {
  const options = { files: [], layers: ['color'], container: false, repeat: 1, threads: 2, rangeCoder: 'wasm', lod: null };
  for (let i = 0; i < args.length; i++) {
    const arg = args[i];
    if (arg === '--layers') options.layers = layersOf(valueOf(args, i++));
    else if (arg === '--container') options.container = true;
    else if (arg === '--repeat') options.repeat = countOf(arg, valueOf(args, i++));
    else if (arg === '--threads') options.threads = countOf(arg, valueOf(args, i++), MAX_THREADS);
    else if (arg === '--lod') options.lod = countOf(arg, valueOf(args, i++), 15, 0);
    else if (arg === '--range-coder') {
      options.rangeCoder = valueOf(args, i++);
      if (!['wasm', 'js'].includes(options.rangeCoder)) throw new UsageError(`--range-coder takes wasm or js, got '${options.rangeCoder}'`);
    } else if (arg.startsWith('--')) throw new UsageError(`unknown option ${arg}`);
    else options.files.push(arg);
  }
  if (!options.files.length) throw new UsageError('give at least one FILE');
  return options;
}

async function main(argv) {
  let options;
  try {
    options = parseArgs(argv.slice(2));
  } catch (err) {
    if (!(err instanceof UsageError)) throw err;
    process.stderr.write(`decode_cli.mjs: error: ${err.message}; ${USAGE}\n`);
    return 2;
  }
  const { files, layers, container, repeat, threads, rangeCoder, lod } = options;
  setRangeCoder(rangeCoder);
  setIntNetKernel(rangeCoder);
  const wanted = new Set(layers);
  let loaded = null;
  const tables = () => { loaded = loaded || loadTables(); return loaded; };
  const lanes = threads > 1 && !container ? workerLanes(threads, rangeCoder) : [];
  let status = 0;
  try {
    for (const file of files) {
      const [code, result] = await decodeFile(file, wanted, container, repeat, tables, lanes, lod);
      status = Math.max(status, code);
      process.stdout.write(`${JSON.stringify({ file, ...result })}\n`);
    }
  } finally {
    await Promise.all(lanes.map((lane) => lane.close()));
  }
  return status;
}

process.exitCode = await main(process.argv);
