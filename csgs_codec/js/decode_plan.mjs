/**
 * The order of a standard scene's decode, written once (decode_tasks.mjs holds the tasks):
 * which task needs which outputs, the order in which their errors count, which tasks a first
 * frame needs, and how the outputs become the decoded scene.
 *
 * Error order is the reference decoder's (spec/FORMAT.md §12.4; csgs_codec/codec/decoder.py):
 * with the color hyperprior, geometry, then the network's cells, then the color streams in
 * order; without it, the color streams in order, then geometry; the semantic layer last.
 * Every task comes after the tasks it needs in that order, so a runner that reports the
 * failed task earliest in the order reports what the reference decoder reports, whatever
 * thread ran what.
 */

import { BAND_CODES, SH_REST, rotations } from './color_layer.mjs';
import { STREAM_CHANNELS } from './color_prior.mjs';
import { modelledChannels } from './decode_tasks.mjs';
import { readViews } from './view_record.mjs';

/** Relative decode cost per payload byte (measured): the geometry's octree and the SH bands'
 * predicted channels cost more than the other streams. */
const COST_PER_BYTE = { GEOM: 3, SHBA: 2, SHBB: 2, SHBC: 2 };
/** Relative cost of the hyperprior's network per Gaussian, per multiply-add of one row. */
const COST_PER_MAC = 1 / 128;

/** Stages of a decode, in the order a viewer can use them: 'first' draws the splats with
 * their base color (geometry, DC, opacity, scales, rotations), 'color' adds the SH bands,
 * 'semantic' the semantic layer. */
export const STAGES = ['first', 'color', 'semantic'];

/**
 * The plan of one prepared scene (or tile).
 * @param {object} prep from scene.mjs prepareContainer
 * @param {{priorParts?: number, stages?: string[]}} options priorParts: row ranges the
 *   hyperprior's network is split into (one per thread that decodes); stages: only the
 *   tasks of these stages (the semantic layer alone after the color layer, say)
 * @returns {{prep, order: string[], tasks: Map<string, {needs: string[], stage: string,
 *   cost: number, rows?: number[]}>, targets: object, channels: object[]}}
 */
export function planDecode(prep, { priorParts = 1, stages = STAGES } = {}) {
  const n = prep.header.count;
  const tasks = new Map();
  const sizes = payloadSizes(prep.container);
  const add = (name, needs, stage, cost, extra = {}) => tasks.set(name, { needs, stage, cost, ...extra });
  const modelled = prep.modelled;
  const parts = [];
  if (modelled.size) {
    const count = Math.max(1, Math.min(priorParts, Math.ceil(n / 1024)));
    const macs = prep.prior.net.layers.reduce((s, l) => s + l.in * l.out, 0);
    for (let k = 0; k < count; k++) {
      const rows = [Math.floor((k * n) / count), Math.floor(((k + 1) * n) / count)];
      parts.push(`PRIOR/${k}`);
      add(parts[k], ['GEOM'], 'first', (rows[1] - rows[0]) * macs * COST_PER_MAC, { rows });
    }
  }
  add('GEOM', [], 'first', 1 + (sizes.GEOM + sizes.OUTL + sizes.OUTQ) * COST_PER_BYTE.GEOM);
  for (const code of prep.codes) {
    const needs = modelled.has(code) ? [...parts] : [];
    if (code === 'ROTN') needs.push('OPAC', 'SCAL'); // scored steps read them (§12.8)
    const stage = BAND_CODES.includes(code) ? 'color' : 'first';
    add(code, needs, stage, 1 + sizes[code] * (COST_PER_BYTE[code] || 1));
  }
  const order = modelled.size ? ['GEOM', ...parts, ...prep.codes] : [...prep.codes, 'GEOM'];
  if (prep.layers.has('semantic')) {
    add('SEMANTIC', [], 'semantic', 1 + sizes.SEMF + sizes.SEMC + sizes.SEML + sizes.SEMR);
    order.push('SEMANTIC');
  }
  const channels = modelled.size ? modelledChannels(prep.prior, prep.codes) : [];
  const kept = order.filter((name) => stages.includes(tasks.get(name).stage));
  for (const name of kept) {
    if (!tasks.get(name).needs.every((need) => kept.includes(need))) throw new Error(`task ${name} needs a stage left out`);
  }
  const color = kept.some((name) => name in STREAM_CHANNELS);
  return { prep, order: kept, tasks, targets: makeTargets(prep.header, color), channels };
}

/** Payload bytes per chunk type of a container (0 for a type it lacks). */
function payloadSizes(container) {
  const sizes = new Proxy({}, { get: (t, k) => t[k] || 0 });
  for (const e of container.toc.entries) sizes[e.type] += e.length;
  return sizes;
}

/**
 * The output arrays of the color streams ({array, stride, offset} each, the SH bands
 * interleaved in one N x R x 3 array, zero where a band is stored but not coded) of a scene
 * header; without ``color`` (no color stream decoded) the N x R x 3 array is left out.
 */
