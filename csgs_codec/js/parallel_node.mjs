/**
 * Decode lanes on Node worker threads (worker_threads), for decodeScene's ``lanes`` option:
 * each is a RemoteLane (lane_client.mjs) whose thread runs worker_node.mjs.
 */

import { Worker } from 'node:worker_threads';

import { RemoteLane } from './lane_client.mjs';

/** A decode lane on one Node worker thread; the thread keeps the process alive only while
 * a task is waiting on it. */
export class WorkerLane extends RemoteLane {
  /** @param {string} rangeCoder 'wasm' or 'js' (see range_decoder.mjs setRangeCoder) */
  constructor(rangeCoder = 'wasm') {
    const worker = new Worker(new URL('./worker_node.mjs', import.meta.url), { workerData: { rangeCoder } });
    worker.unref();
    super({
      post: (message, transfer = []) => worker.postMessage(message, transfer),
      listen: (handler) => worker.on('message', handler),
      close: () => worker.terminate(),
    });
    this.worker = worker;
    worker.on('error', (err) => {
      for (const settle of this.waiting.values()) settle.reject(err);
      this.waiting.clear();
    });
  }

  /** As RemoteLane.run, holding the process open until the answer comes. */
  async run(plan, task, inputs) {
    this.worker.ref();
    try {
      return await super.run(plan, task, inputs);
    } finally {
      if (!this.waiting.size) this.worker.unref();
    }
  }
}

/** ``count`` worker-thread lanes. */
export function workerLanes(count, rangeCoder = 'wasm') {
  return Array.from({ length: count }, () => new WorkerLane(rangeCoder));
}
