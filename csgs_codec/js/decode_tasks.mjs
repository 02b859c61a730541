/**
 * The tasks a standard scene's decode is made of, each a pure function of the prepared
 * scene (scene.mjs prepareContainer) and of the outputs of the tasks it needs, so that any
 * thread can run it: this one, a Node worker thread or a Web Worker (lane_server.mjs).
 *
 *   GEOM         positions (N x 3 float32) and grid cells of the base layer (§12.6, §12.7,
 *                §12.20)
 *   PRIOR/k      the color hyperprior's network (§12.19) on rows [start, end) of the cells
 *   SHDC...ROTN  one color stream (§12.8-§12.15); ROTN also returns the dropped components
 *   SEMANTIC     the SEMF or SEMC features and SEML or SEMR labels (§12.16, §12.23, §12.17, §12.25)
 *
 * decode_plan.mjs says which task needs which and in what order their errors count.
 */

import { decodePositions } from './base_layer.mjs';
import { decodeStream } from './color_layer.mjs';
import { STREAM_CHANNELS } from './color_prior.mjs';
import { FormatError } from './errors.mjs';
import { forwardIntNet } from './intnet.mjs';
import { decodeSemantic } from './semantic_layer.mjs';

/** The modelled channels of the color hyperprior in network-output order:
 * [{code, channel}] (§12.19: output j is the j-th set bit of the channel mask). */
export function modelledChannels(prior, codes) {
  const out = [];
  let t = 0;
  for (const code of codes) {
    for (let c = 0; c < STREAM_CHANNELS[code]; c++, t++) if (prior.mask[t]) out.push({ code, channel: c });
  }
  return out;
}

/**
 * The hyperprior's per-Gaussian mean (in steps) and scale-table index of every modelled
 * channel, for the Gaussians of ``cells`` ({x, y, z}: equal-length arrays of grid cells;
 * far points have cell (0, 0, 0)).
 * @returns {{mean: Float64Array[], scale: Uint8Array[]}} one array per modelled channel
 */
function priorRows(prep, cells) {
  const { prior } = prep;
  const n = cells.x.length;
  const cellLimit = 2 ** prior.net.posBits;
  for (const axis of [cells.x, cells.y, cells.z]) {
    for (let i = 0; i < n; i++) {
      if (axis[i] >= cellLimit) throw new FormatError('the color hyperprior needs smaller cells', { chunk: 'CHYP' });
    }
  }
  const out = forwardIntNet(prior.net, cells.x, cells.y, cells.z, n, prep.sine);
  const m = modelledChannels(prior, prep.codes).length;
  const width = 2 * m;
  const mean = [];
  const scale = [];
  for (let j = 0; j < m; j++) {
    const mu = new Float64Array(n);
    const s = new Uint8Array(n);
    for (let i = 0; i < n; i++) {
      mu[i] = Math.floor((out[i * width + j] + 32) / 64);
      s[i] = out[i * width + m + j];
    }
    mean.push(mu);
    scale.push(s);
  }
  return { mean, scale };
}

/**
 * Run one task.
 * @param {object} prep the prepared scene (or tile)
 * @param {string} task 'GEOM', 'PRIOR/k', a color stream code or 'SEMANTIC'
 * @param {object} inputs what decode_plan.mjs inputsFor gives the task
 * @param {object|null} target where a color stream writes its values ({array, stride,
 *   offset}); null: a new N x C array
 * @returns {object} the task's outputs (typed arrays, so that they transfer between threads)
 */
export function runTask(prep, task, inputs, target = null) {
  const n = prep.header.count;
  if (task === 'GEOM') {
    const positions = new Float32Array(3 * n);
    const cells = decodePositions(prep.container, prep.header, positions);
    return { positions, cells: { x: cells.x, y: cells.y, z: cells.z } };
  }
  if (task.startsWith('PRIOR/')) return priorRows(prep, inputs.cells);
  if (task === 'SEMANTIC') {
    const layer = { semantic: null, semanticNames: [], labels: null, instances: null };
    decodeSemantic(prep.container, prep.header, layer, prep.family);
    return layer;
  }
  const channels = STREAM_CHANNELS[task];
  const into = target || { array: new Float32Array(channels * n), stride: channels, offset: 0 };
  const attributes = task === 'ROTN'
    ? { logScales: () => inputs.logScales, opacity: () => inputs.opacity } : null;
  const axis = decodeStream(prep.container, prep.header, task, inputs.priors || null, prep.family, into, attributes, prep.shTransforms);
  return { values: into.array, axis };
}