function makeTargets(header, color) {
  const n = header.count;
  const restCount = SH_REST[header.stored];
  const shRest = new Float32Array(color ? n * restCount * 3 : 0);
  const targets = { shRest };
  for (const code of ['SHDC', 'OPAC', 'SCAL', 'ROTN']) {
    targets[code] = { array: null, stride: STREAM_CHANNELS[code], offset: 0 };
  }
  BAND_CODES.forEach((code, b) => { targets[code] = { array: shRest, stride: restCount * 3, offset: SH_REST[b] * 3 }; });
  return targets;
}

/** Where a task running on this thread writes its values (null: an array of its own). */
export function targetFor(plan, task) {
  return BAND_CODES.includes(task) ? plan.targets[task] : null;
}

/** What ``task`` takes from the outputs of the tasks it needs (``results``: Map). */
export function inputsFor(plan, task, results) {
  const spec = plan.tasks.get(task);
  if (task.startsWith('PRIOR/')) {
    const [start, end] = spec.rows;
    const { cells } = results.get('GEOM');
    const slice = (axis) => {
      const out = new Uint32Array(end - start); // far points (after the grid's) stay (0, 0, 0)
      out.set(axis.subarray(Math.min(start, axis.length), Math.min(end, axis.length)));
      return out;
    };
    return { cells: { x: slice(cells.x), y: slice(cells.y), z: slice(cells.z) } };
  }
  if (!(task in STREAM_CHANNELS)) return {};
  const inputs = {};
  if (plan.prep.modelled.has(task)) inputs.priors = streamPriors(plan, task, results);
  if (task === 'ROTN') {
    inputs.logScales = results.get('SCAL').values;
    inputs.opacity = results.get('OPAC').values;
  }
  return inputs;
}

/** The hyperprior's priors of one stream's modelled channels, joined over the network's row
 * ranges: Map(channel -> {mean: Float64Array(N), scale: Uint8Array(N)}). */
function streamPriors(plan, code, results) {
  const parts = plan.order.filter((name) => name.startsWith('PRIOR/')).map((name) => results.get(name));
  const n = plan.prep.header.count;
  const priors = new Map();
  plan.channels.forEach(({ code: owner, channel }, j) => {
    if (owner !== code) return;
    const mean = parts.length === 1 ? parts[0].mean[j] : new Float64Array(n);
    const scale = parts.length === 1 ? parts[0].scale[j] : new Uint8Array(n);
    if (parts.length > 1) {
      let at = 0;
      for (const part of parts) {
        mean.set(part.mean[j], at);
        scale.set(part.scale[j], at);
        at += part.mean[j].length;
      }
    }
    priors.set(channel, { mean, scale });
  });
  return priors;
}

/** Keep a finished task's outputs; values decoded elsewhere into an array of their own are
 * copied into their interleaved target (the SH bands). */
export function accept(plan, task, outputs, results) {
  const target = plan.targets[task];
  if (target && target.array && outputs.values !== target.array) {
    const channels = STREAM_CHANNELS[task];
    const { array, stride, offset } = target;
    const values = outputs.values;
    const n = plan.prep.header.count;
    for (let i = 0; i < n; i++) {
      for (let c = 0; c < channels; c++) array[i * stride + offset + c] = values[i * channels + c];
    }
    outputs.values = array;
  }
  results.set(task, outputs);
}

/**
 * The decoded scene of a plan's outputs: count, positions (N x 3), sh_dc (N x 3), sh_rest
 * (N x R x 3), opacity (N), scales (N x 3), rotations (N x 4, w x y z), semantic (N x S) and
 * semanticNames, labels, metadata {views, skipped} (the vdis record, §12.21).
 * ``stage`` 'first' gives the scene a first frame can draw: no SH bands (R = 0), no
 * semantic layer, and ``complete`` false when the whole scene has SH coefficients
 * (``shCoefficients`` R of them per color channel).
 */
export function sceneOf(plan, results, stage = 'semantic') {
  const n = plan.prep.header.count;
  const rotn = results.get('ROTN');
  rotn.quaternions ??= rotations(rotn.axis, rotn.values, n);
  const semantic = stage === 'semantic' ? results.get('SEMANTIC') : null;
  return {
    count: n,
    positions: results.get('GEOM').positions,
    sh_dc: results.get('SHDC').values,
    sh_rest: stage === 'first' ? new Float32Array(0) : plan.targets.shRest,
    opacity: results.get('OPAC').values,
    scales: results.get('SCAL').values,
    rotations: rotn.quaternions,
    semantic: semantic ? semantic.semantic : null,
    semanticNames: semantic ? semantic.semanticNames : [],
    labels: semantic ? semantic.labels : null,
    instances: semantic ? semantic.instances || null : null,
    metadata: readViews(plan.prep.container),
    complete: stage !== 'first' || plan.targets.shRest.length === 0,
    shCoefficients: SH_REST[plan.prep.header.stored],
  };
}
