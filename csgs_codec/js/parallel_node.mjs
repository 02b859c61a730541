/**
 * Decoding a standard scene on two threads in Node (worker_threads), like the Python
 * decoder's two threads: geometry and the color streams are independent (except where the
 * color hyperprior needs the geometry first; such files decode on one thread), so this thread
 * and a worker take them one at a time from a shared queue (largest estimated cost first),
 * writing into shared arrays.
 * The first error in the reference decoder's order (color streams in order, then geometry)
 * is the one raised, whichever lane found it.
 */

import { Worker } from 'node:worker_threads';

import { FormatError } from './errors.mjs';
import {
  checkedTile, decodePrepared, decodeTask, finishScene, joinTiledScenes, makeTargets, prepareScene, tiledScene,
} from './scene.mjs';

/** One worker thread that runs decode jobs one at a time. */
export class WorkerLane {
  /** @param {string} rangeCoder 'wasm' or 'js' (see range_decoder.mjs setRangeCoder) */
  constructor(rangeCoder = 'wasm') {
    this.worker = new Worker(new URL('./worker_node.mjs', import.meta.url), { workerData: { rangeCoder } });
    this.worker.unref();
  }

  /** Post ``job``; resolves with the worker's per-task results. */
  run(job) {
    return new Promise((resolve, reject) => {
      const onError = (err) => { this.worker.off('message', onMessage); reject(err); };
      const onMessage = (results) => { this.worker.off('error', onError); resolve(results); };
      this.worker.once('message', onMessage);
      this.worker.once('error', onError);
      this.worker.postMessage(job);
    });
  }

  /** Stop the worker. */
  close() { return this.worker.terminate(); }
}

/** Relative decode cost per payload byte (measured): the geometry's octree and the SH bands'
 * predicted channels cost more than the other streams. */
const COST_PER_BYTE = { GEOM: 3, SHBA: 2, SHBB: 2, SHBC: 2 };

/** ``tasks`` by estimated cost, largest first (both threads take them in this order). */
function byCost(tasks, sizes) {
  const cost = (task) => sizes[task] * (COST_PER_BYTE[task] || 1);
  return [...tasks].sort((a, b) => cost(b) - cost(a));
}

/** Run tasks claimed from the shared counter until none is left; per-task results. */
export function claimTasks(queue, counter, run) {
  const results = {};
  for (let i = Atomics.add(counter, 0, 1); i < queue.length; i = Atomics.add(counter, 0, 1)) {
    results[queue[i]] = run(queue[i]);
  }
  return results;
}

/**
 * Decode a standard scene using this thread and ``lane`` (a WorkerLane).
 * @param {Uint8Array} data
 * @param {object} options as decodeScene's
 * @param {WorkerLane|null} lane the second thread (null: decode on this thread only)
 * @returns {Promise<object>} the scene, as decodeScene returns it
 */
export async function decodeSceneParallel(data, options, lane) {
  const tiled = tiledScene(data, options);
  if (!tiled) return decodePreparedParallel(data, prepareScene(data, options), lane);
  const scenes = [];
  for (let i = 0; i < tiled.tiles.length; i++) {
    scenes.push(checkedTile(tiled, i, await decodePreparedParallel(data, tiled.prepare(i), lane)));
  }
  return joinTiledScenes(tiled, scenes);
}

/** The rest of decodeSceneParallel after a scene's (or one tile's) preparation. */
async function decodePreparedParallel(data, prep, lane) {
  if (!lane || prep.modelled.size) return decodePrepared(prep);
  const shared = new Uint8Array(new SharedArrayBuffer(data.length));
  shared.set(data);
  const out = makeTargets(prep.header, SharedArrayBuffer);
  const tasks = [...prep.codes, 'GEOM'];
  const sizes = {};
  for (const entry of prep.container.toc.entries) if (tasks.includes(entry.type)) sizes[entry.type] = (sizes[entry.type] || 0) + entry.length;
  for (const task of tasks) sizes[task] = sizes[task] || 0;
  const queue = byCost(tasks, sizes);
  const counter = new Int32Array(new SharedArrayBuffer(4));
  const entries = prep.container.toc.entries.filter((e) => tasks.includes(e.type) || e.type === 'OUTQ' || e.type === 'OUTL');
  const pending = lane.run({ data: shared, entries, header: prep.header, queue, counter, out });
  const results = claimTasks(queue, counter, (task) => {
    try {
      const value = decodeTask(prep, out, task);
      return { ok: true, axis: task === 'ROTN' ? value : null };
    } catch (err) {
      return { ok: false, error: err };
    }
  });
  Object.assign(results, await pending);
  for (const task of tasks) {
    const result = results[task];
    if (result.ok) continue;
    if (result.error) throw result.error;
    if (result.name === 'FormatError') throw new FormatError(result.detail, { chunk: result.chunk, offset: result.offset });
    throw new Error(result.detail);
  }
  return finishScene(prep, out, results.ROTN.axis);
}
